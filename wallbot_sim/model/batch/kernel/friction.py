"""Coulomb contact per wheel (docs/model.md 11.3): a wheel's contact rows, the loads' dependence on the motion
(with the wheels' spin momentum), and the sliding wheels' kinetic friction solved with the loads it holds by
Newton's method (``consistent_friction`` of the Python model): on the friction alone while every wheel stays
pressed (the loads are then affine in it), else on the friction and the loads together."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.batch.kernel.layout import (
    ACCELERATION, ADHESION, BLOCK_END, BLOCK_FIRST, BY_SLIP, DIRECTIONS, DIRECTION_OF, DRIFT, FREE_LOADS, FREE_SLIP,
    GAIN, HALF_BASE, HALF_TRACK, HEIGHT, JACOBIAN, LOAD_BY_FRICTION, LOAD_BY_LOAD, LOAD_RESPONSE, LU, NEGATIVE,
    NEWTON_ITERATIONS, NEWTON_PREDICTED, NEWTON_RESIDUAL, NEWTON_START, NEWTON_STEP, NEWTON_TOLERANCE, ORIGIN, PIVOTS,
    PRESSED, RESIDUALS, SINGULAR, SIZES, SLIP, SLIP_BY_FRICTION, SLIP_BY_LOAD, SLIP_RESPONSE, SLIP_ROWS, SOLVED,
    SQUARES, STATE, STATUS, TRIAL_JACOBIAN, TRIAL_PREDICTED, TRIAL_RESIDUALS, TRIAL_STATE, UNCONVERGED, WHEEL_OF)
from wallbot_sim.model.batch.kernel.linalg import _dot, _lu_factor, _lu_solve, _lu_substitute
from wallbot_sim.model.robot import DOF


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


def _normal_loads(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, constants: np.ndarray, contact: np.ndarray,
                  spin_momentum: bool, out: np.ndarray) -> None:
    """N_1..N_4 at (q, qd, qdd), with the wheels' spin momentum if ``spin_momentum`` (``normal_loads``)."""
    mass, spin, sx, sy, gravity = constants[0], constants[2], constants[3], constants[4], constants[5]
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    thd, thdd = qd[2], qdd[2]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    inertial_x = mass * qdd[0] - thdd * rsy - thd * thd * rsx
    inertial_y = mass * qdd[1] + thdd * rsx - thd * thd * rsy
    fx, fy = -inertial_x, -mass * gravity - inertial_y
    body_x, body_y = cos_t * fx + sin_t * fy, -sin_t * fx + cos_t * fy
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    moment_x, moment_y = h * body_x, h * body_y
    if spin_momentum:
        moment_x -= spin * (qdd[3] + qdd[4] + qdd[5] + qdd[6])
        moment_y -= spin * thd * (qd[3] + qd[4] + qd[5] + qd[6])
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


def _wheel_speeds(count: int, predicted: np.ndarray, ints: np.ndarray, epsilon: float, vecs: np.ndarray) -> None:
    """s = sqrt(|w_i|^2 + eps^2) of each component's wheel into vecs[SIZES] (``kinetic_friction._wheel_speeds``), the
    workspace indexed in place (``_kinetic_equations``)."""
    for wheel in range(4):
        vecs[SQUARES, wheel] = 0.0
    for k in range(count):
        vecs[SQUARES, ints[WHEEL_OF, k]] += predicted[k] * predicted[k]
    for k in range(count):
        vecs[SIZES, k] = math.sqrt(vecs[SQUARES, ints[WHEEL_OF, k]] + epsilon * epsilon)


def _affine_acceleration(count: int, responses: np.ndarray, state: np.ndarray, out: np.ndarray) -> None:
    """qdd = a + D f + R max(N, 0) at z = (f, N) (count + 4) from the boundary's ``responses`` (a, then D's and R's
    columns as rows) into ``out`` (7,)."""
    for j in range(DOF):
        by_friction, by_load = 0.0, 0.0
        for k in range(count):
            by_friction += responses[1 + k, j] * state[k]
        for wheel in range(4):
            load = state[count + wheel]
            by_load += responses[1 + count + wheel, j] * (load if load > 0.0 else 0.0)
        out[j] = (responses[0, j] + by_friction) + by_load


