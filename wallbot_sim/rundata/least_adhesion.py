"""The adhesion force the run needed, when it recorded its wheels' contact (docs/model.md 11.2): the least
F at which, for the same motion, every wheel stays on the wall and its force stays in its friction disc.
The loads are affine in F, N_i(F) = N_i + (F - F_run) / 4 with F_run = sum N_i; the wheels' forces are
shared again by those loads as the run's contact shared them: where a sample's forces are the
load-weighted split of their wrench on the chassis over the four wheels (ideal contact's), that split;
else as coulomb contact shares a sticking robot's (each side's traction between its two wheels by load,
the belt's force being free, the lateral force and its moment by the load-weighted least-norm split).
Either gives back the run's own forces at F_run. Per sample the least F with
|f_i(F)| <= mu_s N_i(F) and N_i(F) >= 0 for every wheel is found by bisection, and the figure is the
largest over the run. Exact for a run that stuck throughout, up to the rolling resistance f_r F, which
changes with F; in a run whose wheels slid, their forces are the kinetic friction they transmitted, so
the figure is a lower bound.
"""

from __future__ import annotations

import numpy as np

from wallbot_sim.model import Robot
from wallbot_sim.model.wheel_forces import split_chassis_wrench

BISECTIONS = 60
"""Halvings of a sample's interval of adhesion forces (to far below a newton's round-off)."""
COARSE = 12
"""Halvings done for every sample before those that cannot hold the largest figure are left out."""
CHASSIS_SPLIT = 1e-9
"""Relative difference below which a sample's forces are taken for the split of their chassis wrench."""


def least_adhesion(loads: np.ndarray, forces: np.ndarray, robot: Robot) -> tuple[float, int, int, bool]:
    """The least adhesion force keeping every wheel of the samples on the wall with its force in its disc
    (the module's docstring): (F, the sample that binds, the wheel that binds there, whether by lift-off).

    ``loads`` (T, 4) and ``forces`` (T, 4, 2) of the run; per sample the shift of F from the run's, F - F_run,
    is bisected between where a load reaches 0 and where every wheel holds, first coarsely for every sample,
    then on for those whose interval reaches the largest lower end.
    """
    lift_off = np.max(-4.0 * loads, axis=1)  # a wheel's load is 0 here: below it the wheel is off the wall
    run_force = loads.sum(axis=1)
    offsets, static = robot.wheel_offsets, robot.params.wall_friction
    resplit = _Resplit(loads, forces, offsets, static)
    low, high = _bisect(resplit, *_bracket(resplit, lift_off, run_force), COARSE)
    candidates = np.flatnonzero(run_force + high >= np.max(run_force + low))
    resplit = _Resplit(loads[candidates], forces[candidates], offsets, static)
    low, high = _bisect(resplit, low[candidates], high[candidates], BISECTIONS - COARSE)
    needed = run_force[candidates] + high
    j = int(np.argmax(needed))
    k = int(candidates[j])
    lifts = high[j] - lift_off[k] <= 1e-9 * max(abs(needed[j]), 1.0)
    wheel = int(np.argmin(loads[k])) if lifts else int(np.argmax(resplit.use(np.full(len(high), high[j]))[j]))
    return float(needed[j]), k, wheel, bool(lifts)


def needed_adhesion(loads: np.ndarray, forces: np.ndarray, robot: Robot) -> np.ndarray:
    """Each sample's least adhesion force keeping its wheels on the wall with their forces in their discs (T,):
    ``least_adhesion`` sample by sample, whose largest it is."""
    return needed_adhesion_of(loads, forces, robot.wheel_offsets, robot.params.wall_friction)


def needed_adhesion_of(loads: np.ndarray, forces: np.ndarray, offsets: np.ndarray,
                       static: float | np.ndarray) -> np.ndarray:
    """``needed_adhesion`` of samples of robots of their own: wheel offsets d_i (4, 2) or each sample's (T, 4, 2),
    wall friction mu_s one or each sample's (T,)."""
    run_force = loads.sum(axis=1)
    resplit = _Resplit(loads, forces, offsets, static)
    _low, high = _bisect(resplit, *_bracket(resplit, np.max(-4.0 * loads, axis=1), run_force), BISECTIONS)
    return run_force + high


def holds_with(loads: np.ndarray, forces: np.ndarray, offsets: np.ndarray, static: float | np.ndarray,
               adhesion: np.ndarray) -> np.ndarray:
    """(T,) whether each sample keeps its wheels on the wall with their forces in their discs under the adhesion
    force ``adhesion`` (T,) (``needed_adhesion_of``'s samples and robots): the test the bisection halves by, so a
    sample that holds needs no more than it."""
    resplit = _Resplit(loads, forces, offsets, static)
    return resplit.holds(adhesion - loads.sum(axis=1))


