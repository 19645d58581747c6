"""The Udwadia-Kalaba acceleration of N robots at once (``constrained_acceleration`` over a batch).

    qdd = a + W B+ (b - A a),   a = M^-1 Q,   B = A W,   W W^T = M^-1

B+ r is the minimum-norm least-squares solution, found robot by robot without a LAPACK call per
robot: the normal equations B^T B x = B^T r on the columns of B that are independent (an unpivoted
Cholesky that skips the columns whose pivot falls below a cut), then the null space of B removed
from that basic solution. A consistent set gives its exact solution, an inconsistent one the
least-squares compromise, and redundant rows are ignored, as in the single-robot solver.
"""

from __future__ import annotations

import numpy as np

_RELATIVE_CUTOFF = 1e-11
"""Cut on the Cholesky pivots of B^T B, relative to its largest diagonal entry: a column whose pivot
falls below counts as dependent on the earlier ones. The pivots square B's singular values, so this
drops directions below ~3e-6 of B's largest. Exactly redundant rows leave pivots at round-off
(~1e-16 relative); the robot's independent directions stay far above (~1e-5 for the full set)."""


def batch_constrained_acceleration(inverse_factor: np.ndarray, force: np.ndarray, rows: np.ndarray,
                                   rhs: np.ndarray) -> np.ndarray:
    """qdd (N, 7) from W (N, 7, 7), Q (N, 7), A (N, k, 7) and b (N, k)."""
    free = stacked_product(inverse_factor, stacked_product(np.swapaxes(inverse_factor, 1, 2), force))
    if rows.shape[1] == 0:
        return free
    correction = minimum_norm_least_squares(rows @ inverse_factor, rhs - stacked_product(rows, free))
    return free + stacked_product(inverse_factor, correction)


def minimum_norm_least_squares(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x (N, n) minimizing |x| among the minimizers of |B x - r|, for B (N, k, n) and r (N, k)."""
    gram = np.swapaxes(matrix, 1, 2) @ matrix
    moment = stacked_product(np.swapaxes(matrix, 1, 2), rhs)
    kept = independent_columns(gram)
    if kept.all():
        return np.linalg.solve(gram, moment[..., None])[..., 0]
    size = gram.shape[-1]
    both_kept = kept[:, :, None] & kept[:, None, :]
    identity = np.eye(size, dtype=bool)
    reduced = np.where(both_kept, gram, identity)  # the kept block, identity on the skipped columns
    # One solve gives the basic solution (zero on the skipped columns) and, for every skipped
    # column j, the combination of kept columns that reproduces it: null vector e_j - that.
    right = np.concatenate((moment[:, :, None], np.where(kept[:, :, None], gram, 0.0)), axis=2)
    solved = np.linalg.solve(reduced, np.where(kept[:, :, None], right, 0.0))
    basic = solved[:, :, 0]
    null = np.where(kept[:, None, :], 0.0, identity - solved[:, :, 1:])
    null_gram = np.swapaxes(null, 1, 2) @ null + np.where(identity & kept[:, None, :], 1.0, 0.0)
    shift = np.linalg.solve(null_gram, stacked_product(np.swapaxes(null, 1, 2), basic)[..., None])[..., 0]
    return basic - stacked_product(null, shift)


def independent_columns(gram: np.ndarray) -> np.ndarray:
    """(N, n) bool: the columns of B that the unpivoted Cholesky of B^T B keeps, in order."""
    count, size = gram.shape[0], gram.shape[-1]
    scale = _RELATIVE_CUTOFF * np.max(np.diagonal(gram, axis1=1, axis2=2), axis=1)
    factor = np.zeros_like(gram)
    kept = np.zeros((count, size), dtype=bool)
    for j in range(size):
        column = gram[:, j:, j] - stacked_product(factor[:, j:, :j], factor[:, j, :j])
        pivot = column[:, 0]
        keep = pivot > scale
        kept[:, j] = keep
        root = np.sqrt(np.where(keep, pivot, 1.0))
        factor[:, j:, j] = np.where(keep[:, None], column / root[:, None], 0.0)
    return kept


def stacked_product(matrix: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """M v for stacked M (N, r, c) and v (N, c)."""
    return np.einsum('nrc,nc->nr', matrix, vector)
