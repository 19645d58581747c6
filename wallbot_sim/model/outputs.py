"""Derived outputs (docs/model.md sections 8 and 11): chassis wrench, wheel torques, drive forces, contact."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.trajectories import ReferenceSample


def lifted_wheels(loads: np.ndarray) -> np.ndarray:
    """The wheel (1..4) lifting off at each instant or robot of ``loads`` (..., 4): the one of the most negative
    load, 0 while every load is >= 0. A coulomb run stops at the first instant this is not 0: the one definition
    of a lift-off the single robot and the batch share."""
    lowest = np.argmin(loads, axis=-1)
    return np.where(np.take_along_axis(loads, lowest[..., None], axis=-1)[..., 0] < 0.0, lowest + 1, 0)


@dataclass(frozen=True)
class DriveForces:
    """Longitudinal traction of each side and the lateral force at the centre (N)."""

    left: float
    right: float
    lateral: float


def drive_forces(theta: float, chassis_wrench: np.ndarray, half_track: float) -> DriveForces:
    """Solve [F_X, F_Y, M_Z] = G [F_L, F_R, F_lat] (paper eqs. 69-72) in closed form.

    G's rows give F_L + F_R = the longitudinal force, F_lat = the lateral force and
    b (F_R - F_L) = M_Z.
    """
    fx, fy, mz = chassis_wrench
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    longitudinal = cos_t * fx + sin_t * fy
    differential = mz / half_track
    return DriveForces(0.5 * (longitudinal - differential), 0.5 * (longitudinal + differential),
                       -sin_t * fx + cos_t * fy)


def side_motor_torques(drive: DriveForces, wheel_torques: Sequence[float], wheel_radius: float) -> tuple[float, float]:
    """(tau_L, tau_R): what each side's motor delivers, or would have to deliver.

    A side's traction F_side comes from its wheels rolling on the wall, so its motor supplies
    r F_side plus the torque that spins the side's wheels (the total torque on each wheel:
    constraint torque, and the motor's share when driven). In a tracking run (no motors) this is
    the torque motors would need to replace the trajectory task; in a driven run it gives back
    the applied torques.
    """
    front_left, rear_left, front_right, rear_right = wheel_torques
    return (wheel_radius * drive.left + front_left + rear_left,
            wheel_radius * drive.right + front_right + rear_right)


@dataclass(frozen=True)
class ContactOutputs:
    """The contact at one instant: per wheel, and per channel of the paper's drive forces (section 8)."""

    loads: np.ndarray
    """N_1..N_4 (N)."""
    use: FrictionUse
    """Friction use per channel: |F_L| / (mu_s (N_1 + N_2)), |F_R| / (mu_s (N_3 + N_4)), |F_lat| / (mu_s F_ad)."""
    limits: tuple[float, float, float]
    """Friction limit per channel: mu_s (N_1 + N_2), mu_s (N_3 + N_4), mu_s F_ad (N)."""
    slipping: tuple[bool, bool, bool]
    """Whether each channel (left, right, lateral) has a sliding wheel (``coulomb_table``); never with ideal
    contact."""
    friction_force: np.ndarray | None
    """Q_f (7,), the kinetic friction of the sliding wheels; None while none slides."""
    wheel_forces: np.ndarray
    """f_i (4, 2): each wheel's tangential contact force on the robot in body axes (x_p, y_p) (N)."""
    wheel_use: np.ndarray
    """|f_i| / (mu_s N_i) (4,): above 1 the wheel's friction disc cannot hold its force."""
    wheel_slipping: tuple[bool, bool, bool, bool]
    """Whether each wheel slides (coulomb contact)."""
    slip_velocity: np.ndarray
    """v_i (4, 2): each wheel's contact-point velocity on the wall in body axes (m/s)."""

    @property
    def detached_wheel(self) -> int | None:
        """The wheel (1..4) with the most negative load, or None while every load is >= 0."""
        return int(lifted_wheels(self.loads)) or None


