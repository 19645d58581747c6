"""The Udwadia-Kalaba solve in the constraint rows' own space for one robot: B = A W, a pivoted (rank-revealing)
Cholesky of B B^T that keeps the independent rows, its triangular solves, and the acceleration from them."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.batch.kernel.linalg import _factor_times, _scaled_rows, _transposed_factor_times
from wallbot_sim.model.batch.solver import RANK_CUTOFF
from wallbot_sim.model.robot import DOF

CONSISTENT = 1e-9
"""Relative misfit up to which a row ``_prepare_rows`` drops agrees with the rows it keeps."""


def _prepare_rows(rows: np.ndarray, factor: np.ndarray, count: int, matrix: np.ndarray, gram: np.ndarray,
                  system: np.ndarray, lower: np.ndarray, order: np.ndarray, kept: np.ndarray) -> int:
    """B = A W into ``matrix``, B B^T into ``gram``, and the independent rows K of B a pivoted Cholesky of B B^T
    keeps with its factor, for ``_projected``: ``order`` the kept rows in pivot order, ``kept`` 1 on each,
    ``lower[r, i]`` column r of the factor at row i (``system`` its scratch); returns the rank. (The cut is the
    normal equations' of ``_minimum_norm``.)"""
    _scaled_rows(rows, factor, count, matrix)
    largest = 0.0
    for i in range(count):
        for j in range(i + 1):
            value = 0.0
            for k in range(DOF):
                value += matrix[i, k] * matrix[j, k]
            gram[i, j] = gram[j, i] = system[i, j] = system[j, i] = value
        largest = max(largest, system[i, i])
    return _pivoted_cholesky(system, count, RANK_CUTOFF * largest, order, kept, lower)


def _pivoted_cholesky(system: np.ndarray, size: int, cut: float, order: np.ndarray, kept: np.ndarray,
                      lower: np.ndarray) -> int:
    """The pivoted Cholesky factor L of the symmetric ``system`` (size x size; left with its Schur complement):
    the largest remaining diagonal first while it exceeds ``cut``; ``order`` the pivots in turn, ``kept`` 1 on each,
    ``lower[r, i]`` column r of L at row i. Returns the rank."""
    for i in range(size):
        kept[i] = 0
    rank = 0
    for r in range(size):
        best, pivot = -1, cut
        for i in range(size):
            if kept[i] == 0 and system[i, i] > pivot:
                best, pivot = i, system[i, i]
        if best < 0:
            break
        kept[best], order[r], rank = 1, best, r + 1
        scale = 1.0 / math.sqrt(pivot)
        for i in range(size):
            lower[r, i] = system[i, best] * scale
        for i in range(size):
            for j in range(size):
                system[i, j] -= lower[r, i] * lower[r, j]
    return rank


def _pivoted_solve(lower: np.ndarray, order: np.ndarray, rank: int, target: np.ndarray, x: np.ndarray) -> None:
    """x (rank,) with L L^T x = target on the pivots of ``_pivoted_cholesky``: L z = target in pivot order, then
    L^T x = z."""
    for a in range(rank):
        value = target[order[a]]
        for r in range(a):
            value -= lower[r, order[a]] * x[r]
        x[a] = value / lower[a, order[a]]
    for a in range(rank - 1, -1, -1):
        value = x[a]
        for r in range(a + 1, rank):
            value -= lower[a, order[r]] * x[r]
        x[a] = value / lower[a, order[a]]


def _projected(factor: np.ndarray, force: np.ndarray, rhs: np.ndarray, with_rhs: bool, matrix: np.ndarray,
               gram: np.ndarray, count: int, rank: int, order: np.ndarray, kept: np.ndarray, lower: np.ndarray,
               scaled: np.ndarray, misfit: np.ndarray, solution: np.ndarray, out: np.ndarray) -> bool:
    """qdd = W (s + B_K^T (B_K B_K^T)^-1 (b - B s)_K), s = W^T Q, by ``_prepare_rows``' factor (b = 0 unless
    ``with_rhs``): the minimum-norm least-squares solution wherever the rows off K agree with those on it, which
    the contact rows and the belt do (a side's contact rows repeat its belt row); where they do not (an
    inconsistent set: the heading task beside the sticking wheels' lateral rows) returns False, ``out`` untouched
    unless it is ``force``, for the caller's least squares. Cheaper than the normal equations of ``_solve`` with
    few rows. ``scaled``, ``misfit``, ``solution``: scratch (7, count and rank long); ``force`` is read before
    ``out`` is written (they may be one array)."""
    _transposed_factor_times(factor, force, scaled)
    for r in range(count):
        value = rhs[r] if with_rhs else 0.0
        for j in range(DOF):
            value -= matrix[r, j] * scaled[j]
        misfit[r] = value
    _pivoted_solve(lower, order, rank, misfit, solution)
    if with_rhs:  # b - B s lies in B's range when b = 0
        for d in range(count):
            if kept[d] == 0:
                reached, size = 0.0, abs(misfit[d])
                for a in range(rank):
                    along = gram[d, order[a]]  # B_d . B_a
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


_pivoted_cholesky = jit(_pivoted_cholesky, inline="always")
_pivoted_solve = jit(_pivoted_solve, inline="always")
_prepare_rows = jit(_prepare_rows)
_projected = jit(_projected, inline="always")
