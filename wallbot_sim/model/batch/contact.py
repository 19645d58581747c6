"""Wheel-wall contact over a batch: normal loads, friction use, and Coulomb stick/slip robot by robot.

Each function reads like its single-robot counterpart (``normal_loads``, ``drive_forces``,
``friction_use``, ``CoulombContact``) with the robot index first. The stick/slip state is a
(N, 3) mask of slipping channels (left, right, lateral); a slipping channel's rows are zeroed in
the solve (a zero row with a zero right side leaves the minimum-norm least-squares solution as
removing it does) and its kinetic friction enters as a generalized force.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.constraints import CHANNELS
from wallbot_sim.model.errors import ModelError

_LOAD_TOLERANCE = 1e-9
"""Relative change of the held loads below which the loads-friction fixed point has converged (as one robot)."""
_LOAD_ITERATIONS = 50


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


class ContactRows:
    """Which channel each stacked row belongs to and which wheels bound it, from the modules' ``channels``."""

    def __init__(self, modules: Sequence[object], row_counts: Sequence[int]) -> None:
        """``row_counts``: how many rows each module stacks, in order."""
        channel, wheels = [], [np.zeros((0, 4))]
        for module, count in zip(modules, row_counts):
            names = getattr(module, 'channels', None)
            if names is None:
                channel += [-1] * count
                wheels.append(np.zeros((count, 4)))
            else:
                channel += [CHANNELS.index(name) for name in names]
                wheels.append(np.asarray(getattr(module, 'row_wheels'), dtype=float))
        self.channel = np.array(channel, dtype=int)
        """(k,) the channel index of each row, -1 for a row no friction holds."""
        self.wheels = np.vstack(wheels)
        """(k, 4) 0/1: the load bounding row k's friction is wheels[k] @ N."""
        self.present = np.array([np.any(self.channel == c) for c in range(len(CHANNELS))])
        """(3,) the channels that have rows."""
        self.traction = self.present & (np.arange(len(CHANNELS)) < 2)
        """(3,) the channels present whose friction a wheel's own load bounds (left, right)."""

    def slipping_rows(self, slipping: np.ndarray) -> np.ndarray:
        """(N, k) bool: the rows of slipping channels."""
        return (self.channel >= 0)[None, :] & np.take(slipping, np.maximum(self.channel, 0), axis=1)

    def rows_of(self, channel: int) -> np.ndarray:
        """The indices of the channel's rows."""
        return np.flatnonzero(self.channel == channel)