@dataclass(frozen=True)
class StepOutputs:
    """Everything the simulation reports at one instant."""

    t: float
    q: np.ndarray
    qd: np.ndarray
    acceleration: np.ndarray
    constraint_force: np.ndarray
    residual: float
    motor_torque: tuple[float, float]
    """The side torques acting (N m): the command, clipped by a motor block (docs/model.md 13.2)."""
    drive: DriveForces
    """The channel forces of the whole contact wrench (constraint force plus kinetic friction)."""
    reference: ReferenceSample | None
    contact: ContactOutputs
    vacuum: tuple[float, float] | None = None
    """(dp (Pa), F_ad (N)) of a vacuum chamber (docs/model.md 13.3); None without one."""
    motor_command: tuple[float, float] | None = None
    """The side torques commanded (N m) that a motor block clipped to ``motor_torque`` (docs/model.md 13.2); None
    without one (the command acts as given)."""

    @property
    def chassis_wrench(self) -> np.ndarray:
        """(F_X, F_Y, M_Z): the constraint wrench on the chassis, wall frame."""
        return self.constraint_force[:3]

    @property
    def wheel_torques(self) -> np.ndarray:
        """Total torque on each wheel: constraint torque, kinetic friction and its share of the motor torque."""
        tau_left, tau_right = self.motor_torque
        torques = self.constraint_force[3:] + 0.5 * np.array([tau_left, tau_left, tau_right, tau_right])
        friction = self.contact.friction_force
        return torques if friction is None else torques + friction[3:]

    @property
    def tracking_error(self) -> float:
        """Distance of the centre from the reference point (m); NaN without a reference."""
        if self.reference is None:
            return math.nan
        # NumPy's hypot, as StepTable's over many instants: the same bits (Python's math.hypot may differ by an ulp)
        return float(np.hypot(self.q[0] - self.reference.position[0], self.q[1] - self.reference.position[1]))


class StepTable(NamedTuple):
    """The outputs of consecutive instants of one robot as arrays, row k the k-th instant (ideal contact:
    what ``StepOutputs`` holds, where a run tabulates a chunk of steps at once)."""

    t: np.ndarray
    """(T,)."""
    q: np.ndarray
    """(T, 7)."""
    qd: np.ndarray
    """(T, 7)."""
    acceleration: np.ndarray
    """qdd (T, 7)."""
    constraint_force: np.ndarray
    """Q_c (T, 7)."""
    residual: np.ndarray
    """(T,)."""
    drive: np.ndarray
    """(F_L, F_R, F_lat) (T, 3)."""
    loads: np.ndarray
    """N_1..N_4 (T, 4)."""
    use: np.ndarray
    """Friction use of the channels (left, right, lateral) (T, 3)."""
    slipping: np.ndarray
    """(T, 3) bool, never set with ideal contact."""
    wheel_forces: np.ndarray
    """(T, 4, 2), as ``ContactOutputs.wheel_forces``."""
    wheel_use: np.ndarray
    """(T, 4)."""
    wheel_slipping: np.ndarray
    """(T, 4) bool, never set with ideal contact."""
    slip_velocity: np.ndarray
    """(T, 4, 2)."""
    reference_position: np.ndarray | None
    """The reference point (T, 2), None without a reference."""

    def wheel_torques(self, motor_torque: tuple[float, float]) -> np.ndarray:
        """Total torque on each wheel (T, 4) under constant ``motor_torque`` with ideal contact (no kinetic
        friction), as ``StepOutputs.wheel_torques``: constraint torque and the wheel's share of its motor's."""
        tau_left, tau_right = motor_torque
        return self.constraint_force[:, 3:] + 0.5 * np.array([tau_left, tau_left, tau_right, tau_right])

    @property
    def tracking_error(self) -> np.ndarray:
        """Distance of the centre from the reference point (T,) (m); NaN without a reference."""
        if self.reference_position is None:
            return np.full(len(self.t), np.nan)
        offset = self.q[:, :2] - self.reference_position
        return np.hypot(offset[:, 0], offset[:, 1])  # StepOutputs' own, to the bit


@dataclass(frozen=True)
class StepBlock:
    """Consecutive instants of one robot with ideal contact (``Simulation.advance``), with what their
    messages carry beside the table: each row what ``StepOutputs`` gives at its instant, to the bit."""

    table: StepTable
    wheel_torques: np.ndarray
    """(T, 4), as ``StepOutputs.wheel_torques``."""

    @property
    def t(self) -> np.ndarray:
        return self.table.t

    @property
    def q(self) -> np.ndarray:
        return self.table.q

    @property
    def qd(self) -> np.ndarray:
        return self.table.qd

    @property
    def chassis_wrench(self) -> np.ndarray:
        """(T, 3), as ``StepOutputs.chassis_wrench``."""
        return self.table.constraint_force[:, :3]

    @property
    def drive(self) -> np.ndarray:
        return self.table.drive

    @property
    def loads(self) -> np.ndarray:
        return self.table.loads

    @property
    def wheel_use(self) -> np.ndarray:
        return self.table.wheel_use

    @property
    def wheel_slipping(self) -> np.ndarray:
        return self.table.wheel_slipping

    @property
    def wheel_forces(self) -> np.ndarray:
        return self.table.wheel_forces

    @property
    def slip_velocity(self) -> np.ndarray:
        return self.table.slip_velocity
