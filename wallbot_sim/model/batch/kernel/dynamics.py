"""One robot's derivative and RK4 step (the batch's fused loop, ``robot_run``) from its problem (``problem``), and
the tracking controller's inverse dynamics."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit, prange, unowned
from wallbot_sim.model.batch.kernel.frame import _frame_rows, _frame_solve
from wallbot_sim.model.batch.kernel.layout import MAX_ROWS
from wallbot_sim.model.batch.kernel.linalg import _full_rank_solve, _least_squares, _scratch, _solve
from wallbot_sim.model.batch.kernel.problem import _applied_force, _factor_of, _module_rows, _problem
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.trajectories import LastSample, Reference, tangent_heading


REFERENCE_FIELDS = 10
"""A reference instant: position, velocity, acceleration (2 each), has heading, angle, rate, its rate."""
NO_HEADING = (0.0, 0.0, 0.0, 0.0)
"""The heading fields of a reference at rest (no direction)."""


def reference_samples(reference: Reference | None, initial_time: float, first_step: int, steps: int,
                      dt: float) -> np.ndarray:
    """(steps, 3, 10): the reference at the three RK4 instants of each step from ``first_step`` on.

    The times are computed as ``BatchSimulation.t`` and ``rk4_step`` compute them.
    """
    if reference is None:
        return np.zeros((steps, 3, REFERENCE_FIELDS))
    half = 0.5 * dt
    shared = LastSample(reference)  # a step's end is often the next step's start to the last bit
    rows = []
    sample, row = None, ()
    for step in range(steps):
        t = initial_time + (first_step + step) * dt
        for time in (t, t + half, t + dt):
            current = shared.sample(time)
            if current is not sample:  # a new instant: its row (the heading takes the most work)
                sample = current
                heading = tangent_heading(sample)
                row = (*sample.position, *sample.velocity, *sample.acceleration,
                       *(NO_HEADING if heading is None else (1.0, *heading)))
            rows.append(row)
    return np.array(rows, dtype=float).reshape(steps, 3, REFERENCE_FIELDS)


def _acceleration(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                  torque: np.ndarray, gains: np.ndarray, contact: bool, sticking: np.ndarray, held: np.ndarray,
                  rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
                  lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, ints: np.ndarray,
                  with_force: bool, out: np.ndarray) -> None:
    """qdd of one robot at (q, qd): ``BatchSimulation._derivative`` for that robot alone (``_problem``, then
    ``_solve``); with ``with_force`` Q, with the held friction of sliding wheels, is left in ``vectors`` row 0 (else
    that row is scratch). With ``contact`` the solve goes through the rows' own space first, in the body
    axes (``frame``: ``mats`` and ``ints`` hold its factored rows). Without, rows of full column rank decide qdd
    alone (``_full_rank_solve``): Q and W are then computed only if ``with_force``."""
    if contact:
        count = _problem(q, qd, reference, flags, constants, torque, gains, contact, sticking, held, rows, rhs,
                         factor, vectors[0])
        rank = _frame_rows(q, qd, reference, flags, constants, sticking, rows, factor, count, mats, ints)
        if _frame_solve(math.cos(q[2]), math.sin(q[2]), flags, factor, vectors[0], rhs, True, count, rank, mats, ints,
                        vectors, out):
            return
        _least_squares(factor, vectors[0], rows, rhs, count, matrix, gram, lower, vectors, scratch, out)
        return
    theta = q[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    count = _module_rows(q, qd, reference, flags, constants, cos_t, sin_t, False, sticking, held, rows, rhs,
                         vectors[0])
    if with_force:
        _applied_force(q, qd, constants, torque, gains, cos_t, sin_t, vectors[0])
    if count >= DOF and _full_rank_solve(rows, rhs, count, gram, lower, out):
        return
    if not with_force:
        _applied_force(q, qd, constants, torque, gains, cos_t, sin_t, vectors[0])
    _factor_of(theta, constants, factor)
    _solve(factor, vectors[0], rows, rhs, count, matrix, gram, lower, vectors, scratch, out)


def _rk4(state: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray, torque: np.ndarray,
         gains: np.ndarray, contact: bool, sticking: np.ndarray, held: np.ndarray, dt: float, known: bool,
         rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
         lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, ints: np.ndarray,
         stage: np.ndarray, slopes: np.ndarray) -> bool:
    """One RK4 step of one robot from ``state`` (14,) into ``stage`` (``rk4_step``); whether it is finite.

    ``references`` (3, 10): the reference at t, t + dt/2 and t + dt. ``known``: slopes[0, 7:] already
    holds qdd at ``state`` (the outputs' solve, RK4's first stage). ``gains``, ``contact``, ``sticking``,
    ``held``: ``_problem``'s, held over the step; ``mats``, ``ints``: ``_acceleration``'s.
    """
    half, sixth = 0.5 * dt, dt / 6.0
    for k in range(4):
        if k == 0:
            for i in range(2 * DOF):
                stage[i] = state[i]
        else:
            weight = dt if k == 3 else half
            for i in range(2 * DOF):
                stage[i] = state[i] + weight * slopes[k - 1, i]
        for i in range(DOF):
            slopes[k, i] = stage[DOF + i]
        if k == 0 and known:
            continue
        instant = 0 if k == 0 else (2 if k == 3 else 1)
        _acceleration(stage[:DOF], stage[DOF:], references[instant], flags, constants, torque, gains, contact,
                      sticking, held, rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, ints, False,
                      slopes[k, DOF:])
    finite = True
    for i in range(2 * DOF):
        stage[i] = state[i] + sixth * (slopes[0, i] + 2.0 * (slopes[1, i] + slopes[2, i]) + slopes[3, i])
        finite = finite and math.isfinite(stage[i])
    return finite


def _steps(y: np.ndarray, steps: int, dt: float, references: np.ndarray, flags: np.ndarray, constants: np.ndarray,
           torques: np.ndarray, chunk: int, diverged: np.ndarray) -> None:
    """``steps`` RK4 steps of every robot, in place on y (N, 14) (``rk4_step`` of the derivative robot by robot).

    A robot whose state stops being finite stops there: diverged[robot] is set to that step.
    """
    count = y.shape[0]
    for block in prange((count + chunk - 1) // chunk):
        rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)  # zero once: see _problem
        factor, matrix, gram, lower, vectors, scratch = _workspace()
        gains, no_wheels, no_held = np.zeros(4), np.zeros(4, dtype=np.bool_), np.zeros(8)
        no_mats, no_ints = np.zeros((1, 1, 1)), np.zeros((1, 1), dtype=np.int64)  # contact mode's only
        state, stage, slopes = np.zeros(2 * DOF), np.zeros(2 * DOF), np.zeros((4, 2 * DOF))
        for robot in range(block * chunk, min(count, (block + 1) * chunk)):
            gains[:] = constants[robot, 8]
            for i in range(2 * DOF):
                state[i] = y[robot, i]
            for step in range(steps):
                if not _rk4(state, references[step], flags, constants[robot], torques[robot], gains, False, no_wheels,
                            no_held, dt, False, rows, rhs, factor, matrix, gram, lower, vectors, scratch, no_mats,
                            no_ints, stage, slopes):
                    diverged[robot] = step
                    break
                for i in range(2 * DOF):
                    state[i] = stage[i]
            for i in range(2 * DOF):
                y[robot, i] = state[i]


def _workspace() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """factor W and ``_scratch`` for one robot's problems of up to MAX_ROWS rows."""
    matrix, gram, lower, vectors, scratch = _scratch(MAX_ROWS)
    return np.zeros((DOF, DOF)), matrix, gram, lower, vectors, scratch


