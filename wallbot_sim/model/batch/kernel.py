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

``constrained_accelerations`` is the solve alone (the NumPy engine's ``batch_constrained_acceleration``
robot by robot), for what the fused step does not cover: the outputs step hooks see with ideal contact.

``robot_run`` takes one robot's RK4 steps a chunk at a time, with the motion (qdd, Q, Q_c, residual) at
each state, for ``Simulation(..., engine='numba')`` (``wallbot_sim.model.compiled``): the same
derivative and RK4 step as the batch's fused loop.

Coulomb contact per wheel (docs/model.md 11.3): ``_settle`` is one robot's step boundary, ``CoulombContact.settle``
of the Python model (its transitions, the solve of each stick/slip set with the friction and loads found by
Newton's method, the split of the sticking wheels' force), and ``_held_step`` the RK4 step from it.
``robot_contact_run`` takes one robot's boundaries and steps a chunk at a time (``Simulation(..., engine='numba',
contact='coulomb')``), ``batch_contact_settle`` and ``batch_contact_step`` a batch's, robot by robot over the
cores. They agree with the Python model to 1e-9 (``test/test_compiled_contact.py``, ``test/test_batch_contact.py``).

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
MAX_ROWS = sum(MODULE_ROWS[:3]) + 8
"""The rows of the tasks and the belt with every wheel's two contact rows (more than every module's at once)."""
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
                  torque: np.ndarray, gains: np.ndarray, contact: bool, sticking: np.ndarray, held: np.ndarray,
                  rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
                  lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, ints: np.ndarray,
                  out: np.ndarray) -> None:
    """qdd of one robot at (q, qd): ``BatchSimulation._derivative`` for that robot alone (``_problem``, then
    ``_solve``); Q, with the held friction of sliding wheels, is left in ``vectors`` row 0. With ``contact`` the
    solve goes through the rows' own space first (``_row_space_solve``, ``mats`` and ``ints`` its scratch)."""
    count = _problem(q, qd, reference, flags, constants, torque, gains, contact, sticking, held, rows, rhs, factor,
                     vectors[0])
    if contact:
        rank = _prepare_rows(rows, factor, count, matrix, mats[ROW_SYSTEM], mats[ROW_FACTOR], ints[ROW_ORDER],
                             ints[ROW_KEPT])
        if _row_space_solve(factor, vectors[0], rhs, True, matrix, count, rank, ints[ROW_ORDER], ints[ROW_KEPT],
                            mats[ROW_FACTOR], vectors, out):
            return
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
    sx, sy = constants[3], constants[4]
    gravity, weight, radius, eps2 = constants[5], constants[6], constants[7], constants[9]
    alpha, beta = constants[10], constants[11]
    # constants[12:16] lateral offsets s_i, [16:24] S d_i = (-s_i, a_i) pairs
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
        scale = -gains[wheel] / math.sqrt(vx * vx + vy * vy + eps2)
        force[0] += scale * vx
        force[1] += scale * vy
        force[2] += scale * (arm_x * vx + arm_y * vy)
    force[3] = force[4] = 0.5 * torque[0]
    force[5] = force[6] = 0.5 * torque[1]
    _factor_of(theta, constants, factor)
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
    if contact:
        return _wheel_rows(qd, flags, constants, sticking, held, cos_t, sin_t, v_long, v_lat, gam, count, rows, rhs,
                           force)
    if flags[3]:
        rows[count, 0], rows[count, 1] = -sin_t, cos_t
        rhs[count] = thd * v_long - gam * v_lat
        count += 1
    if flags[4]:
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
        if sticking[wheel] and flags[4]:
            rows[count, 0], rows[count, 1], rows[count, 2] = cos_t, sin_t, -offset
            for j in range(3, DOF):
                rows[count, j] = -radius if j == 3 + wheel else 0.0
            rhs[count] = -drift_x - gam * (v_long - offset * thd - radius * qd[3 + wheel])
            count += 1
        if sticking[wheel] and flags[3]:
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
                      sticking, held, rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, ints,
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
                  factor, matrix, gram, lower, vectors, scratch, no_mats, no_ints, acceleration)
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
    _motion_of(y, constants, motion, rows, rhs, count)
    for i in range(DOF):
        out[i] = motion[2, i]

# --- coulomb contact per wheel: each wheel's stick and slip at a step boundary (docs/model.md 11.3) ----------
# The functions below are ``CoulombContact`` (settle, its solve), ``consistent_friction`` and ``split_contact_force``
# of wallbot_sim.model for one robot, operation for operation where it can be, on the kernel's modules: the
# non-lateral and nonslip flags give every wheel its lateral and longitudinal contact rows, the other modules
# (the tasks, the belt) stay ideal. They live in this file because numba's cache of a function is invalidated
# by changes to its own file only, and they call this file's functions.

ADHESION, STATIC, KINETIC, STICK, HEIGHT, HALF_BASE, HALF_TRACK = range(7)
ROLLING = 15
"""``contact_constants``' fields: F_ad, mu_s, mu_k, v_st, h, a, b; then the wheels' x_i (7-10) and y_i (11-14),
then f_r."""
NEWTON_TOLERANCE = 1e-12
"""Residual, relative to F_ad, at which the friction and loads are solved (``kinetic_friction._TOLERANCE``)."""
NEWTON_ITERATIONS = 60
"""``kinetic_friction._ITERATIONS``."""
SETTLE_PASSES = 8
"""Rounds of a boundary's transitions at most (``contact._SETTLE_PASSES``)."""
AT_REST = 1e-12
"""Contact speed (m/s) up to which a wheel is at rest (``contact._AT_REST``)."""
SPLIT_CUT = 1e-12
"""Relative pivot below which the split's weighted system has no more directions (``wheel_forces._SINGULAR``)."""
SOLUTION_ROWS, SOLUTION_WIDTH = 8, 8
QDD, CONSTRAINT, FRICTION, LOADS, FORCES, PREDICTED, VELOCITY, STATUS = range(SOLUTION_ROWS)
"""A boundary's solution (8, 8), by row: qdd, Q_c = M qdd - Q, Q_f (the sliding wheels' friction), N_1..N_4,
f_i (interleaved x, y, wheel by wheel: reshaped (4, 2)), the predicted slip w_i and the contact velocities v_i
(likewise), then STATUS."""
RESIDUAL, ERROR, NEWTON_RESIDUAL = range(3)
"""The STATUS row: |A qdd - b|, an error code (``CONTACT_ERRORS``), the Newton residual it stopped at (N)."""
SOLVED, SINGULAR, UNCONVERGED = range(3)
CONTACT_ERRORS = ('', 'kinetic friction and normal loads have no consistent value (singular system)',
                  'kinetic friction and normal loads did not converge (residual {:.3g} N)')
