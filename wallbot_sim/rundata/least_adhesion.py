"""The adhesion force the run needed, when it recorded its wheels' contact (docs/model.md 11.2): the least
F at which, for the same motion, every wheel stays on the wall and its force stays in its friction disc.
The loads are affine in F, N_i(F) = N_i + (F - F_run) / 4 with F_run = sum N_i; the wheels' forces are
shared again by those loads as the run's contact shared them: where a sample's forces are the
load-weighted split of their wrench on the chassis over the four wheels (ideal contact's), that split;
else as coulomb contact shares a sticking robot's (each side's traction between its two wheels by load,
the belt's force being free, the lateral force and its moment by the load-weighted least-norm split).
Either gives back the run's own forces at F_run. Per sample the least F with
|f_i(F)| <= mu_s N_i(F) and N_i(F) >= 0 for every wheel is found by regula falsi (``_Resplit.least_shift``; the
sweep's reduce bisects instead, see ``needed_adhesion_of``), and the figure is the largest over the run. Exact
for a run that stuck throughout, up to the rolling resistance f_r F, which changes with F; in a run whose
wheels slid, their forces are the kinetic friction they transmitted, so the figure is a lower bound.
"""

from __future__ import annotations

import numpy as np

from wallbot_sim.model import Robot
from wallbot_sim.model.wheel_forces import _SINGULAR, split_chassis_wrench  # the chassis split's own cut

WIDENINGS = 60
"""Doublings of a sample's interval of adhesion forces at most, until every wheel holds at its upper end."""
BISECTIONS = 60
"""Halvings of a sample's interval in ``needed_adhesion_of`` (to far below a newton's round-off), its doublings at
most before."""
STEPS = 400
"""Steps of the root search at most (it ends far sooner: every fourth step at least halves the interval)."""
RESOLUTION = 1e-14
"""Width, relative to the forces a sample's interval spans (F_run, its ends), to which it is narrowed."""
CHASSIS_SPLIT = 1e-9
"""Relative difference below which a sample's forces are taken for the split of their chassis wrench."""


def _quiet() -> np.errstate:
    """Where a trial's row has no load, or a side none, its ratios are not finite: no warning, it does not hold."""
    return np.errstate(divide='ignore', invalid='ignore', over='ignore')


def least_adhesion(loads: np.ndarray, forces: np.ndarray, robot: Robot) -> tuple[float, int, int, bool]:
    """The least adhesion force keeping every wheel of the samples on the wall with its force in its disc
    (the module's docstring): (F, the sample that binds, the wheel that binds there, whether by lift-off).

    ``loads`` (T, 4) and ``forces`` (T, 4, 2) of the run: ``needed_adhesion``'s largest.
    """
    resplit = _Resplit(loads, forces, robot.wheel_offsets, robot.params.wall_friction)
    shift = resplit.least_shift(largest=True)
    needed = resplit.run_force + shift
    k = int(np.argmax(needed))
    lifts = shift[k] - resplit.lift_off[k] <= 1e-9 * max(abs(needed[k]), 1.0)
    wheel = int(np.argmin(loads[k])) if lifts else int(np.argmax(resplit.use(shift)[k]))
    return float(needed[k]), k, wheel, bool(lifts)


def needed_adhesion(loads: np.ndarray, forces: np.ndarray, robot: Robot) -> np.ndarray:
    """Each sample's least adhesion force keeping its wheels on the wall with their forces in their discs (T,):
    ``least_adhesion`` sample by sample, whose largest it is."""
    resplit = _Resplit(loads, forces, robot.wheel_offsets, robot.params.wall_friction)
    return resplit.run_force + resplit.least_shift()


def needed_adhesion_of(loads: np.ndarray, forces: np.ndarray, offsets: np.ndarray,
                       static: float | np.ndarray) -> np.ndarray:
    """``needed_adhesion`` of samples of robots of their own: wheel offsets d_i (4, 2) or each sample's (T, 4, 2),
    wall friction mu_s one or each sample's (T,).

    The sweep's reduce and its compiled screen (``sweep/screen.py``), which must pick the same rows, find it the
    same way to the bit: each sample's interval bracketed, then ``BISECTIONS`` halvings, every trial splitting the
    forces again (``_Resplit.bisected_shift``); equal to ``needed_adhesion``'s root search to round-off.
    """
    resplit = _Resplit(loads, forces, offsets, static)
    return resplit.run_force + resplit.bisected_shift()


