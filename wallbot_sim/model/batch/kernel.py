"""The batch compiled with numba: the ideal-contact RK4 steps fused robot by robot, and the solve alone.

The NumPy path (``BatchSimulation`` with ``engine='numpy'``) spends its time in whole-batch
array passes: every operation of a derivative reads and writes (N, k, 7) arrays, so a step is
bound by memory traffic and ~200 NumPy calls. This kernel computes the same derivative robot by
robot in registers and small scratch arrays, all the steps of a ``run`` at once (the reference
sampled beforehand, shared by all robots), the robots split over the cores. It is the same
computation as the NumPy path, operation for operation where it can be: the model's forces,
the rows of the modules of ``BATCH_MODULES`` in stacking order, the Udwadia-Kalaba solve by
normal equations with the pivoted (rank-revealing) fallback per robot, and RK4's sums. The
agreement tests run both.

``constrained_accelerations`` and ``minimum_norm_solutions`` are the solve alone (the NumPy
engine's ``batch_constrained_acceleration`` and ``minimum_norm_least_squares`` robot by robot), for
what the fused step does not cover: coulomb contact, and the outputs step hooks see.

``robot_run`` takes one robot's RK4 steps a chunk at a time, with the motion (qdd, Q, Q_c, residual) at
each state, for ``Simulation(..., engine='numba')`` (``wallbot_sim.model.compiled``): the same
derivative and RK4 step as the batch's fused loop.

numba is optional: ``available()`` says whether it imported.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.solver import RANK_CUTOFF, WELL_CONDITIONED
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.trajectories import LastSample, Reference, tangent_heading

try:
    import numba
    from numba import prange
except ImportError:  # the NumPy path needs nothing more
    numba = None
    prange = range

MODULE_ORDER = ('trajectory', 'tangent_heading', 'belt', 'non_lateral', 'nonslip')
"""The modules the kernel knows, in ``MODULES``' stacking order (its flags follow it)."""
MODULE_ROWS = (2, 1, 2, 1, 4)
MAX_ROWS = sum(MODULE_ROWS)
"""The rows of every module at once."""
REFERENCE_FIELDS = 10
"""A reference instant: position, velocity, acceleration (2 each), has heading, angle, rate, its rate."""
NO_HEADING = (0.0, 0.0, 0.0, 0.0)
"""The heading fields of a reference at rest (no direction)."""


def available() -> bool:
    """Whether numba imported (the compiled engine can run)."""
    return numba is not None


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


def _compile(function: Any, **options: Any) -> Any:
    # error_model 'numpy': a division by zero gives inf or NaN as in NumPy, unchecked (the caller checks the results)
    return numba.njit(cache=True, error_model='numpy', **options)(function) if numba is not None else function


def _cholesky(matrix: np.ndarray, size: int, lower: np.ndarray) -> float:
    """L L^T = M for M (size x size); returns the smallest pivot L_jj^2 (not positive: L is not valid)."""
    smallest = math.inf
    for j in range(size):
        for i in range(j, size):
            value = matrix[i, j]
            for k in range(j):
                value -= lower[j, k] * lower[i, k]
            if i == j:
                smallest = min(smallest, value)
                if not value > 0.0:
                    return value
                lower[j, j] = math.sqrt(value)
            else:
                lower[i, j] = value / lower[j, j]
    return smallest


def _substitute(lower: np.ndarray, size: int, vector: np.ndarray) -> None:
    """vector <- (L L^T)^-1 vector, in place."""
    for j in range(size):
        value = vector[j]
        for k in range(j):
            value -= lower[j, k] * vector[k]
        vector[j] = value / lower[j, j]
    for j in range(size - 1, -1, -1):
        value = vector[j]
        for k in range(j + 1, size):
            value -= lower[k, j] * vector[k]
        vector[j] = value / lower[j, j]


