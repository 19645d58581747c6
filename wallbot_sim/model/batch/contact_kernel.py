"""Coulomb contact compiled for one robot: the stick/slip settlement of each step boundary, and the steps.

``robot_contact_run`` is ``kernel.robot_run`` with ``CoulombContact``'s rules (docs/model.md 11.3) at every
boundary, for ``Simulation(..., engine='numba', contact='coulomb')`` (``wallbot_sim.model.compiled``): the
motion under the slipping set with the loads the kinetic friction holds (their fixed point solved at
once while they move, as ``_consistent_loads``), slipping channels that stop sticking again when the
solve with their rows restored keeps them within the limit (their slip projected away), sticking
channels over the limit slipping, then the RK4 step with the slipping rows' kinetic friction in its
stages (``kernel._problem``). It knows the kernel's modules: the non-lateral row is the lateral
channel's, the nonslip rows of wheels 1-2 and 3-4 the left and right traction's. It agrees with the
Python model within round-off (``test/test_compiled_contact.py``).
"""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.kernel import MAX_ROWS, _compile, _motion_of, _problem, _rk4, _solve, _workspace
from wallbot_sim.model.batch.solver import RANK_CUTOFF
from wallbot_sim.model.robot import DOF, Robot

ADHESION, STATIC, KINETIC, STICK, HEIGHT, HALF_BASE, HALF_TRACK = range(7)
"""``contact_constants``' fields; then the wheels' x_i (7-10) and y_i (11-14)."""
LOAD_TOLERANCE = 1e-9
"""Relative difference below which held loads are the loads they produce (``contact._LOAD_TOLERANCE``)."""
SOLUTION_ROWS = 7
"""A boundary's solution (7, 7): qdd, Q (with Q_f), Q_c, Q_f, then [N_1..N_4, use_L, use_R, use_lat],
[F_L, F_R, F_lat, held N_1..N_4], [residual, singular]."""
LOADS_ROW, DRIVE_ROW, STATUS_ROW = 4, 5, 6
WORK_ROWS = 21
CONSISTENT = 1e-9
"""Relative misfit below which a dropped row agrees with the kept ones (``_responses``)."""


def contact_constants(robot: Robot) -> np.ndarray:
    """(15,) in the fields' order: F_ad, mu_s, mu_k, v_st, h, a, b, x_1..x_4, y_1..y_4."""
    params = robot.params
    return np.array([robot.adsorption.applied_force, params.wall_friction, params.kinetic_friction,
                     params.stick_velocity, params.com_height, params.half_wheelbase, params.half_track,
                     *robot.wheel_offsets[:, 0], *robot.wheel_offsets[:, 1]], dtype=float)


def _normal_loads(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, constants: np.ndarray, contact: np.ndarray,
                  out: np.ndarray) -> None:
    """N_1..N_4 at (q, qd, qdd) (``normal_loads``)."""
    mass, sx, sy, gravity = constants[0], constants[3], constants[4], constants[5]
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    thd, thdd = qd[2], qdd[2]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    inertial_x = mass * qdd[0] - thdd * rsy - thd * thd * rsx
    inertial_y = mass * qdd[1] + thdd * rsx - thd * thd * rsy
    fx, fy = -inertial_x, -mass * gravity - inertial_y
    body_x, body_y = cos_t * fx + sin_t * fy, -sin_t * fx + cos_t * fy
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    along, across = 0.25 * h * body_x / (a * a), 0.25 * h * body_y / (b * b)
    for wheel in range(4):
        out[wheel] = 0.25 * contact[ADHESION] + along * contact[7 + wheel] + across * contact[11 + wheel]


def _ratio(force: float, limit: float) -> float:
    if limit > 0.0:
        return force / limit
    return 0.0 if force == 0.0 else math.inf