def _motion(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, count: int, constants: np.ndarray,
            torque: np.ndarray, gains: np.ndarray, no_wheels: np.ndarray, no_held: np.ndarray, no_mats: np.ndarray,
            no_ints: np.ndarray, motion: np.ndarray, rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray,
            matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray) -> float:
    """One robot at y (14,) with ideal contact: motion (3, 7) gets qdd, Q and Q_c = M qdd - Q; returns the residual
    |A qdd - b|.

    ``reference`` (10,): the reference at this instant; ``flags``, ``count``: ``module_flags``; ``constants``:
    the robot's row of ``robot_constants``; ``torque``: (tau_L, tau_R); ``gains``: ``_problem``'s; ``no_wheels``
    (4,) False, ``no_held`` (8,) zeros, ``no_mats`` and ``no_ints`` any (contact mode's); the rest: the caller's
    workspace.
    """
    acceleration, force = motion[0], motion[1]
    _acceleration(y[:DOF], y[DOF:], reference, flags, constants, torque, gains, False, no_wheels, no_held, rows, rhs,
                  factor, matrix, gram, lower, vectors, scratch, no_mats, no_ints, True, acceleration)
    for i in range(DOF):
        force[i] = vectors[0, i]  # Q: _acceleration leaves it in vectors row 0
    return _constraint_force(y[2], constants, acceleration, force, rows, rhs, count, motion[2])


