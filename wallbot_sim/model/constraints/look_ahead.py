"""Look-ahead point task: a point a distance L ahead of the centre follows the reference.

The point is (x, y) + L (cos th, sin th); its reference is the path point shifted by L along the
path's tangent, so when the point is on its reference and the robot faces along the path, the
centre is exactly on the path. Unlike the centre task with a heading task, these two rows never
conflict with non-lateral motion: a robot that cannot move sideways can still steer a point ahead
of it anywhere. This is the task a tracking controller imposes on a driven robot.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wallbot_sim.model.constraints.base import BaumgarteGains
from wallbot_sim.model.numbers import POSITIVE
from wallbot_sim.model.trajectories import Reference, ReferenceSample, Vec2, tangent_heading


class PointReference(NamedTuple):
    """The look-ahead point's reference at one instant, and the direction it was shifted along."""

    position: Vec2
    velocity: Vec2
    acceleration: Vec2
    direction: float
    """The path's tangent heading, or the direction at rest the shift kept (rad)."""


def point_reference(sample: ReferenceSample, distance: float, direction_at_rest: float = 0.0) -> PointReference:
    """The reference ``sample`` shifted ``distance`` ahead along the path's tangent, with its derivatives.

    At rest the path has no tangent: the shift is along ``direction_at_rest``, not turning.
    """
    heading = tangent_heading(sample)
    angle, rate, turn = (direction_at_rest, 0.0, 0.0) if heading is None else heading
    along_x, along_y = math.cos(angle), math.sin(angle)  # the normal is (-along_y, along_x)
    (x, y), (vx, vy), (ax, ay) = sample.position, sample.velocity, sample.acceleration
    swing, centripetal = distance * rate, rate * rate
    return PointReference((x + distance * along_x, y + distance * along_y),
                          (vx - swing * along_y, vy + swing * along_x),
                          (ax + distance * (-turn * along_y - centripetal * along_x),
                           ay + distance * (turn * along_x - centripetal * along_y)),
                          angle)


class LookAheadPointTask:
    """Rows [[1, 0, -L sin th], [0, 1, L cos th]]; b = point reference acceleration, stabilized."""

    name = 'look_ahead'

    def __init__(self, reference: Reference, gains: BaumgarteGains, distance: float) -> None:
        POSITIVE.check('look-ahead distance', distance)
        self.reference = reference
        self.gains = gains
        self.distance = distance
        self._last_direction = 0.0

    def point_reference(self, t: float) -> tuple[Vec2, Vec2, Vec2]:
        """Position, velocity and acceleration of the point's reference at t (at rest: shifted along the
        last direction of travel)."""
        point = point_reference(self.reference.sample(t), self.distance, self._last_direction)
        self._last_direction = point.direction
        return point.position, point.velocity, point.acceleration

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        position, velocity, acceleration = self.point_reference(t)
        cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
        length, thd = self.distance, qd[2]
        point = q[:2] + length * np.array([cos_t, sin_t])
        point_velocity = qd[:2] + length * thd * np.array([-sin_t, cos_t])
        rows = np.zeros((2, 7))
        rows[0, 0] = rows[1, 1] = 1.0
        rows[0, 2], rows[1, 2] = -length * sin_t, length * cos_t
        rhs = (acceleration - 2.0 * self.gains.alpha * (point_velocity - velocity)
               - self.gains.beta ** 2 * (point - position) + length * thd * thd * np.array([cos_t, sin_t]))
        return rows, rhs
