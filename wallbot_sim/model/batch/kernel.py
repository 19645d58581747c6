"""The batch compiled with numba: the RK4 steps robot by robot, ideal contact fused, coulomb contact settled.

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
what the fused step does not cover: the outputs step hooks see with ideal contact.

``batch_contact_settle`` and ``batch_contact_step`` are a batch's coulomb boundary and step, robot by
robot over the cores with the coulomb functions (below).

``robot_run`` takes one robot's RK4 steps a chunk at a time, with the motion (qdd, Q, Q_c, residual) at
each state, for ``Simulation(..., engine='numba')`` (``wallbot_sim.model.compiled``): the same
derivative and RK4 step as the batch's fused loop.

The coulomb functions (``_settle`` and what it calls) are the batch's contact model, per channel: the
motion under the slipping set with the loads the kinetic friction holds (their fixed point solved at
once while they move), slipping channels that stop sticking again when the solve with their rows
restored keeps them within the limit (their slip projected away), sticking channels over the limit
slipping, then the RK4 step with the slipping rows' kinetic friction in its stages (``_problem``). They
know the kernel's modules: the non-lateral row is the lateral channel's, the nonslip rows of wheels 1-2
and 3-4 the left and right traction's. They agree with the batch's NumPy engine within round-off
(``test/test_batch_contact.py``). They live in this file because numba's cache of a function is
invalidated by changes to its own file only, and they call this file's functions.

numba is optional: ``available()`` says whether it imported.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.solver import RANK_CUTOFF, WELL_CONDITIONED
from wallbot_sim.model.robot import DOF, Robot
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
    elif np.all(np.isfinite(matrix[:size, :size])):
        vector[:size] = np.linalg.solve(matrix[:size, :size], vector[:size].copy())
    else:  # from a state gone non-finite: so is the result (the caller stops there), not numba's LinAlgError
        vector[:size] = np.nan


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
    _transposed_factor_times(factor, force, scaled)
    if count > 0:
        misfit = vectors[2]
        _scaled_rows(rows, factor, count, matrix)
        _misfits(matrix, rhs, scaled, count, misfit)
        _minimum_norm(matrix, misfit, count, gram, lower, vectors, scratch, vectors[4])
        for i in range(DOF):
            scaled[i] += vectors[4, i]
    _factor_times(factor, scaled, out)


def _transposed_factor_times(factor: np.ndarray, vector: np.ndarray, out: np.ndarray) -> None:
    """out = W^T vector, W lower triangular with its off-diagonal entries in the 3 x 3 chassis block."""
    for i in range(3):
        value = 0.0
        for k in range(i, 3):
            value += factor[k, i] * vector[k]
        out[i] = value
    for i in range(3, DOF):
        out[i] = factor[i, i] * vector[i]


def _factor_times(factor: np.ndarray, vector: np.ndarray, out: np.ndarray) -> None:
    """out = W vector (W as ``_transposed_factor_times``)."""
    for i in range(3):
        value = 0.0
        for k in range(i + 1):
            value += factor[i, k] * vector[k]
        out[i] = value
    for i in range(3, DOF):
        out[i] = factor[i, i] * vector[i]


def _scaled_rows(rows: np.ndarray, factor: np.ndarray, count: int, matrix: np.ndarray) -> None:
    """B = A W into matrix's first ``count`` rows."""
    for r in range(count):
        for j in range(3):
            value = 0.0
            for k in range(j, 3):
                value += rows[r, k] * factor[k, j]
            matrix[r, j] = value
        for j in range(3, DOF):
            matrix[r, j] = rows[r, j] * factor[j, j]


def _misfits(matrix: np.ndarray, rhs: np.ndarray, scaled: np.ndarray, count: int, misfit: np.ndarray) -> None:
    """misfit = b - B s over the first ``count`` rows."""
    for r in range(count):
        value = rhs[r]
        for j in range(DOF):
            value -= matrix[r, j] * scaled[j]
        misfit[r] = value


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



