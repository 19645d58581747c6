"""The example tracking controller over a batch: ``TrackingController`` sampled as ``SampledController`` does.

Every robot has its own controller copy of the robot (for instance its body mass scaled: a model
mismatch per robot) and its own error integral; all act at the same instants of simulation time,
on the planar state an odometry message carries (heading wrapped, wheels at their rolling rates).
"""

from __future__ import annotations

from typing import Protocol, Sequence

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.constraints import BatchGains, build_batch_modules
from wallbot_sim.model.batch.contact import drive_forces
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.outputs import BatchOutputs, StepHook
from wallbot_sim.model.batch.simulation import BatchSimulation
from wallbot_sim.model.batch.solver import batch_constrained_acceleration, stacked_product
from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.constraints.look_ahead import point_reference
from wallbot_sim.model.errors import ModelError
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.trajectories import Reference


class TrackingGains(Protocol):
    """The feedback of the tracking controller (``wallbot_sim.control.ControllerGains``)."""

    alpha: float
    beta: float
    look_ahead: float
    integral: float
    integral_zone: float


class BatchTrackingController:
    """Motor torques for every robot of a batch, from its state at each multiple of the control period."""

    def __init__(self, robots: Sequence[Robot], reference: Reference, gains: TrackingGains, rate_hz: int,
                 max_wheel_torque: float) -> None:
        """``robots``: each robot's controller copy, in the batch's order; commands clamped to +-``max_wheel_torque``."""
        self.robots = RobotBatch(robots)
        self.reference = reference
        self.gains = gains
        self.rate_hz = rate_hz
        self.max_wheel_torque = max_wheel_torque
        size = self.robots.size
        baumgarte = BatchGains(np.full(size, float(gains.alpha)), np.full(size, float(gains.beta)))
        selection = ConstraintSelection.structural(trajectory=False)
        self.modules = build_batch_modules(selection, self.robots, None, baumgarte)
        if kernel.available():  # the inverse dynamics robot by robot in the kernel (kernel.tracking_force)
            self._flags = kernel.module_flags(selection.active_names())[0]
            self._constants = kernel.robot_constants(self.robots, baumgarte.alpha, baumgarte.beta)
        self.error_integral = np.zeros((size, 2))
        self.next_due_ns: int | None = None

    @property
    def period_ns(self) -> int:
        return round(1e9 / self.rate_hz)

    def due(self, stamp_ns: int) -> bool:
        """Whether the states stamped ``stamp_ns`` are ones the controller acts on."""
        return self.next_due_ns is None or stamp_ns >= self.next_due_ns

    def instants_until_due(self, simulation: BatchSimulation, most: int) -> int:
        """Steps from ``simulation``'s instant to the next one the controller acts on (``due``, stamped as ``hook``
        stamps them), ``most`` at most."""
        for ahead in range(1, most):
            if self.due(round(simulation.time_at(simulation.steps + ahead) * 1e9)):
                return ahead
        return most

    def command(self, stamp_ns: int, q: np.ndarray, qd: np.ndarray, live: np.ndarray | None = None) -> np.ndarray:
        """The clamped torques (N, 2) for the plant states (N, 7) stamped ``stamp_ns``; the next are due a period on.

        ModelError if a ``live`` robot's torques are not finite (the others are given zero).
        """
        period = self.period_ns
        self.next_due_ns = (stamp_ns // period + 1) * period
        t, dt = stamp_ns * 1e-9, period * 1e-9
        theta = np.arctan2(np.sin(q[:, 2]), np.cos(q[:, 2]))  # the odometry's yaw, as SampledController sees it
        own_q, own_qd = np.zeros_like(q), np.zeros_like(qd)
        own_q[:, :2], own_q[:, 2] = q[:, :2], theta
        own_qd[:, :3] = qd[:, :3]
        v_long = np.cos(theta) * qd[:, 0] + np.sin(theta) * qd[:, 1]
        own_qd[:, 3:] = ((v_long[:, None] - self.robots.lateral_offsets * qd[:, 2:3])
                         / self.robots.wheel_radius[:, None])
        constraint_force = self._constraint_force(t, own_q, own_qd)
        error = q[:, :2] - np.asarray(self.reference.sample(t).position)
        inside = np.hypot(error[:, 0], error[:, 1]) < self.gains.integral_zone
        self.error_integral[inside] += error[inside] * dt
        wrench = constraint_force[:, :3].copy()
        wrench[:, :2] -= self.gains.integral * self.robots.total_mass[:, None] * self.error_integral
        drive = drive_forces(theta, wrench, self.robots.half_track)
        wheels = constraint_force[:, 3:]
        radius = self.robots.wheel_radius
        requested = np.stack((radius * drive[:, 0] + wheels[:, 0] + wheels[:, 1],
                              radius * drive[:, 1] + wheels[:, 2] + wheels[:, 3]), axis=1)
        finite = np.all(np.isfinite(requested), axis=1)
        live = np.ones(len(q), dtype=bool) if live is None else live
        if not np.all(finite[live]):
            robots = np.flatnonzero(~finite & live)
            raise ModelError(f'non-finite torques for robot(s) {robots[:5].tolist()} at t = {t:.3f} s')
        limit = self.max_wheel_torque
        return np.where(finite[:, None], np.clip(requested, -limit, limit), 0.0)

    def _constraint_force(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Q_c (N, 7) of the controller's robots under the driven set and the look-ahead point task (the kernel's
        ``batch_tracking_forces`` where numba is installed, as the single robot's ``CompiledInverseDynamics``)."""
        if kernel.available():
            out = np.empty(q.shape)
            point = np.array(point_reference(self.reference.sample(t), self.gains.look_ahead)[:3])
            kernel.batch_tracking_forces(np.concatenate((q, qd), axis=1), point, self._flags, self._constants,
                                         float(self.gains.look_ahead), out)
            return out
        parts = [module.rows(t, q, qd) for module in self.modules] + [self._look_ahead_rows(t, q, qd)]
        rows = np.concatenate([part[0] for part in parts], axis=1)
        rhs = np.concatenate([part[1] for part in parts], axis=1)
        force = self.robots.applied_force(q, qd, np.zeros((len(q), 2)))
        acceleration = batch_constrained_acceleration(self.robots.mass_inverse_factor(q), force, rows, rhs)
        return stacked_product(self.robots.mass_matrix(q), acceleration) - force

    def _look_ahead_rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``LookAheadPointTask.rows`` of every robot: the point L ahead of the centre on its shifted reference."""
        length, alpha, beta = self.gains.look_ahead, self.gains.alpha, self.gains.beta
        position, velocity, acceleration, _ = point_reference(self.reference.sample(t), length)
        cos_t, sin_t, thd = np.cos(q[:, 2]), np.sin(q[:, 2]), qd[:, 2]
        direction = np.stack((cos_t, sin_t), axis=1)
        point = q[:, :2] + length * direction
        point_velocity = qd[:, :2] + (length * thd)[:, None] * np.stack((-sin_t, cos_t), axis=1)
        rows = np.zeros((len(q), 2, DOF))
        rows[:, 0, 0] = rows[:, 1, 1] = 1.0
        rows[:, 0, 2], rows[:, 1, 2] = -length * sin_t, length * cos_t
        rhs = (acceleration - 2.0 * alpha * (point_velocity - velocity) - beta ** 2 * (point - position)
               + (length * thd * thd)[:, None] * direction)
        return rows, rhs

    def hook(self, simulation: BatchSimulation) -> StepHook:
        """A step hook closing the loop on ``simulation`` (``close_loop`` over a batch).

        Called with the outputs of each instant after they were used, it commands the states it acts
        on and holds the torques from the next step on.
        """
        def answer(out: BatchOutputs) -> None:
            stamp_ns = round(out.t * 1e9)
            if self.due(stamp_ns):
                simulation.set_motor_torque(self.command(stamp_ns, out.q, out.qd, ~out.detached))
        return answer