def _measure(q: np.ndarray, qd: np.ndarray, constants: np.ndarray, contact: np.ndarray,
             solution: np.ndarray) -> None:
    """The loads, friction use and drive forces of the solution's motion (``Simulation._measure``)."""
    loads = solution[LOADS_ROW]
    _normal_loads(q, qd, solution[0], constants, contact, loads)
    fx = solution[2, 0] + solution[3, 0]
    fy = solution[2, 1] + solution[3, 1]
    mz = solution[2, 2] + solution[3, 2]
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    longitudinal, differential = cos_t * fx + sin_t * fy, mz / contact[HALF_TRACK]
    drive = solution[DRIVE_ROW]
    drive[0], drive[1] = 0.5 * (longitudinal - differential), 0.5 * (longitudinal + differential)
    drive[2] = -sin_t * fx + cos_t * fy
    static = contact[STATIC]
    loads[4] = _ratio(abs(drive[0]), static * (loads[0] + loads[1]))
    loads[5] = _ratio(abs(drive[1]), static * (loads[2] + loads[3]))
    loads[6] = _ratio(abs(drive[2]), static * contact[ADHESION])


def _slip_rows(q: np.ndarray, qd: np.ndarray, flags: np.ndarray, constants: np.ndarray, slipping: np.ndarray,
               rows: np.ndarray, slip: np.ndarray, present: np.ndarray) -> None:
    """The velocity rows a_k (5, 7) of the slipping rows, their slip a_k qd, and which are present.

    k: 0 the non-lateral row (lateral), 1 + i wheel i's nonslip row (left for wheels 1-2, right for 3-4).
    """
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    radius = constants[7]
    for k in range(5):
        present[k] = flags[3] and slipping[2] if k == 0 else flags[4] and slipping[(k - 1) // 2]
        for j in range(DOF):
            rows[k, j] = 0.0
    rows[0, 0], rows[0, 1] = -sin_t, cos_t
    for wheel in range(4):
        row = rows[1 + wheel]
        row[0], row[1], row[2], row[3 + wheel] = -cos_t, -sin_t, constants[12 + wheel], radius
    for k in range(5):
        value = 0.0
        for j in range(DOF):
            value += rows[k, j] * qd[j]
        slip[k] = value


def _bounds(held: np.ndarray, kinetic: float, bounds: np.ndarray) -> None:
    """-mu_k times each row's bounding load: F_ad = sum N_i for the lateral row, N_i for wheel i's."""
    bounds[0] = -kinetic * (held[0] + held[1] + held[2] + held[3])
    for wheel in range(4):
        bounds[1 + wheel] = -kinetic * held[wheel]


def _converged(loads: np.ndarray, held: np.ndarray) -> bool:
    largest, total = 0.0, 0.0
    for wheel in range(4):
        largest = max(largest, abs(loads[wheel] - held[wheel]))
        total += abs(loads[wheel])
    return largest <= LOAD_TOLERANCE * total


def _contact_solve(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                   contact: np.ndarray, torque: np.ndarray, slipping: np.ndarray, held: np.ndarray, moving: bool,
                   rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
                   lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, work: np.ndarray,
                   zero_rhs: np.ndarray, bounds: np.ndarray, present: np.ndarray, solution: np.ndarray) -> None:
    """The motion at y with ``slipping`` channels slipping, and the loads their friction holds
    (``CoulombContact._solve``), into ``solution``.

    ``work`` (WORK_ROWS, 7): scratch for the slipping rows, their per-load friction, the responses and the
    free motion; ``zero_rhs`` (MAX_ROWS,) zeros.
    """
    q, qd = y[:DOF], y[DOF:]
    eps2 = constants[9]
    force, friction, acceleration = solution[1], solution[3], solution[0]
    for wheel in range(4):
        bounds[wheel] = 0.0
    bounds[4] = 0.0
    count = _problem(q, qd, reference, flags, constants, torque, slipping, bounds, rows, rhs, factor, force)
    held_out = solution[DRIVE_ROW, 3:]
    for wheel in range(4):
        held_out[wheel] = held[wheel]
    for j in range(DOF):
        friction[j] = 0.0
    solution[STATUS_ROW, 1] = 0.0
    slip_rows, slip, direction, total = work[0:5], work[5], work[6], work[7]
    _slip_rows(q, qd, flags, constants, slipping, slip_rows, slip, present)
    slipping_rows = False
    dependent = False
    for k in range(5):
        if present[k]:
            slipping_rows = True
            dependent = dependent or k > 0
            direction[k] = slip[k] / math.sqrt(slip[k] * slip[k] + eps2)
    solved = False
    if not slipping_rows:
        _solve(factor, force, rows, rhs, count, matrix, gram, lower, vectors, scratch, acceleration)
        solved = True
    elif not (dependent and moving):
        _bounds(held, contact[KINETIC], bounds)
        for k in range(5):
            if present[k]:
                for j in range(DOF):
                    friction[j] += bounds[k] * direction[k] * slip_rows[k, j]
        for j in range(DOF):
            total[j] = force[j] + friction[j]
        _solve(factor, total, rows, rhs, count, matrix, gram, lower, vectors, scratch, acceleration)
        loads = solution[LOADS_ROW]
        _normal_loads(q, qd, acceleration, constants, contact, loads)
        if not dependent or _converged(loads, held):
            for j in range(DOF):
                force[j] = total[j]
            solved = True
    if not solved:
        _consistent_loads(q, qd, constants, contact, rows, rhs, count, factor, matrix, gram, lower, vectors, scratch,
                          work, zero_rhs, present, direction, solution)
    residual = _motion_of(y, constants, solution[:3], rows, rhs, count)
    _measure(q, qd, constants, contact, solution)
    solution[STATUS_ROW, 0] = residual


def _consistent_loads(q: np.ndarray, qd: np.ndarray, constants: np.ndarray, contact: np.ndarray, rows: np.ndarray,
                      rhs: np.ndarray, count: int, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
                      lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, work: np.ndarray,
                      zero_rhs: np.ndarray, present: np.ndarray, direction: np.ndarray, solution: np.ndarray) -> None:
    """The held loads h that are the loads the friction F h produces, and the motion (``contact._consistent_loads``).

    qdd = qdd_0 + D h (D: the response to each wheel's per-load friction, rhs 0), N = N(qdd_0) + U B D[:3] h,
    so h = N(qdd_0) + U (I_2 - C U)^-1 C N(qdd_0) with C = B D[:3]. Sets solution row 6's singular flag
    when I_2 - C U is singular.
    """
    slip_rows, free, per_load, responses = work[0:5], work[8], work[9:13], work[13:17]
    force, friction, acceleration = solution[1], solution[3], solution[0]
    kinetic = contact[KINETIC]
    for wheel in range(4):
        column = per_load[wheel]
        for j in range(DOF):
            column[j] = 0.0
        for k in range(5):
            if present[k] and (k == 0 or k == 1 + wheel):  # the lateral row is bounded by every wheel's load
                for j in range(DOF):
                    column[j] -= kinetic * direction[k] * slip_rows[k, j]
    if not _responses(factor, force, rhs, per_load, rows, count, matrix, gram, lower, vectors[2], work, free,
                      responses):
        _solve(factor, force, rows, rhs, count, matrix, gram, lower, vectors, scratch, free)
        for wheel in range(4):
            _solve(factor, per_load[wheel], rows, zero_rhs, count, matrix, gram, lower, vectors, scratch,
                   responses[wheel])
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    mass, sx, sy = constants[0], constants[3], constants[4]
    rsx, rsy = cos_t * sx - sin_t * sy, sin_t * sx + cos_t * sy
    body = ((-cos_t * mass, -sin_t * mass, cos_t * rsy - sin_t * rsx),
            (sin_t * mass, -cos_t * mass, -sin_t * rsy - cos_t * rsx))
    a, b, h = contact[HALF_BASE], contact[HALF_TRACK], contact[HEIGHT]
    along, across = 0.25 * h / (a * a), 0.25 * h / (b * b)
    coupling, unheld = work[17:19], work[20]
    for i in range(2):
        for wheel in range(4):
            coupling[i, wheel] = (body[i][0] * responses[wheel, 0] + body[i][1] * responses[wheel, 1]
                                  + body[i][2] * responses[wheel, 2])
    _normal_loads(q, qd, free, constants, contact, unheld)
    # (I_2 - C U) z = C N(qdd_0), U's columns the arms along x_i and across y_i
    m00, m01, m10, m11 = 1.0, 0.0, 0.0, 1.0
    v0, v1 = 0.0, 0.0
    for wheel in range(4):
        arm_x, arm_y = along * contact[7 + wheel], across * contact[11 + wheel]
        m00 -= coupling[0, wheel] * arm_x
        m01 -= coupling[0, wheel] * arm_y
        m10 -= coupling[1, wheel] * arm_x
        m11 -= coupling[1, wheel] * arm_y
        v0 += coupling[0, wheel] * unheld[wheel]
        v1 += coupling[1, wheel] * unheld[wheel]
    determinant = m00 * m11 - m01 * m10
    if determinant == 0.0:
        solution[STATUS_ROW, 1] = 1.0
        determinant = math.nan
    z0, z1 = (m11 * v0 - m01 * v1) / determinant, (m00 * v1 - m10 * v0) / determinant
    held = solution[DRIVE_ROW, 3:]
    for wheel in range(4):
        held[wheel] = unheld[wheel] + along * contact[7 + wheel] * z0 + across * contact[11 + wheel] * z1
    for j in range(DOF):
        value, push = free[j], 0.0
        for wheel in range(4):
            value += responses[wheel, j] * held[wheel]
            push += per_load[wheel, j] * held[wheel]
        acceleration[j] = value
        friction[j] = push
        force[j] += push

def _responses(factor: np.ndarray, force: np.ndarray, rhs: np.ndarray, per_load: np.ndarray, rows: np.ndarray,
               count: int, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, misfit: np.ndarray,
               work: np.ndarray, free: np.ndarray, responses: np.ndarray) -> bool:
    """qdd under Q and b (``free``), and the response to each wheel's per-load friction with b = 0
    (``responses``), from one factorization: qdd = W (s + B_K^T (B_K B_K^T)^-1 (b - B s)_K), s = W^T Q,
    B = A W, K the independent rows a pivoted Cholesky of B B^T keeps (the nonslip rows of a side imply
    its belt row).

    That is the minimum-norm solution wherever the dropped rows agree with the kept ones, which the
    responses (b = 0) always do. Returns False, leaving the work to ``_solve``'s least squares, where the
    free motion's dropped rows disagree (an inconsistent set).
    """
    for r in range(count):
        for j in range(3):
            value = 0.0
            for k in range(j, 3):
                value += rows[r, k] * factor[k, j]
            matrix[r, j] = value
        for j in range(3, DOF):
            matrix[r, j] = rows[r, j] * factor[j, j]
    if count > DOF:
        return False
    largest = 0.0
    for i in range(count):
        for j in range(i + 1):
            entry = 0.0
            for k in range(DOF):
                entry += matrix[i, k] * matrix[j, k]
            gram[i, j] = gram[j, i] = entry
        largest = max(largest, gram[i, i])
    # pivoted Cholesky of B B^T in place: gram becomes the Schur complement, lower[r, i] column r of L
    # at row i, order[r] the row of pivot r
    order = np.empty(DOF, dtype=np.int64)
    kept = np.zeros(DOF, dtype=np.bool_)
    rank = 0
    cut = RANK_CUTOFF * largest
    for rank_now in range(count):
        best, pivot = -1, cut
        for i in range(count):
            if not kept[i] and gram[i, i] > pivot:
                best, pivot = i, gram[i, i]
        if best < 0:
            break
        kept[best] = True
        order[rank_now] = best
        rank = rank_now + 1
        scale = 1.0 / math.sqrt(pivot)
        for i in range(count):
            lower[rank_now, i] = gram[i, best] * scale
        for i in range(count):
            for j in range(count):
                gram[i, j] -= lower[rank_now, i] * lower[rank_now, j]
    scaled, solution = work[19], work[7]
    for column in range(5):
        source = force if column == 0 else per_load[column - 1]
        out = free if column == 0 else responses[column - 1]
        for i in range(3):
            value = 0.0
            for k in range(i, 3):
                value += factor[k, i] * source[k]
            scaled[i] = value
        for i in range(3, DOF):
            scaled[i] = factor[i, i] * source[i]
        for r in range(count):
            value = rhs[r] if column == 0 else 0.0
            for k in range(DOF):
                value -= matrix[r, k] * scaled[k]
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
        if column == 0:
            for d in range(count):
                if not kept[d]:
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
        for i in range(3):
            value = 0.0
            for k in range(i + 1):
                value += factor[i, k] * scaled[k]
            out[i] = value
        for i in range(3, DOF):
            out[i] = factor[i, i] * scaled[i]
    return True


def _project(y: np.ndarray, flags: np.ndarray, constants: np.ndarray, slipping: np.ndarray,
             factor: np.ndarray) -> None:
    """qd <- qd - M^-1 A^T (A M^-1 A^T)+ A qd over the velocity rows of the sticking modules (in place on y).

    ``factor``: W at y's q (W W^T = M^-1), as ``_problem`` left it.
    """
    cos_t, sin_t = math.cos(y[2]), math.sin(y[2])
    rows = np.zeros((7, DOF))
    count = 0
    if flags[2]:
        rows[0, 3], rows[0, 4], rows[1, 5], rows[1, 6] = 1.0, -1.0, 1.0, -1.0
        count = 2
    if flags[3] and not slipping[2]:
        rows[count, 0], rows[count, 1] = -sin_t, cos_t
        count += 1
    if flags[4]:
        for wheel in range(4):
            if not slipping[wheel // 2]:
                rows[count, 0], rows[count, 1], rows[count, 2] = -cos_t, -sin_t, constants[12 + wheel]
                rows[count, 3 + wheel] = constants[7]
                count += 1
    if count == 0:
        return
    active = rows[:count]
    inverse = factor @ factor.T
    weighted = inverse @ active.T
    velocities = y[DOF:].copy()
    correction = weighted @ (np.linalg.pinv(active @ weighted) @ (active @ velocities))
    for j in range(DOF):
        y[DOF + j] = velocities[j] - correction[j]


def _stopping(y: np.ndarray, flags: np.ndarray, constants: np.ndarray, slipping: np.ndarray,
              solution: np.ndarray, dt: float, stick_velocity: float, work: np.ndarray, present: np.ndarray,
              candidates: np.ndarray) -> bool:
    """The slipping channels whose every row's slip is below v_st or changes sign by qd + dt qdd
    (``KineticFriction.stopping``); whether there is one."""
    predicted = work[7]
    for j in range(DOF):
        predicted[j] = y[DOF + j] + dt * solution[0, j]
    slip_rows, slip = work[0:5], work[5]
    _slip_rows(y[:DOF], y[DOF:], flags, constants, slipping, slip_rows, slip, present)
    for channel in range(3):
        candidates[channel] = False
    seen = np.zeros(3, dtype=np.bool_)
    for k in range(5):
        if present[k]:
            channel = 2 if k == 0 else (k - 1) // 2
            then = 0.0
            for j in range(DOF):
                then += slip_rows[k, j] * predicted[j]
            stops = abs(slip[k]) < stick_velocity or slip[k] * then < 0.0
            candidates[channel] = stops if not seen[channel] else candidates[channel] and stops
            seen[channel] = True
    return candidates[0] or candidates[1] or candidates[2]


def _settle(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
            torque: np.ndarray, dt: float, slipping: np.ndarray, held: np.ndarray, moving: np.ndarray,
            rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
            lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, work: np.ndarray, zero_rhs: np.ndarray,
            bounds: np.ndarray, present: np.ndarray, solution: np.ndarray, trial_solution: np.ndarray) -> None:
    """The stick/slip transitions at y's boundary, then the solution of the step (``CoulombContact.settle``).

    ``slipping`` (3,), ``held`` (4,) and ``moving`` (1,) are the contact state before, updated in place; y's
    velocities are projected in place where a channel sticks again.
    """
    channels = (flags[4], flags[4], flags[3])  # left, right, lateral: which channels have rows
    for channel in range(3):
        slipping[channel] = slipping[channel] and channels[channel]
    _contact_solve(y, reference, flags, constants, contact, torque, slipping, held, moving[0], rows, rhs, factor,
                   matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds, present, solution)
    candidates, trial, holding = np.zeros(3, dtype=np.bool_), np.zeros(3, dtype=np.bool_), np.zeros(3, dtype=np.bool_)
    trial_y = np.empty(2 * DOF)
    searching = (slipping[0] or slipping[1] or slipping[2]) and _stopping(
        y, flags, constants, slipping, solution, dt, contact[STICK], work, present, candidates)
    while searching:
        for channel in range(3):
            trial[channel] = slipping[channel] and not candidates[channel]
        for i in range(2 * DOF):
            trial_y[i] = y[i]
        _project(trial_y, flags, constants, trial, factor)
        _contact_solve(trial_y, reference, flags, constants, contact, torque, trial, held, moving[0], rows, rhs,
                       factor, matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds, present, trial_solution)
        same, searching = True, False
        for channel in range(3):
            holding[channel] = candidates[channel] and not trial_solution[LOADS_ROW, 4 + channel] > 1.0
            same = same and holding[channel] == candidates[channel]
            searching = searching or holding[channel]
        if same:
            for channel in range(3):
                slipping[channel] = trial[channel]
            for i in range(2 * DOF):
                y[i] = trial_y[i]
            solution[:, :] = trial_solution
            break
        for channel in range(3):
            candidates[channel] = holding[channel]
    while True:
        exceeded = False
        for channel in range(3):
            if channels[channel] and not slipping[channel] and solution[LOADS_ROW, 4 + channel] > 1.0:
                slipping[channel] = exceeded = True
        if not exceeded:
            break
        _contact_solve(y, reference, flags, constants, contact, torque, slipping, held, moving[0], rows, rhs, factor,
                       matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds, present, solution)
    new_held = solution[DRIVE_ROW, 3:]
    moving[0] = (slipping[0] or slipping[1] or slipping[2]) and not _converged(new_held, held)
    for wheel in range(4):
        held[wheel] = new_held[wheel]


def robot_contact_run(states: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                      contact: np.ndarray, torque: np.ndarray, dt: float, steps: int, slipping: np.ndarray,
                      held: np.ndarray, moving: np.ndarray, solutions: np.ndarray) -> int:
    """One robot with coulomb contact over consecutive instants: each boundary settled (``_settle``), then the
    RK4 step from it; the number of steps taken (``kernel.robot_run``'s, with ``contact_constants``).

    ``slipping`` (T + 1, 3), ``held`` (T + 1, 4), ``moving`` (T + 1,): row 0 the contact state before the
    first boundary, row k + 1 the state boundary k settled to (held over step k). ``states`` row k is
    projected in place where a channel sticks again. ``solutions`` (T, 7, 7): each instant's solution
    (``SOLUTION_ROWS``). The run stops at an instant where a wheel's load is negative (detached) or the
    loads have no consistent value (the solution's singular flag), without stepping from it.
    """
    rows, rhs = np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)
    factor, matrix, gram, lower, vectors, scratch = _workspace()
    slopes = np.zeros((4, 2 * DOF))
    work, zero_rhs = np.zeros((WORK_ROWS, DOF)), np.zeros(MAX_ROWS)
    bounds, present = np.zeros(5), np.zeros(5, dtype=np.bool_)
    trial_solution = np.zeros((SOLUTION_ROWS, DOF))
    step_bounds = np.zeros(5)
    for k in range(solutions.shape[0]):
        for channel in range(3):
            slipping[k + 1, channel] = slipping[k, channel]
        for wheel in range(4):
            held[k + 1, wheel] = held[k, wheel]
        moving[k + 1] = moving[k]
        _settle(states[k], references[k, 0], flags, constants, contact, torque, dt, slipping[k + 1], held[k + 1],
                moving[k + 1:k + 2], rows, rhs, factor, matrix, gram, lower, vectors, scratch, work, zero_rhs, bounds,
                present, solutions[k], trial_solution)
        loads = solutions[k, LOADS_ROW]
        if (solutions[k, STATUS_ROW, 1] != 0.0 or min(min(loads[0], loads[1]), min(loads[2], loads[3])) < 0.0
                or k == steps):
            return k
        for i in range(DOF):
            slopes[0, DOF + i] = solutions[k, 0, i]
        _bounds(held[k + 1], contact[KINETIC], step_bounds)
        if not _rk4(states[k], references[k], flags, constants, torque, slipping[k + 1], step_bounds, dt, True, rows,
                    rhs, factor, matrix, gram, lower, vectors, scratch, states[k + 1], slopes):
            return k
    return steps


_normal_loads = _compile(_normal_loads, inline="always")
_ratio = _compile(_ratio, inline="always")
_measure = _compile(_measure, inline="always")
_slip_rows = _compile(_slip_rows, inline="always")
_bounds = _compile(_bounds, inline="always")
_converged = _compile(_converged, inline="always")
_responses = _compile(_responses)
_consistent_loads = _compile(_consistent_loads)
_contact_solve = _compile(_contact_solve)
_project = _compile(_project)
_stopping = _compile(_stopping)
_settle = _compile(_settle)
robot_contact_run = _compile(robot_contact_run)


def available() -> bool:
    """Whether the compiled contact can run (numba imported)."""
    return kernel.available()
