"""Small dense linear algebra for one robot: Cholesky factors, the Udwadia-Kalaba solve by normal equations with its
rank-revealing fallback, and LU with partial pivoting (the solve in the rows' own space: ``row_space``)."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.batch.solver import RANK_CUTOFF, WELL_CONDITIONED
from wallbot_sim.model.robot import DOF


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


# Long on purpose: the pivoted factor, the basic solution and the null space removed share the pivot set and
# the scratch in one compiled frame (numba), one robot's least squares without calls between the stages.
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


def _full_rank_solve(rows: np.ndarray, rhs: np.ndarray, count: int, gram: np.ndarray, lower: np.ndarray,
                     out: np.ndarray) -> bool:
    """qdd = (A^T A)^-1 A^T b of the first ``count`` rows A, b, where A has full column rank (its normal equations
    well conditioned; else False, ``out`` scratch). Then the Udwadia-Kalaba acceleration W (s + B+ (b - B s)),
    B = A W, is this whatever M and Q: B+ B = I, and W (W^T A^T A W)^-1 W^T = (A^T A)^-1 for W invertible. The
    rows' zeros are skipped: a module's row touches few coordinates."""
    for i in range(DOF):
        out[i] = 0.0
        for j in range(i + 1):
            gram[i, j] = 0.0
    for r in range(count):
        for i in range(DOF):
            entry = rows[r, i]
            if entry != 0.0:
                out[i] += entry * rhs[r]
                for j in range(i + 1):
                    gram[i, j] += entry * rows[r, j]
    # L D L^T of the gram without square roots, one division a column (its pivots D_j are the Cholesky factor's
    # squared); ``lower`` holds L D below its diagonal and 1/D on it
    largest = 0.0
    for i in range(DOF):
        largest = max(largest, gram[i, i])
    floor = WELL_CONDITIONED * largest
    for j in range(DOF):
        pivot = gram[j, j]
        for k in range(j):
            pivot -= lower[j, k] * lower[j, k] * lower[k, k]
        if not pivot > floor:
            return False
        lower[j, j] = 1.0 / pivot
        for i in range(j + 1, DOF):
            value = gram[i, j]
            for k in range(j):
                value -= lower[i, k] * lower[j, k] * lower[k, k]
            lower[i, j] = value
    for j in range(DOF):  # L z = A^T b
        value = out[j]
        for k in range(j):
            value -= lower[j, k] * lower[k, k] * out[k]
        out[j] = value
    for j in range(DOF - 1, -1, -1):  # D L^T x = z
        value = out[j]
        for k in range(j + 1, DOF):
            value -= lower[k, j] * out[k]
        out[j] = value * lower[j, j]
    return True


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


def _dot(a: np.ndarray, b: np.ndarray, size: int) -> float:
    value = 0.0
    for j in range(size):
        value += a[j] * b[j]
    return value


def _lu_factor(matrix: np.ndarray, size: int, factors: np.ndarray, pivots: np.ndarray) -> bool:
    """P matrix = L U into ``factors`` (L's multipliers below the diagonal) by partial pivoting (LAPACK's dgetrf),
    each step's pivot row in ``pivots``; False where a pivot is exactly 0 (singular)."""
    for i in range(size):
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
        for i in range(k + 1, size):
            scale = factors[i, k] / factors[k, k]
            factors[i, k] = scale
            for j in range(k + 1, size):
                factors[i, j] -= scale * factors[k, j]
    return True


def _lu_substitute(factors: np.ndarray, pivots: np.ndarray, size: int, rhs: np.ndarray, out: np.ndarray) -> None:
    """out = matrix^-1 rhs from ``_lu_factor``'s factors and pivots (LAPACK's dgetrs)."""
    for i in range(size):
        out[i] = rhs[i]
    for k in range(size):  # the rows' swaps first: a later swap moved the multipliers of the earlier columns too
        best = pivots[k]
        if best != k:
            out[k], out[best] = out[best], out[k]
    for k in range(size):
        for i in range(k + 1, size):
            out[i] -= factors[i, k] * out[k]
    for i in range(size - 1, -1, -1):
        value = out[i]
        for j in range(i + 1, size):
            value -= factors[i, j] * out[j]
        out[i] = value / factors[i, i]


def _lu_solve(matrix: np.ndarray, size: int, factors: np.ndarray, pivots: np.ndarray, rhs: np.ndarray,
              out: np.ndarray) -> bool:
    """out = matrix^-1 rhs by LU with partial pivoting (LAPACK's dgesv); False where a pivot is exactly 0 (singular)."""
    if not _lu_factor(matrix, size, factors, pivots):
        return False
    _lu_substitute(factors, pivots, size, rhs, out)
    return True


_cholesky = jit(_cholesky, inline="always")
_substitute = jit(_substitute, inline="always")
_solve_factored = jit(_solve_factored)
_solve_positive = jit(_solve_positive)
_rank_revealing = jit(_rank_revealing)
_minimum_norm = jit(_minimum_norm, inline="always")
_transposed_factor_times = jit(_transposed_factor_times, inline="always")
_factor_times = jit(_factor_times, inline="always")
_scaled_rows = jit(_scaled_rows, inline="always")
_misfits = jit(_misfits, inline="always")
_least_squares = jit(_solve)
"""``_solve`` as a call, for the coulomb solves' rare fallback: a compiled run holds their every solve inline."""
_solve = jit(_solve, inline="always")
_full_rank_solve = jit(_full_rank_solve, inline="always")
_scratch = jit(_scratch)
_accelerations = jit(_accelerations)
_dot = jit(_dot, inline="always")
_lu_factor = jit(_lu_factor, inline="always")
_lu_substitute = jit(_lu_substitute, inline="always")
_lu_solve = jit(_lu_solve)
