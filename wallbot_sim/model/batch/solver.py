"""The Udwadia-Kalaba acceleration of N robots at once (``constrained_acceleration`` over a batch).

    qdd = a + W B+ (b - A a),   a = M^-1 Q,   B = A W,   W W^T = M^-1

B+ r is the minimum-norm least-squares solution, found robot by robot without a LAPACK call per
robot: the normal equations B^T B x = B^T r, solved by Cholesky when every robot's B is safely of
full column rank; otherwise on the columns of B that a pivoted (rank-revealing) Cholesky finds
independent, then the null space of B removed from that basic solution. A consistent set gives its exact solution, an inconsistent one the
least-squares compromise, and redundant rows are ignored, as in the single-robot solver.
The normal equations square B's condition number: the batch agrees with the single solver to
~1e-16 cond(B)^2 relative, 1e-11 for the robot of config/robot.yaml under the full set (cond 300).
"""

from __future__ import annotations

import numpy as np

RANK_CUTOFF = 1e-11
"""Rank cut on the pivots of B^T B, relative to its largest diagonal entry. The pivots square B's
singular values, so this drops directions below ~3e-6 of B's largest. Exactly redundant rows leave
pivots at round-off (~1e-16 relative); the robot's independent directions stay far above (~1e-5
for the full constraint set)."""
WELL_CONDITIONED = 1e-6
"""The smallest unpivoted Cholesky pivot of B^T B (relative) for which a batch takes the plain solve."""


def batch_constrained_acceleration(inverse_factor: np.ndarray, force: np.ndarray, rows: np.ndarray,
                                   rhs: np.ndarray) -> np.ndarray:
    """qdd (N, 7) from W (N, 7, 7), Q (N, 7), A (N, k, 7) and b (N, k): qdd = W (W^T Q + B+ (b - B W^T Q))."""
    scaled_force = stacked_product(np.swapaxes(inverse_factor, 1, 2), force)
    if rows.shape[1] > 0:
        matrix = rows @ inverse_factor
        scaled_force = scaled_force + minimum_norm_least_squares(matrix, rhs - stacked_product(matrix, scaled_force))
    return stacked_product(inverse_factor, scaled_force)


def minimum_norm_least_squares(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x (N, n) minimizing |x| among the minimizers of |B x - r|, for B (N, k, n) and r (N, k)."""
    gram = np.swapaxes(matrix, 1, 2) @ matrix
    moment = stacked_product(np.swapaxes(matrix, 1, 2), rhs)
    lower, pivots = _cholesky(gram)
    floor = WELL_CONDITIONED * np.max(np.diagonal(gram, axis1=1, axis2=2), axis=1)
    if np.all(pivots > floor):
        # Every robot's B is safely of full column rank: an unpivoted Cholesky does not reveal rank
        # below that floor, so a batch with any smaller pivot goes the rank-revealing way.
        return _substitute(lower, moment.T[:, None, :])[:, 0, :].T
    kept = independent_columns(gram)
    size = gram.shape[-1]
    both_kept = kept[:, :, None] & kept[:, None, :]
    identity = np.eye(size, dtype=bool)
    reduced = np.where(both_kept, gram, identity)  # the kept block, identity on the skipped columns
    # One solve gives the basic solution (zero on the skipped columns) and, for every skipped
    # column j, the combination of kept columns that reproduces it: null vector e_j - that.
    right = np.concatenate((moment[:, :, None], gram), axis=2) * kept[:, :, None]
    solved = _positive_definite_solve(reduced, right)
    basic = solved[:, :, 0]
    null = np.where(kept[:, None, :], 0.0, identity - solved[:, :, 1:])
    null_gram = np.swapaxes(null, 1, 2) @ null + (identity & kept[:, None, :])
    shift = _positive_definite_solve(null_gram, stacked_product(np.swapaxes(null, 1, 2), basic)[:, :, None])
    return basic - stacked_product(null, shift[:, :, 0])


def _positive_definite_solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """X (N, n, m) with M X = R for stacked positive definite M (N, n, n)."""
    lower, pivots = _cholesky(matrix)
    if not np.all(pivots > 0.0):  # positive definite in exact arithmetic, not quite in round-off
        return np.linalg.solve(matrix, rhs)
    return np.moveaxis(_substitute(lower, np.moveaxis(rhs, 0, -1)), -1, 0)


def _cholesky(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """L (n, n, N), batch last, with L L^T = M for stacked symmetric M (N, n, n); and the pivots L_jj^2 (N,).

    Unpivoted; a pivot that is not positive leaves NaN in L (the caller looks at the pivots).
    Batch last, every entry is one contiguous vector over the robots: several times faster than
    numpy.linalg.cholesky's loop over 7x7 matrices.
    """
    size = matrix.shape[-1]
    upper = np.moveaxis(matrix, 0, -1)
    lower = np.zeros(upper.shape)
    smallest = np.full(matrix.shape[0], np.inf)
    for j in range(size):
        column = upper[j:, j] - np.einsum('kr,ikr->ir', lower[j, :j], lower[j:, :j])
        smallest = np.fmin(smallest, column[0])
        with np.errstate(invalid='ignore', divide='ignore'):
            lower[j:, j] = column / np.sqrt(column[0])
    return lower, smallest


def _substitute(lower: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """X (n, m, N) with L L^T X = R, all batch last: forward then back substitution."""
    size = lower.shape[0]
    solution = rhs.copy()
    for j in range(size):
        solution[j] -= np.einsum('kr,kcr->cr', lower[j, :j], solution[:j])
        solution[j] /= lower[j, j]
    for j in reversed(range(size)):
        solution[j] -= np.einsum('kr,kcr->cr', lower[j + 1:, j], solution[j + 1:])
        solution[j] /= lower[j, j]
    return solution


def independent_columns(gram: np.ndarray) -> np.ndarray:
    """(N, n) bool: a largest set of columns of B independent beyond the cut, for every robot.

    Cholesky of B^T B with diagonal pivoting (rank revealing, as the single solver's pivoted QR):
    the largest remaining pivot is taken until none is above the cut.
    """
    count, size = gram.shape[0], gram.shape[-1]
    diagonal = np.arange(size)
    schur = np.moveaxis(gram, 0, -1).copy()  # (n, n, N), batch last as in _cholesky
    cut = RANK_CUTOFF * np.max(schur[diagonal, diagonal], axis=0)
    kept = np.zeros((size, count), dtype=bool)
    for _ in range(size):
        pivots = np.where(kept, -np.inf, schur[diagonal, diagonal])
        best = np.argmax(pivots, axis=0)
        pivot = np.take_along_axis(pivots, best[None], axis=0)[0]
        take = pivot > cut
        if not take.any():
            break
        kept[best[take], np.flatnonzero(take)] = True
        column = np.take_along_axis(schur, best[None, None, :], axis=1)[:, 0, :]
        column *= take / np.sqrt(np.where(take, pivot, 1.0))
        schur -= column[:, None, :] * column[None, :, :]
    return kept.T


def stacked_product(matrix: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """M v for stacked M (N, r, c) and v (N, c)."""
    # as the row vectors v^T M^T: numpy's stacked matrix-vector product is several times slower
    return (vector[:, None, :] @ np.swapaxes(matrix, 1, 2))[:, 0]
