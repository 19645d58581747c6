"""The unconstrained robot: chassis plus four omni-directional wheels (docs/model.md sections 3 and 4).

Generalized coordinates q = [x, y, th, p1, p2, p3, p4]: the geometric centre in the wall frame,
the heading, and the spin angles of the left-front, left-rear, right-front and right-rear wheels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.world import World

DOF = 7


@dataclass(frozen=True)
class Adsorption:
    """Adsorption analysis: what keeps the robot on the wall standing still."""

    total_mass: float
    """m_t = m_b + 4 m_w (kg)."""
    sliding_limit: float
    """m_t g / mu: the force below which the robot slides down (N)."""
    tipping_limit: float
    """m_t g h / min(a, b): the force below which it peels off about the lowest wheel line (N)."""
    minimum_force: float
    """F_min, the larger of the two limits (N)."""
    applied_force: float
    """F_ad: the robot file's ``adhesion_force``, or k_ad F_min when that is null (N)."""

    @property
    def normal_force_per_wheel(self) -> float:
        """N = F_ad / 4: each wheel's press on the wall (N)."""
        return self.applied_force / 4.0

    @property
    def margin(self) -> float:
        """F_ad / F_min, the safety factor actually applied."""
        return self.applied_force / self.minimum_force


def adsorption_analysis(params: RobotParameters, applied: float | None = None) -> Adsorption:
    """F_min = max(m_t g / mu, m_t g h / min(a, b)) on a vertical wall, and F_ad: ``applied`` (a vacuum chamber's
    force now), else the robot file's ``adhesion_force``, else k_ad F_min."""
    total_mass = params.body_mass + 4.0 * params.wheel_mass
    weight = total_mass * params.gravity
    sliding = weight / params.wall_friction
    tipping = weight * params.com_height / min(params.half_wheelbase, params.half_track)
    minimum = max(sliding, tipping)
    if applied is None:
        applied = params.adsorption_safety * minimum if params.adhesion_force is None else params.adhesion_force
    return Adsorption(total_mass, sliding, tipping, minimum, applied)


