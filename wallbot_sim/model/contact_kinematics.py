"""How each wheel's contact point moves on the wall (docs/model.md 11.3).

Wheel i touches the wall below its axle d_i = (a_i, s_i). Its contact point moves, in body axes,
with the chassis point d_i less the wheel's rolling:

    v_i = (v_long - s_i thd - r pd_i,  v_lat + a_i thd) = J_i(th) qd.

v_i is zero for a wheel that rolls without slipping in both directions; its longitudinal part is
-h_i of the nonslip constraint. Its time derivative is J_i qdd + c_i with the drift
c_i = (thd v_lat, -thd v_long) (J_i depends on th alone).
"""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.robot import DOF, Robot

LONGITUDINAL_ROW, LATERAL_ROW = 0, 1
"""The rows of a wheel's contact velocity: along x_p, along y_p."""


class ContactKinematics:
    """J_i(th) and c_i of the four wheels of one robot."""

    def __init__(self, robot: Robot) -> None:
        self.offsets = robot.wheel_offsets
        self.radius = robot.params.wheel_radius
        self._template = np.zeros((4, 2, DOF))
        self._template[:, LONGITUDINAL_ROW, 2] = -self.offsets[:, 1]
        self._template[:, LONGITUDINAL_ROW, 3:] = -self.radius * np.eye(4)
        self._template[:, LATERAL_ROW, 2] = self.offsets[:, 0]
        self._theta, self._jacobian = math.nan, self._template

    def jacobian(self, theta: float) -> np.ndarray:
        """J (4, 2, 7): v_i = J[i] qd (read-only; the last one is kept: a step asks again at the same heading)."""
        if theta != self._theta:
            cos_t, sin_t = math.cos(theta), math.sin(theta)
            jacobian = self._template.copy()
            jacobian[:, LONGITUDINAL_ROW, :2] = (cos_t, sin_t)
            jacobian[:, LATERAL_ROW, :2] = (-sin_t, cos_t)
            jacobian.flags.writeable = False
            self._theta, self._jacobian = theta, jacobian
        return self._jacobian

    def velocities(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """v (4, 2) at (q, qd)."""
        return self.jacobian(float(q[2])) @ qd

    @staticmethod
    def drift(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """c (2,), the same for every wheel: dv_i/dt = J_i qdd + c."""
        cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
        xd, yd, thd = qd[:3].tolist()
        return np.array([thd * (-sin_t * xd + cos_t * yd), -thd * (cos_t * xd + sin_t * yd)])


def contact_velocities(theta: np.ndarray, qd: np.ndarray, offsets: np.ndarray,
                       radius: float | np.ndarray) -> np.ndarray:
    """v (T, 4, 2) of consecutive instants or robots (theta (T,), qd (T, 7)): what the outputs report as slip
    velocity. ``offsets``: d_i (4, 2), or (T, 4, 2) with ``radius`` (T, 1) for robots of their own."""
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    xd, yd, thd = qd[:, 0], qd[:, 1], qd[:, 2]
    v_long, v_lat = cos_t * xd + sin_t * yd, -sin_t * xd + cos_t * yd
    along = v_long[:, None] - offsets[..., 1] * thd[:, None] - radius * qd[:, 3:]
    across = v_lat[:, None] + offsets[..., 0] * thd[:, None]
    return np.stack((along, across), axis=2)
