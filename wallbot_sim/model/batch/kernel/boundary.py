"""One stick/slip set's solve at a step boundary (``CoulombContact._solve``): the motion under the sticking wheels'
rows, the sliding wheels' friction and the loads, the load-weighted split of the sticking wheels' force, and the
switch projection of a wheel that sticks again."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.batch.kernel.dynamics import _constraint_force
from wallbot_sim.model.batch.kernel.frame import _frame_responses, _frame_rows, _frame_solve, _sliding_responses
from wallbot_sim.model.batch.kernel.friction import (
    _affine_acceleration, _contact_row, _kinetic, _load_gain, _normal_loads)
from wallbot_sim.model.batch.kernel.layout import (
    ADHESION, BELT, CONSTRAINT, DIRECTION_OF, DRIFT, ERROR, FORCES, FRICTION, GAIN, HELD_BY, KINETIC, LOADS, MADE,
    NEWTON_PREDICTED, NON_LATERAL, NONSLIP, ORIGIN, PREDICTED, QDD, REDUCED, RESIDUAL, RESIDUALS, ROLLING, ROW_LOADS,
    SLIP, SLIP_ROWS, SOLVED, SPLIT, SPLIT_CUT, SPLIT_KEPT, SPLIT_LOWER, SPLIT_PIVOTS, SPLIT_X, STATE, STATUS, STICKING,
    STUCK_ROWS, TANGENT_HEADING, TOTAL, TRAJECTORY, VELOCITY, WHEEL_OF, ZERO)
from wallbot_sim.model.batch.kernel.linalg import _dot, _factor_times, _least_squares, _minimum_norm, _scaled_rows
from wallbot_sim.model.batch.kernel.problem import _factor_of, _problem
from wallbot_sim.model.batch.kernel.row_space import _pivoted_cholesky, _pivoted_solve
from wallbot_sim.model.robot import DOF


def _reduce(flags: np.ndarray, vector: np.ndarray, out: np.ndarray) -> int:
    """U^T v into ``out`` for U a basis of the velocities the other modules' rows annul (the tasks' unit rows, the
    belt's pd1 = pd2 and pd3 = pd4); the basis' size. U need not be orthonormal: the split below is the same for
    any basis of that space."""
    size = 0
    if not flags[TRAJECTORY]:
        out[0], out[1] = vector[0], vector[1]
        size = 2
    if not (flags[TRAJECTORY] or flags[TANGENT_HEADING]):
        out[size] = vector[2]
        size += 1
    if flags[BELT]:
        out[size], out[size + 1] = vector[3] + vector[4], vector[5] + vector[6]
        return size + 2
    for j in range(3, DOF):
        out[size] = vector[j]
        size += 1
    return size


def _split(count: int, flags: np.ndarray, force: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
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
    pivots = ints[SPLIT_PIVOTS]
    rank = _pivoted_cholesky(system, size, SPLIT_CUT * largest, pivots, ints[SPLIT_KEPT], lower)
    _pivoted_solve(lower, pivots, rank, target, x)
    for k in range(count):
        weight = loads[k] if loads[k] > 0.0 else 0.0
        value = 0.0
        for a in range(rank):
            value += made[pivots[a], k] * x[a]
        out[k] = weight * value


def _responded(cos_t: float, sin_t: float, flags: np.ndarray, factor: np.ndarray, force: np.ndarray,
               rhs: np.ndarray, with_rhs: bool, count: int, rank: int, rows: np.ndarray, matrix: np.ndarray,
               gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray,
               ints: np.ndarray, zero: np.ndarray, out: np.ndarray) -> None:
    """qdd under ``force`` and the rows (b = 0 unless ``with_rhs``) by ``_frame_solve`` after ``_frame_rows``, or by
    ``_solve``'s least squares where the rows disagree: one column of ``constrained_acceleration``."""
    if not _frame_solve(cos_t, sin_t, flags, factor, force, rhs, with_rhs, count, rank, mats, ints, vectors, out):
        _least_squares(factor, force, rows, rhs if with_rhs else zero, count, matrix, gram, lower, vectors, scratch,
                       out)


