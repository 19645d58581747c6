"""The frame coulomb contact's solves run in: the chassis' body axes, where the rows and the mass matrix are
constant, so that a stick/slip set's rows are factored once while the set holds instead of at every solve.

With T the rotation of the chassis' (x, y) by theta (the spins unturned), every contact row, the belt's and the
heading task's satisfy A(theta) T = A(0), and M(theta) = T M(0) T^T. T W(0) is then a factor of M(theta)^-1 and
B = A(theta) T W(0) = A(0) W(0) depends on the sticking set alone. The Udwadia-Kalaba motion is the same for any
factor of M^-1 (replacing W by W U, U orthogonal, gives (B U)+ = U^T B+), so qdd = T W(0) (s + B+ (b - B s)),
s = W(0)^T T^T Q: the force turned into the body axes, the constant problem solved, the motion turned back. A
force's response with b = 0 (a sliding component's, a load's) is then a constant matrix's product, T P T^T f with
P = W(0) (I - B+ B) W(0)^T, kept with the set's factorization. The sliding wheels' contact rows and the loads' gain
turn the same way (J_S = J_S(0) T^T, L = L(0) T^T), so the friction's responses T P J_S(0)^T and Newton's blocks
dt J_S D = dt J_S(0) P J_S(0)^T and L D = L(0) P J_S(0)^T are the set's constants too. The trajectory task's rows
are fixed in the world instead: with it the world's rows are factored at every solve.
"""

from __future__ import annotations

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.batch.kernel.friction import _contact_row, _load_gain
from wallbot_sim.model.batch.kernel.layout import (
    DIRECTION_OF, FRAME, FRAME_FACTOR, FRAME_GRAM, FRAME_MATRIX, FRAME_PROJECTION, FRAME_ROWS, FRAME_SCRATCH,
    LOAD_BY_FRICTION, ROW_FACTOR, ROW_KEPT, ROW_ORDER, ROW_SYSTEM, SLIDING_MOTION, SLIP_BY_FRICTION, TRAJECTORY,
    WHEEL_OF)
from wallbot_sim.model.batch.kernel.problem import _factor_of, _module_rows
from wallbot_sim.model.batch.kernel.row_space import _prepare_rows, _projected
from wallbot_sim.model.robot import DOF

KEY, RANK, SLID = range(3)
"""ints[FRAME]: the sticking set whose rows are factored (0: none, else 1 + its wheels as bits), their rank, and the
set whose sliding components' responses and blocks are kept (``_sliding_responses``)."""


def _into_body(cos_t: float, sin_t: float, force: np.ndarray, out: np.ndarray) -> None:
    """T^T Q into ``out``: the chassis' force components turned into the body axes at heading theta."""
    out[0], out[1] = cos_t * force[0] + sin_t * force[1], -sin_t * force[0] + cos_t * force[1]
    for j in range(2, DOF):
        out[j] = force[j]


def _into_world(cos_t: float, sin_t: float, motion: np.ndarray) -> None:
    """T qdd in place: the chassis' acceleration components turned back into the world's axes."""
    along, across = motion[0], motion[1]
    motion[0], motion[1] = cos_t * along - sin_t * across, sin_t * along + cos_t * across


def _frame_rows(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                sticking: np.ndarray, rows: np.ndarray, factor: np.ndarray, count: int, mats: np.ndarray,
                ints: np.ndarray) -> int:
    """The factored rows ``_frame_solve`` solves with, for the ``count`` rows ``rows`` and factor ``factor`` that
    ``_problem`` gave at (q, qd) with the ``sticking`` wheels; their rank. In the body axes (no trajectory task) the
    set's rows are factored once, with the responses' matrix P, and kept in the workspace (mats[FRAME_*],
    ints[FRAME]) while the set holds; with the task, the world's rows are factored each time."""
    if flags[TRAJECTORY]:
        ints[FRAME, KEY] = 0
        return _prepare_rows(rows, factor, count, mats[FRAME_MATRIX], mats[FRAME_GRAM], mats[ROW_SYSTEM],
                             mats[ROW_FACTOR], ints[ROW_ORDER], ints[ROW_KEPT])
    key = 1
    for wheel in range(4):
        if sticking[wheel]:
            key += 1 << wheel
    if ints[FRAME, KEY] == key:
        return ints[FRAME, RANK]
    return _factor_frame(q, qd, reference, flags, constants, sticking, count, key, mats, ints)


def _factor_frame(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                  sticking: np.ndarray, count: int, key: int, mats: np.ndarray, ints: np.ndarray) -> int:
    """``_frame_rows``' factoring of a new sticking set (``key``: 1 + its wheels as bits) in the body axes, kept in
    the workspace; its rank."""
    body_rows, scratch = mats[FRAME_ROWS], mats[FRAME_SCRATCH]
    for i in range(16):
        scratch[2, i] = 0.0
    _module_rows(q, qd, reference, flags, constants, 1.0, 0.0, True, sticking, scratch[2], body_rows, scratch[0],
                 scratch[1])  # A(0): only the rows are kept
    _factor_of(0.0, constants, mats[FRAME_FACTOR])
    rank = _prepare_rows(body_rows, mats[FRAME_FACTOR], count, mats[FRAME_MATRIX], mats[FRAME_GRAM],
                         mats[ROW_SYSTEM], mats[ROW_FACTOR], ints[ROW_ORDER], ints[ROW_KEPT])
    ints[FRAME, KEY], ints[FRAME, RANK] = key, rank
    projection, unit = mats[FRAME_PROJECTION], scratch[3]
    for j in range(DOF):  # P = W (I - B_K^T (B_K B_K^T)^-1 B_K) W^T, column by column: the motion under e_j, b = 0
        for i in range(DOF):
            unit[i] = 1.0 if i == j else 0.0
        _projected(mats[FRAME_FACTOR], unit, unit, False, mats[FRAME_MATRIX], mats[FRAME_GRAM], count, rank,
                   ints[ROW_ORDER], ints[ROW_KEPT], mats[ROW_FACTOR], scratch[4], scratch[5], scratch[6], scratch[7])
        for i in range(DOF):
            projection[i, j] = scratch[7, i]
    return rank


