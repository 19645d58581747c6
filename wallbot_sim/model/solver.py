"""The Udwadia-Phohomsiri equation (MODEL.md section 6).

    qdd = [ (I - A+ A) M ; A ]+ [ (I - A+ A) Q ; b ],   Q_c = M qdd - Q

``solve`` uses the general form, valid for a singular M. When M is positive definite the
same qdd is the Udwadia-Kalaba form qdd = a + M^-1 A^T (A M^-1 A^T)+ (b - A a), a = M^-1 Q,
which needs one small symmetric eigen-decomposition instead of two pseudo-inverses:
``solve_with_inverse`` takes that route. Both give the least-squares compromise on an
inconsistent set and ignore redundant rows.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.linalg.lapack import dsyevd as _symmetric_eigen

_RELATIVE_EIGEN_CUTOFF = 1e-12
"""Eigenvalues of A M^-1 A^T below this fraction of the largest are treated as zero.

A M^-1 A^T = B B^T with B = A M^-1/2, so its eigenvalues are squared singular values of B:
round-off puts the zero ones near 1e-16 of the largest, far below this cut.
"""


class ConstrainedMotion(NamedTuple):
    """The solution at one state."""

    acceleration: np.ndarray
    """qdd (7,)."""
    constraint_force: np.ndarray
    """Q_c = M qdd - Q (7,): (F_X, F_Y, M_Z) on the chassis, then the wheel torques."""
    residual: float
    """|A qdd - b|: zero for a consistent set, the least-squares misfit otherwise."""


def solve(mass: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> ConstrainedMotion:
    """The general Udwadia-Phohomsiri equation with two pseudo-inverses (any M, any A)."""
    if rows.shape[0] == 0:
        acceleration = np.linalg.pinv(mass) @ force
    else:
        null_projector = np.eye(mass.shape[0]) - np.linalg.pinv(rows) @ rows
        stacked = np.vstack((null_projector @ mass, rows))
        acceleration = np.linalg.pinv(stacked) @ np.concatenate((null_projector @ force, rhs))
    return _motion(mass, force, rows, rhs, acceleration)


def solve_with_inverse(mass: np.ndarray, mass_inverse: np.ndarray, force: np.ndarray,
                       rows: np.ndarray, rhs: np.ndarray) -> ConstrainedMotion:
    """The same qdd for a positive definite M whose inverse is known."""
    return _motion(mass, force, rows, rhs, constrained_acceleration(mass_inverse, force, rows, rhs))


def constrained_acceleration(mass_inverse: np.ndarray, force: np.ndarray, rows: np.ndarray,
                             rhs: np.ndarray) -> np.ndarray:
    """qdd = a + M^-1 A^T (A M^-1 A^T)+ (b - A a) alone: what an integrator needs."""
    free = mass_inverse @ force
    if rows.shape[0] == 0:
        return free
    weighted = mass_inverse @ rows.T
    eigenvalues, eigenvectors, info = _symmetric_eigen(rows @ weighted)
    if info != 0:
        raise np.linalg.LinAlgError(f'eigen-decomposition of A M^-1 A^T failed (LAPACK info {info})')
    keep = eigenvalues > _RELATIVE_EIGEN_CUTOFF * eigenvalues[-1]
    basis = eigenvectors[:, keep]
    return free + weighted @ (basis @ ((basis.T @ (rhs - rows @ free)) / eigenvalues[keep]))


def _motion(mass: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray,
            acceleration: np.ndarray) -> ConstrainedMotion:
    misfit = rows @ acceleration - rhs
    residual = math.sqrt(float(misfit @ misfit))
    return ConstrainedMotion(acceleration, mass @ acceleration - force, residual)