"""What a boundary's error code means (``consistent_friction``'s ModelError messages)."""
RAN, DETACHED, DIVERGED, FAILED = range(4)
"""How a contact run ended (``robot_contact_run``'s outcome): as asked, a wheel lifted off, a state stopped being
finite, a boundary had no solution."""
COLUMNS = 1 + 8 + 4
"""A boundary's right-hand sides at most: the forces, each sliding component's unit force, each wheel's unit load."""
(JACOBIAN, TRIAL_JACOBIAN, LU, SLIP_ROWS, GAIN, SLIP_BY_FRICTION, SLIP_BY_LOAD, LOAD_BY_FRICTION, LOAD_BY_LOAD,
 BY_SLIP, STUCK_ROWS, MADE, SPLIT, SPLIT_LOWER, ROW_SYSTEM, ROW_FACTOR, PROJECTION) = range(17)
"""``_contact_workspace``'s matrices (16 x 16 each): the Newton Jacobian, its trial and LU factors; J_S, L, the
constant blocks dt J_S D, dt J_S R, -L D, L R and the Newton step's d(f mu N w / s)/dw; the sticking rows, the
split's U^T J^T, its weighted system and factor; B B^T of the rows and its pivoted factor (``_prepare_rows``); the
rows of a projection."""
(STATE, TRIAL_STATE, NEWTON_STEP, RESIDUALS, TRIAL_RESIDUALS, NEWTON_PREDICTED, TRIAL_PREDICTED, SIZES,
 DIRECTIONS, PRESSED, SQUARES, SLIP, DRIFT, ORIGIN, ACCELERATION, TOTAL, REDUCED, SPLIT_X, ROW_LOADS, KEPT, ZERO,
 NEGATIVE, TRIAL_Y) = range(23)
"""``_contact_workspace``'s vectors (16 each)."""
WHEEL_OF, DIRECTION_OF, PIVOTS, SPLIT_PIVOTS, ROW_ORDER, ROW_KEPT = range(6)
"""``_contact_workspace``'s integer rows (16 each): each sliding component's wheel and direction, LU's pivots, the
split's pivots, the rows ``_prepare_rows`` keeps (in pivot order, and 1 on each)."""
STICKING, TRIAL_SLIDING, STOPPED, REVERSING, CANDIDATES, HOLDING = range(6)
"""``_contact_workspace``'s wheel sets (4 each)."""
MATRICES, VECTORS, INTEGERS, SETS = PROJECTION + 1, TRIAL_Y + 1, ROW_KEPT + 1, HOLDING + 1
CONSISTENT = 1e-9
"""Relative misfit up to which a row ``_prepare_rows`` drops agrees with the rows it keeps."""


def contact_constants(robot: Robot) -> np.ndarray:
    """(16,) in the fields' order: F_ad, mu_s, mu_k, v_st, h, a, b, x_1..x_4, y_1..y_4, f_r."""
    params = robot.params
    return np.array([robot.adsorption.applied_force, params.wall_friction, params.kinetic_friction,
                     params.stick_velocity, params.com_height, params.half_wheelbase, params.half_track,
                     *robot.wheel_offsets[:, 0], *robot.wheel_offsets[:, 1], params.rolling_resistance], dtype=float)


def _contact_workspace() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One robot's scratch for its boundaries beside ``_workspace``'s: matrices, vectors, integers, wheel sets, and
    the columns and responses of a boundary's solve (COLUMNS x 7 each)."""
    return (np.zeros((MATRICES, 16, 16)), np.zeros((VECTORS, 16)), np.zeros((INTEGERS, 16), dtype=np.int64),
            np.zeros((SETS, 4), dtype=np.bool_), np.zeros((COLUMNS, DOF)), np.zeros((COLUMNS, DOF)))


def _contact_row(cos_t: float, sin_t: float, constants: np.ndarray, wheel: int, direction: int,
                 row: np.ndarray) -> None:
    """J of wheel ``wheel``'s contact velocity along x_p (direction 0) or y_p (1) into ``row`` (7,)
    (``ContactKinematics.jacobian``)."""
    for j in range(DOF):
        row[j] = 0.0
    if direction == 0:
        row[0], row[1], row[2], row[3 + wheel] = cos_t, sin_t, -constants[12 + wheel], -constants[7]
    else:
        row[0], row[1], row[2] = -sin_t, cos_t, constants[17 + 2 * wheel]


def _dot(a: np.ndarray, b: np.ndarray, size: int) -> float:
    value = 0.0
    for j in range(size):
        value += a[j] * b[j]
    return value


def _spin_loads(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, constants: np.ndarray, contact: np.ndarray,
                out: np.ndarray) -> None:
    """N_1..N_4 at (q, qd, qdd) with the wheels' spin momentum (``normal_loads(..., spin_momentum=True)``)."""
    mass, spin, sx, sy, gravity = constants[0], constants[2], constants[3], constants[4], constants[5]
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    thd, thdd = qd[2], qdd[2]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    inertial_x = mass * qdd[0] - thdd * rsy - thd * thd * rsx
    inertial_y = mass * qdd[1] + thdd * rsx - thd * thd * rsy
    fx, fy = -inertial_x, -mass * gravity - inertial_y
    body_x, body_y = cos_t * fx + sin_t * fy, -sin_t * fx + cos_t * fy
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    moment_x = h * body_x - spin * (qdd[3] + qdd[4] + qdd[5] + qdd[6])
    moment_y = h * body_y - spin * thd * (qd[3] + qd[4] + qd[5] + qd[6])
    along, across = 0.25 * moment_x / (a * a), 0.25 * moment_y / (b * b)
    for wheel in range(4):
        out[wheel] = 0.25 * contact[ADHESION] + along * contact[7 + wheel] + across * contact[11 + wheel]


def _load_gain(theta: float, constants: np.ndarray, contact: np.ndarray, out: np.ndarray) -> None:
    """L (4 x 7), N(qdd) = N(0) + L qdd with the spin momentum (``load_acceleration_gain``)."""
    mass, spin, sx, sy = constants[0], constants[2], constants[3], constants[4]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    first = (h * (-cos_t * mass), h * (-sin_t * mass), h * (cos_t * rsy - sin_t * rsx))
    second = (h * (sin_t * mass), h * (-cos_t * mass), h * (-sin_t * rsy - cos_t * rsx))
    for wheel in range(4):
        along, across = contact[7 + wheel] * (0.25 / (a * a)), contact[11 + wheel] * (0.25 / (b * b))
        for j in range(3):
            out[wheel, j] = along * first[j] + across * second[j]
        for j in range(3, DOF):
            out[wheel, j] = along * -spin