def _solve_positive(matrix: np.ndarray, size: int, lower: np.ndarray, vector: np.ndarray) -> None:
    """vector <- M^-1 vector for a positive definite M (LU when round-off leaves a pivot <= 0)."""
    _solve_factored(matrix, size, _cholesky(matrix, size, lower) > 0.0, lower, vector)


def _solve_factored(matrix: np.ndarray, size: int, factored: bool, lower: np.ndarray, vector: np.ndarray) -> None:
    """vector <- M^-1 vector with M's Cholesky factor in ``lower`` if ``factored``, else by LU."""
    if factored:
        _substitute(lower, size, vector)
    else:
        vector[:size] = np.linalg.solve(matrix[:size, :size], vector[:size].copy())


def _rank_revealing(gram: np.ndarray, moment: np.ndarray, scratch: np.ndarray, lower: np.ndarray,
                    result: np.ndarray) -> None:
    """Minimum-norm least squares from B^T B and B^T r of a B not safely of full rank.

    ``minimum_norm_least_squares`` for one robot: pivoted Cholesky, basic solution, null space removed.
    """
    size = DOF
    schur = scratch[0]
    kept = np.zeros(size, dtype=np.bool_)
    largest = 0.0
    for j in range(size):
        largest = max(largest, gram[j, j])
        for i in range(size):
            schur[i, j] = gram[i, j]
    cut = RANK_CUTOFF * largest
    for _ in range(size):
        best, pivot = -1, -math.inf
        for j in range(size):
            if not kept[j] and schur[j, j] > pivot:
                best, pivot = j, schur[j, j]
        if best < 0 or not pivot > cut:
            break
        kept[best] = True
        scale = 1.0 / math.sqrt(pivot)
        column = scratch[1, 0]
        for i in range(size):
            column[i] = schur[i, best] * scale
        for i in range(size):
            for j in range(size):
                schur[i, j] -= column[i] * column[j]
    reduced = scratch[2]
    for i in range(size):
        for j in range(size):
            reduced[i, j] = gram[i, j] if kept[i] and kept[j] else (1.0 if i == j else 0.0)
    # the basic solution (zero on the skipped columns), then each skipped column from the kept ones
    basic = scratch[1, 1]
    for i in range(size):
        basic[i] = moment[i] if kept[i] else 0.0
    factored = _cholesky(reduced, size, lower) > 0.0  # one factorization for the basic solution and the columns
    _solve_factored(reduced, size, factored, lower, basic)
    null = scratch[3]
    column = scratch[1, 2]
    for j in range(size):
        if kept[j]:
            for i in range(size):
                null[i, j] = 0.0
        else:
            for i in range(size):
                column[i] = gram[i, j] if kept[i] else 0.0
            _solve_factored(reduced, size, factored, lower, column)
            for i in range(size):
                null[i, j] = (1.0 if i == j else 0.0) - column[i]
    null_gram = scratch[4]
    shift = scratch[1, 3]
    for i in range(size):
        value = 0.0
        for k in range(size):
            value += null[k, i] * basic[k]
        shift[i] = value
        for j in range(size):
            entry = 0.0
            for k in range(size):
                entry += null[k, i] * null[k, j]
            null_gram[i, j] = entry + (1.0 if i == j and kept[i] else 0.0)
    _solve_positive(null_gram, size, lower, shift)
    for i in range(size):
        value = basic[i]
        for j in range(size):
            value -= null[i, j] * shift[j]
        result[i] = value


def _acceleration(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                  torque: np.ndarray, slipping: np.ndarray, bounds: np.ndarray, rows: np.ndarray, rhs: np.ndarray,
                  factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray,
                  scratch: np.ndarray, out: np.ndarray) -> None:
    """qdd of one robot at (q, qd): ``BatchSimulation._derivative`` for that robot alone (``_problem``, then
    ``_solve``); Q, with the kinetic friction of slipping rows, is left in ``vectors`` row 0."""
    count = _problem(q, qd, reference, flags, constants, torque, slipping, bounds, rows, rhs, factor, vectors[0])
    _solve(factor, vectors[0], rows, rhs, count, matrix, gram, lower, vectors, scratch, out)


