"""Wheel-wall contact over a batch: normal loads, friction use, and Coulomb stick/slip per wheel robot by robot.

Each function reads like its single-robot counterpart (``normal_loads``, ``drive_forces``,
``friction_use``) with the robot index first. ``BatchCoulomb`` is every robot's coulomb contact per wheel
(``CoulombContact``): its state is each robot's sliding wheels (N, 4), held loads (N, 4) and held friction
(N, 8), and each step boundary is settled robot by robot, by the compiled kernel (engine 'numba',
``kernel.settle``) or by the model's own ``CoulombContact`` (engine 'numpy'), into the kernel's solution layout.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.constraints import BatchGains
from wallbot_sim.model.batch.outputs import BatchTable
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.constraint_set import ConstraintSelection, build_modules
from wallbot_sim.model.constraints import BaumgarteGains, ConstraintModule
from wallbot_sim.model.contact import CoulombContact, coulomb_table
from wallbot_sim.model.errors import DivergedError, ModelError
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.constrained_problem import impulsive_projection
from wallbot_sim.model.trajectories import LastSample, Reference


class BatchMotion(NamedTuple):
    """The constrained motion of every robot at one instant."""

    acceleration: np.ndarray
    """qdd (N, 7)."""
    constraint_force: np.ndarray
    """Q_c = M qdd - (Q + Q_f) (N, 7)."""
    residual: np.ndarray
    """|A qdd - b| over the rows in the solve (N,)."""


def normal_loads(robots: RobotBatch, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """N_1..N_4 (N, 4): F_ad/4 + h F_bx x_i/(4 a^2) + h F_by y_i/(4 b^2) (``normal_loads`` per robot)."""
    cos_t, sin_t = np.cos(q[:, 2]), np.sin(q[:, 2])
    sx, sy = robots.first_moment[:, 0], robots.first_moment[:, 1]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    mass, thd, thdd = robots.total_mass, qd[:, 2], qdd[:, 2]
    inertial_x = mass * qdd[:, 0] - thdd * rsy - thd * thd * rsx
    inertial_y = mass * qdd[:, 1] + thdd * rsx - thd * thd * rsy
    fx, fy = -inertial_x, -mass * robots.gravity - inertial_y
    body_x, body_y = cos_t * fx + sin_t * fy, -sin_t * fx + cos_t * fy
    a, b, h = robots.half_wheelbase, robots.half_track, robots.com_height
    offsets = robots.wheel_offsets
    return (0.25 * robots.adhesion_force[:, None] + (0.25 * h * body_x / (a * a))[:, None] * offsets[:, :, 0]
            + (0.25 * h * body_y / (b * b))[:, None] * offsets[:, :, 1])


def drive_forces(theta: np.ndarray, wrench: np.ndarray, half_track: np.ndarray) -> np.ndarray:
    """(F_L, F_R, F_lat) (N, 3) of chassis wrenches (N, 3) (``drive_forces`` per robot)."""
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    fx, fy = wrench[:, 0], wrench[:, 1]
    longitudinal = cos_t * fx + sin_t * fy
    differential = wrench[:, 2] / half_track
    return np.stack((0.5 * (longitudinal - differential), 0.5 * (longitudinal + differential),
                     -sin_t * fx + cos_t * fy), axis=1)


def channel_loads(robots: RobotBatch, loads: np.ndarray) -> np.ndarray:
    """The load bounding each channel (N, 3): N_1 + N_2, N_3 + N_4, F_ad."""
    return np.stack((loads[:, 0] + loads[:, 1], loads[:, 2] + loads[:, 3], robots.adhesion_force), axis=1)


def friction_use(robots: RobotBatch, drive: np.ndarray, loads: np.ndarray) -> np.ndarray:
    """|F| / (mu_s N) per channel (N, 3); a channel of no positive load: 0 without force, else inf."""
    limit = robots.static_friction[:, None] * channel_loads(robots, loads)
    force = np.abs(drive)
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = force / limit
    return np.where(limit > 0.0, ratio, np.where(force == 0.0, 0.0, np.inf))


class HeldRun(NamedTuple):
    """``kernel.batch_contact_run``'s T steps of a batch at held torques: the states (N, T + 1, 14), the settled
    states (N, T, 14), the solutions (N, T, 8, 8), the sliding wheels (N, T, 4) of each instant, each robot's
    outcome (N, 4), and the reference at each step's RK4 instants (T, 3, 10)."""

    states: np.ndarray
    settled: np.ndarray
    solutions: np.ndarray
    slid: np.ndarray
    outcomes: np.ndarray
    references: np.ndarray

    def first_error(self, live: np.ndarray, times: np.ndarray, dt: float) -> ModelError | None:
        """The error stepping the ``live`` robots one step at a time would raise first (a boundary without a solution,
        or a state no longer finite), with its message, for ``times`` each instant's t; None if the run has none."""
        ends = self.outcomes[:, 2]
        failed, diverged = live & (ends == kernel.FAILED), live & (ends == kernel.DIVERGED)
        if not (failed | diverged).any():
            return None
        # in time order: instant k's boundary (2 k), then its step (2 k + 1)
        when = np.where(failed, 2 * self.outcomes[:, 0], np.where(diverged, 2 * self.outcomes[:, 1] + 1, -1))
        first = int(np.min(when[when >= 0]))
        robots = np.flatnonzero(when == first)
        if first % 2 == 0:
            return contact_error(robots, self.outcomes[robots[0], 3], self.solutions[robots[0], first // 2])
        return diverged_error(robots, times[first // 2] + dt)


def contact_error(robots: np.ndarray, code: int, solution: np.ndarray) -> ModelError:
    """The error of the ``robots`` whose boundary has no solution, the first's error ``code`` (``CONTACT_ERRORS``)
    and its ``solution`` (8, 8)."""
    return ModelError(f'robot(s) {robots[:5].tolist()}: '
                      + kernel.CONTACT_ERRORS[code].format(solution[kernel.STATUS, kernel.NEWTON_RESIDUAL]))


def diverged_error(robots: np.ndarray, t: float) -> DivergedError:
    """The error of the ``robots`` whose state is no longer finite at ``t``."""
    return DivergedError(f'state of robot(s) {robots[:5].tolist()} is no longer finite at t = {t:.3f} s')


class BatchCoulomb:
    """Every robot's coulomb contact per wheel: its sliding wheels and held loads, and its settled step boundary."""

    def __init__(self, robots: RobotBatch, selection: ConstraintSelection, reference: Reference | None,
                 gains: BatchGains) -> None:
        self.robots, self.selection, self.reference, self.gains = robots, selection, reference, gains
        size = robots.size
        self.sliding = np.zeros((size, 4), dtype=bool)
        """(N, 4): the wheels sliding over the step."""
        self.loads = np.repeat(0.25 * robots.adhesion_force[:, None], 4, axis=1)
        """(N, 4): the loads held over the step (Newton's start at the next boundary)."""
        self.friction = np.zeros((size, 8))
        """(N, 8): the sliding wheels' forces held over the step, (f_x, f_y) wheel by wheel, zero for the others
        (Newton's start too)."""
        self.solutions = np.zeros((size, kernel.SOLUTION_ROWS, kernel.SOLUTION_WIDTH))
        """(N, 8, 8): each robot's settled boundary (``kernel.SOLUTION_ROWS``), kept for a robot no longer settled."""
        self.contact = np.array([kernel.contact_constants(robot) for robot in robots.robots])
        """(N, 16): each robot's ``kernel.contact_constants``."""
        self._workspaces: tuple[np.ndarray, ...] | None = None
        """Each robot's scratch in the kernel's calls (``kernel.contact_workspaces``), made at the first."""
        self._singles: list[tuple[list[ConstraintModule], CoulombContact]] | None = None

    @property
    def workspaces(self) -> tuple[np.ndarray, ...]:
        """The robots' workspaces for the kernel (a batch's configuration never changes: they hold for its life)."""
        if self._workspaces is None:
            self._workspaces = kernel.contact_workspaces(self.robots.size)
        return self._workspaces

    @property
    def directions(self) -> tuple[int, ...]:
        """The rows of the contact velocity that have friction (0 along x_p, 1 along y_p)."""
        return tuple(row for row, on in ((0, self.selection.nonslip), (1, self.selection.non_lateral)) if on)

    def settle_compiled(self, y: np.ndarray, references: np.ndarray, constants: np.ndarray, torques: np.ndarray,
                        dt: float, live: np.ndarray) -> None:
        """The ``live`` robots' boundaries by the kernel (``kernel.batch_contact_settle``), their velocities projected
        in place on y (N, 14); ``references`` (3, 10): the reference at the step's RK4 instants."""
        errors = kernel.batch_contact_settle(y, references[0], tuple(self.selection.active_names()), constants,
                                             self.contact, np.ascontiguousarray(torques), dt, self.sliding,
                                             self.loads, self.friction, live, self.solutions, self.workspaces)
        failed = np.flatnonzero(errors)
        if len(failed):
            raise contact_error(failed, errors[failed[0]], self.solutions[failed[0]])

    def run_compiled(self, y: np.ndarray, references: np.ndarray, constants: np.ndarray, torques: np.ndarray,
                     dt: float, live: np.ndarray) -> HeldRun:
        """T = len(references) steps of the ``live`` robots from their settled boundaries y (N, 14) at the held
        ``torques`` (``kernel.batch_contact_run``), the contact state updated."""
        return HeldRun(*kernel.batch_contact_run(y, references, tuple(self.selection.active_names()), constants,
                                                 self.contact, torques, dt, self.sliding, self.loads, self.friction,
                                                 live, self.solutions, self.workspaces), references)

    def table(self, run: HeldRun, robots: RobotBatch, times: np.ndarray, torques: np.ndarray,
              reference: Reference | None) -> BatchTable:
        """The outputs of the instants after the first of ``run`` (at ``times[1:]``), as ``BatchSimulation.outputs``
        gives each (``coulomb_table``)."""
        solutions, settled = run.solutions[:, 1:], run.settled[:, 1:]
        size, instants = solutions.shape[:2]
        loads = solutions[..., kernel.LOADS, :4]
        forces = solutions[..., kernel.FORCES, :].reshape(size, instants, 4, 2)
        flat = coulomb_table(loads.reshape(-1, 4), forces.reshape(-1, 4, 2), run.slid[:, 1:].reshape(-1, 4),
                             self.directions, np.repeat(robots.static_friction, instants),
                             np.repeat(robots.adhesion_force, instants))
        on_wall = np.arange(1, instants + 1) < run.outcomes[:, :1]  # the instants each robot's run settled
        return BatchTable(times[1:], settled[..., :DOF], settled[..., DOF:], solutions[..., kernel.CONSTRAINT, :DOF],
                          solutions[..., kernel.FRICTION, :DOF], solutions[..., kernel.STATUS, kernel.RESIDUAL],
                          torques.copy(), flat.drive.reshape(size, instants, 3), loads, forces,
                          flat.wheel_use.reshape(size, instants, 4), run.slid[:, 1:],
                          run.references[1:, 0, :2] if reference is not None else None, on_wall)

    def settle_each(self, t: float, y: np.ndarray, torques: np.ndarray, dt: float, live: np.ndarray) -> None:
        """The ``live`` robots' boundaries by the model's ``CoulombContact``, one robot at a time, their velocities
        projected in place on y (N, 14)."""
        singles = self._single_models()
        for robot in np.flatnonzero(live):
            model = self.robots.robots[robot]
            modules, contact = singles[robot]
            contact.sliding = frozenset(np.flatnonzero(self.sliding[robot]).tolist())
            contact.loads = self.loads[robot].copy()
            contact.friction = self.friction[robot].reshape(4, 2).copy()
            q = y[robot, :DOF]
            try:
                qd, solution = contact.settle(model, modules, t, q, y[robot, DOF:], dt, tuple(torques[robot].tolist()),
                                              lambda active, velocities: impulsive_projection(model, active, q,
                                                                                              velocities))
            except ModelError as error:
                raise ModelError(f'robot(s) [{robot}]: {error}') from error
            y[robot, DOF:] = qd
            self.sliding[robot] = [wheel in solution.sliding for wheel in range(4)]
            self.loads[robot] = solution.loads
            self.friction[robot] = contact.friction.ravel()
            record = self.solutions[robot]
            record[kernel.QDD, :DOF] = solution.motion.acceleration
            record[kernel.CONSTRAINT, :DOF] = solution.motion.constraint_force
            record[kernel.FRICTION, :DOF] = 0.0 if solution.friction_force is None else solution.friction_force
            record[kernel.LOADS, :4] = solution.loads
            record[kernel.FORCES] = solution.wheel_forces.ravel()
            record[kernel.PREDICTED] = solution.predicted.ravel()
            record[kernel.VELOCITY] = solution.velocities.ravel()
            record[kernel.STATUS, kernel.RESIDUAL] = solution.motion.residual

    def _single_models(self) -> list[tuple[list[ConstraintModule], CoulombContact]]:
        """Each robot's modules and ``CoulombContact`` (made once)."""
        if self._singles is None:
            shared = LastSample(self.reference) if self.reference is not None else None
            self._singles = []
            for robot, alpha, beta in zip(self.robots.robots, self.gains.alpha, self.gains.beta):
                gains = BaumgarteGains(float(alpha), float(beta))
                self._singles.append((build_modules(self.selection, robot, shared, gains),
                                      CoulombContact(robot, gains)))
        return self._singles

    def held(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the step holds from the settled boundaries: the sticking wheels (N, 4), the loads (N, 4) and the
        sliding wheels' forces (N, 4, 2) in body axes (zero for the others)."""
        forces = self.solutions[:, kernel.FORCES].reshape(-1, 4, 2) * self.sliding[:, :, None]
        return ~self.sliding if self.directions else np.zeros_like(self.sliding), self.loads, forces