def _prepare_rows(rows: np.ndarray, factor: np.ndarray, count: int, matrix: np.ndarray, system: np.ndarray,
                  lower: np.ndarray, order: np.ndarray, kept: np.ndarray) -> int:
    """B = A W into ``matrix``, and the independent rows K of B a pivoted Cholesky of B B^T keeps with its factor,
    for ``_row_space_solve``: ``order`` the kept rows in pivot order, ``kept`` 1 on each, ``lower[r, i]`` column r
    of the factor at row i; returns the rank. (The cut is the normal equations' of ``_minimum_norm``.)"""
    _scaled_rows(rows, factor, count, matrix)
    largest = 0.0
    for i in range(count):
        kept[i] = 0
        for j in range(i + 1):
            value = 0.0
            for k in range(DOF):
                value += matrix[i, k] * matrix[j, k]
            system[i, j] = system[j, i] = value
        largest = max(largest, system[i, i])
    cut = RANK_CUTOFF * largest
    rank = 0
    for r in range(count):
        best, pivot = -1, cut
        for i in range(count):
            if kept[i] == 0 and system[i, i] > pivot:
                best, pivot = i, system[i, i]
        if best < 0:
            break
        kept[best], order[r], rank = 1, best, r + 1
        scale = 1.0 / math.sqrt(pivot)
        for i in range(count):
            lower[r, i] = system[i, best] * scale
        for i in range(count):
            for j in range(count):
                system[i, j] -= lower[r, i] * lower[r, j]
    return rank


def _row_space_solve(factor: np.ndarray, force: np.ndarray, rhs: np.ndarray, with_rhs: bool, matrix: np.ndarray,
                     count: int, rank: int, order: np.ndarray, kept: np.ndarray, lower: np.ndarray,
                     vectors: np.ndarray, out: np.ndarray) -> bool:
    """qdd = W (s + B_K^T (B_K B_K^T)^-1 (b - B s)_K), s = W^T Q, by ``_prepare_rows``' factor (b = 0 unless
    ``with_rhs``): the minimum-norm least-squares solution wherever the rows off K agree with those on it, which
    the contact rows and the belt do (a side's contact rows repeat its belt row); where they do not (an
    inconsistent set: the heading task beside the sticking wheels' lateral rows) returns False, ``out`` untouched,
    for the caller's least squares. Cheaper than the normal equations of ``_solve`` with few rows. ``vectors``
    rows 1-3 are scratch."""
    scaled, misfit, solution = vectors[1], vectors[2], vectors[3]
    _transposed_factor_times(factor, force, scaled)
    for r in range(count):
        value = rhs[r] if with_rhs else 0.0
        for j in range(DOF):
            value -= matrix[r, j] * scaled[j]
        misfit[r] = value
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
    if with_rhs:  # b - B s lies in B's range when b = 0
        for d in range(count):
            if kept[d] == 0:
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
    _factor_times(factor, scaled, out)
    return True


def _wheel_speeds(count: int, predicted: np.ndarray, wheel_of: np.ndarray, epsilon: float, squares: np.ndarray,
                  sizes: np.ndarray) -> None:
    """sqrt(|w_i|^2 + eps^2) of each component's wheel (``kinetic_friction._wheel_speeds``)."""
    for wheel in range(4):
        squares[wheel] = 0.0
    for k in range(count):
        squares[wheel_of[k]] += predicted[k] * predicted[k]
    for k in range(count):
        sizes[k] = math.sqrt(squares[wheel_of[k]] + epsilon * epsilon)


def _kinetic_equations(count: int, responses: np.ndarray, mats: np.ndarray, vecs: np.ndarray, wheel_of: np.ndarray,
                       kinetic: float, epsilon: float, dt: float, state: np.ndarray, residual: np.ndarray,
                       jacobian: np.ndarray, predicted: np.ndarray) -> float:
    """The residual of z = (f, N) (count + 4), its Jacobian and the predicted slip w (``kinetic_friction._equations``);
    returns the residual's largest magnitude.

    r_f = f + mu_k max(N_i, 0) w / s,  r_N = N - N_0 - L qdd,  qdd = a + D f + R max(N, 0).
    """
    acceleration, pressed, sizes, direction = vecs[ACCELERATION], vecs[PRESSED], vecs[SIZES], vecs[DIRECTIONS]
    for wheel in range(4):
        pressed[wheel] = state[count + wheel] if state[count + wheel] > 0.0 else 0.0
    for j in range(DOF):
        by_friction, by_load = 0.0, 0.0
        for k in range(count):
            by_friction += responses[1 + k, j] * state[k]
        for wheel in range(4):
            by_load += responses[1 + count + wheel, j] * pressed[wheel]
        acceleration[j] = (responses[0, j] + by_friction) + by_load
    gain, origin = mats[GAIN], vecs[ORIGIN]
    load_by_friction, load_by_load = mats[LOAD_BY_FRICTION], mats[LOAD_BY_LOAD]
    size = 0.0
    for wheel in range(4):
        row = count + wheel
        residual[row] = (state[row] - origin[wheel]) - _dot(gain[wheel], acceleration, DOF)
        size = max(size, abs(residual[row]))
        for k in range(count):
            jacobian[row, k] = load_by_friction[wheel, k]
        for other in range(4):
            positive = 1.0 if state[count + other] > 0.0 else 0.0
            jacobian[row, count + other] = (1.0 if other == wheel else 0.0) - load_by_load[wheel, other] * positive
    if count == 0:
        return size
    slip_rows, slip, drift = mats[SLIP_ROWS], vecs[SLIP], vecs[DRIFT]
    for k in range(count):
        predicted[k] = slip[k] + dt * (_dot(slip_rows[k], acceleration, DOF) + drift[k])
    _wheel_speeds(count, predicted, wheel_of, epsilon, vecs[SQUARES], sizes)
    by_slip = mats[BY_SLIP]
    for k in range(count):
        direction[k] = predicted[k] / sizes[k]
    for k in range(count):
        force = kinetic * pressed[wheel_of[k]]
        residual[k] = state[k] + force * direction[k]
        size = max(size, abs(residual[k]))
        for p in range(count):  # d(w/s)/dw within each wheel: I/s - w w^T/s^3
            same = wheel_of[k] == wheel_of[p]
            by_slip[k, p] = force * ((((1.0 if k == p else 0.0) - direction[k] * direction[p]) if same else 0.0)
                                     / sizes[k])
    slip_by_friction, slip_by_load = mats[SLIP_BY_FRICTION], mats[SLIP_BY_LOAD]
    for k in range(count):
        for column in range(count):
            value = 0.0
            for p in range(count):
                value += by_slip[k, p] * slip_by_friction[p, column]
            jacobian[k, column] = (1.0 if k == column else 0.0) + value
        for wheel in range(4):
            positive = 1.0 if state[count + wheel] > 0.0 else 0.0
            value = 0.0
            for p in range(count):
                value += by_slip[k, p] * (slip_by_load[p, wheel] * positive)
            jacobian[k, count + wheel] = value
        wheel = wheel_of[k]
        if state[count + wheel] > 0.0:
            jacobian[k, count + wheel] += kinetic * direction[k]
    return size