def _frame_solve(cos_t: float, sin_t: float, flags: np.ndarray, factor: np.ndarray, force: np.ndarray,
                 rhs: np.ndarray, with_rhs: bool, count: int, rank: int, mats: np.ndarray, ints: np.ndarray,
                 vectors: np.ndarray, out: np.ndarray) -> bool:
    """qdd under ``force`` and the rows factored by ``_frame_rows`` (b = 0 unless ``with_rhs``), as ``_projected``
    gives it in the world, at heading theta (cos_t, sin_t); False where the rows disagree (``out`` then
    scratch)."""
    if flags[TRAJECTORY]:
        return _projected(factor, force, rhs, with_rhs, mats[FRAME_MATRIX], mats[FRAME_GRAM], count, rank,
                          ints[ROW_ORDER], ints[ROW_KEPT], mats[ROW_FACTOR], vectors[1], vectors[2], vectors[3], out)
    _into_body(cos_t, sin_t, force, out)
    if not _projected(mats[FRAME_FACTOR], out, rhs, with_rhs, mats[FRAME_MATRIX], mats[FRAME_GRAM], count, rank,
                      ints[ROW_ORDER], ints[ROW_KEPT], mats[ROW_FACTOR], vectors[1], vectors[2], vectors[3], out):
        return False
    _into_world(cos_t, sin_t, out)
    return True


def _frame_responses(cos_t: float, sin_t: float, flags: np.ndarray, factor: np.ndarray, forces: np.ndarray,
                     first: int, end: int, count: int, rank: int, mats: np.ndarray, ints: np.ndarray,
                     vectors: np.ndarray, out: np.ndarray) -> None:
    """``_frame_solve`` with b = 0 of each force ``forces[c]`` into ``out[c]``, c = first..end - 1 (always
    consistent: b - B s = -B s lies in B's range): in the body axes T P T^T f by the set's P of ``_frame_rows``,
    P being the same for every force."""
    if flags[TRAJECTORY]:
        for column in range(first, end):
            _frame_solve(cos_t, sin_t, flags, factor, forces[column], forces[column], False, count, rank, mats,
                         ints, vectors, out[column])
        return
    projection, turned = mats[FRAME_PROJECTION], vectors[1]
    for column in range(first, end):
        _into_body(cos_t, sin_t, forces[column], turned)
        motion = out[column]
        for i in range(DOF):
            value = 0.0
            for j in range(DOF):
                value += projection[i, j] * turned[j]
            motion[i] = value
        _into_world(cos_t, sin_t, motion)


def _sliding_responses(cos_t: float, sin_t: float, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
                       dt: float, sliders: int, mats: np.ndarray, ints: np.ndarray, responses: np.ndarray) -> bool:
    """After ``_frame_rows``, in the body axes: each sliding component's response (D's columns, T P J_S(0)^T) into
    ``responses[1..sliders]`` and Newton's blocks dt J_S D and -L D into mats[SLIP_BY_FRICTION] and
    mats[LOAD_BY_FRICTION], those computed once while the set holds (its components in ints[WHEEL_OF],
    ints[DIRECTION_OF]). False with the trajectory task: the caller computes them in the world's axes."""
    if flags[TRAJECTORY]:
        return False
    kept, scratch = mats[SLIDING_MOTION], mats[FRAME_SCRATCH]
    if ints[FRAME, SLID] != ints[FRAME, KEY]:
        projection, gain = mats[FRAME_PROJECTION], scratch[:4]
        _load_gain(0.0, constants, contact, gain)  # L(0); J_S(0)'s rows in scratch[8:]
        for k in range(sliders):
            row = scratch[8 + k]
            _contact_row(1.0, 0.0, constants, ints[WHEEL_OF, k], ints[DIRECTION_OF, k], row)
            for i in range(DOF):
                value = 0.0
                for j in range(DOF):
                    value += projection[i, j] * row[j]
                kept[k, i] = value
        for column in range(sliders):
            for k in range(sliders):
                value = 0.0
                for j in range(DOF):
                    value += scratch[8 + k, j] * kept[column, j]
                mats[SLIP_BY_FRICTION, k, column] = dt * value
            for wheel in range(4):
                value = 0.0
                for j in range(DOF):
                    value += -gain[wheel, j] * kept[column, j]
                mats[LOAD_BY_FRICTION, wheel, column] = value
        ints[FRAME, SLID] = ints[FRAME, KEY]
    for k in range(sliders):
        motion = responses[1 + k]
        for i in range(DOF):
            motion[i] = kept[k, i]
        _into_world(cos_t, sin_t, motion)
    return True


_into_body = jit(_into_body, inline="always")
_into_world = jit(_into_world, inline="always")
_frame_rows = jit(_frame_rows, inline="always")  # every solve's check; the factoring, rare, stays a call
_factor_frame = jit(_factor_frame)
_frame_solve = jit(_frame_solve, inline="always")
_frame_responses = jit(_frame_responses, inline="always")
_sliding_responses = jit(_sliding_responses, inline="always")
