"""One robot's derivative and RK4 step with ideal contact (the batch's fused loop, ``robot_run``) and the tracking
controller's inverse dynamics; the constraint rows of the modules the kernel knows."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit, prange
from wallbot_sim.model.batch.kernel.layout import (
    BELT, MAX_ROWS, NON_LATERAL, NONSLIP, ROW_FACTOR, ROW_KEPT, ROW_ORDER, ROW_SYSTEM, TANGENT_HEADING, TRAJECTORY)
from wallbot_sim.model.batch.kernel.linalg import _full_rank_solve, _scratch, _solve
from wallbot_sim.model.batch.kernel.row_space import _prepare_rows, _row_space_solve
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
    that row is scratch). With ``contact`` the solve goes through the rows' own space first (``_row_space_solve``,
    ``mats`` and ``ints`` its scratch). Without, rows of full column rank decide qdd alone (``_full_rank_solve``):
    Q and W are then computed only if ``with_force``."""
    if contact:
        count = _problem(q, qd, reference, flags, constants, torque, gains, contact, sticking, held, rows, rhs,
                         factor, vectors[0])
        rank = _prepare_rows(rows, factor, count, matrix, mats[ROW_SYSTEM], mats[ROW_FACTOR], ints[ROW_ORDER],
                             ints[ROW_KEPT])
        if _row_space_solve(factor, vectors[0], rhs, True, matrix, count, rank, ints[ROW_ORDER], ints[ROW_KEPT],
                            mats[ROW_FACTOR], vectors, out):
            return
        _solve(factor, vectors[0], rows, rhs, count, matrix, gram, lower, vectors, scratch, out)
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


def _factor_of(theta: float, constants: np.ndarray, factor: np.ndarray) -> None:
    """W (7, 7), lower triangular, W W^T = M^-1 at heading theta: the chassis block's Cholesky factor in closed
    form, 1/sqrt(J_w) on the spins (``RobotBatch.mass_inverse_factor``)."""
    mass, yaw_inertia, spin_inertia, sx, sy = constants[0], constants[1], constants[2], constants[3], constants[4]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    ux, uy = -cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx
    inv_schur = 1.0 / (yaw_inertia - (ux * ux + uy * uy) / mass)
    wx, wy = ux / mass, uy / mass
    c00, c10, c11 = 1.0 / mass + wx * wx * inv_schur, wx * wy * inv_schur, 1.0 / mass + wy * wy * inv_schur
    c20, c21 = -wx * inv_schur, -wy * inv_schur
    l00 = math.sqrt(c00)
    l10 = c10 / l00
    l11 = math.sqrt(c11 - l10 * l10)
    l20 = c20 / l00
    l21 = (c21 - l20 * l10) / l11
    factor[0, 0], factor[1, 0], factor[1, 1] = l00, l10, l11
    factor[2, 0], factor[2, 1], factor[2, 2] = l20, l21, math.sqrt(inv_schur - l20 * l20 - l21 * l21)
    factor[0, 1] = factor[0, 2] = factor[1, 2] = 0.0
    spin = math.sqrt(1.0 / spin_inertia)
    for j in range(3, DOF):
        factor[j, j] = spin


