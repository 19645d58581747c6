"""Look-ahead point task: a point a distance L ahead of the centre follows the reference.

The point is (x, y) + L (cos th, sin th); its reference is the path point shifted by L along the
path's tangent, so when the point is on its reference and the robot faces along the path, the
centre is exactly on the path. Unlike the centre task with a heading task, these two rows never
conflict with non-lateral motion: a robot that cannot move sideways can still steer a point ahead
of it anywhere. This is the task a tracking controller imposes on a driven robot.
"""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.constraints.base import BaumgarteGains
from wallbot_sim.model.numbers import POSITIVE
from wallbot_sim.model.trajectories import Reference, tangent_heading


class LookAheadPointTask:
    """Rows [[1, 0, -L sin th], [0, 1, L cos th]]; b = point reference acceleration, stabilized."""

    name = 'look_ahead'

    def __init__(self, reference: Reference, gains: BaumgarteGains, distance: float) -> None:
        POSITIVE.check('look-ahead distance', distance)
        self.reference = reference
        self.gains = gains
        self.distance = distance
        self._last_direction = 0.0

    def point_reference(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration of the point's reference at t."""
        sample = self.reference.sample(t)
        heading = tangent_heading(sample)
        if heading is None:  # at rest: keep shifting along the last direction of travel
            angle, rate, acceleration = self._last_direction, 0.0, 0.0
        else:
            angle, rate, acceleration = heading
            self._last_direction = angle
        along = np.array([math.cos(angle), math.sin(angle)])
        normal = np.array([-along[1], along[0]])
        length = self.distance
        return (np.add(sample.position, length * along),
                np.add(sample.velocity, length * rate * normal),
                np.add(sample.acceleration, length * (acceleration * normal - rate * rate * along)))

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