def _lu_solve(matrix: np.ndarray, size: int, factors: np.ndarray, pivots: np.ndarray, rhs: np.ndarray,
              out: np.ndarray) -> bool:
    """out = matrix^-1 rhs by LU with partial pivoting (LAPACK's dgesv); False where a pivot is exactly 0 (singular)."""
    for i in range(size):
        out[i] = rhs[i]
        for j in range(size):
            factors[i, j] = matrix[i, j]
    for k in range(size):
        best, largest = k, abs(factors[k, k])
        for i in range(k + 1, size):
            if abs(factors[i, k]) > largest:
                best, largest = i, abs(factors[i, k])
        pivots[k] = best
        if largest == 0.0:
            return False
        if best != k:
            for j in range(size):
                factors[k, j], factors[best, j] = factors[best, j], factors[k, j]
            out[k], out[best] = out[best], out[k]
        for i in range(k + 1, size):
            scale = factors[i, k] / factors[k, k]
            factors[i, k] = scale
            for j in range(k + 1, size):
                factors[i, j] -= scale * factors[k, j]
            out[i] -= scale * out[k]
    for i in range(size - 1, -1, -1):
        value = out[i]
        for j in range(i + 1, size):
            value -= factors[i, j] * out[j]
        out[i] = value / factors[i, i]
    return True


def _kinetic(count: int, responses: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
             kinetic: float, epsilon: float, dt: float, start: np.ndarray, adhesion: float,
             solution: np.ndarray) -> int:
    """The sliding components' friction f (count) and the loads N (4) solving the boundary's equations, by Newton's
    method with a halving line search from the ``start`` loads (``consistent_friction``): f and N into vecs[STATE],
    the predicted slip into vecs[NEWTON_PREDICTED]; an error code (``CONTACT_ERRORS``), the residual it stopped
    at in solution[STATUS, NEWTON_RESIDUAL]."""
    size_of = count + 4
    wheel_of = ints[WHEEL_OF]
    slip_rows, gain = mats[SLIP_ROWS], mats[GAIN]
    # the blocks of the Jacobian that do not change: dt J_S D, dt J_S R, -L D, L R
    for k in range(count):
        for column in range(count):
            value = 0.0
            for j in range(DOF):
                value += slip_rows[k, j] * responses[1 + column, j]
            mats[SLIP_BY_FRICTION, k, column] = dt * value
        for wheel in range(4):
            value = 0.0
            for j in range(DOF):
                value += slip_rows[k, j] * responses[1 + count + wheel, j]
            mats[SLIP_BY_LOAD, k, wheel] = dt * value
    for wheel in range(4):
        for column in range(count):
            value = 0.0
            for j in range(DOF):
                value += -gain[wheel, j] * responses[1 + column, j]
            mats[LOAD_BY_FRICTION, wheel, column] = value
        for other in range(4):
            value = 0.0
            for j in range(DOF):
                value += gain[wheel, j] * responses[1 + count + other, j]
            mats[LOAD_BY_LOAD, wheel, other] = value
    state, predicted = vecs[STATE], vecs[NEWTON_PREDICTED]
    for wheel in range(4):
        state[count + wheel] = start[wheel]
    if count:  # Newton's start: the friction opposing the slip predicted with no friction (``_friction_of``)
        acceleration, pressed, sizes = vecs[ACCELERATION], vecs[PRESSED], vecs[SIZES]
        for wheel in range(4):
            pressed[wheel] = start[wheel] if start[wheel] > 0.0 else 0.0
        for j in range(DOF):
            value = 0.0
            for wheel in range(4):
                value += responses[1 + count + wheel, j] * pressed[wheel]
            acceleration[j] = responses[0, j] + value
        for k in range(count):
            predicted[k] = vecs[SLIP, k] + dt * (_dot(slip_rows[k], acceleration, DOF) + vecs[DRIFT, k])
        _wheel_speeds(count, predicted, wheel_of, epsilon, vecs[SQUARES], sizes)
        for k in range(count):
            state[k] = -kinetic * pressed[wheel_of[k]] * predicted[k] / sizes[k]
    residual, jacobian = vecs[RESIDUALS], mats[JACOBIAN]
    size = _kinetic_equations(count, responses, mats, vecs, wheel_of, kinetic, epsilon, dt, state, residual, jacobian,
                              predicted)
    trial, trial_residual, trial_predicted = vecs[TRIAL_STATE], vecs[TRIAL_RESIDUALS], vecs[TRIAL_PREDICTED]
    trial_jacobian, step, negative = mats[TRIAL_JACOBIAN], vecs[NEWTON_STEP], vecs[NEGATIVE]
    for _ in range(NEWTON_ITERATIONS):
        if size <= NEWTON_TOLERANCE * adhesion:
            solution[STATUS, NEWTON_RESIDUAL] = size
            for k in range(count):  # a lifted wheel (N_i <= 0) has no friction, not a remainder within the tolerance
                if not state[count + wheel_of[k]] > 0.0:
                    state[k] = 0.0
            return SOLVED
        for i in range(size_of):
            negative[i] = -residual[i]
        if not _lu_solve(jacobian, size_of, mats[LU], ints[PIVOTS], negative, step):
            return SINGULAR
        scale = 1.0
        while True:
            for i in range(size_of):
                trial[i] = state[i] + scale * step[i]
            trial_size = _kinetic_equations(count, responses, mats, vecs, wheel_of, kinetic, epsilon, dt, trial,
                                            trial_residual, trial_jacobian, trial_predicted)
            if trial_size < size or scale < 1e-6:
                break
            scale *= 0.5
        for i in range(size_of):
            state[i], residual[i] = trial[i], trial_residual[i]
            for j in range(size_of):
                jacobian[i, j] = trial_jacobian[i, j]
        for k in range(count):
            predicted[k] = trial_predicted[k]
        size = trial_size
    solution[STATUS, NEWTON_RESIDUAL] = size
    return UNCONVERGED


def _reduce(flags: np.ndarray, vector: np.ndarray, out: np.ndarray) -> int:
    """U^T v into ``out`` for U a basis of the velocities the other modules' rows annul (the tasks' unit rows, the
    belt's pd1 = pd2 and pd3 = pd4); the basis' size. U need not be orthonormal: the split below is the same for
    any basis of that space."""
    size = 0
    if not flags[0]:
        out[0], out[1] = vector[0], vector[1]
        size = 2
    if not (flags[0] or flags[1]):
        out[size] = vector[2]
        size += 1
    if flags[2]:
        out[size], out[size + 1] = vector[3] + vector[4], vector[5] + vector[6]
        return size + 2
    for j in range(3, DOF):
        out[size] = vector[j]
        size += 1
    return size


