"""One robot's problem at a state: the applied force Q, the factor W of M^-1 and the rows A, b of the active
constraint modules (with coulomb contact, the sticking wheels' contact rows and the sliding wheels' held
friction), as the model's modules and forces give them (``test/test_constraint_table.py``)."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.batch.kernel.layout import BELT, NON_LATERAL, NONSLIP, TANGENT_HEADING, TRAJECTORY
from wallbot_sim.model.robot import DOF


def _factor_of(theta: float, constants: np.ndarray, factor: np.ndarray) -> None:
    """W (7, 7), lower triangular, W W^T = M^-1 at heading theta: the chassis block's Cholesky factor in closed
    form, 1/sqrt(J_w) on the spins (``RobotBatch.mass_inverse_factor``)."""
    mass, yaw_inertia, spin_inertia, sx, sy = constants[0], constants[1], constants[2], constants[3], constants[4]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    ux, uy = -cos_t * sy - sin_t * sx, -sin_t * sy + cos_t * sx
    inv_schur = 1.0 / (yaw_inertia - (ux * ux + uy * uy) / mass)
    wx, wy = ux / mass, uy / mass
    c00, c10, c11 = 1.0 / mass + wx * wx * inv_schur, wx * wy * inv_schur, 1.0 / mass + wy * wy * inv_schur
    c20, c21 = -wx * inv_schur, -wy * inv_schur
    l00 = math.sqrt(c00)
    l10 = c10 / l00
    l11 = math.sqrt(c11 - l10 * l10)
    l20 = c20 / l00
    l21 = (c21 - l20 * l10) / l11
    factor[0, 0], factor[1, 0], factor[1, 1] = l00, l10, l11
    factor[2, 0], factor[2, 1], factor[2, 2] = l20, l21, math.sqrt(inv_schur - l20 * l20 - l21 * l21)
    factor[0, 1] = factor[0, 2] = factor[1, 2] = 0.0
    spin = math.sqrt(1.0 / spin_inertia)
    for j in range(3, DOF):
        factor[j, j] = spin


def _problem(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
             torque: np.ndarray, gains: np.ndarray, contact: bool, sticking: np.ndarray, held: np.ndarray,
             rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, force: np.ndarray) -> int:
    """Q, the factor W of M^-1 and the rows A, b of the active modules of one robot at (q, qd); the row count.

    ``gains`` (4,): each wheel's rolling resistance per unit speed, f_r N (section 4's f_r F_ad / 4 with ideal
    contact). ``contact`` (coulomb contact, docs/model.md 11.3): the non-lateral and nonslip modules give each
    ``sticking`` wheel its contact rows (lateral and longitudinal), J_i qdd = -c - gam v_i, in wheel order after
    the other modules' rows, and ``held`` (8,), the sliding wheels' forces (f_x, f_y) in body axes wheel by wheel
    (zero for the others), enters Q as sum_i J_i^T f_i (``HeldFriction``).
    """
    theta = q[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    _applied_force(q, qd, constants, torque, gains, cos_t, sin_t, force)
    _factor_of(theta, constants, factor)
    return _module_rows(q, qd, reference, flags, constants, cos_t, sin_t, contact, sticking, held, rows, rhs, force)


def _applied_force(q: np.ndarray, qd: np.ndarray, constants: np.ndarray, torque: np.ndarray, gains: np.ndarray,
                   cos_t: float, sin_t: float, force: np.ndarray) -> None:
    """Q of one robot at (q, qd), heading cos_t, sin_t (``_problem``'s ``gains``)."""
    sx, sy = constants[3], constants[4]
    gravity, weight, eps2 = constants[5], constants[6], constants[9]
    # constants[16:24] S d_i = (-s_i, a_i) pairs
    thd = qd[2]
    thd2 = thd * thd
    force[0] = thd2 * (cos_t * sx - sin_t * sy)
    force[1] = thd2 * (sin_t * sx + cos_t * sy) - weight
    force[2] = -gravity * (-sin_t * sy + cos_t * sx)
    for wheel in range(4):
        px, py = constants[16 + 2 * wheel], constants[17 + 2 * wheel]
        arm_x, arm_y = cos_t * px - sin_t * py, sin_t * px + cos_t * py
        vx, vy = qd[0] + thd * arm_x, qd[1] + thd * arm_y
        scale = -gains[wheel] / math.sqrt(vx * vx + vy * vy + eps2)
        force[0] += scale * vx
        force[1] += scale * vy
        force[2] += scale * (arm_x * vx + arm_y * vy)
    force[3] = force[4] = 0.5 * torque[0]
    force[5] = force[6] = 0.5 * torque[1]


def _module_rows(q: np.ndarray, qd: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray,
                 cos_t: float, sin_t: float, contact: bool, sticking: np.ndarray, held: np.ndarray, rows: np.ndarray,
                 rhs: np.ndarray, force: np.ndarray) -> int:
    """The rows A, b of the active modules of one robot at (q, qd), heading cos_t, sin_t; the row count. With
    ``contact``, the sticking wheels' rows and the held friction added to Q in ``force`` (``_problem``)."""
    radius, alpha, beta = constants[7], constants[10], constants[11]
    # constants[12:16] lateral offsets s_i
    theta, thd = q[2], qd[2]
    # the rows of the active modules, in stacking order: their entries that are not written here stay
    # zero from the block's start (each module writes the same entries at every stage)
    gam = 2.0 * alpha
    count = 0
    if flags[TRAJECTORY]:
        for axis in range(2):
            rows[count, axis] = 1.0
            rhs[count] = (reference[4 + axis] - 2.0 * alpha * (qd[axis] - reference[2 + axis])
                          - beta * beta * (q[axis] - reference[axis]))
            count += 1
    if flags[TANGENT_HEADING]:
        rows[count, 2] = 1.0
        if reference[6] == 0.0:
            rhs[count] = -gam * thd
        else:
            error = theta - reference[7]
            turn = 2.0 * math.pi
            error = error - turn * np.round(error / turn)
            if error <= -math.pi:
                error += turn
            rhs[count] = reference[9] - gam * (thd - reference[8]) - beta * beta * error
        count += 1
    if flags[BELT]:
        rows[count, 3], rows[count, 4] = 1.0, -1.0
        rhs[count] = -gam * (qd[3] - qd[4])
        rows[count + 1, 5], rows[count + 1, 6] = 1.0, -1.0
        rhs[count + 1] = -gam * (qd[5] - qd[6])
        count += 2
    v_long = cos_t * qd[0] + sin_t * qd[1]
    v_lat = -sin_t * qd[0] + cos_t * qd[1]
    if contact:
        return _wheel_rows(qd, flags, constants, sticking, held, cos_t, sin_t, v_long, v_lat, gam, count, rows, rhs,
                           force)
    if flags[NON_LATERAL]:
        rows[count, 0], rows[count, 1] = -sin_t, cos_t
        rhs[count] = thd * v_long - gam * v_lat
        count += 1
    if flags[NONSLIP]:
        for wheel in range(4):
            offset = constants[12 + wheel]
            violation = -cos_t * qd[0] - sin_t * qd[1] + offset * thd + radius * qd[3 + wheel]
            rows[count, 0], rows[count, 1], rows[count, 2] = -cos_t, -sin_t, offset
            rows[count, 3 + wheel] = radius
            rhs[count] = thd * v_lat - gam * violation
            count += 1
    return count


def _wheel_rows(qd: np.ndarray, flags: np.ndarray, constants: np.ndarray, sticking: np.ndarray, held: np.ndarray,
                cos_t: float, sin_t: float, v_long: float, v_lat: float, gam: float, count: int, rows: np.ndarray,
                rhs: np.ndarray, force: np.ndarray) -> int:
    """``_problem``'s contact rows of the sticking wheels after its first ``count`` rows (every entry written: the
    sticking set changes between calls), and the held friction added to ``force``; the row count."""
    thd, radius = qd[2], constants[7]
    drift_x, drift_y = thd * v_lat, -thd * v_long  # c = (thd v_lat, -thd v_long)
    for wheel in range(4):
        offset, along = constants[12 + wheel], constants[17 + 2 * wheel]  # s_i, a_i
        if sticking[wheel] and flags[NONSLIP]:
            rows[count, 0], rows[count, 1], rows[count, 2] = cos_t, sin_t, -offset
            for j in range(3, DOF):
                rows[count, j] = -radius if j == 3 + wheel else 0.0
            rhs[count] = -drift_x - gam * (v_long - offset * thd - radius * qd[3 + wheel])
            count += 1
        if sticking[wheel] and flags[NON_LATERAL]:
            rows[count, 0], rows[count, 1], rows[count, 2] = -sin_t, cos_t, along
            for j in range(3, DOF):
                rows[count, j] = 0.0
            rhs[count] = -drift_y - gam * (v_lat + along * thd)
            count += 1
        push_x, push_y = held[2 * wheel], held[2 * wheel + 1]
        force[0] += push_x * cos_t - push_y * sin_t
        force[1] += push_x * sin_t + push_y * cos_t
        force[2] += -push_x * offset + push_y * along
        force[3 + wheel] -= push_x * radius
    return count


_factor_of = jit(_factor_of, inline="always")
_problem = jit(_problem, inline="always")
_applied_force = jit(_applied_force, inline="always")
_module_rows = jit(_module_rows, inline="always")
_wheel_rows = jit(_wheel_rows, inline="always")