def _constraint_force(theta: float, constants: np.ndarray, acceleration: np.ndarray, force: np.ndarray,
                      rows: np.ndarray, rhs: np.ndarray, count: int, constraint: np.ndarray) -> float:
    """Q_c = M qdd - Q into ``constraint`` (7,) from qdd (``acceleration``) and Q (``force``) at heading theta;
    returns the residual |A qdd - b| of the rows."""
    mass, yaw_inertia, spin_inertia, sx, sy = constants[0], constants[1], constants[2], constants[3], constants[4]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    ux, uy = -cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx  # M's coupling entries (Robot.offset_moment_arm)
    constraint[0] = mass * acceleration[0] + ux * acceleration[2] - force[0]
    constraint[1] = mass * acceleration[1] + uy * acceleration[2] - force[1]
    constraint[2] = ux * acceleration[0] + uy * acceleration[1] + yaw_inertia * acceleration[2] - force[2]
    for i in range(3, DOF):
        constraint[i] = spin_inertia * acceleration[i] - force[i]
    squares = 0.0
    for r in range(count):
        misfit = -rhs[r]
        for j in range(DOF):
            misfit += rows[r, j] * acceleration[j]
        squares += misfit * misfit
    return math.sqrt(squares)


def robot_run(states: np.ndarray, references: np.ndarray, flags: np.ndarray, count: int, constants: np.ndarray,
              torque: np.ndarray, dt: float, steps: int, motions: np.ndarray, residuals: np.ndarray) -> int:
    """One robot over consecutive instants: the motion at each state (``_motion``), then the RK4 step from
    it with that qdd as the first stage; the number of steps taken.

    ``states`` (T + 1, 14): row 0 the state at the first instant; row k + 1 gets the state one step after
    row k, for k < ``steps`` (at most T), until a state is not finite (then that row is not valid and the
    count is k). ``motions`` (T, 3, 7) and ``residuals`` (T,) get the motion at every state reached among
    the first T; ``references`` (T, 3, 10): each step's three RK4 instants (``reference_samples``).
    """
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    slopes = np.zeros((4, 2 * DOF))
    gains, no_wheels, no_held = np.full(4, constants[8]), np.zeros(4, dtype=np.bool_), np.zeros(8)
    no_mats, no_ints = np.zeros((1, 1, 1)), np.zeros((1, 1), dtype=np.int64)
    return _robot_run(states, references, flags, count, constants, torque, dt, steps, motions, residuals, rows, rhs,
                      factor, matrix, gram, lower, vectors, scratch, slopes, gains, no_wheels, no_held, no_mats,
                      no_ints)