def _split(count: int, flags: np.ndarray, force: np.ndarray, mats: np.ndarray, vecs: np.ndarray, pivots: np.ndarray,
           out: np.ndarray) -> None:
    """The sticking rows' forces f (count) minimizing sum f_k^2 / max(N_k, 0) with U^T J_T^T f = U^T Q_c
    (``split_contact_force``): J_T in mats[STUCK_ROWS], each row's load in vecs[ROW_LOADS].

    f = W G^T x for G = U^T J_T^T, W the weights and any solution x of (G W G^T) x = U^T Q_c: one on the pivots
    a pivoted Cholesky keeps (a solution off them changes f by nothing, since G W G^T z = 0 gives W G^T z = 0).
    """
    made, system, lower = mats[MADE], mats[SPLIT], mats[SPLIT_LOWER]
    rows, loads, target, x = mats[STUCK_ROWS], vecs[ROW_LOADS], vecs[REDUCED], vecs[SPLIT_X]
    size = _reduce(flags, force, target)
    for k in range(count):
        _reduce(flags, rows[k], vecs[TOTAL])
        for i in range(size):
            made[i, k] = vecs[TOTAL, i]
    largest = 0.0
    for i in range(size):
        for j in range(i + 1):
            value = 0.0
            for k in range(count):
                weight = loads[k] if loads[k] > 0.0 else 0.0
                value += made[i, k] * weight * made[j, k]
            system[i, j] = system[j, i] = value
        largest = max(largest, system[i, i])
    # pivoted Cholesky of the system in place (as ``_responses``): lower[r, i] column r of L at row i
    kept = vecs[KEPT]
    rank = 0
    for i in range(size):
        kept[i] = 0.0
    cut = SPLIT_CUT * largest
    for r in range(size):
        best, pivot = -1, cut
        for i in range(size):
            if kept[i] == 0.0 and system[i, i] > pivot:
                best, pivot = i, system[i, i]
        if best < 0:
            break
        kept[best] = 1.0
        pivots[r] = best
        rank = r + 1
        scale = 1.0 / math.sqrt(pivot)
        for i in range(size):
            lower[r, i] = system[i, best] * scale
        for i in range(size):
            for j in range(size):
                system[i, j] -= lower[r, i] * lower[r, j]
    for a in range(rank):  # L z = target on the pivots, then L^T x = z
        value = target[pivots[a]]
        for r in range(a):
            value -= lower[r, pivots[a]] * x[r]
        x[a] = value / lower[a, pivots[a]]
    for a in range(rank - 1, -1, -1):
        value = x[a]
        for r in range(a + 1, rank):
            value -= lower[a, pivots[r]] * x[r]
        x[a] = value / lower[a, pivots[a]]
    for k in range(count):
        weight = loads[k] if loads[k] > 0.0 else 0.0
        value = 0.0
        for a in range(rank):
            value += made[pivots[a], k] * x[a]
        out[k] = weight * value


def _responded(factor: np.ndarray, force: np.ndarray, rhs: np.ndarray, with_rhs: bool, count: int, rank: int,
               rows: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray,
               scratch: np.ndarray, mats: np.ndarray, ints: np.ndarray, zero: np.ndarray, out: np.ndarray) -> None:
    """qdd under ``force`` and the rows (b = 0 unless ``with_rhs``) by ``_row_space_solve`` after ``_prepare_rows``,
    or by ``_solve``'s least squares where the rows disagree: one column of ``constrained_acceleration``."""
    if not _row_space_solve(factor, force, rhs, with_rhs, matrix, count, rank, ints[ROW_ORDER], ints[ROW_KEPT],
                            mats[ROW_FACTOR], vectors, out):
        _solve(factor, force, rows, rhs if with_rhs else zero, count, matrix, gram, lower, vectors, scratch, out)