def tracking_force(y: np.ndarray, point: np.ndarray, flags: np.ndarray, constants: np.ndarray, distance: float,
                   out: np.ndarray) -> None:
    """Q_c (7,) into ``out``: the inverse dynamics of one unpowered robot at y (14,) under the modules of
    ``flags`` and the look-ahead point task (``LookAheadPointTask.rows``) stacked after them.

    ``point`` (3, 2): the point's reference position, velocity and acceleration; ``distance``: L.
    """
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    motion = np.zeros((3, DOF))
    no_torque, sticking, no_bounds = np.zeros(2), np.zeros(3, dtype=np.bool_), np.zeros(5)
    q, qd = y[:DOF], y[DOF:]
    count = _problem(q, qd, np.zeros(REFERENCE_FIELDS), flags, constants, no_torque, sticking, no_bounds, rows, rhs,
                     factor, vectors[0])
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
    _motion_of(y, constants, motion, rows, rhs, count)
    for i in range(DOF):
        out[i] = motion[2, i]

# --- coulomb contact: the stick/slip of one robot at each step boundary (docs/model.md 11.3) -------------

ADHESION, STATIC, KINETIC, STICK, HEIGHT, HALF_BASE, HALF_TRACK = range(7)
"""``contact_constants``' fields; then the wheels' x_i (7-10) and y_i (11-14)."""
LOAD_TOLERANCE = 1e-9
"""Relative difference below which held loads are the loads they produce (``contact._LOAD_TOLERANCE``)."""
SOLUTION_ROWS = 7
"""A boundary's solution (7, 7): qdd, Q (with Q_f), Q_c, Q_f, then [N_1..N_4, use_L, use_R, use_lat],
[F_L, F_R, F_lat, held N_1..N_4], [residual, singular]."""
LOADS_ROW, DRIVE_ROW, STATUS_ROW = 4, 5, 6
WORK_ROWS = 21
CONSISTENT = 1e-9
"""Relative misfit below which a dropped row agrees with the kept ones (``_responses``)."""


def contact_constants(robot: Robot) -> np.ndarray:
    """(15,) in the fields' order: F_ad, mu_s, mu_k, v_st, h, a, b, x_1..x_4, y_1..y_4."""
    params = robot.params
    return np.array([robot.adsorption.applied_force, params.wall_friction, params.kinetic_friction,
                     params.stick_velocity, params.com_height, params.half_wheelbase, params.half_track,
                     *robot.wheel_offsets[:, 0], *robot.wheel_offsets[:, 1]], dtype=float)


def _normal_loads(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, constants: np.ndarray, contact: np.ndarray,
                  out: np.ndarray) -> None:
    """N_1..N_4 at (q, qd, qdd) (``normal_loads``)."""
    mass, sx, sy, gravity = constants[0], constants[3], constants[4], constants[5]
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    thd, thdd = qd[2], qdd[2]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    inertial_x = mass * qdd[0] - thdd * rsy - thd * thd * rsx
    inertial_y = mass * qdd[1] + thdd * rsx - thd * thd * rsy
    fx, fy = -inertial_x, -mass * gravity - inertial_y
    body_x, body_y = cos_t * fx + sin_t * fy, -sin_t * fx + cos_t * fy
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    along, across = 0.25 * h * body_x / (a * a), 0.25 * h * body_y / (b * b)
    for wheel in range(4):
        out[wheel] = 0.25 * contact[ADHESION] + along * contact[7 + wheel] + across * contact[11 + wheel]


def _ratio(force: float, limit: float) -> float:
    if limit > 0.0:
        return force / limit
    return 0.0 if force == 0.0 else math.inf


def _measure(q: np.ndarray, qd: np.ndarray, constants: np.ndarray, contact: np.ndarray,
             solution: np.ndarray) -> None:
    """The loads, friction use and drive forces of the solution's motion (``Simulation._measure``)."""
    loads = solution[LOADS_ROW]
    _normal_loads(q, qd, solution[0], constants, contact, loads)
    fx = solution[2, 0] + solution[3, 0]
    fy = solution[2, 1] + solution[3, 1]
    mz = solution[2, 2] + solution[3, 2]
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    longitudinal, differential = cos_t * fx + sin_t * fy, mz / contact[HALF_TRACK]
    drive = solution[DRIVE_ROW]
    drive[0], drive[1] = 0.5 * (longitudinal - differential), 0.5 * (longitudinal + differential)
    drive[2] = -sin_t * fx + cos_t * fy
    static = contact[STATIC]
    loads[4] = _ratio(abs(drive[0]), static * (loads[0] + loads[1]))
    loads[5] = _ratio(abs(drive[1]), static * (loads[2] + loads[3]))
    loads[6] = _ratio(abs(drive[2]), static * contact[ADHESION])