def _robot_run(states: np.ndarray, references: np.ndarray, flags: np.ndarray, count: int, constants: np.ndarray,
               torque: np.ndarray, dt: float, steps: int, motions: np.ndarray, residuals: np.ndarray,
               rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
               lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, slopes: np.ndarray, gains: np.ndarray,
               no_wheels: np.ndarray, no_held: np.ndarray, no_mats: np.ndarray, no_ints: np.ndarray) -> int:
    """``robot_run`` in its workspace, every array taken ``unowned``: the caller holds them all for the run."""
    states, references, flags, constants = unowned(states), unowned(references), unowned(flags), unowned(constants)
    torque, motions, residuals = unowned(torque), unowned(motions), unowned(residuals)
    rows, rhs, factor, matrix, gram = unowned(rows), unowned(rhs), unowned(factor), unowned(matrix), unowned(gram)
    lower, vectors, scratch, slopes = unowned(lower), unowned(vectors), unowned(scratch), unowned(slopes)
    gains, no_wheels, no_held = unowned(gains), unowned(no_wheels), unowned(no_held)
    no_mats, no_ints = unowned(no_mats), unowned(no_ints)
    for k in range(motions.shape[0]):
        residuals[k] = _motion(states[k], references[k, 0], flags, count, constants, torque, gains, no_wheels, no_held,
                               no_mats, no_ints, motions[k], rows, rhs, factor, matrix, gram, lower, vectors, scratch)
        if k == steps:
            return k
        for i in range(DOF):
            slopes[0, DOF + i] = motions[k, 0, i]
        if not _rk4(states[k], references[k], flags, constants, torque, gains, False, no_wheels, no_held, dt, True,
                    rows, rhs, factor, matrix, gram, lower, vectors, scratch, no_mats, no_ints, states[k + 1], slopes):
            return k
    return steps


def tracking_force(y: np.ndarray, point: np.ndarray, flags: np.ndarray, constants: np.ndarray, distance: float,
                   out: np.ndarray) -> None:
    """Q_c (7,) into ``out``: the inverse dynamics of one unpowered robot at y (14,) under the modules of
    ``flags`` and the look-ahead point task (``LookAheadPointTask.rows``) stacked after them.

    ``point`` (3, 2): the point's reference position, velocity and acceleration; ``distance``: L.
    """
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    motion = np.zeros((3, DOF))
    no_torque, gains = np.zeros(2), np.full(4, constants[8])
    no_wheels, no_held = np.zeros(4, dtype=np.bool_), np.zeros(8)
    q, qd = y[:DOF], y[DOF:]
    count = _problem(q, qd, np.zeros(REFERENCE_FIELDS), flags, constants, no_torque, gains, False, no_wheels, no_held,
                     rows, rhs, factor, vectors[0])
    alpha, beta = constants[10], constants[11]
    cos_t, sin_t, thd = math.cos(q[2]), math.sin(q[2]), qd[2]
    heading = (cos_t, sin_t)
    point_velocity = (qd[0] - distance * thd * sin_t, qd[1] + distance * thd * cos_t)
    for axis in range(2):
        rows[count, axis] = 1.0
        rows[count, 2] = distance * (-sin_t if axis == 0 else cos_t)
        rhs[count] = (point[2, axis] - 2.0 * alpha * (point_velocity[axis] - point[1, axis])
                      - beta * beta * (q[axis] + distance * heading[axis] - point[0, axis])
                      + distance * thd * thd * heading[axis])
        count += 1
    for i in range(DOF):
        motion[1, i] = vectors[0, i]
    _solve(factor, vectors[0], rows, rhs, count, matrix, gram, lower, vectors, scratch, motion[0])
    _constraint_force(y[2], constants, motion[0], motion[1], rows, rhs, count, motion[2])
    for i in range(DOF):
        out[i] = motion[2, i]


def batch_tracking_forces(states: np.ndarray, point: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                          distance: float, out: np.ndarray) -> None:
    """``tracking_force`` of every robot of a batch into ``out`` (N, 7): ``states`` (N, 14), ``constants`` (N, 24),
    the same ``point`` (3, 2) and ``distance`` for all (one controller instant of a batch)."""
    for robot in range(states.shape[0]):
        tracking_force(states[robot], point, flags, constants[robot], distance, out[robot])


_acceleration = jit(_acceleration, inline="always")
_rk4 = jit(_rk4, inline="always")
_steps = jit(_steps, parallel=True)
_workspace = jit(_workspace, inline="always")
_constraint_force = jit(_constraint_force, inline="always")
_motion = jit(_motion, inline="always")
robot_run = jit(robot_run)
_robot_run = jit(_robot_run)
tracking_force = jit(tracking_force)
batch_tracking_forces = jit(batch_tracking_forces)
