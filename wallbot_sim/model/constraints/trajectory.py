"""Task constraints: the centre follows a reference point, optionally heading along its tangent."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.constraints.base import BaumgarteGains
from wallbot_sim.model.trajectories import Reference, tangent_heading

_UNIT_XY = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                     [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
_UNIT_TH = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]])


def wrap_angle(angle: float) -> float:
    """The angle in (-pi, pi]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


class TrajectoryTask:
    """(x, y) = p_d(t), stabilized: xdd = pdd_d - 2 alpha ed - beta^2 e (paper eq. 42)."""

    name = 'trajectory'

    def __init__(self, reference: Reference, gains: BaumgarteGains) -> None:
        self.reference = reference
        self.gains = gains

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ref = self.reference.sample(t)
        two_alpha, beta2 = 2.0 * self.gains.alpha, self.gains.beta ** 2
        position, velocity = q[:2].tolist(), qd[:2].tolist()
        b = np.array([
            ref.acceleration[i] - two_alpha * (velocity[i] - ref.velocity[i]) - beta2 * (position[i] - ref.position[i])
            for i in (0, 1)])
        return _UNIT_XY, b


class TangentHeadingTask:
    """th = atan2(yd_d, xd_d): the robot faces along the reference path.

    While the reference is at rest it has no direction; the task then holds the current
    heading (thdd = -2 alpha thd).
    """

    name = 'tangent_heading'

    def __init__(self, reference: Reference, gains: BaumgarteGains) -> None:
        self.reference = reference
        self.gains = gains

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        heading = tangent_heading(self.reference.sample(t))
        two_alpha, theta, rate = 2.0 * self.gains.alpha, float(q[2]), float(qd[2])
        if heading is None:
            return _UNIT_TH, np.array([-two_alpha * rate])
        error = wrap_angle(theta - heading.angle)
        return _UNIT_TH, np.array([heading.acceleration - two_alpha * (rate - heading.rate)
                                   - self.gains.beta ** 2 * error])