# Long on purpose: the residual and its Jacobian in one pass over Newton's state, called at every trial of the
# line search; the Jacobian reuses the residual's intermediates (qdd, the slip's directions and sizes).
def _kinetic_equations(count: int, responses: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
                       kinetic: float, epsilon: float, dt: float, state: np.ndarray, residual: np.ndarray,
                       jacobian: np.ndarray, predicted: np.ndarray) -> float:
    """The residual of z = (f, N) (count + 4), its Jacobian and the predicted slip w (``kinetic_friction._equations``);
    returns the residual's largest magnitude.

    r_f = f + mu_k max(N_i, 0) w / s,  r_N = N - N_0 - L qdd,  qdd = a + D f + R max(N, 0).

    The workspace rows are indexed in place (vecs[PRESSED, i] for N_i^+, ...), not taken as views: a view costs
    two atomic reference counts, and this runs three times a boundary.
    """
    for wheel in range(4):
        vecs[PRESSED, wheel] = state[count + wheel] if state[count + wheel] > 0.0 else 0.0
    _affine_acceleration(count, responses, state, vecs[ACCELERATION])
    size = 0.0
    for wheel in range(4):
        row = count + wheel
        gained = 0.0  # L qdd
        for j in range(DOF):
            gained += mats[GAIN, wheel, j] * vecs[ACCELERATION, j]
        residual[row] = (state[row] - vecs[ORIGIN, wheel]) - gained
        size = max(size, abs(residual[row]))
        for k in range(count):
            jacobian[row, k] = mats[LOAD_BY_FRICTION, wheel, k]
        for other in range(4):
            positive = 1.0 if state[count + other] > 0.0 else 0.0
            jacobian[row, count + other] = ((1.0 if other == wheel else 0.0)
                                            - mats[LOAD_BY_LOAD, wheel, other] * positive)
    if count == 0:
        return size
    for k in range(count):  # w = v_S + dt (J_S qdd + c_S)
        along = 0.0
        for j in range(DOF):
            along += mats[SLIP_ROWS, k, j] * vecs[ACCELERATION, j]
        predicted[k] = vecs[SLIP, k] + dt * (along + vecs[DRIFT, k])
    _wheel_speeds(count, predicted, ints, epsilon, vecs)
    for k in range(count):
        vecs[DIRECTIONS, k] = predicted[k] / vecs[SIZES, k]
    for k in range(count):
        force = kinetic * vecs[PRESSED, ints[WHEEL_OF, k]]
        residual[k] = state[k] + force * vecs[DIRECTIONS, k]
        size = max(size, abs(residual[k]))
        for p in range(ints[BLOCK_FIRST, k], ints[BLOCK_END, k]):  # d(w/s)/dw within each wheel: I/s - w w^T/s^3
            mats[BY_SLIP, k, p] = force * (((1.0 if k == p else 0.0) - vecs[DIRECTIONS, k] * vecs[DIRECTIONS, p])
                                           / vecs[SIZES, k])
    for k in range(count):
        first, end = ints[BLOCK_FIRST, k], ints[BLOCK_END, k]
        for column in range(count):
            value = 0.0
            for p in range(first, end):
                value += mats[BY_SLIP, k, p] * mats[SLIP_BY_FRICTION, p, column]
            jacobian[k, column] = (1.0 if k == column else 0.0) + value
        for wheel in range(4):
            positive = 1.0 if state[count + wheel] > 0.0 else 0.0
            value = 0.0
            for p in range(first, end):
                value += mats[BY_SLIP, k, p] * (mats[SLIP_BY_LOAD, p, wheel] * positive)
            jacobian[k, count + wheel] = value
        wheel = ints[WHEEL_OF, k]
        if state[count + wheel] > 0.0:
            jacobian[k, count + wheel] += kinetic * vecs[DIRECTIONS, k]
    return size


