"""Each wheel's tangential contact force (docs/model.md 11.2): the load-weighted least-norm split of a contact force.

Four wheels in contact are statically indeterminate: many sets of wheel forces produce the same
force on the robot. The split chosen minimizes sum_i |f_i|^2 / N_i, the forces a rigid chassis
on four equal tangential springs loaded in proportion to N_i would take: a uniform load is shared
in proportion to normal load, so every wheel reaches its friction disc together. A wheel with no
positive load takes no force.

``split_chassis_wrench``: a wrench on the chassis over all four wheels in both directions (ideal
contact: what friction would have to supply). ``split_contact_force``: a generalized force over
given contact rows, the force of other constraint rows (the belt's) free in the minimization
(coulomb contact's sticking wheels).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from wallbot_sim.model.contact_kinematics import contact_velocities
from wallbot_sim.model.robot import Robot

_SINGULAR = 1e-12
"""Relative size below which the moment a split can make counts as none (fewer than two loaded wheels)."""


def split_chassis_wrench(theta: np.ndarray, wrench: np.ndarray, loads: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """f (T, 4, 2), body axes, of consecutive instants or robots: theta (T,), wrench (F_X, F_Y, M_Z) (T, 3) in the
    wall frame, loads (T, 4), offsets d_i (4, 2), or (T, 4, 2) for robots of their own.

    With weights n_i = max(N_i, 0), f_i = n_i (l_x - s_i l_m, l_y + a_i l_m), the multipliers solving
    sum f_x = F_bx, sum f_y = F_by, sum (a_i f_y - s_i f_x) = M_Z in closed form:
    l_m = (S0 M_Z + Ss F_bx - Sa F_by) / (S0 Sr - Ss^2 - Sa^2), l_x = (F_bx + Ss l_m) / S0,
    l_y = (F_by - Sa l_m) / S0 (S0 = sum n_i, Sa = sum n_i a_i, Ss = sum n_i s_i, Sr = sum n_i |d_i|^2).
    With one loaded wheel no moment can be made (l_m = 0); with none, every force is 0.
    """
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):  # a diverged state gives non-finite forces
        return _split(theta, wrench, loads, offsets)


def _split(theta: np.ndarray, wrench: np.ndarray, loads: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    force_x = cos_t * wrench[:, 0] + sin_t * wrench[:, 1]
    force_y = -sin_t * wrench[:, 0] + cos_t * wrench[:, 1]
    moment = wrench[:, 2]
    weights = np.maximum(loads, 0.0)
    along, across = offsets[..., 0], offsets[..., 1]
    radii = along * along + across * across
    # sums written out: the same operations at every table size (a reduction's order may depend on its length)
    total = weights[:, 0] + weights[:, 1] + weights[:, 2] + weights[:, 3]
    sum_a = (weights[:, 0] * along[..., 0] + weights[:, 1] * along[..., 1] + weights[:, 2] * along[..., 2]
             + weights[:, 3] * along[..., 3])
    sum_s = (weights[:, 0] * across[..., 0] + weights[:, 1] * across[..., 1] + weights[:, 2] * across[..., 2]
             + weights[:, 3] * across[..., 3])
    sum_r = (weights[:, 0] * radii[..., 0] + weights[:, 1] * radii[..., 1] + weights[:, 2] * radii[..., 2]
             + weights[:, 3] * radii[..., 3])
    spread = total * sum_r - sum_s * sum_s - sum_a * sum_a
    loaded = total > 0.0
    turning = loaded & (spread > _SINGULAR * total * sum_r)
    turn = np.where(turning, (total * moment + sum_s * force_x - sum_a * force_y) / spread, 0.0)
    lam_x = np.where(loaded, (force_x + sum_s * turn) / total, 0.0)
    lam_y = np.where(loaded, (force_y - sum_a * turn) / total, 0.0)
    return np.stack((weights * (lam_x[:, None] - across * turn[:, None]),
                     weights * (lam_y[:, None] + along * turn[:, None])), axis=2)


def split_contact_force(contact_rows: np.ndarray, row_loads: np.ndarray, other_rows: np.ndarray,
                        force: np.ndarray) -> np.ndarray:
    """The contact rows' forces f (k,) minimizing sum f_k^2 / max(N_k, 0) with contact_rows^T f + other_rows^T mu = force.

    ``contact_rows`` (k x 7) are contact velocity rows (a force f_k along row k is the generalized force
    f_k contact_rows[k]); ``row_loads`` (k,) the normal load of each row's wheel; ``other_rows`` (m x 7)
    the rows of the other constraints, whose forces mu are free. Only force components outside the
    other rows' span are the contact's to make: with V a basis of the vectors those rows annul, the
    split is the weighted least-norm solution of V^T contact_rows^T f = V^T force (least squares
    where the force cannot be made).
    """
    weights = np.maximum(row_loads, 0.0)
    if len(other_rows):
        _, values, vectors = np.linalg.svd(other_rows)
        rank = int(np.sum(values > _SINGULAR * values[0])) if len(values) and values[0] > 0.0 else 0
        basis = vectors[rank:].T
    else:
        basis = np.eye(contact_rows.shape[1])
    made = basis.T @ contact_rows.T
    return weights * (made.T @ (np.linalg.pinv((made * weights) @ made.T, rcond=_SINGULAR) @ (basis.T @ force)))


def wheel_use(forces: np.ndarray, loads: np.ndarray, static_friction: float | np.ndarray) -> np.ndarray:
    """|f_i| / (mu_s N_i) (T, 4) of forces (T, 4, 2), mu_s one or each wheel's: above 1 the wheel's friction disc
    cannot hold it.

    A wheel of no positive load can hold nothing: its use is infinite unless its force is 0 (then 0).
    """
    magnitude = np.hypot(forces[..., 0], forces[..., 1])
    limit = static_friction * loads
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = magnitude / limit
    return np.where(limit > 0.0, ratio, np.where(magnitude == 0.0, 0.0, np.inf))


class WheelOutputs(NamedTuple):
    """Per wheel at consecutive instants: force (T, 4, 2), use (T, 4), contact velocity (T, 4, 2)."""

    forces: np.ndarray
    use: np.ndarray
    velocities: np.ndarray


def ideal_wheel_outputs(robot: Robot, q: np.ndarray, qd: np.ndarray, wrench: np.ndarray,
                        loads: np.ndarray) -> WheelOutputs:
    """Each wheel's share of the wrench (T, 3) on the chassis at states q, qd (T, 7) with loads (T, 4): ideal
    contact's outputs per wheel (what friction would have to supply)."""
    forces = split_chassis_wrench(q[:, 2], wrench, loads, robot.wheel_offsets)
    static = (np.array([robot.wheel_friction(row)[0] for row in q]) if robot.world.patches
              else robot.params.wall_friction)
    return WheelOutputs(forces, wheel_use(forces, loads, static),
                        contact_velocities(q[:, 2], qd, robot.wheel_offsets, robot.params.wheel_radius))