def _problem(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
             torque: np.ndarray, slipping: np.ndarray, bounds: np.ndarray, rows: np.ndarray, rhs: np.ndarray,
             factor: np.ndarray, force: np.ndarray) -> int:
    """Q, the factor W of M^-1 and the rows A, b of the active modules of one robot at (q, qd); the row count.

    ``slipping`` (left, right, lateral): a slipping channel's rows (docs/model.md 11.3) are left out, and
    the kinetic friction bounds[k] v_k / sqrt(v_k^2 + eps^2) a_k of each of its rows k is added to Q
    (k: 0 the non-lateral row, 1 + i wheel i's nonslip row; ``bounds`` -mu_k times the bounding load).
    """
    mass, yaw_inertia, spin_inertia, sx, sy = constants[0], constants[1], constants[2], constants[3], constants[4]
    gravity, weight, radius, resistance, eps2 = constants[5], constants[6], constants[7], constants[8], constants[9]
    alpha, beta = constants[10], constants[11]
    # constants[12:16] lateral offsets s_i, [16:24] S d_i as (x, y) pairs
    theta, thd = q[2], qd[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    thd2 = thd * thd
    force[0] = thd2 * (cos_t * sx - sin_t * sy)
    force[1] = thd2 * (sin_t * sx + cos_t * sy) - weight
    force[2] = -gravity * (-sin_t * sy + cos_t * sx)
    for wheel in range(4):
        px, py = constants[16 + 2 * wheel], constants[17 + 2 * wheel]
        arm_x, arm_y = cos_t * px - sin_t * py, sin_t * px + cos_t * py
        vx, vy = qd[0] + thd * arm_x, qd[1] + thd * arm_y
        scale = -resistance / math.sqrt(vx * vx + vy * vy + eps2)
        force[0] += scale * vx
        force[1] += scale * vy
        force[2] += scale * (arm_x * vx + arm_y * vy)
    force[3] = force[4] = 0.5 * torque[0]
    force[5] = force[6] = 0.5 * torque[1]
    # W: the chassis block's Cholesky factor of M^-1 in closed form, 1/sqrt(J_w) on the spins
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
    # the rows of the active modules, in stacking order: their entries that are not written here stay
    # zero from the block's start (each module writes the same entries at every stage)
    gam = 2.0 * alpha
    count = 0
    if flags[0]:
        for axis in range(2):
            rows[count, axis] = 1.0
            rhs[count] = (reference[4 + axis] - 2.0 * alpha * (qd[axis] - reference[2 + axis])
                          - beta * beta * (q[axis] - reference[axis]))
            count += 1
    if flags[1]:
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
    if flags[2]:
        rows[count, 3], rows[count, 4] = 1.0, -1.0
        rhs[count] = -gam * (qd[3] - qd[4])
        rows[count + 1, 5], rows[count + 1, 6] = 1.0, -1.0
        rhs[count + 1] = -gam * (qd[5] - qd[6])
        count += 2
    v_long = cos_t * qd[0] + sin_t * qd[1]
    v_lat = -sin_t * qd[0] + cos_t * qd[1]
    # a slipping row leaves the rows below it one place up: each row clears the entries it does not write
    if flags[3]:
        if slipping[2]:
            push = bounds[0] * v_lat / math.sqrt(v_lat * v_lat + eps2)
            force[0] -= push * sin_t
            force[1] += push * cos_t
        else:
            rows[count, 0], rows[count, 1] = -sin_t, cos_t
            for j in range(2, DOF):
                rows[count, j] = 0.0
            rhs[count] = thd * v_long - gam * v_lat
            count += 1
    if flags[4]:
        for wheel in range(4):
            offset = constants[12 + wheel]
            violation = -cos_t * qd[0] - sin_t * qd[1] + offset * thd + radius * qd[3 + wheel]
            if slipping[wheel // 2]:
                push = bounds[1 + wheel] * violation / math.sqrt(violation * violation + eps2)
                force[0] -= push * cos_t
                force[1] -= push * sin_t
                force[2] += push * offset
                force[3 + wheel] += push * radius
            else:
                rows[count, 0], rows[count, 1], rows[count, 2] = -cos_t, -sin_t, offset
                for j in range(3, DOF):
                    rows[count, j] = radius if j == 3 + wheel else 0.0
                rhs[count] = thd * v_lat - gam * violation
                count += 1
    for j in range(3, DOF):
        factor[j, j] = spin
    return count


def _solve(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray, count: int,
           matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray,
           out: np.ndarray) -> None:
    """qdd = W (W^T Q + B+ (b - B W^T Q)), B = A W, of one robot (``batch_constrained_acceleration``).

    W is the robot's factor of M^-1: lower triangular, its off-diagonal entries in the 3 x 3 chassis
    block. ``vectors`` rows 1-4 are scratch (row 0 may hold Q).
    """
    scaled = vectors[1]
    for i in range(3):
        value = 0.0
        for k in range(i, 3):
            value += factor[k, i] * force[k]
        scaled[i] = value
    for i in range(3, DOF):
        scaled[i] = factor[i, i] * force[i]
    if count > 0:
        misfit = vectors[2]
        for r in range(count):
            value_r = rhs[r]
            for j in range(3):
                value = 0.0
                for k in range(j, 3):
                    value += rows[r, k] * factor[k, j]
                matrix[r, j] = value
                value_r -= value * scaled[j]
            for j in range(3, DOF):
                value = rows[r, j] * factor[j, j]
                matrix[r, j] = value
                value_r -= value * scaled[j]
            misfit[r] = value_r
        _minimum_norm(matrix, misfit, count, gram, lower, vectors, scratch, vectors[4])
        for i in range(DOF):
            scaled[i] += vectors[4, i]
    for i in range(3):
        value = 0.0
        for k in range(i + 1):
            value += factor[i, k] * scaled[k]
        out[i] = value
    for i in range(3, DOF):
        out[i] = factor[i, i] * scaled[i]


def _minimum_norm(matrix: np.ndarray, rhs: np.ndarray, count: int, gram: np.ndarray, lower: np.ndarray,
                  vectors: np.ndarray, scratch: np.ndarray, solution: np.ndarray) -> None:
    """B+ r for one robot's B (count x 7): normal equations, or the pivoted fallback (``minimum_norm_least_squares``).

    Uses ``vectors`` row 3 as scratch.
    """
    moment = vectors[3]
    largest = 0.0
    for i in range(DOF):
        value = 0.0
        for r in range(count):
            value += matrix[r, i] * rhs[r]
        moment[i] = value
        for j in range(i + 1):
            entry = 0.0
            for r in range(count):
                entry += matrix[r, i] * matrix[r, j]
            gram[i, j] = gram[j, i] = entry
        largest = max(largest, gram[i, i])
    if _cholesky(gram, DOF, lower) > WELL_CONDITIONED * largest:
        for i in range(DOF):
            solution[i] = moment[i]
        _substitute(lower, DOF, solution)
    else:
        _rank_revealing(gram, moment, scratch, lower, solution)


def _scratch(rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """matrix, gram, lower, vectors and the fallback's scratch for problems of up to ``rows`` rows."""
    return (np.zeros((max(rows, 1), DOF)), np.zeros((DOF, DOF)), np.zeros((DOF, DOF)),
            np.zeros((5, max(rows, DOF))), np.zeros((5, DOF, DOF)))


def _accelerations(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray, out: np.ndarray) -> None:
    """``_solve`` of every robot, on one thread: called several times a step, a solve is too short to pay
    for waking the others (on a machine others load, that costs more than it gains)."""
    count = rows.shape[1]
    matrix, gram, lower, vectors, scratch = _scratch(count)
    for robot in range(rows.shape[0]):
        _solve(factor[robot], force[robot], rows[robot], rhs[robot], count, matrix, gram, lower, vectors, scratch,
               out[robot])


def _minimum_norms(matrix: np.ndarray, rhs: np.ndarray, out: np.ndarray) -> None:
    """``_minimum_norm`` of every robot, on one thread (as ``_accelerations``)."""
    count = matrix.shape[1]
    _, gram, lower, vectors, scratch = _scratch(count)
    for robot in range(matrix.shape[0]):
        _minimum_norm(matrix[robot], rhs[robot], count, gram, lower, vectors, scratch, out[robot])


def _rk4(state: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray, torque: np.ndarray,
         slipping: np.ndarray, bounds: np.ndarray, dt: float, known: bool, rows: np.ndarray, rhs: np.ndarray,
         factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray,
         scratch: np.ndarray, stage: np.ndarray, slopes: np.ndarray) -> bool:
    """One RK4 step of one robot from ``state`` (14,) into ``stage`` (``rk4_step``); whether it is finite.

    ``references`` (3, 10): the reference at t, t + dt/2 and t + dt. ``known``: slopes[0, 7:] already
    holds qdd at ``state`` (the outputs' solve, RK4's first stage). ``slipping``, ``bounds``: the
    channels slipping over the step and their rows' friction bounds (``_problem``).
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
        _acceleration(stage[:DOF], stage[DOF:], references[instant], flags, constants, torque, slipping, bounds,
                      rows, rhs, factor, matrix, gram, lower, vectors, scratch, slopes[k, DOF:])
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
        sticking, no_bounds = np.zeros(3, dtype=np.bool_), np.zeros(5)
        state, stage, slopes = np.zeros(2 * DOF), np.zeros(2 * DOF), np.zeros((4, 2 * DOF))
        for robot in range(block * chunk, min(count, (block + 1) * chunk)):
            for i in range(2 * DOF):
                state[i] = y[robot, i]
            for step in range(steps):
                if not _rk4(state, references[step], flags, constants[robot], torques[robot], sticking, no_bounds,
                            dt, False, rows, rhs, factor, matrix, gram, lower, vectors, scratch, stage, slopes):
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
            torque: np.ndarray, slipping: np.ndarray, bounds: np.ndarray, motion: np.ndarray, rows: np.ndarray,
            rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray,
            vectors: np.ndarray, scratch: np.ndarray) -> float:
    """One robot at y (14,): motion (3, 7) gets qdd, Q and Q_c = M qdd - Q; returns the residual |A qdd - b|.

    ``reference`` (10,): the reference at this instant; ``flags``, ``count``: ``module_flags``; ``constants``:
    the robot's row of ``robot_constants``; ``torque``: (tau_L, tau_R); ``slipping``, ``bounds``: ``_problem``'s;
    the rest: the caller's workspace.
    """
    acceleration, force = motion[0], motion[1]
    _acceleration(y[:DOF], y[DOF:], reference, flags, constants, torque, slipping, bounds, rows, rhs, factor, matrix,
                  gram, lower, vectors, scratch, acceleration)
    for i in range(DOF):
        force[i] = vectors[0, i]  # Q: _acceleration leaves it in vectors row 0
    return _motion_of(y, constants, motion, rows, rhs, count)


def _motion_of(y: np.ndarray, constants: np.ndarray, motion: np.ndarray, rows: np.ndarray, rhs: np.ndarray,
               count: int) -> float:
    """Q_c = M qdd - Q into motion[2] from motion's qdd and Q at y; returns the residual |A qdd - b| of the rows."""
    acceleration, force = motion[0], motion[1]
    mass, yaw_inertia, spin_inertia, sx, sy = constants[0], constants[1], constants[2], constants[3], constants[4]
    cos_t, sin_t = math.cos(y[2]), math.sin(y[2])
    ux, uy = -cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx  # M's coupling entries (Robot.offset_moment_arm)
    constraint = motion[2]
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
    sticking, no_bounds = np.zeros(3, dtype=np.bool_), np.zeros(5)
    for k in range(motions.shape[0]):
        residuals[k] = _motion(states[k], references[k, 0], flags, count, constants, torque, sticking, no_bounds,
                               motions[k], rows, rhs, factor, matrix, gram, lower, vectors, scratch)
        if k == steps:
            return k
        for i in range(DOF):
            slopes[0, DOF + i] = motions[k, 0, i]
        if not _rk4(states[k], references[k], flags, constants, torque, sticking, no_bounds, dt, True, rows, rhs,
                    factor, matrix, gram, lower, vectors, scratch, states[k + 1], slopes):
            return k
    return steps


_cholesky = _compile(_cholesky, inline="always")
_substitute = _compile(_substitute, inline="always")
_solve_factored = _compile(_solve_factored)
_solve_positive = _compile(_solve_positive)
_rank_revealing = _compile(_rank_revealing)
_minimum_norm = _compile(_minimum_norm, inline="always")
_solve = _compile(_solve, inline="always")
_scratch = _compile(_scratch)
_problem = _compile(_problem, inline="always")
_acceleration = _compile(_acceleration, inline="always")
_accelerations = _compile(_accelerations)
_minimum_norms = _compile(_minimum_norms)
_rk4 = _compile(_rk4, inline="always")
_steps = _compile(_steps, parallel=True)
_workspace = _compile(_workspace, inline="always")
_motion_of = _compile(_motion_of, inline="always")
_motion = _compile(_motion, inline="always")
robot_run = _compile(robot_run)


def constrained_accelerations(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``batch_constrained_acceleration`` compiled robot by robot, for the robots' own factors W (N, 7, 7)."""
    out = np.empty(force.shape)
    _accelerations(np.ascontiguousarray(factor), np.ascontiguousarray(force), np.ascontiguousarray(rows),
                   np.ascontiguousarray(rhs), out)
    return out


def minimum_norm_solutions(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``minimum_norm_least_squares`` compiled robot by robot, for B (N, k, 7)."""
    out = np.empty((matrix.shape[0], DOF))
    _minimum_norms(np.ascontiguousarray(matrix), np.ascontiguousarray(rhs), out)
    return out


def robot_constants(robots: RobotBatch, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """(N, 24) per robot, in ``_acceleration``'s order, from a ``RobotBatch`` and the Baumgarte gains."""
    return np.ascontiguousarray(np.column_stack((
        robots.total_mass, robots.yaw_inertia, robots.spin_inertia, robots.first_moment, robots.gravity,
        robots.weight, robots.wheel_radius, robots.resistance_gain, robots.velocity_epsilon2, alpha, beta,
        robots.lateral_offsets, robots.perpendicular_offsets.reshape(len(alpha), 8))))


def module_flags(active: Sequence[str]) -> tuple[np.ndarray, int]:
    """The kernel's flags (in MODULE_ORDER) of the modules named ``active``, and their row count."""
    flags = np.array([name in active for name in MODULE_ORDER], dtype=np.bool_)
    return flags, sum(rows for name, rows in zip(MODULE_ORDER, MODULE_ROWS) if name in active)


def advance(y: np.ndarray, steps: int, dt: float, references: np.ndarray, active: tuple[str, ...],
            constants: np.ndarray, torques: np.ndarray, chunk: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """y after ``steps`` steps (a new array), and (N,) the step each robot diverged at (-1: none)."""
    flags, _ = module_flags(active)
    advanced = np.array(y, dtype=float, order='C')
    diverged = np.full(len(y), -1, dtype=np.int64)
    _steps(advanced, steps, dt, references, flags, constants, np.ascontiguousarray(torques), chunk, diverged)
    return advanced, diverged
