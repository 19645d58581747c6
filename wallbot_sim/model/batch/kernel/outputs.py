"""One robot's outputs with ideal contact at consecutive instants of a run (``robot_run``'s states and motions): the
normal loads, drive forces, each channel's friction use, and per wheel its share of the chassis wrench, its use and
its contact velocity. The NumPy forms (``batch.contact.normal_loads``, ``drive_forces``, ``friction_use``,
``wheel_forces.ideal_wheel_outputs``) written out per instant, as the hot loop of a table needs them."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit, unowned
from wallbot_sim.model.batch.kernel.friction import _normal_loads
from wallbot_sim.model.batch.kernel.layout import ADHESION, HALF_TRACK, SPLIT_CUT, STATIC
from wallbot_sim.model.robot import DOF


def _ratio(force: float, limit: float) -> float:
    """|force| / limit; with no positive limit 0 for no force, else inf (``friction_use``, ``wheel_use``)."""
    if limit > 0.0:
        return force / limit
    return 0.0 if force == 0.0 else math.inf


def _weight(load: float) -> float:
    """max(N, 0) as NumPy's maximum takes it: a NaN load stays NaN."""
    return 0.0 if load < 0.0 else load


def ideal_outputs(states: np.ndarray, motions: np.ndarray, count: int, constants: np.ndarray, contact: np.ndarray,
                  loads: np.ndarray, drive: np.ndarray, use: np.ndarray, forces: np.ndarray, wheel_use: np.ndarray,
                  velocities: np.ndarray) -> None:
    """The outputs at the first ``count`` instants of ``states`` (T, 14) with their motions (T, 3, 7): qdd, Q, Q_c.

    ``constants``: the robot's ``robot_constants`` row, ``contact`` its ``contact_constants``; into ``loads`` (T, 4),
    ``drive`` (T, 3: F_L, F_R, F_lat), ``use`` (T, 3: per channel), ``forces`` (T, 4, 2: body axes), ``wheel_use``
    (T, 4) and ``velocities`` (T, 4, 2). A wheel's force is its load-weighted least-norm share of the wrench
    Q_c[:3] (``split_chassis_wrench``), the loads N_i = F_ad/4 + h F_bx x_i/(4 a^2) + h F_by y_i/(4 b^2).
    Every array is taken ``unowned``: an instant's views of them cost no reference counts.
    """
    states, motions, constants, contact = unowned(states), unowned(motions), unowned(constants), unowned(contact)
    loads, drive, use, forces = unowned(loads), unowned(drive), unowned(use), unowned(forces)
    wheel_use, velocities = unowned(wheel_use), unowned(velocities)
    radius = constants[7]
    adhesion, static, half_track = contact[ADHESION], contact[STATIC], contact[HALF_TRACK]
    along, across = contact[7:11], contact[11:15]
    for k in range(count):
        q, qd, qdd, wrench = states[k, :DOF], states[k, DOF:], motions[k, 0], motions[k, 2]
        _normal_loads(q, qd, qdd, constants, contact, False, loads[k])
        cos_t, sin_t, thd = math.cos(q[2]), math.sin(q[2]), qd[2]
        longitudinal = cos_t * wrench[0] + sin_t * wrench[1]
        lateral = -sin_t * wrench[0] + cos_t * wrench[1]
        differential = wrench[2] / half_track
        drive[k, 0] = 0.5 * (longitudinal - differential)
        drive[k, 1] = 0.5 * (longitudinal + differential)
        drive[k, 2] = lateral
        use[k, 0] = _ratio(abs(drive[k, 0]), static * (loads[k, 0] + loads[k, 1]))
        use[k, 1] = _ratio(abs(drive[k, 1]), static * (loads[k, 2] + loads[k, 3]))
        use[k, 2] = _ratio(abs(drive[k, 2]), static * adhesion)
        total = sum_a = sum_s = sum_r = 0.0
        for wheel in range(4):
            weight = _weight(loads[k, wheel])
            total += weight
            sum_a += weight * along[wheel]
            sum_s += weight * across[wheel]
            sum_r += weight * (along[wheel] * along[wheel] + across[wheel] * across[wheel])
        spread = total * sum_r - sum_s * sum_s - sum_a * sum_a
        turn = lam_x = lam_y = 0.0
        if total > 0.0:
            if spread > SPLIT_CUT * total * sum_r:
                turn = (total * wrench[2] + sum_s * longitudinal - sum_a * lateral) / spread
            lam_x, lam_y = (longitudinal + sum_s * turn) / total, (lateral - sum_a * turn) / total
        v_long, v_lat = cos_t * qd[0] + sin_t * qd[1], -sin_t * qd[0] + cos_t * qd[1]
        for wheel in range(4):
            weight = _weight(loads[k, wheel])
            force_x = weight * (lam_x - across[wheel] * turn)
            force_y = weight * (lam_y + along[wheel] * turn)
            forces[k, wheel, 0], forces[k, wheel, 1] = force_x, force_y
            wheel_use[k, wheel] = _ratio(math.hypot(force_x, force_y), static * loads[k, wheel])
            velocities[k, wheel, 0] = v_long - across[wheel] * thd - radius * qd[3 + wheel]
            velocities[k, wheel, 1] = v_lat + along[wheel] * thd


_ratio = jit(_ratio, inline="always")
_weight = jit(_weight, inline="always")
ideal_outputs = jit(ideal_outputs)