# Long on purpose: a boundary's set-up (rows, the response to each column) and its outputs from Newton's result
# share ~20 scratch arrays in one compiled frame (numba) instead of passing them through calls; Newton (_kinetic)
# and the split (_split) are its own calls.
def _boundary(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
              torque: np.ndarray, dt: float, sliding: np.ndarray, start: np.ndarray, held: np.ndarray, rows: np.ndarray,
              rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray,
              vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
              marks: np.ndarray, columns: np.ndarray, responses: np.ndarray, solution: np.ndarray) -> int:
    """The motion at y with the ``sliding`` wheels sliding (``CoulombContact._solve``) into ``solution``: their
    friction and every wheel's load solved together from the ``start`` loads and the ``held`` friction (``_kinetic``),
    the motion under them, the sticking wheels' split of the constraint force; an error code (``CONTACT_ERRORS``)."""
    q, qd = y[:DOF], y[DOF:]
    frictional = flags[NON_LATERAL] or flags[NONSLIP]
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
            if frictional and sliding[wheel] and flags[HELD_BY[direction]]:
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
    rank = _frame_rows(q, qd, reference, flags, constants, sticking, rows, factor, count, mats, ints)
    _responded(cos_t, sin_t, flags, factor, unloaded, rhs, True, count, rank, rows, matrix, gram, lower, vectors,
               scratch, mats, ints, zero, responses[0])
    kept_blocks = _sliding_responses(cos_t, sin_t, flags, constants, contact, dt, sliders, mats, ints, responses)
    first = 1 + sliders if kept_blocks else 1  # the loads' responses, and the sliders' unless kept
    _frame_responses(cos_t, sin_t, flags, factor, columns, first, 1 + sliders + 4, count, rank, mats, ints, vectors,
                     responses)  # b = 0: consistent
    _normal_loads(q, qd, zero, constants, contact, True, vecs[ORIGIN])
    _load_gain(theta, constants, contact, mats[GAIN])
    v_long, v_lat = cos_t * qd[0] + sin_t * qd[1], -sin_t * qd[0] + cos_t * qd[1]
    for k in range(sliders):
        vecs[SLIP, k] = _dot(slip_rows[k], qd, DOF)
        vecs[DRIFT, k] = thd * v_lat if direction_of[k] == 0 else -thd * v_long
    error = _kinetic(sliders, responses, mats, vecs, ints, contact[KINETIC], math.sqrt(eps2), dt, start, held,
                     contact[ADHESION], solution, kept_blocks)
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
    _affine_acceleration(sliders, responses, state, acceleration)  # qdd is affine in Q: the solve of ``total``
    constraint = solution[CONSTRAINT]
    solution[STATUS, RESIDUAL] = _constraint_force(theta, constants, acceleration, total, rows, rhs, count, constraint)
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
            if sticking[wheel] and flags[HELD_BY[direction]]:
                _contact_row(cos_t, sin_t, constants, wheel, direction, stuck_rows[stuck])
                row_loads[stuck] = loads[wheel]
                stuck += 1
    if stuck:
        split = vecs[RESIDUALS]
        _split(stuck, flags, constraint, mats, vecs, ints, split)
        stuck = 0
        for wheel in range(4):
            for direction in range(2):
                if sticking[wheel] and flags[HELD_BY[direction]]:
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
    if flags[BELT]:
        for r in range(2):
            for j in range(DOF):
                rows[r, j] = 0.0
        rows[0, 3], rows[0, 4], rows[1, 5], rows[1, 6] = 1.0, -1.0, 1.0, -1.0
        count = 2
    for wheel in range(4):
        for direction in range(2):
            if sticking[wheel] and flags[HELD_BY[direction]]:
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


_responded = jit(_responded, inline="always")
_reduce = jit(_reduce, inline="always")
_split = jit(_split, inline="always")
_inline_boundary = jit(_boundary, inline="always")
"""``_boundary`` compiled into its caller: for the boundary every step begins with (``_settle``'s first), where a
call would pass its ~25 arrays field by field; the transitions' boundaries, rarer, call the one ``_boundary``."""
_boundary = jit(_boundary)
_project_onto = jit(_project_onto)