def _contact_rows(theta: float, constants: np.ndarray, rows: np.ndarray) -> None:
    """The velocity rows (5, 7) of the contact channels at heading theta: 0 the non-lateral row (lateral),
    1 + i wheel i's nonslip row (left traction for wheels 1-2, right for 3-4)."""
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    for k in range(5):
        for j in range(DOF):
            rows[k, j] = 0.0
    rows[0, 0], rows[0, 1] = -sin_t, cos_t
    for wheel in range(4):
        row = rows[1 + wheel]
        row[0], row[1], row[2], row[3 + wheel] = -cos_t, -sin_t, constants[12 + wheel], constants[7]


def _slip_rows(q: np.ndarray, qd: np.ndarray, flags: np.ndarray, constants: np.ndarray, slipping: np.ndarray,
               rows: np.ndarray, slip: np.ndarray, present: np.ndarray) -> bool:
    """Which contact rows (``_contact_rows``' order) are present and slipping; where any is, their velocity
    rows a_k and slip velocities a_k qd too. Returns whether any is."""
    any_present = False
    for k in range(5):
        present[k] = flags[3] and slipping[2] if k == 0 else flags[4] and slipping[(k - 1) // 2]
        any_present = any_present or present[k]
    if not any_present:
        return False
    _contact_rows(q[2], constants, rows)
    for k in range(5):
        value = 0.0
        for j in range(DOF):
            value += rows[k, j] * qd[j]
        slip[k] = value
    return True


def _bounds(held: np.ndarray, kinetic: float, bounds: np.ndarray) -> None:
    """-mu_k times each row's bounding load: F_ad = sum N_i for the lateral row, N_i for wheel i's."""
    bounds[0] = -kinetic * (held[0] + held[1] + held[2] + held[3])
    for wheel in range(4):
        bounds[1 + wheel] = -kinetic * held[wheel]


def _converged(loads: np.ndarray, held: np.ndarray) -> bool:
    largest, total = 0.0, 0.0
    for wheel in range(4):
        largest = max(largest, abs(loads[wheel] - held[wheel]))
        total += abs(loads[wheel])
    return largest <= LOAD_TOLERANCE * total


def _contact_solve(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                   contact: np.ndarray, torque: np.ndarray, slipping: np.ndarray, held: np.ndarray, moving: bool,
                   rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
                   lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, work: np.ndarray,
                   zero_rhs: np.ndarray, bounds: np.ndarray, present: np.ndarray, solution: np.ndarray) -> None:
    """The motion at y with ``slipping`` channels slipping, and the loads their friction holds
    (``CoulombContact._solve``), into ``solution``.

    ``work`` (WORK_ROWS, 7): scratch for the slipping rows, their per-load friction, the responses and the
    free motion; ``zero_rhs`` (MAX_ROWS,) zeros.
    """
    q, qd = y[:DOF], y[DOF:]
    eps2 = constants[9]
    force, friction, acceleration = solution[1], solution[3], solution[0]
    for k in range(5):
        bounds[k] = 0.0
    count = _problem(q, qd, reference, flags, constants, torque, slipping, bounds, rows, rhs, factor, force)
    held_out = solution[DRIVE_ROW, 3:]
    for wheel in range(4):
        held_out[wheel] = held[wheel]
    for j in range(DOF):
        friction[j] = 0.0
    solution[STATUS_ROW, 1] = 0.0
    slip_rows, slip, direction, total = work[0:5], work[5], work[6], work[7]
    slipping_rows = _slip_rows(q, qd, flags, constants, slipping, slip_rows, slip, present)
    dependent = False
    for k in range(5):
        if present[k]:
            dependent = dependent or k > 0
            direction[k] = slip[k] / math.sqrt(slip[k] * slip[k] + eps2)
    solved = False
    if not slipping_rows:
        _solve(factor, force, rows, rhs, count, matrix, gram, lower, vectors, scratch, acceleration)
        solved = True
    elif not (dependent and moving):
        _bounds(held, contact[KINETIC], bounds)
        for k in range(5):
            if present[k]:
                for j in range(DOF):
                    friction[j] += bounds[k] * direction[k] * slip_rows[k, j]
        for j in range(DOF):
            total[j] = force[j] + friction[j]
        _solve(factor, total, rows, rhs, count, matrix, gram, lower, vectors, scratch, acceleration)
        loads = solution[LOADS_ROW]
        _normal_loads(q, qd, acceleration, constants, contact, loads)
        if not dependent or _converged(loads, held):
            for j in range(DOF):
                force[j] = total[j]
            solved = True
    if not solved:
        _consistent_loads(q, qd, constants, contact, rows, rhs, count, factor, matrix, gram, lower, vectors, scratch,
                          work, zero_rhs, present, direction, solution)
    residual = _motion_of(y, constants, solution[:3], rows, rhs, count)
    _measure(q, qd, constants, contact, solution)
    solution[STATUS_ROW, 0] = residual


def _consistent_loads(q: np.ndarray, qd: np.ndarray, constants: np.ndarray, contact: np.ndarray, rows: np.ndarray,
                      rhs: np.ndarray, count: int, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
                      lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, work: np.ndarray,
                      zero_rhs: np.ndarray, present: np.ndarray, direction: np.ndarray, solution: np.ndarray) -> None:
    """The held loads h that are the loads the friction F h produces, and the motion (``contact._consistent_loads``).

    qdd = qdd_0 + D h (D: the response to each wheel's per-load friction, rhs 0), N = N(qdd_0) + U B D[:3] h,
    so h = N(qdd_0) + U (I_2 - C U)^-1 C N(qdd_0) with C = B D[:3]. Sets solution row 6's singular flag
    when I_2 - C U is singular.
    """
    slip_rows, free, per_load, responses = work[0:5], work[8], work[9:13], work[13:17]
    force, friction, acceleration = solution[1], solution[3], solution[0]
    kinetic = contact[KINETIC]
    for wheel in range(4):
        column = per_load[wheel]
        for j in range(DOF):
            column[j] = 0.0
        for k in range(5):
            if present[k] and (k == 0 or k == 1 + wheel):  # the lateral row is bounded by every wheel's load
                for j in range(DOF):
                    column[j] -= kinetic * direction[k] * slip_rows[k, j]
    if not _responses(factor, force, rhs, zero_rhs, per_load, rows, count, matrix, gram, lower, vectors[2], work,
                      free, responses):
        _solve(factor, force, rows, rhs, count, matrix, gram, lower, vectors, scratch, free)
        for wheel in range(4):
            _solve(factor, per_load[wheel], rows, zero_rhs, count, matrix, gram, lower, vectors, scratch,
                   responses[wheel])
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    mass, sx, sy = constants[0], constants[3], constants[4]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    body = ((-cos_t * mass, -sin_t * mass, cos_t * rsy - sin_t * rsx),
            (sin_t * mass, -cos_t * mass, -sin_t * rsy - cos_t * rsx))
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    along, across = 0.25 * h / (a * a), 0.25 * h / (b * b)
    coupling, unheld = work[17:19], work[20]
    for i in range(2):
        for wheel in range(4):
            coupling[i, wheel] = (body[i][0] * responses[wheel, 0] + body[i][1] * responses[wheel, 1]
                                  + body[i][2] * responses[wheel, 2])
    _normal_loads(q, qd, free, constants, contact, unheld)
    # (I_2 - C U) z = C N(qdd_0), U's columns the arms along x_i and across y_i
    m00, m01, m10, m11 = 1.0, 0.0, 0.0, 1.0
    v0, v1 = 0.0, 0.0
    for wheel in range(4):
        arm_x, arm_y = along * contact[7 + wheel], across * contact[11 + wheel]
        m00 -= coupling[0, wheel] * arm_x
        m01 -= coupling[0, wheel] * arm_y
        m10 -= coupling[1, wheel] * arm_x
        m11 -= coupling[1, wheel] * arm_y
        v0 += coupling[0, wheel] * unheld[wheel]
        v1 += coupling[1, wheel] * unheld[wheel]
    determinant = m00 * m11 - m01 * m10
    if determinant == 0.0:
        solution[STATUS_ROW, 1] = 1.0
        determinant = math.nan
    z0, z1 = (m11 * v0 - m01 * v1) / determinant, (m00 * v1 - m10 * v0) / determinant
    held = solution[DRIVE_ROW, 3:]
    for wheel in range(4):
        held[wheel] = unheld[wheel] + along * contact[7 + wheel] * z0 + across * contact[11 + wheel] * z1
    for j in range(DOF):
        value, push = free[j], 0.0
        for wheel in range(4):
            value += responses[wheel, j] * held[wheel]
            push += per_load[wheel, j] * held[wheel]
        acceleration[j] = value
        friction[j] = push
        force[j] += push


def _responses(factor: np.ndarray, force: np.ndarray, rhs: np.ndarray, zero_rhs: np.ndarray, per_load: np.ndarray,
               rows: np.ndarray, count: int, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray,
               misfit: np.ndarray, work: np.ndarray, free: np.ndarray, responses: np.ndarray) -> bool:
    """qdd under Q and b (``free``), and the response to each wheel's per-load friction with b = 0
    (``responses``), from one factorization: qdd = W (s + B_K^T (B_K B_K^T)^-1 (b - B s)_K), s = W^T Q,
    B = A W, K the independent rows a pivoted Cholesky of B B^T keeps (the nonslip rows of a side imply
    its belt row).

    That is the minimum-norm solution wherever the dropped rows agree with the kept ones, which the
    responses (b = 0) always do. Returns False, leaving the work to ``_solve``'s least squares, where the
    free motion's dropped rows disagree (an inconsistent set).
    """
    _scaled_rows(rows, factor, count, matrix)
    if count > DOF:
        return False
    largest = 0.0
    for i in range(count):
        for j in range(i + 1):
            entry = 0.0
            for k in range(DOF):
                entry += matrix[i, k] * matrix[j, k]
            gram[i, j] = gram[j, i] = entry
        largest = max(largest, gram[i, i])
    # pivoted Cholesky of B B^T in place: gram becomes the Schur complement, lower[r, i] column r of L
    # at row i, order[r] the row of pivot r
    order = np.empty(DOF, dtype=np.int64)
    kept = np.zeros(DOF, dtype=np.bool_)
    rank = 0
    cut = RANK_CUTOFF * largest
    for rank_now in range(count):
        best, pivot = -1, cut
        for i in range(count):
            if not kept[i] and gram[i, i] > pivot:
                best, pivot = i, gram[i, i]
        if best < 0:
            break
        kept[best] = True
        order[rank_now] = best
        rank = rank_now + 1
        scale = 1.0 / math.sqrt(pivot)
        for i in range(count):
            lower[rank_now, i] = gram[i, best] * scale
        for i in range(count):
            for j in range(count):
                gram[i, j] -= lower[rank_now, i] * lower[rank_now, j]
    scaled, solution = work[19], work[7]
    for column in range(5):
        _transposed_factor_times(factor, force if column == 0 else per_load[column - 1], scaled)
        _misfits(matrix, rhs if column == 0 else zero_rhs, scaled, count, misfit)
        for a in range(rank):  # L z = misfit_K, then L^T y = z, in pivot order
            value = misfit[order[a]]
            for r in range(a):
                value -= lower[r, order[a]] * solution[r]
            solution[a] = value / lower[a, order[a]]
        for a in range(rank - 1, -1, -1):
            value = solution[a]
            for r in range(a + 1, rank):
                value -= lower[a, order[r]] * solution[r]
            solution[a] = value / lower[a, order[a]]
        if column == 0:
            for d in range(count):
                if not kept[d]:
                    reached, size = 0.0, abs(misfit[d])
                    for a in range(rank):
                        along = 0.0
                        for k in range(DOF):
                            along += matrix[d, k] * matrix[order[a], k]
                        reached += along * solution[a]
                        size += abs(along * solution[a])
                    if abs(misfit[d] - reached) > CONSISTENT * (1.0 + size):
                        return False
        for k in range(DOF):
            value = scaled[k]
            for a in range(rank):
                value += matrix[order[a], k] * solution[a]
            scaled[k] = value
        _factor_times(factor, scaled, free if column == 0 else responses[column - 1])
    return True


def _project(y: np.ndarray, flags: np.ndarray, constants: np.ndarray, slipping: np.ndarray,
             factor: np.ndarray) -> None:
    """qd <- qd - M^-1 A^T (A M^-1 A^T)+ A qd over the velocity rows of the sticking modules (in place on y).

    ``factor``: W at y's q (W W^T = M^-1), as ``_problem`` left it.
    """
    rows, contact_rows = np.zeros((7, DOF)), np.empty((5, DOF))
    _contact_rows(y[2], constants, contact_rows)
    count = 0
    if flags[2]:
        rows[0, 3], rows[0, 4], rows[1, 5], rows[1, 6] = 1.0, -1.0, 1.0, -1.0
        count = 2
    for k in range(5):
        if flags[3] and not slipping[2] if k == 0 else flags[4] and not slipping[(k - 1) // 2]:
            rows[count] = contact_rows[k]
            count += 1
    if count == 0:
        return
    active = rows[:count]
    inverse = factor @ factor.T
    weighted = inverse @ active.T
    velocities = y[DOF:].copy()
    correction = weighted @ (np.linalg.pinv(active @ weighted) @ (active @ velocities))
    for j in range(DOF):
        y[DOF + j] = velocities[j] - correction[j]


def _stopping(y: np.ndarray, flags: np.ndarray, constants: np.ndarray, slipping: np.ndarray,
              solution: np.ndarray, dt: float, stick_velocity: float, work: np.ndarray, present: np.ndarray,
              candidates: np.ndarray) -> bool:
    """The slipping channels whose every row's slip is below v_st or changes sign by qd + dt qdd
    (``KineticFriction.stopping``); whether there is one."""
    predicted = work[7]
    for j in range(DOF):
        predicted[j] = y[DOF + j] + dt * solution[0, j]
    slip_rows, slip = work[0:5], work[5]
    _slip_rows(y[:DOF], y[DOF:], flags, constants, slipping, slip_rows, slip, present)
    for channel in range(3):
        candidates[channel] = False
    seen = np.zeros(3, dtype=np.bool_)
    for k in range(5):
        if present[k]:
            channel = 2 if k == 0 else (k - 1) // 2
            then = 0.0
            for j in range(DOF):
                then += slip_rows[k, j] * predicted[j]
            stops = abs(slip[k]) < stick_velocity or slip[k] * then < 0.0
            candidates[channel] = stops if not seen[channel] else candidates[channel] and stops
            seen[channel] = True
    return candidates[0] or candidates[1] or candidates[2]


def _settle(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
            torque: np.ndarray, dt: float, slipping: np.ndarray, held: np.ndarray, moving: np.ndarray,
            rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
            lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, work: np.ndarray, zero_rhs: np.ndarray,
            bounds: np.ndarray, present: np.ndarray, solution: np.ndarray, trial_solution: np.ndarray) -> None:
    """The stick/slip transitions at y's boundary, then the solution of the step (``CoulombContact.settle``).

    ``slipping`` (3,), ``held`` (4,) and ``moving`` (1,) are the contact state before, updated in place; y's
    velocities are projected in place where a channel sticks again.
    """
    channels = (flags[4], flags[4], flags[3])  # left, right, lateral: which channels have rows
    for channel in range(3):
        slipping[channel] = slipping[channel] and channels[channel]
    _contact_solve(y, reference, flags, constants, contact, torque, slipping, held, moving[0], rows, rhs, factor,
                   matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds, present, solution)
    candidates, trial, holding = np.zeros(3, dtype=np.bool_), np.zeros(3, dtype=np.bool_), np.zeros(3, dtype=np.bool_)
    trial_y = np.empty(2 * DOF)
    searching = (slipping[0] or slipping[1] or slipping[2]) and _stopping(
        y, flags, constants, slipping, solution, dt, contact[STICK], work, present, candidates)
    while searching:
        for channel in range(3):
            trial[channel] = slipping[channel] and not candidates[channel]
        for i in range(2 * DOF):
            trial_y[i] = y[i]
        _project(trial_y, flags, constants, trial, factor)
        _contact_solve(trial_y, reference, flags, constants, contact, torque, trial, held, moving[0], rows, rhs,
                       factor, matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds, present, trial_solution)
        same, searching = True, False
        for channel in range(3):
            holding[channel] = candidates[channel] and not trial_solution[LOADS_ROW, 4 + channel] > 1.0
            same = same and holding[channel] == candidates[channel]
            searching = searching or holding[channel]
        if same:
            for channel in range(3):
                slipping[channel] = trial[channel]
            for i in range(2 * DOF):
                y[i] = trial_y[i]
            solution[:, :] = trial_solution
            break
        for channel in range(3):
            candidates[channel] = holding[channel]
    while True:
        exceeded = False
        for channel in range(3):
            if channels[channel] and not slipping[channel] and solution[LOADS_ROW, 4 + channel] > 1.0:
                slipping[channel] = exceeded = True
        if not exceeded:
            break
        _contact_solve(y, reference, flags, constants, contact, torque, slipping, held, moving[0], rows, rhs, factor,
                       matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds, present, solution)
    new_held = solution[DRIVE_ROW, 3:]
    moving[0] = (slipping[0] or slipping[1] or slipping[2]) and not _converged(new_held, held)
    for wheel in range(4):
        held[wheel] = new_held[wheel]


def _contact_workspace() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``_settle``'s scratch beside ``_workspace``'s: work, zero_rhs, bounds, present and a trial solution."""
    return (np.zeros((WORK_ROWS, DOF)), np.zeros(MAX_ROWS), np.zeros(5), np.zeros(5, dtype=np.bool_),
            np.zeros((SOLUTION_ROWS, DOF)))


def _batch_settle(states: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                  contact: np.ndarray, torques: np.ndarray, dt: float, slipping: np.ndarray, held: np.ndarray,
                  moving: np.ndarray, live: np.ndarray, solutions: np.ndarray, chunk: int) -> None:
    """Every robot's boundary (N robots: ``states`` (N, 14), ``constants`` (N, 24), ``contact`` (N, 15), ...):
    the live ones settled (``_settle``), the others' motion under their slipping set, their state kept.
    ``slipping`` (N, 3), ``held`` (N, 4), ``moving`` (N,) are updated in place, ``solutions`` (N, 7, 7) filled."""
    count = states.shape[0]
    for block in prange((count + chunk - 1) // chunk):
        rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
        factor, matrix, gram, lower, vectors, scratch = _workspace()
        work, zero_rhs, bounds, present, trial_solution = _contact_workspace()
        for robot in range(block * chunk, min(count, (block + 1) * chunk)):
            if live[robot]:
                _settle(states[robot], reference, flags, constants[robot], contact[robot], torques[robot], dt,
                        slipping[robot], held[robot], moving[robot:robot + 1], rows, rhs, factor, matrix, gram, lower,
                        vectors, scratch, work, zero_rhs, bounds, present, solutions[robot], trial_solution)
            else:
                _contact_solve(states[robot], reference, flags, constants[robot], contact[robot], torques[robot],
                               slipping[robot], held[robot], moving[robot], rows, rhs, factor, matrix, gram, lower,
                               vectors, scratch, work, zero_rhs, bounds, present, solutions[robot])


def _batch_step(states: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                contact: np.ndarray, torques: np.ndarray, dt: float, slipping: np.ndarray, held: np.ndarray,
                live: np.ndarray, solutions: np.ndarray, out: np.ndarray, finite: np.ndarray, chunk: int) -> None:
    """The RK4 step of every live robot from its settled boundary (``solutions``' qdd its first stage, the
    kinetic friction of its slipping rows with ``held`` loads in every stage) into ``out``; the others keep
    their state. ``finite`` (N,) says whether each new state is finite."""
    count = states.shape[0]
    for block in prange((count + chunk - 1) // chunk):
        rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
        factor, matrix, gram, lower, vectors, scratch = _workspace()
        slopes, step_bounds = np.zeros((4, 2 * DOF)), np.zeros(5)
        for robot in range(block * chunk, min(count, (block + 1) * chunk)):
            if not live[robot]:
                for i in range(2 * DOF):
                    out[robot, i] = states[robot, i]
                finite[robot] = True
                continue
            for i in range(DOF):
                slopes[0, DOF + i] = solutions[robot, 0, i]
            _bounds(held[robot], contact[robot, KINETIC], step_bounds)
            finite[robot] = _rk4(states[robot], references, flags, constants[robot], torques[robot], slipping[robot],
                                 step_bounds, dt, True, rows, rhs, factor, matrix, gram, lower, vectors, scratch,
                                 out[robot], slopes)


_cholesky = _compile(_cholesky, inline="always")
_substitute = _compile(_substitute, inline="always")
_solve_factored = _compile(_solve_factored)
_solve_positive = _compile(_solve_positive)
_rank_revealing = _compile(_rank_revealing)
_minimum_norm = _compile(_minimum_norm, inline="always")
_transposed_factor_times = _compile(_transposed_factor_times, inline="always")
_factor_times = _compile(_factor_times, inline="always")
_scaled_rows = _compile(_scaled_rows, inline="always")
_misfits = _compile(_misfits, inline="always")
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
tracking_force = _compile(tracking_force)
_normal_loads = _compile(_normal_loads, inline="always")
_ratio = _compile(_ratio, inline="always")
_measure = _compile(_measure, inline="always")
_contact_rows = _compile(_contact_rows, inline="always")
_slip_rows = _compile(_slip_rows, inline="always")
_bounds = _compile(_bounds, inline="always")
_converged = _compile(_converged, inline="always")
_responses = _compile(_responses)
_consistent_loads = _compile(_consistent_loads)
_contact_solve = _compile(_contact_solve)
_project = _compile(_project)
_stopping = _compile(_stopping)
_settle = _compile(_settle)
_contact_workspace = _compile(_contact_workspace, inline="always")
_batch_settle = _compile(_batch_settle, parallel=True)
_batch_step = _compile(_batch_step, parallel=True)


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


def batch_contact_settle(states: np.ndarray, reference: np.ndarray, active: tuple[str, ...], constants: np.ndarray,
                         contact: np.ndarray, torques: np.ndarray, dt: float, slipping: np.ndarray, held: np.ndarray,
                         moving: np.ndarray, live: np.ndarray, chunk: int = 64) -> np.ndarray:
    """Every robot's coulomb boundary, robot by robot over the cores: ``_batch_settle``; returns the solutions
    (N, 7, 7). ``states`` (velocities projected), ``slipping``, ``held`` and ``moving`` change in place."""
    flags, _ = module_flags(active)
    solutions = np.empty((states.shape[0], SOLUTION_ROWS, DOF))
    _batch_settle(states, reference, flags, constants, contact, torques, dt, slipping, held, moving, live, solutions,
                  chunk)
    return solutions


def batch_contact_step(states: np.ndarray, references: np.ndarray, active: tuple[str, ...], constants: np.ndarray,
                       contact: np.ndarray, torques: np.ndarray, dt: float, slipping: np.ndarray, held: np.ndarray,
                       live: np.ndarray, solutions: np.ndarray, chunk: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Every live robot's RK4 step from its settled boundary (``_batch_step``): the new states and which are finite."""
    flags, _ = module_flags(active)
    out, finite = np.empty_like(states), np.ones(states.shape[0], dtype=np.bool_)
    _batch_step(states, references, flags, constants, contact, torques, dt, slipping, held, live, solutions, out,
                finite, chunk)
    return out, finite