# Long on purpose: Newton's iteration with its line search in one compiled frame (numba): the fixed Jacobian
# blocks, the state and the trial arrays stay local to the loop instead of being passed through calls.
def _kinetic(count: int, responses: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
             kinetic: float, epsilon: float, dt: float, start: np.ndarray, held: np.ndarray, adhesion: float,
             solution: np.ndarray, kept_blocks: bool) -> int:
    """The sliding components' friction f (count) and the loads N (4) solving the boundary's equations, by Newton's
    method with a halving line search from the ``start`` loads and the ``held`` friction (8,: each wheel's (f_x, f_y),
    zero where it did not slide) (``consistent_friction``): f and N into vecs[STATE],
    the predicted slip into vecs[NEWTON_PREDICTED]; an error code (``CONTACT_ERRORS``), the residual it stopped
    at in solution[STATUS, NEWTON_RESIDUAL]. ``kept_blocks``: the blocks dt J_S D and -L D are in mats already."""
    size_of = count + 4
    slip_rows, gain = mats[SLIP_ROWS], mats[GAIN]
    # the blocks of the Jacobian that do not change: dt J_S D, dt J_S R, -L D, L R
    for k in range(count):
        for column in range(0 if kept_blocks else count):
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
        for column in range(0 if kept_blocks else count):
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
    wheel_of, direction_of, first, end = ints[WHEEL_OF], ints[DIRECTION_OF], ints[BLOCK_FIRST], ints[BLOCK_END]
    for k in range(count):  # a wheel's components are consecutive; d(w/s)/dw couples them alone
        first[k] = first[k - 1] if k > 0 and wheel_of[k - 1] == wheel_of[k] else k
    for k in range(count - 1, -1, -1):
        end[k] = end[k + 1] if k < count - 1 and wheel_of[k + 1] == wheel_of[k] else k + 1
    cold = False
    for k in range(count):  # Newton's start: the friction held over the last step where there is one
        state[k] = held[2 * wheel_of[k] + direction_of[k]]
        cold = cold or state[k] == 0.0
    if cold:  # else the friction opposing the slip predicted with no friction (``_friction_of``)
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
        _wheel_speeds(count, predicted, ints, epsilon, vecs)
        for k in range(count):
            if state[k] == 0.0:
                state[k] = -kinetic * pressed[wheel_of[k]] * predicted[k] / sizes[k]
    begun = vecs[NEWTON_START]
    for i in range(size_of):
        begun[i] = state[i]
    if _pressed_kinetic(count, responses, mats, vecs, ints, kinetic, epsilon, dt, adhesion, solution):
        return SOLVED
    for i in range(size_of):  # a load left zero or below: Newton on the friction and the loads, from the start
        state[i] = begun[i]
    residual, jacobian = vecs[RESIDUALS], mats[JACOBIAN]
    size = _kinetic_equations(count, responses, mats, vecs, ints, kinetic, epsilon, dt, state, residual, jacobian,
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
            trial_size = _kinetic_equations(count, responses, mats, vecs, ints, kinetic, epsilon, dt, trial,
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


def _pressed_residual(count: int, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray, kinetic: float,
                      epsilon: float, state: np.ndarray, predicted: np.ndarray, residual: np.ndarray) -> float:
    """r_f = f + mu_k N_i w / s at the friction f of ``state`` (its first ``count`` entries), with the loads it gives,
    N = N_a + G f (into ``state`` after f), and the predicted slip, w = w_a + H f (into ``predicted``); returns the
    residual's largest magnitude, or -1 where a load is not positive (the loads are not affine in f there)."""
    load_response, slip_response = mats[LOAD_RESPONSE], mats[SLIP_RESPONSE]
    for wheel in range(4):
        load = vecs[FREE_LOADS, wheel]
        for column in range(count):
            load += load_response[wheel, column] * state[column]
        if not load > 0.0:
            return -1.0
        state[count + wheel] = load
    for k in range(count):
        slip = vecs[FREE_SLIP, k]
        for column in range(count):
            slip += slip_response[k, column] * state[column]
        predicted[k] = slip
    _wheel_speeds(count, predicted, ints, epsilon, vecs)
    size = 0.0
    for k in range(count):
        residual[k] = state[k] + kinetic * state[count + ints[WHEEL_OF, k]] * predicted[k] / vecs[SIZES, k]
        size = max(size, abs(residual[k]))
    return size


def _pressed_jacobian(count: int, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray, kinetic: float,
                      state: np.ndarray, predicted: np.ndarray, jacobian: np.ndarray) -> None:
    """dr_f/df at the state ``_pressed_residual`` evaluated last (its speeds in vecs[SIZES]):
    I + mu_k N_i d(w/s)/dw H + mu_k (w / s) G_i, with d(w_k/s)/dw = (e_k - (w_k/s) w^T/s) / s within the wheel."""
    load_response, slip_response, directions = mats[LOAD_RESPONSE], mats[SLIP_RESPONSE], vecs[DIRECTIONS]
    for k in range(count):
        directions[k] = predicted[k] / vecs[SIZES, k]
    for k in range(count):
        wheel, direction = ints[WHEEL_OF, k], directions[k]
        pressing = kinetic * state[count + wheel] / vecs[SIZES, k]  # mu_k N_i / s
        first, end = ints[BLOCK_FIRST, k], ints[BLOCK_END, k]
        for column in range(count):
            along = 0.0  # the slip's response along the wheel's slip direction
            for p in range(first, end):
                along += directions[p] * slip_response[p, column]
            jacobian[k, column] = (pressing * (slip_response[k, column] - direction * along)
                                   + kinetic * direction * load_response[wheel, column])
        jacobian[k, k] += 1.0


# Long on purpose, as _kinetic: the elimination and Newton's iteration share the workspace in one compiled frame.
def _pressed_kinetic(count: int, responses: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray,
                     kinetic: float, epsilon: float, dt: float, adhesion: float, solution: np.ndarray) -> bool:
    """``_kinetic``'s equations solved on the friction alone, from the friction in vecs[STATE], while every load stays
    positive: N = N_0 + L qdd with qdd = a + D f + R N gives N = N_a + G f, (I - L R) N_a = N_0 + L a,
    (I - L R) G = L D, and the predicted slip w = w_a + H f, H = dt J_S (D + R G); Newton's method with the same
    halving line search on r_f(f) alone (the Schur complement of the whole Jacobian). Whether it solved them (f and N
    into vecs[STATE], w into vecs[NEWTON_PREDICTED]); False where a load reached zero or below or a system was
    singular, leaving ``_kinetic``'s scratch changed."""
    system, factors, pivots = mats[JACOBIAN], mats[LU], ints[PIVOTS]
    load_response, slip_response, gain = mats[LOAD_RESPONSE], mats[SLIP_RESPONSE], mats[GAIN]
    right_side, column_of = vecs[NEGATIVE], vecs[NEWTON_STEP]
    for wheel in range(4):
        for other in range(4):
            system[wheel, other] = (1.0 if wheel == other else 0.0) - mats[LOAD_BY_LOAD, wheel, other]
        right_side[wheel] = vecs[ORIGIN, wheel] + _dot(gain[wheel], responses[0], DOF)
    if not _lu_factor(system, 4, factors, pivots):
        return False
    _lu_substitute(factors, pivots, 4, right_side, vecs[FREE_LOADS])
    for column in range(count):  # G's columns: L D is -LOAD_BY_FRICTION
        for wheel in range(4):
            right_side[wheel] = -mats[LOAD_BY_FRICTION, wheel, column]
        _lu_substitute(factors, pivots, 4, right_side, column_of)
        for wheel in range(4):
            load_response[wheel, column] = column_of[wheel]
    slip_rows, free = mats[SLIP_ROWS], vecs[ACCELERATION]
    for j in range(DOF):  # qdd at f = 0: a + R N_a
        value = responses[0, j]
        for wheel in range(4):
            value += responses[1 + count + wheel, j] * vecs[FREE_LOADS, wheel]
        free[j] = value
    for k in range(count):
        vecs[FREE_SLIP, k] = vecs[SLIP, k] + dt * (_dot(slip_rows[k], free, DOF) + vecs[DRIFT, k])
        for column in range(count):
            value = mats[SLIP_BY_FRICTION, k, column]
            for wheel in range(4):
                value += mats[SLIP_BY_LOAD, k, wheel] * load_response[wheel, column]
            slip_response[k, column] = value
    state, predicted, residual = vecs[STATE], vecs[NEWTON_PREDICTED], vecs[RESIDUALS]
    trial, trial_predicted, trial_residual = vecs[TRIAL_STATE], vecs[TRIAL_PREDICTED], vecs[TRIAL_RESIDUALS]
    jacobian, step, negative = mats[TRIAL_JACOBIAN], vecs[NEWTON_STEP], vecs[NEGATIVE]
    size = _pressed_residual(count, mats, vecs, ints, kinetic, epsilon, state, predicted, residual)
    if size < 0.0:
        return False
    for _ in range(NEWTON_ITERATIONS):
        if size <= NEWTON_TOLERANCE * adhesion:
            solution[STATUS, NEWTON_RESIDUAL] = size
            return True
        _pressed_jacobian(count, mats, vecs, ints, kinetic, state, predicted, jacobian)
        for k in range(count):
            negative[k] = -residual[k]
        if not _lu_factor(jacobian, count, factors, pivots):
            return False
        _lu_substitute(factors, pivots, count, negative, step)
        scale = 1.0
        while True:
            for k in range(count):
                trial[k] = state[k] + scale * step[k]
            trial_size = _pressed_residual(count, mats, vecs, ints, kinetic, epsilon, trial, trial_predicted,
                                           trial_residual)
            if trial_size < 0.0:
                return False
            if trial_size < size or scale < 1e-6:
                break
            scale *= 0.5
        for i in range(count + 4):
            state[i] = trial[i]
        for k in range(count):
            predicted[k], residual[k] = trial_predicted[k], trial_residual[k]
        size = trial_size
    return False


_contact_row = jit(_contact_row, inline="always")
_normal_loads = jit(_normal_loads, inline="always")
_load_gain = jit(_load_gain, inline="always")
_wheel_speeds = jit(_wheel_speeds, inline="always")
_affine_acceleration = jit(_affine_acceleration, inline="always")
_kinetic_equations = jit(_kinetic_equations)
_pressed_residual = jit(_pressed_residual, inline="always")
_pressed_jacobian = jit(_pressed_jacobian, inline="always")
_pressed_kinetic = jit(_pressed_kinetic)
_kinetic = jit(_kinetic)