class Robot:
    """Mass matrix M(q) and generalized applied force Q(q, qd, tau) of the unconstrained robot on its surface."""

    def __init__(self, params: RobotParameters, world: World | None = None,
                 adhesion_force: float | None = None) -> None:
        """``world``: the surface (None: a vertical, uniform wall); ``adhesion_force``: F_ad now, in place of the
        robot file's (a vacuum chamber's force, >= 0)."""
        self.params = params
        self.world = world or World()
        self.adsorption = adsorption_analysis(params, adhesion_force)
        a, b = params.half_wheelbase, params.half_track
        self.wheel_offsets = np.array([[a, b], [-a, b], [a, -b], [-a, -b]])
        """d_i: axle centres in the body frame, rows in wheel order."""
        self.lateral_offsets = self.wheel_offsets[:, 1].copy()
        """s_i = d_i,y: +b for the left wheels, -b for the right."""
        self.total_mass = self.adsorption.total_mass
        c = np.asarray(params.com_offset)
        self.first_moment = params.body_mass * c
        """s = m_b c, the body's first mass moment about the centre."""
        self.yaw_inertia = (params.body_yaw_inertia + params.body_mass * float(c @ c)
                            + 4.0 * params.wheel_yaw_inertia
                            + params.wheel_mass * float(np.sum(self.wheel_offsets ** 2)))
        """J_t about the geometric centre."""
        slope_sin, slope_cos = self.world.slope
        self.slope_gravity = params.gravity * slope_sin
        """g sin i: gravity's pull down the slope, along -Y (m/s^2)."""
        self.normal_weight = self.total_mass * params.gravity * slope_cos
        """m_t g cos i: the weight pressing the robot on the surface (negative: pulling it off) (N)."""
        self._resistance_gains = [params.rolling_resistance * (0.25 * max(self.wall_load, 0.0))] * 4
        self._perpendicular_offsets = [(-dy, dx) for dx, dy in self.wheel_offsets.tolist()]
        self._first_moment_xy = tuple(self.first_moment.tolist())
        self._weight = self.total_mass * self.slope_gravity
        self._centred = not self.first_moment.any()
        """With the CoM at the centre, M is constant (and so is its inverse)."""
        chassis = [self.total_mass, self.total_mass, self.yaw_inertia]
        self._mass_centred = np.diag(chassis + [params.wheel_spin_inertia] * 4)
        self._inverse_centred = np.diag([1.0 / d for d in chassis] + [1.0 / params.wheel_spin_inertia] * 4)
        self._inverse_factor_centred = np.sqrt(self._inverse_centred)
        for constant in (self._mass_centred, self._inverse_centred, self._inverse_factor_centred):
            constant.flags.writeable = False

    @property
    def wall_load(self) -> float:
        """F_ad + m_t g cos i: what the surface pushes back with, the sum of the normal loads (N)."""
        return self.adsorption.applied_force + self.normal_weight

    def with_adhesion_force(self, force: float) -> Robot:
        """The same robot on the same surface pressed by ``force`` (N) instead."""
        return Robot(self.params, self.world, force)

    def wheel_points(self, q: np.ndarray) -> np.ndarray:
        """The wheels' contact points in the wall frame (4, 2): the centre plus R(th) d_i."""
        cos_t, sin_t = math.cos(float(q[2])), math.sin(float(q[2]))
        rotated = self.wheel_offsets @ np.array([[cos_t, sin_t], [-sin_t, cos_t]])
        return rotated + q[:2]

    def wheel_friction(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(mu_s, mu_k) of each wheel (4,) at q: its patch's, else the robot file's."""
        return self.world.friction_at(self.wheel_points(q), self.params.wall_friction, self.params.kinetic_friction)

    def offset_moment_arm(self, theta: float) -> tuple[float, float]:
        """u(th) = R(th) S s, the coupling between heading and translation."""
        sx, sy = self._first_moment_xy
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        return (-cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q): chassis block [[m_t, 0, u_x], [0, m_t, u_y], [u_x, u_y, J_t]], then J_w I_4."""
        if self._centred:
            return self._mass_centred
        ux, uy = self.offset_moment_arm(q[2])
        mass = self._mass_centred.copy()
        mass[0, 2] = mass[2, 0] = ux
        mass[1, 2] = mass[2, 1] = uy
        return mass

    def mass_matrix_inverse(self, q: np.ndarray) -> np.ndarray:
        """M(q)^-1 in closed form (block inverse through the Schur complement of m_t I_2)."""
        if self._centred:
            return self._inverse_centred
        ux, uy = self.offset_moment_arm(q[2])
        m = self.total_mass
        inv_schur = 1.0 / (self.yaw_inertia - (ux * ux + uy * uy) / m)
        wx, wy = ux / m, uy / m
        inverse = self._inverse_centred.copy()
        inverse[:3, :3] = [[1.0 / m + wx * wx * inv_schur, wx * wy * inv_schur, -wx * inv_schur],
                           [wx * wy * inv_schur, 1.0 / m + wy * wy * inv_schur, -wy * inv_schur],
                           [-wx * inv_schur, -wy * inv_schur, inv_schur]]
        return inverse

    def mass_inverse_factor(self, q: np.ndarray) -> np.ndarray:
        """W, lower triangular, with W W^T = M(q)^-1 (the Cholesky factor of the inverse)."""
        if self._centred:
            return self._inverse_factor_centred
        c = self.mass_matrix_inverse(q)
        l00 = math.sqrt(c[0, 0])
        l10 = c[1, 0] / l00
        l11 = math.sqrt(c[1, 1] - l10 * l10)
        l20 = c[2, 0] / l00
        l21 = (c[2, 1] - l20 * l10) / l11
        factor = self._inverse_factor_centred.copy()
        factor[:3, :3] = [[l00, 0.0, 0.0], [l10, l11, 0.0], [l20, l21, math.sqrt(c[2, 2] - l20 * l20 - l21 * l21)]]
        return factor

    def applied_force(self, q: np.ndarray, qd: np.ndarray, motor_torque: tuple[float, float] = (0.0, 0.0),
                      loads: np.ndarray | None = None) -> np.ndarray:
        """Q: offset-CoM centripetal term, gravity, rolling resistance and motor torques.

        Rolling resistance f_r N at each wheel with N = (F_ad + m_t g cos i) / 4 (section 4), or with each wheel's own
        load where ``loads`` are given (coulomb contact: f_r max(N_i, 0), a lifted wheel has none).
        """
        gains = (self._resistance_gains if loads is None
                 else (self.params.rolling_resistance * np.maximum(loads, 0.0)).tolist())
        return self._applied_force(q, qd, motor_torque, gains)

    def rolling_resistance_per_load(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """dQ/dN (7 x 4): each wheel's rolling resistance per newton of its load, -f_r v_i / sqrt(|v_i|^2 + eps^2)."""
        per_load = np.zeros((DOF, 4))
        eps2 = self.params.velocity_epsilon ** 2
        for wheel, (arm_x, arm_y, vx, vy) in enumerate(self._axle_velocities(q, qd)):
            scale = -self.params.rolling_resistance / math.sqrt(vx * vx + vy * vy + eps2)
            per_load[:3, wheel] = scale * vx, scale * vy, scale * (arm_x * vx + arm_y * vy)
        return per_load

    def _axle_velocities(self, q: np.ndarray, qd: np.ndarray) -> list[tuple[float, float, float, float]]:
        """(R S d_i, v_i) of each wheel: its moment arm and its axle's velocity (wall frame)."""
        theta = float(q[2])
        xd, yd, thd = qd[:3].tolist()
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        axles = []
        for px, py in self._perpendicular_offsets:
            arm_x, arm_y = cos_t * px - sin_t * py, sin_t * px + cos_t * py  # R S d_i
            axles.append((arm_x, arm_y, xd + thd * arm_x, yd + thd * arm_y))
        return axles

    def _applied_force(self, q: np.ndarray, qd: np.ndarray, motor_torque: tuple[float, float],
                       gains: list[float]) -> np.ndarray:
        theta = float(q[2])
        thd = float(qd[2])
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        sx, sy = self._first_moment_xy
        uy = -sin_t * sy + cos_t * sx  # y component of u(th) = R(th) S s
        thd2 = thd * thd
        fx = thd2 * (cos_t * sx - sin_t * sy)
        fy = thd2 * (sin_t * sx + cos_t * sy) - self._weight
        mz = -self.slope_gravity * uy
        eps2 = self.params.velocity_epsilon ** 2
        for gain, (arm_x, arm_y, vx, vy) in zip(gains, self._axle_velocities(q, qd)):
            scale = -gain / math.sqrt(vx * vx + vy * vy + eps2)
            fx += scale * vx
            fy += scale * vy
            mz += scale * (arm_x * vx + arm_y * vy)
        tau_left, tau_right = 0.5 * motor_torque[0], 0.5 * motor_torque[1]
        return np.array([fx, fy, mz, tau_left, tau_left, tau_right, tau_right])

    def rolling_spin_rates(self, theta: float, velocity: tuple[float, float], yaw_rate: float) -> np.ndarray:
        """pd_i = (v_long - s_i thd) / r: the spin rates at which every wheel rolls without slip."""
        v_long = math.cos(theta) * velocity[0] + math.sin(theta) * velocity[1]
        return (v_long - self.lateral_offsets * yaw_rate) / self.params.wheel_radius
