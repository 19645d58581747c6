"""M(q), its inverse factor W and Q(q, qd, tau) of N robots at once (``Robot`` stacked over a batch).

Arrays carry the robot index first: q and qd are (N, 7), M and W are (N, 7, 7).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.robot import DOF, Robot


class RobotBatch:
    """The robots' constants as arrays over the batch, and their mass matrices and applied forces."""

    def __init__(self, robots: Sequence[Robot]) -> None:
        if not robots:
            raise ParameterError('a robot batch needs at least one robot')
        self.robots = tuple(robots)
        params = [robot.params for robot in self.robots]
        self.size = len(self.robots)
        self.total_mass = np.array([robot.total_mass for robot in self.robots])
        self.yaw_inertia = np.array([robot.yaw_inertia for robot in self.robots])
        self.spin_inertia = np.array([p.wheel_spin_inertia for p in params])
        self.first_moment = np.array([robot.first_moment for robot in self.robots])
        """s = m_b c (N, 2)."""
        self.gravity = np.array([p.gravity for p in params])
        self.weight = self.total_mass * self.gravity
        self.wheel_radius = np.array([p.wheel_radius for p in params])
        self.lateral_offsets = np.array([robot.lateral_offsets for robot in self.robots])
        """s_i (N, 4)."""
        self.perpendicular_offsets = np.array([robot.wheel_offsets[:, ::-1] * (-1.0, 1.0) for robot in self.robots])
        """S d_i = (-d_iy, d_ix) (N, 4, 2)."""
        self.rolling_resistance = np.array([p.rolling_resistance for p in params])
        """f_r (N,)."""
        self.resistance_gain = np.array([p.rolling_resistance * robot.adsorption.normal_force_per_wheel
                                         for p, robot in zip(params, self.robots)])
        self.velocity_epsilon2 = np.array([p.velocity_epsilon for p in params]) ** 2
        self.adhesion_force = np.array([robot.adsorption.applied_force for robot in self.robots])
        """F_ad (N,): the robot file's adhesion_force, or k_ad F_min."""
        self.half_wheelbase = np.array([p.half_wheelbase for p in params])
        self.half_track = np.array([p.half_track for p in params])
        self.com_height = np.array([p.com_height for p in params])
        self.static_friction = np.array([p.wall_friction for p in params])
        self.kinetic_friction = np.array([p.kinetic_friction for p in params])
        self.stick_velocity = np.array([p.stick_velocity for p in params])
        self.wheel_offsets = np.array([robot.wheel_offsets for robot in self.robots])
        """d_i (N, 4, 2)."""
        chassis = np.stack((self.total_mass, self.total_mass, self.yaw_inertia), axis=1)
        self._diagonal = np.concatenate((chassis, np.repeat(self.spin_inertia[:, None], 4, axis=1)), axis=1)

    @classmethod
    def repeated(cls, robot: Robot, count: int) -> RobotBatch:
        """``count`` copies of one robot: what ``RobotBatch([robot] * count)`` holds, built from one copy (a
        robot's outputs at ``count`` instants are computed as those of a batch of it)."""
        one = cls([robot])
        batch = cls.__new__(cls)
        for name, value in vars(one).items():
            setattr(batch, name, np.repeat(value, count, axis=0) if isinstance(value, np.ndarray) else value)
        batch.robots, batch.size = (robot,) * count, count
        return batch

    def offset_moment_arm(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u(th) = R(th) S s for every robot: (u_x, u_y), each (N,)."""
        sx, sy = self.first_moment[:, 0], self.first_moment[:, 1]
        cos_t, sin_t = np.cos(theta), np.sin(theta)
        return -cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q) (N, 7, 7)."""
        ux, uy = self.offset_moment_arm(q[:, 2])
        mass = np.zeros((self.size, DOF, DOF))
        mass[:, range(DOF), range(DOF)] = self._diagonal
        mass[:, 0, 2] = mass[:, 2, 0] = ux
        mass[:, 1, 2] = mass[:, 2, 1] = uy
        return mass

    def mass_inverse_factor(self, q: np.ndarray) -> np.ndarray:
        """W (N, 7, 7), lower triangular, W W^T = M(q)^-1: the chassis block's Cholesky factor in closed form."""
        ux, uy = self.offset_moment_arm(q[:, 2])
        m = self.total_mass
        inv_schur = 1.0 / (self.yaw_inertia - (ux * ux + uy * uy) / m)
        wx, wy = ux / m, uy / m
        c00, c10, c11 = 1.0 / m + wx * wx * inv_schur, wx * wy * inv_schur, 1.0 / m + wy * wy * inv_schur
        c20, c21 = -wx * inv_schur, -wy * inv_schur
        factor = np.zeros((self.size, DOF, DOF))
        l00 = np.sqrt(c00)
        l10 = c10 / l00
        l11 = np.sqrt(c11 - l10 * l10)
        l20 = c20 / l00
        l21 = (c21 - l20 * l10) / l11
        factor[:, 0, 0], factor[:, 1, 0], factor[:, 1, 1] = l00, l10, l11
        factor[:, 2, 0], factor[:, 2, 1] = l20, l21
        factor[:, 2, 2] = np.sqrt(inv_schur - l20 * l20 - l21 * l21)
        factor[:, range(3, DOF), range(3, DOF)] = np.sqrt(1.0 / self.spin_inertia)[:, None]
        return factor

    def applied_force(self, q: np.ndarray, qd: np.ndarray, motor_torque: np.ndarray,
                      loads: np.ndarray | None = None) -> np.ndarray:
        """Q (N, 7): offset-CoM centripetal term, gravity, rolling resistance and the (N, 2) motor torques.

        Rolling resistance f_r N at each wheel with N = F_ad / 4, or each wheel's own load where ``loads`` (N, 4)
        are given (coulomb contact: f_r max(N_i, 0), ``Robot.applied_force``).
        """
        gains = (self.resistance_gain[:, None] if loads is None
                 else self.rolling_resistance[:, None] * np.maximum(loads, 0.0))
        theta = q[:, 2]
        cos_t, sin_t = np.cos(theta), np.sin(theta)
        sx, sy = self.first_moment[:, 0], self.first_moment[:, 1]
        thd = qd[:, 2]
        thd2 = thd * thd
        force = np.empty((self.size, DOF))
        force[:, 0] = thd2 * (cos_t * sx - sin_t * sy)
        force[:, 1] = thd2 * (sin_t * sx + cos_t * sy) - self.weight
        force[:, 2] = -self.gravity * (-sin_t * sy + cos_t * sx)
        px, py = self.perpendicular_offsets[:, :, 0], self.perpendicular_offsets[:, :, 1]
        arm_x = cos_t[:, None] * px - sin_t[:, None] * py  # R S d_i, (N, 4)
        arm_y = sin_t[:, None] * px + cos_t[:, None] * py
        vx = qd[:, 0:1] + thd[:, None] * arm_x
        vy = qd[:, 1:2] + thd[:, None] * arm_y
        scale = -gains / np.sqrt(vx * vx + vy * vy + self.velocity_epsilon2[:, None])
        force[:, 0] += np.sum(scale * vx, axis=1)
        force[:, 1] += np.sum(scale * vy, axis=1)
        force[:, 2] += np.sum(scale * (arm_x * vx + arm_y * vy), axis=1)
        force[:, 3:5] = 0.5 * motor_torque[:, 0:1]
        force[:, 5:7] = 0.5 * motor_torque[:, 1:2]
        return force
