"""The Udwadia-Phohomsiri equation (docs/model.md section 6).

    qdd = [ (I - A+ A) M ; A ]+ [ (I - A+ A) Q ; b ],   Q_c = M qdd - Q

``solve`` uses the general form, valid for a singular M. When M is positive definite the
same qdd is the Udwadia-Kalaba form qdd = a + M^-1 A^T (A M^-1 A^T)+ (b - A a), a = M^-1 Q,
which needs one small least-squares solve instead of two pseudo-inverses:
``solve_with_factor`` and ``constrained_acceleration`` take that route. Both give the
least-squares compromise on an inconsistent set and ignore redundant rows.
"""

from __future__ import annotations

import functools
import math
from typing import Callable, NamedTuple

import numpy as np

_RELATIVE_CUTOFF = 1e-10
"""Rank cut of A M^-1/2: directions whose pivoted-QR diagonal falls below this fraction of the
largest count as redundant. Exactly redundant rows leave them at round-off, ~1e-16 of the largest;
the robot's independent rows stay far above the cut.
"""
_lwork: dict[tuple[int, int], int] = {}
"""LAPACK workspace size of dgelsy by row count and right-hand sides (n = 7 columns)."""


@functools.cache
def _lapack() -> tuple[Callable, Callable]:
    """SciPy's dgelsy and its workspace query, imported at the first solve: SciPy's linear algebra takes a third
    of a second to import, which a process that only names the model's parts (the launcher, the trajectory and
    constraint_config nodes) does not pay."""
    from scipy.linalg.lapack import dgelsy, dgelsy_lwork
    return dgelsy, dgelsy_lwork


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
    return motion_of(mass, force, rows, rhs, acceleration)


def solve_with_factor(mass: np.ndarray, inverse_factor: np.ndarray, force: np.ndarray,
                      rows: np.ndarray, rhs: np.ndarray) -> ConstrainedMotion:
    """The same qdd for a positive definite M, given W with W W^T = M^-1."""
    return motion_of(mass, force, rows, rhs, constrained_acceleration(inverse_factor, force, rows, rhs))


def constrained_acceleration(inverse_factor: np.ndarray, force: np.ndarray, rows: np.ndarray,
                             rhs: np.ndarray) -> np.ndarray:
    """qdd alone (what an integrator needs), given any W with W W^T = M^-1.

    With B = A W, qdd = a + W B+ (b - A a): the Udwadia-Kalaba form, whose M^-1/2 may be any
    such factor since qdd - a is the M-norm-smallest least-squares solution either way.
    B+ (b - A a) is the minimum-norm least-squares solution of one small LAPACK call (dgelsy:
    QR with column pivoting, then a complete orthogonal factorization of the rank found).

    ``force`` (7, m) with ``rhs`` (k, m) solves m problems on the same rows in that one call
    (qdd (7, m)): the response of the motion to several forces at once.
    """
    free = inverse_factor @ (inverse_factor.T @ force)
    count, size = rows.shape
    if count == 0:
        return free
    misfit = rhs - rows @ free
    if count < size:
        misfit = np.concatenate((misfit, np.zeros((size - count, *misfit.shape[1:]))))
    columns = 1 if misfit.ndim == 1 else misfit.shape[1]
    least_squares, least_squares_lwork = _lapack()
    work = _lwork.get((count, columns))
    if work is None:
        work = _lwork[count, columns] = int(least_squares_lwork(count, size, columns, _RELATIVE_CUTOFF)[0])
    _, solution, _, _, info = least_squares(rows @ inverse_factor, misfit, np.zeros(size, dtype=np.int32),
                                            _RELATIVE_CUTOFF, work)
    if info != 0:
        raise np.linalg.LinAlgError(f'least-squares solve of A M^-1/2 failed (LAPACK info {info})')
    return free + inverse_factor @ solution[:size]


def motion_of(mass: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray,
              acceleration: np.ndarray) -> ConstrainedMotion:
    """The solution with its acceleration ``qdd`` found: Q_c and the residual."""
    misfit = rows @ acceleration - rhs
    residual = math.sqrt(float(misfit @ misfit))
    return ConstrainedMotion(acceleration, mass @ acceleration - force, residual)