Evaluate = Callable[[np.ndarray, np.ndarray, np.ndarray], BatchMotion]
"""(slipping rows (N, k), Q_f (N, 7), qd) -> the motion of every robot at this instant."""
Project = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""(slipping rows (N, k), qd) -> qd projected onto the other rows' velocity constraints."""
Measure = Callable[[BatchMotion, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""(motion, Q_f, qd) -> (normal loads (N, 4), friction use (N, 3))."""
VelocityRows = Callable[[np.ndarray], np.ndarray]
"""qd -> the stacked rows A (N, k, 7) (at the boundary's q), which are the velocity rows of the contact modules."""


class BatchContactSolution(NamedTuple):
    """Every robot's motion at a step boundary under its stick/slip state (``ContactSolution``)."""

    motion: BatchMotion
    friction: np.ndarray
    """Q_f (N, 7), zero for a robot none of whose channels slips."""
    loads: np.ndarray
    use: np.ndarray
    held: np.ndarray
    """The loads the kinetic friction holds over the step (N, 4)."""


class BatchCoulomb:
    """The stick/slip state of every robot's channels and the kinetic friction of the slipping ones."""

    def __init__(self, robots: RobotBatch, rows: ContactRows) -> None:
        self.robots = robots
        self.rows = rows
        self.slipping = np.zeros((robots.size, len(CHANNELS)), dtype=bool)
        self.loads = np.repeat(0.25 * robots.adhesion_force[:, None], 4, axis=1)
        """The loads bounding kinetic friction, held over a step (N, 4)."""
        self.loads_moving = np.zeros(robots.size, dtype=bool)
        """Whether each robot's held loads changed at the last boundary: the compiled engine's
        ``CoulombContact.loads_moving`` (the NumPy engine iterates the loads from the held ones instead)."""

    def bounds(self, slipping: np.ndarray, held: np.ndarray) -> np.ndarray:
        """mu_k N_k of every row (N, k), zero for the rows that do not slip."""
        return (self.robots.kinetic_friction[:, None] * (held @ self.rows.wheels.T)) * self.rows.slipping_rows(slipping)

    def friction(self, velocity_rows: np.ndarray, qd: np.ndarray, bounds: np.ndarray) -> np.ndarray:
        """Q_f (N, 7) = -sum_k mu_k N_k v_k / sqrt(v_k^2 + eps^2) a_k over the slipping rows."""
        slip = np.einsum('nkc,nc->nk', velocity_rows, qd)
        scale = bounds * slip / np.sqrt(slip * slip + self.robots.velocity_epsilon2[:, None])
        return -np.einsum('nk,nkc->nc', scale, velocity_rows)

    def settle(self, live: np.ndarray, qd: np.ndarray, dt: float, velocity_rows: VelocityRows, evaluate: Evaluate,
               project: Project, measure: Measure) -> tuple[np.ndarray, BatchContactSolution]:
        """Stick/slip transitions of the ``live`` robots at this boundary, then every robot's motion of the step.

        Robot by robot what ``CoulombContact.settle`` does: stopping slips stick again when their force
        stays within the limit (their slip projected away), then every sticking channel over its limit slips.
        """
        present = self.rows.present
        self.slipping &= present
        result = self._solve(self.slipping, qd, velocity_rows, evaluate, measure)
        predicted = qd + dt * result.motion.acceleration
        candidates = self._stopping(velocity_rows(qd), qd, predicted) & live[:, None]
        while candidates.any():
            trying = candidates.any(axis=1)
            trial = self.slipping & ~candidates
            trial_qd = np.where(trying[:, None], project(self.rows.slipping_rows(trial), qd), qd)
            trial_result = self._solve(trial, trial_qd, velocity_rows, evaluate, measure)
            holding = candidates & ~(trial_result.use > 1.0)
            accepted = trying & np.all(holding == candidates, axis=1)
            self.slipping = np.where(accepted[:, None], trial, self.slipping)
            qd = np.where(accepted[:, None], trial_qd, qd)
            result = _choose(accepted, trial_result, result)
            candidates = holding & ~accepted[:, None]
        while True:
            exceeded = present & ~self.slipping & (result.use > 1.0) & live[:, None]
            changed = exceeded.any(axis=1)
            if not changed.any():
                break
            self.slipping = self.slipping | exceeded
            result = _choose(changed, self._solve(self.slipping, qd, velocity_rows, evaluate, measure), result)
        self.loads = np.where(live[:, None], result.held, self.loads)
        return qd, result

    def _stopping(self, rows: np.ndarray, qd: np.ndarray, predicted: np.ndarray) -> np.ndarray:
        """(N, 3): slipping channels whose every slip velocity is below v_st or changes sign within the step."""
        now = np.einsum('nkc,nc->nk', rows, qd)
        then = np.einsum('nkc,nc->nk', rows, predicted)
        row_stops = (np.abs(now) < self.robots.stick_velocity[:, None]) | (now * then < 0.0)
        stopping = self.slipping.copy()
        for channel in range(len(CHANNELS)):
            channel_rows = self.rows.rows_of(channel)
            if len(channel_rows):
                stopping[:, channel] &= np.all(row_stops[:, channel_rows], axis=1)
        return stopping

    def _solve(self, slipping: np.ndarray, qd: np.ndarray, velocity_rows: VelocityRows, evaluate: Evaluate,
               measure: Measure) -> BatchContactSolution:
        """The motion with ``slipping`` channels slipping, loads and traction friction iterated to their fixed point."""
        rows = velocity_rows(qd)
        slipping_rows = self.rows.slipping_rows(slipping)
        frictionless = ~slipping_rows.any(axis=1)
        load_independent = ~np.any(slipping & self.rows.traction, axis=1)
        held = self.loads.copy()
        done = np.zeros(self.robots.size, dtype=bool)
        solution: BatchContactSolution | None = None
        for _ in range(_LOAD_ITERATIONS):
            friction = self.friction(rows, qd, self.bounds(slipping, held))
            motion = evaluate(slipping_rows, friction, qd)
            loads, use = measure(motion, friction, qd)
            converged = np.max(np.abs(loads - held), axis=1) <= _LOAD_TOLERANCE * np.sum(np.abs(loads), axis=1)
            finished = ~done & (frictionless | load_independent | converged)
            current = BatchContactSolution(motion, friction, loads, use, held)
            solution = current if solution is None else _choose(finished, current, solution)
            done |= finished
            if done.all():
                return solution
            held = np.where(done[:, None], held, loads)
        stuck = np.flatnonzero(~done)
        raise ModelError(f'normal loads and kinetic friction found no consistent value in {_LOAD_ITERATIONS} '
                         f'iterations for robot(s) {stuck[:5].tolist()}')


def _choose(which: np.ndarray, new: BatchContactSolution, old: BatchContactSolution) -> BatchContactSolution:
    """``new`` for the robots ``which``, ``old`` for the others, field by field."""
    def pick(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.where(which.reshape((-1,) + (1,) * (a.ndim - 1)), a, b)
    return BatchContactSolution(BatchMotion(*(pick(a, b) for a, b in zip(new.motion, old.motion))),
                                *(pick(a, b) for a, b in zip(new[1:], old[1:])))


def detached_wheels(loads: np.ndarray) -> np.ndarray:
    """(N,) the wheel (1..4) with the most negative load, 0 while every load is >= 0 (``detached_wheel``)."""
    lowest = np.argmin(loads, axis=1)
    return np.where(np.take_along_axis(loads, lowest[:, None], axis=1)[:, 0] < 0.0, lowest + 1, 0)