def _boundary(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
              torque: np.ndarray, dt: float, sliding: np.ndarray, start: np.ndarray, rows: np.ndarray,
              rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray,
              vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
              marks: np.ndarray, columns: np.ndarray, responses: np.ndarray, solution: np.ndarray) -> int:
    """The motion at y with the ``sliding`` wheels sliding (``CoulombContact._solve``) into ``solution``: their
    friction and every wheel's load solved together from the ``start`` loads, the motion under them, the sticking
    wheels' split of the constraint force; an error code (``CONTACT_ERRORS``)."""
    q, qd = y[:DOF], y[DOF:]
    frictional = flags[3] or flags[4]
    sticking, zero = marks[STICKING], vecs[ZERO]
    for wheel in range(4):
        sticking[wheel] = frictional and not sliding[wheel]
    for i in range(16):
        zero[i] = 0.0
    unloaded = columns[0]  # Q with no rolling resistance, the rows of the others and of the sticking wheels
    count = _problem(q, qd, reference, flags, constants, torque, zero, True, sticking, zero, rows, rhs, factor,
                     unloaded)
    theta, thd = q[2], qd[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    slip_rows, wheel_of, direction_of = mats[SLIP_ROWS], ints[WHEEL_OF], ints[DIRECTION_OF]
    sliders = 0
    for wheel in range(4):
        for direction in range(2):
            if frictional and sliding[wheel] and flags[4 - direction]:  # x_p: nonslip, y_p: non-lateral
                wheel_of[sliders], direction_of[sliders] = wheel, direction
                _contact_row(cos_t, sin_t, constants, wheel, direction, slip_rows[sliders])
                for j in range(DOF):
                    columns[1 + sliders, j] = slip_rows[sliders, j]
                sliders += 1
    eps2, rolling = constants[9], contact[ROLLING]
    for wheel in range(4):  # the rolling resistance per newton of each wheel's load (Robot.rolling_resistance_per_load)
        column = columns[1 + sliders + wheel]
        for j in range(DOF):
            column[j] = 0.0
        px, py = constants[16 + 2 * wheel], constants[17 + 2 * wheel]
        arm_x, arm_y = cos_t * px - sin_t * py, sin_t * px + cos_t * py
        vx, vy = qd[0] + thd * arm_x, qd[1] + thd * arm_y
        scale = -rolling / math.sqrt(vx * vx + vy * vy + eps2)
        column[0], column[1], column[2] = scale * vx, scale * vy, scale * (arm_x * vx + arm_y * vy)
    order, kept, system = ints[ROW_ORDER], ints[ROW_KEPT], mats[ROW_SYSTEM]
    rank = _prepare_rows(rows, factor, count, matrix, system, mats[ROW_FACTOR], order, kept)
    for column in range(1 + sliders + 4):
        _responded(factor, columns[column], rhs, column == 0, count, rank, rows, matrix, gram, lower, vectors,
                   scratch, mats, ints, zero, responses[column])
    _spin_loads(q, qd, zero, constants, contact, vecs[ORIGIN])
    _load_gain(theta, constants, contact, mats[GAIN])
    v_long, v_lat = cos_t * qd[0] + sin_t * qd[1], -sin_t * qd[0] + cos_t * qd[1]
    for k in range(sliders):
        vecs[SLIP, k] = _dot(slip_rows[k], qd, DOF)
        vecs[DRIFT, k] = thd * v_lat if direction_of[k] == 0 else -thd * v_long
    error = _kinetic(sliders, responses, mats, vecs, ints, contact[KINETIC], math.sqrt(eps2), dt, start,
                     contact[ADHESION], solution)
    solution[STATUS, ERROR] = error
    if error != SOLVED:
        return error
    state = vecs[STATE]
    loads, friction, total = solution[LOADS], solution[FRICTION], vecs[TOTAL]
    for wheel in range(4):
        loads[wheel] = state[sliders + wheel]
    for j in range(DOF):
        value = 0.0
        for k in range(sliders):
            value += state[k] * slip_rows[k, j]
        friction[j] = value
    for j in range(DOF):  # Q with each wheel's rolling resistance f_r max(N_i, 0), plus Q_f
        value = unloaded[j]
        for wheel in range(4):
            if loads[wheel] > 0.0:
                value += loads[wheel] * columns[1 + sliders + wheel, j]
        total[j] = value + friction[j]
    acceleration = solution[QDD]
    _responded(factor, total, rhs, True, count, rank, rows, matrix, gram, lower, vectors, scratch, mats, ints, zero,
               acceleration)
    mass, yaw_inertia, spin_inertia, sx, sy = constants[0], constants[1], constants[2], constants[3], constants[4]
    ux, uy = -cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx
    constraint = solution[CONSTRAINT]
    constraint[0] = mass * acceleration[0] + ux * acceleration[2] - total[0]
    constraint[1] = mass * acceleration[1] + uy * acceleration[2] - total[1]
    constraint[2] = ux * acceleration[0] + uy * acceleration[1] + yaw_inertia * acceleration[2] - total[2]
    for i in range(3, DOF):
        constraint[i] = spin_inertia * acceleration[i] - total[i]
    squares = 0.0
    for r in range(count):
        misfit = -rhs[r]
        for j in range(DOF):
            misfit += rows[r, j] * acceleration[j]
        squares += misfit * misfit
    solution[STATUS, RESIDUAL] = math.sqrt(squares)
    forces, predicted, velocity = solution[FORCES], solution[PREDICTED], solution[VELOCITY]
    for i in range(8):
        forces[i] = predicted[i] = 0.0
    for k in range(sliders):
        forces[2 * wheel_of[k] + direction_of[k]] = state[k]
        predicted[2 * wheel_of[k] + direction_of[k]] = vecs[NEWTON_PREDICTED, k]
    row = vecs[TOTAL]
    for wheel in range(4):
        for direction in range(2):
            _contact_row(cos_t, sin_t, constants, wheel, direction, row)
            velocity[2 * wheel + direction] = _dot(row, qd, DOF)
    stuck, stuck_rows, row_loads = 0, mats[STUCK_ROWS], vecs[ROW_LOADS]
    for wheel in range(4):
        for direction in range(2):
            if sticking[wheel] and flags[4 - direction]:
                _contact_row(cos_t, sin_t, constants, wheel, direction, stuck_rows[stuck])
                row_loads[stuck] = loads[wheel]
                stuck += 1
    if stuck:
        split = vecs[RESIDUALS]
        _split(stuck, flags, constraint, mats, vecs, ints[SPLIT_PIVOTS], split)
        stuck = 0
        for wheel in range(4):
            for direction in range(2):
                if sticking[wheel] and flags[4 - direction]:
                    forces[2 * wheel + direction] = split[stuck]
                    stuck += 1
    return SOLVED


def _project_onto(y: np.ndarray, flags: np.ndarray, constants: np.ndarray, sticking: np.ndarray, rows: np.ndarray,
                  factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray,
                  scratch: np.ndarray) -> None:
    """qd <- qd - M^-1 A^T (A M^-1 A^T)+ A qd = qd - W (A W)+ A qd over the belt's rows and the ``sticking`` wheels'
    contact rows, in place on y (``Simulation._project``); ``rows`` (>= 10 x 7) is the caller's own scratch."""
    theta = y[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    count = 0
    if flags[2]:
        for r in range(2):
            for j in range(DOF):
                rows[r, j] = 0.0
        rows[0, 3], rows[0, 4], rows[1, 5], rows[1, 6] = 1.0, -1.0, 1.0, -1.0
        count = 2
    for wheel in range(4):
        for direction in range(2):
            if sticking[wheel] and flags[4 - direction]:
                _contact_row(cos_t, sin_t, constants, wheel, direction, rows[count])
                count += 1
    if count == 0:
        return
    _factor_of(theta, constants, factor)
    _scaled_rows(rows, factor, count, matrix)
    target = vectors[2]
    for r in range(count):
        target[r] = _dot(rows[r], y[DOF:], DOF)
    _minimum_norm(matrix, target, count, gram, lower, vectors, scratch, vectors[4])
    _factor_times(factor, vectors[4], vectors[1])
    for j in range(DOF):
        y[DOF + j] -= vectors[1, j]


def _speed(velocity: np.ndarray, wheel: int, flags: np.ndarray) -> float:
    """|v| of a wheel's velocity (interleaved) over the directions that have friction (``contact._speed``)."""
    along = velocity[2 * wheel] if flags[4] else 0.0
    across = velocity[2 * wheel + 1] if flags[3] else 0.0
    return math.sqrt(along * along + across * across)


def _reverses(solution: np.ndarray, wheel: int, flags: np.ndarray) -> bool:
    """Whether the step would reverse the wheel's slip, v_i . w_i < 0; never for a wheel at rest
    (``contact._reverses``)."""
    return ((solution[VELOCITY, 2 * wheel] * solution[PREDICTED, 2 * wheel]
             + solution[VELOCITY, 2 * wheel + 1] * solution[PREDICTED, 2 * wheel + 1]) < 0.0
            and _speed(solution[VELOCITY], wheel, flags) > AT_REST)


def _holds(solution: np.ndarray, wheel: int, static: float) -> bool:
    """Whether the wheel's force lies in its friction disc, |f_i| <= mu_s N_i (``contact._holds``)."""
    return not math.hypot(solution[FORCES, 2 * wheel], solution[FORCES, 2 * wheel + 1]) > static * solution[LOADS, wheel]


def _settle(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
            torque: np.ndarray, dt: float, sliding: np.ndarray, loads: np.ndarray, rows: np.ndarray, rhs: np.ndarray,
            factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray,
            scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray, marks: np.ndarray,
            columns: np.ndarray, responses: np.ndarray, solution: np.ndarray, trial: np.ndarray) -> int:
    """The stick/slip transitions at y's boundary, then the solution the step integrates (``CoulombContact.settle``,
    one long function as numba compiles it best: a round of transitions shares its state, the sets, in registers).

    In turn, until nothing changes: a sliding wheel the step would reverse is stopped by the switch projection and
    slides on from rest; sliding wheels that are stopping stick again when the solve with their rows restored
    holds them in their discs (their slip projected away); every sticking wheel whose force leaves its disc
    slides. ``sliding`` (4,) and ``loads`` (4,) (held, Newton's start) are the contact state before, updated in
    place, and y's velocities are projected in place, unless an error code is returned (``CONTACT_ERRORS``).
    """
    frictional = flags[3] or flags[4]
    static, stick = contact[STATIC], contact[STICK]
    for wheel in range(4):
        sliding[wheel] = sliding[wheel] and frictional
    error = _boundary(y, reference, flags, constants, contact, torque, dt, sliding, loads, rows, rhs, factor, matrix,
                      gram, lower, vectors, scratch, mats, vecs, ints, marks, columns, responses, solution)
    if error != SOLVED:
        return error
    sticking, trial_sliding, stopped = marks[STICKING], marks[TRIAL_SLIDING], marks[STOPPED]
    reversing, candidates, holding = marks[REVERSING], marks[CANDIDATES], marks[HOLDING]
    trial_y, projection = vecs[TRIAL_Y, :2 * DOF], mats[PROJECTION]
    for wheel in range(4):
        stopped[wheel] = False
    for _ in range(SETTLE_PASSES):
        any_reversing = False
        for wheel in range(4):
            reversing[wheel] = sliding[wheel] and not stopped[wheel] and _reverses(solution, wheel, flags)
            any_reversing = any_reversing or reversing[wheel]
        if any_reversing:
            for wheel in range(4):
                stopped[wheel] = stopped[wheel] or reversing[wheel]
                sticking[wheel] = frictional and (not sliding[wheel] or reversing[wheel])
            _project_onto(y, flags, constants, sticking, projection, factor, matrix, gram, lower, vectors, scratch)
            error = _boundary(y, reference, flags, constants, contact, torque, dt, sliding, loads, rows, rhs, factor,
                              matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns, responses,
                              solution)
            if error != SOLVED:
                return error
        searching = False
        for wheel in range(4):
            candidates[wheel] = sliding[wheel] and (_speed(solution[VELOCITY], wheel, flags) < stick
                                                    or _speed(solution[PREDICTED], wheel, flags) < stick)
            searching = searching or candidates[wheel]
        while searching:
            for wheel in range(4):
                trial_sliding[wheel] = sliding[wheel] and not candidates[wheel]
                sticking[wheel] = frictional and not trial_sliding[wheel]
            for i in range(2 * DOF):
                trial_y[i] = y[i]
            _project_onto(trial_y, flags, constants, sticking, projection, factor, matrix, gram, lower, vectors,
                          scratch)
            error = _boundary(trial_y, reference, flags, constants, contact, torque, dt, trial_sliding,
                              loads, rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints,
                              marks, columns, responses, trial)
            if error != SOLVED:
                return error
            same, searching = True, False
            for wheel in range(4):
                holding[wheel] = candidates[wheel] and _holds(trial, wheel, static)
                same = same and holding[wheel] == candidates[wheel]
                searching = searching or holding[wheel]
            if same:
                for wheel in range(4):
                    sliding[wheel] = trial_sliding[wheel]
                for i in range(2 * DOF):
                    y[i] = trial_y[i]
                solution[:, :] = trial
                break
            for wheel in range(4):
                candidates[wheel] = holding[wheel]
        while True:
            exceeded = False
            for wheel in range(4):
                if frictional and not sliding[wheel] and not _holds(solution, wheel, static):
                    sliding[wheel] = exceeded = True
            if not exceeded:
                break
            error = _boundary(y, reference, flags, constants, contact, torque, dt, sliding, loads, rows, rhs, factor,
                              matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns, responses,
                              solution)
            if error != SOLVED:
                return error
        reversed_again = False
        for wheel in range(4):
            reversed_again = reversed_again or (sliding[wheel] and not stopped[wheel]
                                                and _reverses(solution, wheel, flags))
        if not reversed_again:
            break
    for wheel in range(4):
        loads[wheel] = solution[LOADS, wheel]
    return SOLVED


def _hold(solution: np.ndarray, sliding: np.ndarray, flags: np.ndarray, contact: np.ndarray, gains: np.ndarray,
          sticking: np.ndarray, held: np.ndarray) -> None:
    """What a step holds from its settled boundary (``_problem``'s gains, sticking and held): each wheel's rolling
    resistance f_r max(N_i, 0), the sticking wheels, the sliding wheels' friction."""
    frictional = flags[3] or flags[4]
    for wheel in range(4):
        load = solution[LOADS, wheel]
        gains[wheel] = contact[ROLLING] * (load if load > 0.0 else 0.0)
        sticking[wheel] = frictional and not sliding[wheel]
        for direction in range(2):
            held[2 * wheel + direction] = solution[FORCES, 2 * wheel + direction] if sliding[wheel] else 0.0


def _held_step(state: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray,
               contact: np.ndarray, torque: np.ndarray, dt: float, solution: np.ndarray, sliding: np.ndarray,
               rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
               lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray,
               ints: np.ndarray, marks: np.ndarray, out: np.ndarray, slopes: np.ndarray) -> bool:
    """The RK4 step from a settled boundary (``Simulation.step``): the solution's qdd its first stage, the sticking
    set, loads and sliding wheels' friction held; whether the state it gives (``out``) is finite."""
    gains, held, sticking = vecs[PRESSED], vecs[TOTAL], marks[STICKING]
    _hold(solution, sliding, flags, contact, gains, sticking, held)
    for i in range(DOF):
        slopes[0, DOF + i] = solution[QDD, i]
    return _rk4(state, references, flags, constants, torque, gains, True, sticking, held, dt, True, rows, rhs, factor,
                matrix, gram, lower, vectors, scratch, mats, ints, out, slopes)


def robot_contact_run(states: np.ndarray, settled: np.ndarray, references: np.ndarray, flags: np.ndarray,
                      constants: np.ndarray, contact: np.ndarray, torque: np.ndarray, dt: float, steps: int,
                      sliding: np.ndarray, loads: np.ndarray, solutions: np.ndarray, slid: np.ndarray,
                      outcome: np.ndarray) -> None:
    """One robot with coulomb contact over consecutive instants: each boundary settled (``_settle``), then the
    step from it (``_held_step``).

    ``states`` (T + 1, 14): row 0 the state at the first instant; ``settled`` (T, 14) gets each instant's state
    with its velocities projected where a wheel stopped or stuck, ``solutions`` (T, 8, 8) its solution, ``slid``
    (T, 4) its sliding wheels, and ``states`` row k + 1 the state one step later, for k < ``steps`` (at most T).
    ``sliding`` (4,) and ``loads`` (4,): the contact state at the start, updated instant by instant.
    ``outcome`` (4,): the instants settled, the steps taken, how the run ended (RAN, DETACHED at the last instant
    settled, DIVERGED after it, FAILED at the next: its error code in outcome[3]).
    """
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    mats, vecs, ints, marks, columns, responses = _contact_workspace()
    trial, slopes = np.zeros((SOLUTION_ROWS, SOLUTION_WIDTH)), np.zeros((4, 2 * DOF))
    outcome[0], outcome[1], outcome[2], outcome[3] = 0, 0, RAN, SOLVED
    for k in range(solutions.shape[0]):
        for i in range(2 * DOF):
            settled[k, i] = states[k, i]
        error = _settle(settled[k], references[k, 0], flags, constants, contact, torque, dt, sliding, loads, rows, rhs,
                        factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns, responses,
                        solutions[k], trial)
        if error != SOLVED:
            outcome[2], outcome[3] = FAILED, error
            return
        outcome[0] = k + 1
        for wheel in range(4):
            slid[k, wheel] = sliding[wheel]
        if min(loads[0], loads[1], loads[2], loads[3]) < 0.0:
            outcome[2] = DETACHED
            return
        if k == steps:
            return
        if not _held_step(settled[k], references[k], flags, constants, contact, torque, dt, solutions[k], sliding,
                          rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks,
                          states[k + 1], slopes):
            outcome[2] = DIVERGED
            return
        outcome[1] = k + 1


def _batch_settle(states: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                  contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, loads: np.ndarray,
                  live: np.ndarray, solutions: np.ndarray, errors: np.ndarray, chunk: int) -> None:
    """The boundary of every ``live`` robot (N robots: ``states`` (N, 14), ``constants`` (N, 24), ``contact``
    (N, 16), ...) settled (``_settle``): ``sliding`` (N, 4), ``loads`` (N, 4) and the states updated in place,
    ``solutions`` (N, 8, 8) filled, ``errors`` (N,) each robot's error code; the others are left as they are.
    The robots are split over the cores in blocks of ``chunk`` (``_settle_block``: a parallel loop compiles
    fastest around one call)."""
    for block in prange((states.shape[0] + chunk - 1) // chunk):
        _settle_block(block * chunk, min(states.shape[0], (block + 1) * chunk), states, reference, flags, constants,
                      contact, torques, dt, sliding, loads, live, solutions, errors)


def _settle_block(first: int, end: int, states: np.ndarray, reference: np.ndarray, flags: np.ndarray,
                  constants: np.ndarray, contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray,
                  loads: np.ndarray, live: np.ndarray, solutions: np.ndarray, errors: np.ndarray) -> None:
    """``_batch_settle`` of robots first..end - 1 on one core."""
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    mats, vecs, ints, marks, columns, responses = _contact_workspace()
    trial = np.zeros((SOLUTION_ROWS, SOLUTION_WIDTH))
    for robot in range(first, end):
        if live[robot]:
            errors[robot] = _settle(states[robot], reference, flags, constants[robot], contact[robot], torques[robot],
                                    dt, sliding[robot], loads[robot], rows, rhs, factor, matrix, gram, lower, vectors,
                                    scratch, mats, vecs, ints, marks, columns, responses, solutions[robot], trial)


def _batch_step(states: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, live: np.ndarray,
                solutions: np.ndarray, out: np.ndarray, finite: np.ndarray, chunk: int) -> None:
    """The RK4 step of every ``live`` robot from its settled boundary (``_held_step``) into ``out``; the others keep
    their state. ``finite`` (N,) says whether each new state is finite. Over the cores as ``_batch_settle``."""
    for block in prange((states.shape[0] + chunk - 1) // chunk):
        _step_block(block * chunk, min(states.shape[0], (block + 1) * chunk), states, references, flags, constants,
                    contact, torques, dt, sliding, live, solutions, out, finite)


def _step_block(first: int, end: int, states: np.ndarray, references: np.ndarray, flags: np.ndarray,
                constants: np.ndarray, contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray,
                live: np.ndarray, solutions: np.ndarray, out: np.ndarray, finite: np.ndarray) -> None:
    """``_batch_step`` of robots first..end - 1 on one core."""
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    mats, vecs, ints, marks, _, _ = _contact_workspace()
    slopes = np.zeros((4, 2 * DOF))
    for robot in range(first, end):
        if live[robot]:
            finite[robot] = _held_step(states[robot], references, flags, constants[robot], contact[robot],
                                       torques[robot], dt, solutions[robot], sliding[robot], rows, rhs, factor, matrix,
                                       gram, lower, vectors, scratch, mats, vecs, ints, marks, out[robot], slopes)
        else:
            for i in range(2 * DOF):
                out[robot, i] = states[robot, i]
            finite[robot] = True


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
_rk4 = _compile(_rk4, inline="always")
_steps = _compile(_steps, parallel=True)
_workspace = _compile(_workspace, inline="always")
_motion_of = _compile(_motion_of, inline="always")
_motion = _compile(_motion, inline="always")
robot_run = _compile(robot_run)
tracking_force = _compile(tracking_force)
_factor_of = _compile(_factor_of, inline="always")
_wheel_rows = _compile(_wheel_rows, inline="always")
_contact_workspace = _compile(_contact_workspace, inline="always")
_contact_row = _compile(_contact_row, inline="always")
_dot = _compile(_dot, inline="always")
_spin_loads = _compile(_spin_loads, inline="always")
_load_gain = _compile(_load_gain, inline="always")
_prepare_rows = _compile(_prepare_rows)
_row_space_solve = _compile(_row_space_solve)
_responded = _compile(_responded)
_wheel_speeds = _compile(_wheel_speeds, inline="always")
_kinetic_equations = _compile(_kinetic_equations)
_lu_solve = _compile(_lu_solve)
_kinetic = _compile(_kinetic)
_reduce = _compile(_reduce, inline="always")
_split = _compile(_split)
_boundary = _compile(_boundary)
_project_onto = _compile(_project_onto)
_speed = _compile(_speed, inline="always")
_reverses = _compile(_reverses, inline="always")
_holds = _compile(_holds, inline="always")
_settle = _compile(_settle)
_hold = _compile(_hold, inline="always")
_held_step = _compile(_held_step)
robot_contact_run = _compile(robot_contact_run)
_settle_block = _compile(_settle_block)
_step_block = _compile(_step_block)
_batch_settle = _compile(_batch_settle, parallel=True)
_batch_step = _compile(_batch_step, parallel=True)


def constrained_accelerations(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``batch_constrained_acceleration`` compiled robot by robot, for the robots' own factors W (N, 7, 7)."""
    out = np.empty(force.shape)
    _accelerations(np.ascontiguousarray(factor), np.ascontiguousarray(force), np.ascontiguousarray(rows),
                   np.ascontiguousarray(rhs), out)
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
                         contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, loads: np.ndarray,
                         live: np.ndarray, solutions: np.ndarray, chunk: int = 64) -> np.ndarray:
    """Every live robot's coulomb boundary, robot by robot over the cores (``_batch_settle``): ``states`` (velocities
    projected), ``sliding``, ``loads`` and ``solutions`` (N, 8, 8) change in place; returns each robot's error code
    (``CONTACT_ERRORS``)."""
    flags, _ = module_flags(active)
    errors = np.zeros(states.shape[0], dtype=np.int64)
    _batch_settle(states, reference, flags, constants, contact, torques, dt, sliding, loads, live, solutions, errors,
                  chunk)
    return errors


def batch_contact_step(states: np.ndarray, references: np.ndarray, active: tuple[str, ...], constants: np.ndarray,
                       contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, live: np.ndarray,
                       solutions: np.ndarray, chunk: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Every live robot's RK4 step from its settled boundary (``_batch_step``): the new states and which are finite."""
    flags, _ = module_flags(active)
    out, finite = np.empty_like(states), np.ones(states.shape[0], dtype=np.bool_)
    _batch_step(states, references, flags, constants, contact, torques, dt, sliding, live, solutions, out, finite,
                chunk)
    return out, finite