def holds_with(loads: np.ndarray, forces: np.ndarray, offsets: np.ndarray, static: float | np.ndarray,
               adhesion: np.ndarray) -> np.ndarray:
    """(T,) whether each sample keeps its wheels on the wall with their forces in their discs under the adhesion
    force ``adhesion`` (T,) (``needed_adhesion_of``'s samples and robots): the test its halvings go by, so a sample
    that holds needs no more than it."""
    resplit = _Resplit(loads, forces, offsets, static)
    return resplit.split_holds(adhesion - resplit.run_force)


class _Resplit:
    """The samples' wheel forces shared again by the loads of another adhesion force (the module's docstring), of
    one robot (offsets d_i (4, 2), mu_s a number) or of each sample's own (offsets (T, 4, 2), mu_s (T,)).

    Beyond lift-off every load N_i + s / 4 (s = F - F_run) is positive, so every load-weighted sum either split
    takes is affine in s, and a wheel's force over its load, g_i = f_i / N_i, is a few operations on them per
    sample: the samples are tested at any s without splitting their forces again.
    """

    def __init__(self, loads: np.ndarray, forces: np.ndarray, offsets: np.ndarray,
                 static: float | np.ndarray) -> None:
        self.loads, self.offsets = loads, offsets
        self.static = static if np.ndim(static) == 0 else np.asarray(static)
        self.run_force = loads.sum(axis=1)
        self.lift_off = np.max(-4.0 * loads, axis=1)
        """(T,) s at which a load reaches 0: below it a wheel is off the wall."""
        along, across = offsets[..., 0], offsets[..., 1]
        self.along, self.across = along, across
        self.same_side = same_side = _same_side(across)
        longitudinal, lateral = forces[:, :, 0], forces[:, :, 1]
        self.wrench = (longitudinal.sum(axis=1), lateral.sum(axis=1),
                       _weighted(lateral, along) - _weighted(longitudinal, across))
        """The wheels' wrench on the chassis in body axes, (F_bx, F_by, M_Z), each (T,)."""
        self.heading, self.wrench_rows = np.zeros(len(loads)), np.column_stack(self.wrench)  # body axes already
        made = split_chassis_wrench(self.heading, self.wrench_rows, loads, offsets)
        scale = 1.0 + np.max(np.abs(forces), axis=(1, 2))
        self.chassis = np.all(np.abs(made - forces) <= CHASSIS_SPLIT * scale[:, None, None], axis=(1, 2))
        """(T,) the samples whose forces are their chassis wrench's split over the four wheels (ideal contact's)."""
        # each sum of the loads, at s = 0 and its rate in s (a quarter of the sum of what each load is weighted by)
        self.first = (_weighted(loads, along), 0.25 * along.sum(axis=-1))
        if not self.chassis.all():
            self.second = (_weighted(loads, along * along), 0.25 * (along * along).sum(axis=-1))
            self.side_loads = (_sides(loads, same_side), 0.25 * same_side.sum(axis=-1))
            """Each wheel's side's load (T, 4) and its rate."""
            self.traction = _sides(longitudinal, same_side)
            """Each wheel's side's traction (T, 4)."""
            self.lateral, self.moment = self.wrench[1], _weighted(lateral, along)
        if self.chassis.any():
            self.across_sum = (_weighted(loads, across), 0.25 * across.sum(axis=-1))
            radii = along * along + across * across
            self.radii_sum = (_weighted(loads, radii), 0.25 * radii.sum(axis=-1))

    def ratios(self, shift: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """g_i = f_i / N_i along x_p and y_p (T, 4 each) with F - F_run = ``shift`` (T,) beyond lift-off (a row without
        load gives non-finite values: run under ``_quiet``)."""
        total = self.run_force + shift
        first = _at(self.first, shift)
        if not self.chassis.all():
            second = _at(self.second, shift)
            spread = total * second - first * first
            lam = (second * self.lateral - first * self.moment) / spread
            mu = (total * self.moment - first * self.lateral) / spread
            along = self.traction / _at(self.side_loads, shift[:, None])
            across = lam[:, None] + mu[:, None] * self.along
            if not self.chassis.any():
                return along, across
        force_x, force_y, moment = self.wrench
        sum_s, sum_r = _at(self.across_sum, shift), _at(self.radii_sum, shift)
        spread = total * sum_r - sum_s * sum_s - first * first
        turn = np.where(spread > _SINGULAR * total * sum_r,
                        (total * moment + sum_s * force_x - first * force_y) / spread, 0.0)
        lam_x, lam_y = (force_x + sum_s * turn) / total, (force_y - first * turn) / total
        chassis_along = lam_x[:, None] - self.across * turn[:, None]
        chassis_across = lam_y[:, None] + self.along * turn[:, None]
        if self.chassis.all():
            return chassis_along, chassis_across
        keep = self.chassis[:, None]
        return np.where(keep, chassis_along, along), np.where(keep, chassis_across, across)

    def excess(self, shift: np.ndarray) -> np.ndarray:
        """(T,) F (max_i |g_i| - mu_s) with F - F_run = ``shift`` beyond lift-off: positive where a wheel's force
        leaves its disc, nearly affine in the shift (a wheel's force over its load falls about as 1 / F)."""
        along, across = self.ratios(shift)
        return (self.run_force + shift) * (np.sqrt((along * along + across * across).max(axis=1)) - self.static)

    def use(self, shift: np.ndarray) -> np.ndarray:
        """|f_i| / (mu_s N_i) (T, 4) with F - F_run = ``shift`` beyond lift-off."""
        with _quiet():
            along, across = self.ratios(shift)
        return np.hypot(along, across) / (self.static if np.ndim(self.static) == 0 else self.static[:, None])

    def components(self, shift: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The forces along x_p and y_p and the loads (T, 4 each) with F - F_run = ``shift`` (T,), the forces split
        again in full."""
        loads = self.loads + 0.25 * shift[:, None]
        if self.chassis.all():  # ideal contact's samples: the chassis split alone
            split = split_chassis_wrench(self.heading, self.wrench_rows, loads, self.offsets)
            return split[:, :, 0], split[:, :, 1], loads
        total, first = loads.sum(axis=1), _weighted(loads, self.along)
        second = _weighted(loads, self.along * self.along)
        with _quiet():
            spread = total * second - first * first
            lam = (second * self.lateral - first * self.moment) / spread
            mu = (total * self.moment - first * self.lateral) / spread
            along = self.traction * loads / _sides(loads, self.same_side)
        across = loads * (lam[:, None] + mu[:, None] * self.along)
        if self.chassis.any():
            split = split_chassis_wrench(self.heading, self.wrench_rows, loads, self.offsets)
            along = np.where(self.chassis[:, None], split[:, :, 0], along)
            across = np.where(self.chassis[:, None], split[:, :, 1], across)
        return along, across, loads

    def split_holds(self, shift: np.ndarray) -> np.ndarray:
        """(T,) whether every wheel is on the wall with its force in its disc with F - F_run = ``shift``, by the
        forces split again in full (``components``)."""
        along, across, loads = self.components(shift)
        limit = (self.static if np.ndim(self.static) == 0 else self.static[:, None]) * loads
        return np.all((loads > 0.0) & (along * along + across * across <= limit * limit), axis=1)

    def bisected_shift(self) -> np.ndarray:
        """Each sample's least F - F_run at which it holds (T,) by ``split_holds``: its interval from lift-off, widened
        until every wheel holds at its upper end, then halved ``BISECTIONS`` times."""
        low, high = self.lift_off, np.maximum(self.lift_off, 0.0) + self.run_force + 1.0
        for _ in range(BISECTIONS):
            short = ~self.split_holds(high)
            if not short.any():
                break
            high = np.where(short, low + 2.0 * (high - low), high)
        for _ in range(BISECTIONS):
            middle = 0.5 * (low + high)
            holds = self.split_holds(middle)
            low, high = np.where(holds, low, middle), np.where(holds, middle, high)
        return high

    def least_shift(self, largest: bool = False) -> np.ndarray:
        """Each sample's least F - F_run at which it holds (T,); with ``largest`` only the samples that can need the
        most adhesion are narrowed to the end (the others' figures are less than it, and otherwise rough).

        Each sample's interval from lift-off to where every wheel holds is narrowed by regula falsi (the Illinois
        variant) until it is ``RESOLUTION`` of the forces it spans wide; a step keeps half of that from either end,
        so that one next to the root falls on its other side too, and halves the interval wherever four steps did
        not. A sample whose wheels hold as soon as all are on the wall needs the lift-off's.
        """
        with _quiet():
            return self._narrow(largest)

    def _narrow(self, largest: bool) -> np.ndarray:
        """``least_shift`` (under ``_quiet``)."""
        low, high, high_excess = self._bracket()
        resolution = RESOLUTION * (np.abs(self.run_force) + np.abs(low) + np.abs(high) + 1.0)
        margin = 0.5 * resolution
        low_excess = self.excess(low)
        high = np.where(low_excess <= 0.0, low, high)
        width = high - low
        halvings = [np.inf] * 4  # half the widths of the last four steps
        lowered = raised = np.zeros(len(low), dtype=bool)  # which end the last step moved
        for _ in range(STEPS):
            wide = width > resolution
            if largest:
                wide &= self.run_force + high >= (self.run_force + low).max()
            if not wide.any():
                break
            secant = high - high_excess * width / (high_excess - low_excess)
            secant = np.where((width <= halvings[0]) & ~np.isnan(secant), secant, 0.5 * (low + high))
            step = np.minimum(np.maximum(secant, low + margin), high - margin)
            step_excess = self.excess(step)
            held = step_excess <= 0.0
            lower, raise_ = wide & held, wide & ~held
            # Illinois: an end kept a second time weighs half, so that the next step falls beyond the root
            low_excess = low_excess * np.where(lower & lowered, 0.5, 1.0)
            high_excess = high_excess * np.where(raise_ & raised, 0.5, 1.0)
            low, low_excess = np.where(raise_, step, low), np.where(raise_, step_excess, low_excess)
            high, high_excess = np.where(lower, step, high), np.where(lower, step_excess, high_excess)
            lowered, raised = lower, raise_
            halvings = halvings[1:] + [0.5 * width]
            width = high - low
        return high

    def _bracket(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each sample's interval of F - F_run from where a load reaches 0 (not held) to where every wheel holds,
        and ``excess`` there."""
        low = self.lift_off
        high = np.maximum(low, 0.0) + np.abs(self.run_force) + 1.0  # above lift-off whatever the loads
        high_excess = self.excess(high)
        for _ in range(WIDENINGS):  # widen until every wheel holds (the loads grow, the forces stay bounded)
            short = ~((high > low) & (high_excess <= 0.0))
            if not short.any():
                break
            high = np.where(short, low + 2.0 * (high - low), high)
            high_excess = self.excess(high)
        return low, high, high_excess


def _same_side(across: np.ndarray) -> np.ndarray:
    """(4, 4), or each sample's (T, 4, 4) where their wheels' sides differ: 1 where two wheels are of one side."""
    side = np.sign(across)
    if side.ndim == 2 and len(side) and np.all(side == side[:1]):
        side = side[0]
    return (side[..., :, None] == side[..., None, :]).astype(float)


def _sides(values: np.ndarray, same_side: np.ndarray) -> np.ndarray:
    """Each wheel's side's sum of ``values`` (T, 4)."""
    if same_side.ndim == 2:
        return values @ same_side
    return np.einsum('ti,tij->tj', values, same_side)


def _at(affine: tuple[np.ndarray, np.ndarray | float], shift: np.ndarray) -> np.ndarray:
    """A load-weighted sum (value at s = 0, rate) at s = ``shift``."""
    value, rate = affine
    return value + shift * rate


def _weighted(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """sum_i values_i weights_i (T,) of values (T, 4), weights (4,) or each sample's (T, 4)."""
    return values @ weights if weights.ndim == 1 else np.einsum('ti,ti->t', values, weights)