def _bracket(resplit: _Resplit, lift_off: np.ndarray, run_force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each sample's interval of F - F_run from where a load reaches 0 (not held) to where every wheel holds."""
    low, high = lift_off, np.maximum(lift_off, 0.0) + run_force + 1.0
    for _ in range(BISECTIONS):  # widen until every wheel holds (the loads grow, the forces stay bounded)
        short = ~resplit.holds(high)
        if not short.any():
            break
        high = np.where(short, low + 2.0 * (high - low), high)
    return low, high


def _bisect(resplit: _Resplit, low: np.ndarray, high: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` halvings of each interval (low: not held, high: held)."""
    for _ in range(count):
        middle = 0.5 * (low + high)
        holds = resplit.holds(middle)
        low, high = np.where(holds, low, middle), np.where(holds, middle, high)
    return low, high


class _Resplit:
    """The samples' wheel forces shared again by the loads of another adhesion force (the module's docstring), of
    one robot (offsets d_i (4, 2), mu_s a number) or of each sample's own (offsets (T, 4, 2), mu_s (T,))."""

    def __init__(self, loads: np.ndarray, forces: np.ndarray, offsets: np.ndarray,
                 static: float | np.ndarray) -> None:
        self.loads, self.offsets = loads, offsets
        self.static = static if np.ndim(static) == 0 else np.asarray(static)[:, None]
        self.along, across = offsets[..., 0], offsets[..., 1]
        side = np.sign(across)
        self.same_side = (side[..., :, None] == side[..., None, :]).astype(float)
        """(4, 4) or (T, 4, 4): 1 where two wheels are of one side; ``_sides`` gives each wheel's side's sum."""
        longitudinal, lateral = forces[:, :, 0], forces[:, :, 1]
        self.traction = self._sides(longitudinal)
        """Each wheel's side's traction (T, 4)."""
        self.lateral, self.moment = lateral.sum(axis=1), _weighted(lateral, self.along)
        self.wrench = np.column_stack((longitudinal.sum(axis=1), self.lateral,
                                       self.moment - _weighted(longitudinal, across)))
        """The wheels' wrench on the chassis in body axes, (F_bx, F_by, M_Z) (T, 3)."""
        self.heading = np.zeros(len(loads))  # the wrench is in body axes already
        made = split_chassis_wrench(self.heading, self.wrench, loads, self.offsets)
        scale = 1.0 + np.max(np.abs(forces), axis=(1, 2))
        self.chassis = np.all(np.abs(made - forces) <= CHASSIS_SPLIT * scale[:, None, None], axis=(1, 2))
        """(T,) the samples whose forces are their chassis wrench's split over the four wheels (ideal contact's)."""

    def _sides(self, values: np.ndarray) -> np.ndarray:
        """Each wheel's side's sum of ``values`` (T, 4)."""
        if self.same_side.ndim == 2:
            return values @ self.same_side
        return np.einsum('ti,tij->tj', values, self.same_side)

    def components(self, shift: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The forces along x_p and y_p and the loads (T, 4 each) with F - F_run = ``shift`` (T,)."""
        loads = self.loads + 0.25 * shift[:, None]
        if self.chassis.all():  # ideal contact's samples: the chassis split alone
            split = split_chassis_wrench(self.heading, self.wrench, loads, self.offsets)
            return split[:, :, 0], split[:, :, 1], loads
        total, first = loads.sum(axis=1), _weighted(loads, self.along)
        second = _weighted(loads, self.along * self.along)
        with np.errstate(divide='ignore', invalid='ignore'):  # a side or a row without load holds nothing
            spread = total * second - first * first
            lam = (second * self.lateral - first * self.moment) / spread
            mu = (total * self.moment - first * self.lateral) / spread
            along = self.traction * loads / self._sides(loads)
        across = loads * (lam[:, None] + mu[:, None] * self.along)
        if self.chassis.any():
            split = split_chassis_wrench(self.heading, self.wrench, loads, self.offsets)
            along = np.where(self.chassis[:, None], split[:, :, 0], along)
            across = np.where(self.chassis[:, None], split[:, :, 1], across)
        return along, across, loads

    def use(self, shift: np.ndarray) -> np.ndarray:
        """|f_i| / (mu_s N_i) (T, 4) with F - F_run = ``shift``."""
        along, across, loads = self.components(shift)
        with np.errstate(divide='ignore', invalid='ignore'):
            return np.hypot(along, across) / (self.static * loads)

    def holds(self, shift: np.ndarray) -> np.ndarray:
        """(T,) whether every wheel is on the wall with its force in its disc."""
        along, across, loads = self.components(shift)
        limit = self.static * loads
        return np.all((loads > 0.0) & (along * along + across * across <= limit * limit), axis=1)


def _weighted(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """sum_i values_i weights_i (T,) of values (T, 4), weights (4,) or each sample's (T, 4)."""
    return values @ weights if weights.ndim == 1 else np.einsum('ti,ti->t', values, weights)