def _problem(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
             torque: np.ndarray, gains: np.ndarray, contact: bool, sticking: np.ndarray, held: np.ndarray,
             rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, force: np.ndarray) -> int:
    """Q, the factor W of M^-1 and the rows A, b of the active modules of one robot at (q, qd); the row count.

    ``gains`` (4,): each wheel's rolling resistance per unit speed, f_r N (section 4's f_r F_ad / 4 with ideal
    contact). ``contact`` (coulomb contact, docs/model.md 11.3): the non-lateral and nonslip modules give each
    ``sticking`` wheel its contact rows (lateral and longitudinal), J_i qdd = -c - gam v_i, in wheel order after
    the other modules' rows, and ``held`` (8,), the sliding wheels' forces (f_x, f_y) in body axes wheel by wheel
    (zero for the others), enters Q as sum_i J_i^T f_i (``HeldFriction``).
    """
    theta = q[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    _applied_force(q, qd, constants, torque, gains, cos_t, sin_t, force)
    _factor_of(theta, constants, factor)
    return _module_rows(q, qd, reference, flags, constants, cos_t, sin_t, contact, sticking, held, rows, rhs, force)


def _applied_force(q: np.ndarray, qd: np.ndarray, constants: np.ndarray, torque: np.ndarray, gains: np.ndarray,
                   cos_t: float, sin_t: float, force: np.ndarray) -> None:
    """Q of one robot at (q, qd), heading cos_t, sin_t (``_problem``'s ``gains``)."""
    sx, sy = constants[3], constants[4]
    gravity, weight, eps2 = constants[5], constants[6], constants[9]
    # constants[16:24] S d_i = (-s_i, a_i) pairs
    thd = qd[2]
    thd2 = thd * thd
    force[0] = thd2 * (cos_t * sx - sin_t * sy)
    force[1] = thd2 * (sin_t * sx + cos_t * sy) - weight
    force[2] = -gravity * (-sin_t * sy + cos_t * sx)
    for wheel in range(4):
        px, py = constants[16 + 2 * wheel], constants[17 + 2 * wheel]
        arm_x, arm_y = cos_t * px - sin_t * py, sin_t * px + cos_t * py
        vx, vy = qd[0] + thd * arm_x, qd[1] + thd * arm_y
        scale = -gains[wheel] / math.sqrt(vx * vx + vy * vy + eps2)
        force[0] += scale * vx
        force[1] += scale * vy
        force[2] += scale * (arm_x * vx + arm_y * vy)
    force[3] = force[4] = 0.5 * torque[0]
    force[5] = force[6] = 0.5 * torque[1]


# Long on purpose: the rows of every active module in stacking order, in one pass over the shared heading terms;
# numba inlines it into each RK4 stage of the hot loop, one frame with the row counter in registers.
def _module_rows(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                 cos_t: float, sin_t: float, contact: bool, sticking: np.ndarray, held: np.ndarray, rows: np.ndarray,
                 rhs: np.ndarray, force: np.ndarray) -> int:
    """The rows A, b of the active modules of one robot at (q, qd), heading cos_t, sin_t; the row count. With
    ``contact``, the sticking wheels' rows and the held friction added to Q in ``force`` (``_problem``)."""
    radius, alpha, beta = constants[7], constants[10], constants[11]
    # constants[12:16] lateral offsets s_i
    theta, thd = q[2], qd[2]
    # the rows of the active modules, in stacking order: their entries that are not written here stay
    # zero from the block's start (each module writes the same entries at every stage)
    gam = 2.0 * alpha
    count = 0
    if flags[TRAJECTORY]:
        for axis in range(2):
            rows[count, axis] = 1.0
            rhs[count] = (reference[4 + axis] - 2.0 * alpha * (qd[axis] - reference[2 + axis])
                          - beta * beta * (q[axis] - reference[axis]))
            count += 1
    if flags[TANGENT_HEADING]:
        rows[count, 2] = 1.0
        if reference[6] == 0.0:
            rhs[count] = -gam * thd
        else:
            error = theta - reference[7]
            turn = 2.0 * math.pi
            error = error - turn * np.round(error / turn)
            if error <= -math.pi:
                error += turn
            rhs[count] = reference[9] - gam * (thd - reference[8]) - beta * beta * error
        count += 1
    if flags[BELT]:
        rows[count, 3], rows[count, 4] = 1.0, -1.0
        rhs[count] = -gam * (qd[3] - qd[4])
        rows[count + 1, 5], rows[count + 1, 6] = 1.0, -1.0
        rhs[count + 1] = -gam * (qd[5] - qd[6])
        count += 2
    v_long = cos_t * qd[0] + sin_t * qd[1]
    v_lat = -sin_t * qd[0] + cos_t * qd[1]
    if contact:
        return _wheel_rows(qd, flags, constants, sticking, held, cos_t, sin_t, v_long, v_lat, gam, count, rows, rhs,
                           force)
    if flags[NON_LATERAL]:
        rows[count, 0], rows[count, 1] = -sin_t, cos_t
        rhs[count] = thd * v_long - gam * v_lat
        count += 1
    if flags[NONSLIP]:
        for wheel in range(4):
            offset = constants[12 + wheel]
            violation = -cos_t * qd[0] - sin_t * qd[1] + offset * thd + radius * qd[3 + wheel]
            rows[count, 0], rows[count, 1], rows[count, 2] = -cos_t, -sin_t, offset
            rows[count, 3 + wheel] = radius
            rhs[count] = thd * v_lat - gam * violation
            count += 1
    return count


def _wheel_rows(qd: np.ndarray, flags: np.ndarray, constants: np.ndarray, sticking: np.ndarray, held: np.ndarray,
                cos_t: float, sin_t: float, v_long: float, v_lat: float, gam: float, count: int, rows: np.ndarray,
                rhs: np.ndarray, force: np.ndarray) -> int:
    """``_problem``'s contact rows of the sticking wheels after its first ``count`` rows (every entry written: the
    sticking set changes between calls), and the held friction added to ``force``; the row count."""
    thd, radius = qd[2], constants[7]
    drift_x, drift_y = thd * v_lat, -thd * v_long  # c = (thd v_lat, -thd v_long)
    for wheel in range(4):
        offset, along = constants[12 + wheel], constants[17 + 2 * wheel]  # s_i, a_i
        if sticking[wheel] and flags[NONSLIP]:
            rows[count, 0], rows[count, 1], rows[count, 2] = cos_t, sin_t, -offset
            for j in range(3, DOF):
                rows[count, j] = -radius if j == 3 + wheel else 0.0
            rhs[count] = -drift_x - gam * (v_long - offset * thd - radius * qd[3 + wheel])
            count += 1
        if sticking[wheel] and flags[NON_LATERAL]:
            rows[count, 0], rows[count, 1], rows[count, 2] = -sin_t, cos_t, along
            for j in range(3, DOF):
                rows[count, j] = 0.0
            rhs[count] = -drift_y - gam * (v_lat + along * thd)
            count += 1
        push_x, push_y = held[2 * wheel], held[2 * wheel + 1]
        force[0] += push_x * cos_t - push_y * sin_t
        force[1] += push_x * sin_t + push_y * cos_t
        force[2] += -push_x * offset + push_y * along
        force[3 + wheel] -= push_x * radius
    return count


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


_problem = jit(_problem, inline="always")
_applied_force = jit(_applied_force, inline="always")
_module_rows = jit(_module_rows, inline="always")
_acceleration = jit(_acceleration, inline="always")
_rk4 = jit(_rk4, inline="always")
_steps = jit(_steps, parallel=True)
_workspace = jit(_workspace, inline="always")
_constraint_force = jit(_constraint_force, inline="always")
_motion = jit(_motion, inline="always")
robot_run = jit(robot_run)
tracking_force = jit(tracking_force)
_factor_of = jit(_factor_of, inline="always")
_wheel_rows = jit(_wheel_rows, inline="always")
