"""``reduce.deciding_rows`` compiled: each robot's deciding rows picked in one pass over its rows, row by row.

The same picks as the NumPy reference (``reduce.deciding_rows``, whose docstring says what each is), taken as a
running scan: a peak is replaced by a strictly larger value and a least by a strictly smaller one (NumPy's argmax
and argmin give the first of equal values), a first instant is kept once met. The row binding the least adhesion
force is found as the reference finds it: the largest figure of the start rows, then every row with the wheels'
contact that does not hold under that figure (``least_adhesion.holds_with``) bisected. The figure of a row is
``least_adhesion.needed_adhesion_of``'s, the same operations in the same order (sums of four written out, left to
right, as NumPy's reductions and einsum over four take them; einsum's of two contiguous operands, the first wheel
with the third and the second with the fourth), so the two pick the same rows.

The rows come from two arrays, the rows kept of the robot's run so far and the next block, a row's index counting
through both (kept first): the new kept rows are gathered from them without joining them. This module calls no
function of another file, so numba's cache of it (checked against this file alone) never runs stale code.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit, unowned
from wallbot_sim.rundata.csv_format import COLUMN

PICKS = 17
"""Rows a robot keeps (some of them one row twice): the first, the last with a tracking error, the late error's
peak, the four peaks of ``reduce.PEAKS``, the two sides' motor torques, the four wheels' use, the least load, the
first slip, the first negative load and the binding row."""
COLUMNS = np.array([COLUMN[name] for name in (
    't', 'err', 'F_left', 'F_right', 'F_lateral', 'residual', 'tau1', 'dphi1', 'N1', 'use1', 'slip1', 'fx1', 'fy1')])
"""The columns the screen reads, in the order of the ``_T`` .. ``_FY`` indices (a wheel's: the first of four)."""
_T, _ERR, _LEFT, _RIGHT, _LATERAL, _RESIDUAL, _TAU, _DPHI, _N, _USE, _SLIP, _FX, _FY = range(13)
LATE = 5.0
"""As ``reduce.LATE``. The constants are this file's own: numba's cache of it is renewed by a change of this file
alone, so a value imported from another would be kept through a change of it."""
BISECTIONS = 60
"""As ``least_adhesion.BISECTIONS``."""
CHASSIS_SPLIT = 1e-9
"""As ``least_adhesion.CHASSIS_SPLIT``."""
SINGULAR = 1e-12
"""As ``wheel_forces._SINGULAR``."""


def _row(kept: np.ndarray, block: np.ndarray, index: int) -> np.ndarray:
    """A row counted through the kept rows and the block."""
    if index < kept.shape[0]:
        return kept[index]
    return block[index - kept.shape[0]]


def _valid(kept_valid: np.ndarray, valid: np.ndarray, index: int) -> bool:
    if index < kept_valid.shape[0]:
        return kept_valid[index]
    return valid[index - kept_valid.shape[0]]


def _contact(row: np.ndarray, columns: np.ndarray) -> bool:
    """Whether every wheel's load, use and force of the row is finite."""
    for name in (_N, _USE, _FX, _FY):
        for wheel in range(4):
            if not math.isfinite(row[columns[name] + wheel]):
                return False
    return True


def _split(force_x: float, force_y: float, moment: float, loads: tuple, along: tuple,
           across: tuple) -> tuple[tuple, tuple]:
    """``wheel_forces.split_chassis_wrench`` of one sample's body-axes wrench: the wheels' forces along x_p and
    along y_p."""
    w0, w1, w2, w3 = max(loads[0], 0.0), max(loads[1], 0.0), max(loads[2], 0.0), max(loads[3], 0.0)
    a0, a1, a2, a3 = along
    s0, s1, s2, s3 = across
    total = w0 + w1 + w2 + w3
    sum_a = w0 * a0 + w1 * a1 + w2 * a2 + w3 * a3
    sum_s = w0 * s0 + w1 * s1 + w2 * s2 + w3 * s3
    sum_r = w0 * (a0 * a0 + s0 * s0) + w1 * (a1 * a1 + s1 * s1) + w2 * (a2 * a2 + s2 * s2) + w3 * (a3 * a3 + s3 * s3)
    spread = total * sum_r - sum_s * sum_s - sum_a * sum_a
    loaded = total > 0.0
    turn = 0.0
    if loaded and spread > SINGULAR * total * sum_r:
        turn = (total * moment + sum_s * force_x - sum_a * force_y) / spread
    lam_x = (force_x + sum_s * turn) / total if loaded else 0.0
    lam_y = (force_y - sum_a * turn) / total if loaded else 0.0
    return ((w0 * (lam_x - s0 * turn), w1 * (lam_x - s1 * turn), w2 * (lam_x - s2 * turn), w3 * (lam_x - s3 * turn)),
            (w0 * (lam_y + a0 * turn), w1 * (lam_y + a1 * turn), w2 * (lam_y + a2 * turn), w3 * (lam_y + a3 * turn)))


def _sides(values: tuple, same_side: np.ndarray, wheel: int) -> float:
    """The sum of ``values`` (4) over the wheels of ``wheel``'s side."""
    return (values[0] * same_side[0, wheel] + values[1] * same_side[1, wheel] + values[2] * same_side[2, wheel]
            + values[3] * same_side[3, wheel])


class _Sample(NamedTuple):
    """``least_adhesion._Resplit``'s constants of one sample (``_sample``)."""

    loads: tuple
    chassis: bool
    """Whether the forces are their chassis wrench's split (ideal contact's)."""
    wrench: tuple
    """The wheels' wrench on the chassis in body axes (F_bx, F_by, M_Z)."""
    traction: tuple
    """Each wheel's side's traction."""
    lateral: float
    moment: float
    """The lateral forces' moment about the centre, sum a_i f_yi."""


def _sample(row: np.ndarray, columns: np.ndarray, along: tuple, across: tuple, same_side: np.ndarray) -> _Sample:
    loads = (row[columns[_N]], row[columns[_N] + 1], row[columns[_N] + 2], row[columns[_N] + 3])
    fx = (row[columns[_FX]], row[columns[_FX] + 1], row[columns[_FX] + 2], row[columns[_FX] + 3])
    fy = (row[columns[_FY]], row[columns[_FY] + 1], row[columns[_FY] + 2], row[columns[_FY] + 3])
    traction = (_sides(fx, same_side, 0), _sides(fx, same_side, 1), _sides(fx, same_side, 2),
                _sides(fx, same_side, 3))
    lateral = fy[0] + fy[1] + fy[2] + fy[3]
    moment = fy[0] * along[0] + fy[1] * along[1] + fy[2] * along[2] + fy[3] * along[3]
    wrench = (fx[0] + fx[1] + fx[2] + fx[3], lateral,
              moment - (fx[0] * across[0] + fx[1] * across[1] + fx[2] * across[2] + fx[3] * across[3]))
    made_x, made_y = _split(1.0 * wrench[0] + 0.0 * wrench[1], -0.0 * wrench[0] + 1.0 * wrench[1], wrench[2], loads,
                            along, across)  # the reference's cosine and sine of a heading of 0
    tolerance = CHASSIS_SPLIT * (1.0 + max(abs(fx[0]), abs(fx[1]), abs(fx[2]), abs(fx[3]),
                                           abs(fy[0]), abs(fy[1]), abs(fy[2]), abs(fy[3])))
    chassis = True
    for wheel in range(4):
        if not (abs(made_x[wheel] - fx[wheel]) <= tolerance and abs(made_y[wheel] - fy[wheel]) <= tolerance):
            chassis = False
    return _Sample(loads, chassis, wrench, traction, lateral, moment)


def _holds(sample: _Sample, shift: float, along: tuple, across: tuple, same_side: np.ndarray, static: float) -> bool:
    """``least_adhesion._Resplit.holds`` of one sample: every wheel on the wall with its force in its disc with
    F - F_run = ``shift``."""
    loads = sample.loads
    shifted = (loads[0] + 0.25 * shift, loads[1] + 0.25 * shift, loads[2] + 0.25 * shift, loads[3] + 0.25 * shift)
    if sample.chassis:
        wrench = sample.wrench
        made_x, made_y = _split(1.0 * wrench[0] + 0.0 * wrench[1], -0.0 * wrench[0] + 1.0 * wrench[1], wrench[2],
                                shifted, along, across)
    else:
        a0, a1, a2, a3 = along
        total = shifted[0] + shifted[1] + shifted[2] + shifted[3]
        first = shifted[0] * a0 + shifted[1] * a1 + shifted[2] * a2 + shifted[3] * a3
        second = (shifted[0] * (a0 * a0) + shifted[2] * (a2 * a2)) + (shifted[1] * (a1 * a1) + shifted[3] * (a3 * a3))
        spread = total * second - first * first
        lam = (second * sample.lateral - first * sample.moment) / spread
        mu = (total * sample.moment - first * sample.lateral) / spread
        traction = sample.traction
        made_x = (traction[0] * shifted[0] / _sides(shifted, same_side, 0),
                  traction[1] * shifted[1] / _sides(shifted, same_side, 1),
                  traction[2] * shifted[2] / _sides(shifted, same_side, 2),
                  traction[3] * shifted[3] / _sides(shifted, same_side, 3))
        made_y = (shifted[0] * (lam + mu * a0), shifted[1] * (lam + mu * a1), shifted[2] * (lam + mu * a2),
                  shifted[3] * (lam + mu * a3))
    for wheel in range(4):
        limit = static * shifted[wheel]
        if not (shifted[wheel] > 0.0
                and made_x[wheel] * made_x[wheel] + made_y[wheel] * made_y[wheel] <= limit * limit):
            return False
    return True


def _figure(row: np.ndarray, columns: np.ndarray, along: tuple, across: tuple, same_side: np.ndarray, static: float,
            above: float) -> float:
    """The row's least adhesion force (``least_adhesion.needed_adhesion_of``: its interval of F - F_run bracketed,
    then halved) if the row does not hold under the adhesion force ``above`` (``holds_with``), else -inf (it needs
    no more than ``above``)."""
    sample = _sample(row, columns, along, across, same_side)
    loads = sample.loads
    run_force = loads[0] + loads[1] + loads[2] + loads[3]
    if _holds(sample, above - run_force, along, across, same_side, static):
        return -math.inf
    low = max(-4.0 * loads[0], -4.0 * loads[1], -4.0 * loads[2], -4.0 * loads[3])
    high = max(low, 0.0) + run_force + 1.0
    for _ in range(BISECTIONS):
        if _holds(sample, high, along, across, same_side, static):
            break
        high = low + 2.0 * (high - low)
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        if _holds(sample, middle, along, across, same_side, static):
            high = middle
        else:
            low = middle
    return run_force + high


def _motor_peaks(row: np.ndarray, index: int, radius: float, columns: np.ndarray, best: np.ndarray,
                 picks: np.ndarray) -> None:
    """Each side's peak |motor torque| (picks 7 and 8) raised to the row's, as model.outputs.side_motor_torques
    gives it, where the row has the motor analysis' columns."""
    t_at, lateral_at, tau_at, dphi_at = columns[_T], columns[_LATERAL], columns[_TAU], columns[_DPHI]
    motor = (math.isfinite(row[t_at]) and math.isfinite(row[lateral_at]) and math.isfinite(row[dphi_at])
             and math.isfinite(row[dphi_at + 1]) and math.isfinite(row[dphi_at + 2])
             and math.isfinite(row[dphi_at + 3]))
    left = radius * row[columns[_LEFT]] + row[tau_at] + row[tau_at + 1]
    right = radius * row[columns[_RIGHT]] + row[tau_at + 2] + row[tau_at + 3]
    if motor and math.isfinite(left) and math.isfinite(right):
        if abs(left) > best[7]:
            best[7], picks[7] = abs(left), index
        if abs(right) > best[8]:
            best[8], picks[8] = abs(right), index


def _wheel_picks(row: np.ndarray, index: int, contact: bool, columns: np.ndarray, best: np.ndarray,
                 picks: np.ndarray) -> tuple[float, bool, bool]:
    """Each wheel's peak use (picks 9-12) raised to the row's where it has the wheels' ``contact``; the row's least
    load (NaN loads left out), whether a load is negative and whether a wheel slips."""
    loads_at, use_at, slip_at = columns[_N], columns[_USE], columns[_SLIP]
    least = math.inf
    negative = slipping = False
    for wheel in range(4):
        load = row[loads_at + wheel]
        if not math.isnan(load):
            least = min(least, load)
        negative = negative or load < 0.0
        slipping = slipping or row[slip_at + wheel] > 0.5
        use = abs(row[use_at + wheel])
        if contact and use > best[9 + wheel]:
            best[9 + wheel], picks[9 + wheel] = use, index
    return least, negative, slipping


def _robot_picks(kept: np.ndarray, kept_valid: np.ndarray, block: np.ndarray, valid: np.ndarray, binding: int,
                 radius: float, offsets: np.ndarray, static: float, columns: np.ndarray, picks: np.ndarray) -> int:
    """One robot's picks (PICKS,), in time order, of its rows counted through ``kept`` then ``block``; returns the
    row binding its least adhesion force (-1: none). ``binding``: that of the kept rows (-1: none)."""
    t_at, err_at = columns[_T], columns[_ERR]
    peak_at = (columns[_LEFT], columns[_RIGHT], columns[_LATERAL], columns[_RESIDUAL])  # reduce.PEAKS
    best = np.full(PICKS, -math.inf)
    picks[:] = 0
    best[13] = math.inf  # the least load: a least, not a peak
    seen_slip = seen_negative = False
    last_error = -1
    late = _row(kept, block, 0)[t_at] + LATE
    least_contact, least_contact_load = 0, math.inf
    for source in range(2):
        rows, flags, first = (kept, kept_valid, 0) if source == 0 else (block, valid, kept.shape[0])
        for i in range(rows.shape[0]):
            if not flags[i]:
                continue
            row, index = rows[i], first + i
            t, err = row[t_at], row[err_at]
            if math.isfinite(err):
                last_error = index
                if t >= late and abs(err) > best[2]:
                    best[2], picks[2] = abs(err), index
            for pick in range(4):
                value = row[peak_at[pick]]
                if math.isfinite(value) and abs(value) > best[3 + pick]:
                    best[3 + pick], picks[3 + pick] = abs(value), index
            _motor_peaks(row, index, radius, columns, best, picks)
            contact = _contact(row, columns)
            least, negative, slipping = _wheel_picks(row, index, contact, columns, best, picks)
            if least < best[13]:
                best[13], picks[13] = least, index
            if contact and least < least_contact_load:
                least_contact, least_contact_load = index, least
            if slipping and not seen_slip:
                seen_slip, picks[14] = True, index
            if negative and not seen_negative:
                seen_negative, picks[15] = True, index
    picks[1] = last_error if last_error >= 0 else kept.shape[0] + block.shape[0] - 1
    binding = _binding(kept, kept_valid, block, valid, columns, offsets, static,
                       (binding, least_contact, picks[9], picks[10], picks[11], picks[12]))
    picks[16] = max(binding, 0)
    picks.sort()
    return binding


def _binding(kept: np.ndarray, kept_valid: np.ndarray, block: np.ndarray, valid: np.ndarray, columns: np.ndarray,
             offsets: np.ndarray, static: float, starts: tuple) -> int:
    """``reduce._binding`` of one robot: the row of the largest figure among its contact rows (-1: none), found from
    the largest figure of its ``starts`` rows (-1 or a row without contact: none)."""
    along = (offsets[0, 0], offsets[1, 0], offsets[2, 0], offsets[3, 0])
    across = (offsets[0, 1], offsets[1, 1], offsets[2, 1], offsets[3, 1])
    same_side = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            same_side[i, j] = 1.0 if np.sign(across[i]) == np.sign(across[j]) else 0.0
    binding, figure = -1, -math.inf
    for start in starts:
        if start >= 0 and _valid(kept_valid, valid, start) and _contact(_row(kept, block, start), columns):
            needed = _figure(_row(kept, block, start), columns, along, across, same_side, static, -math.inf)
            if needed > figure:
                binding, figure = start, needed
    screen = figure
    for source in range(2):
        rows, flags, first = (kept, kept_valid, 0) if source == 0 else (block, valid, kept.shape[0])
        for i in range(rows.shape[0]):
            if flags[i] and _contact(rows[i], columns):
                needed = _figure(rows[i], columns, along, across, same_side, static, screen)
                if needed > figure:
                    binding, figure = first + i, needed
    return binding


def _screen(kept: np.ndarray, kept_valid: np.ndarray, block: np.ndarray, valid: np.ndarray, binding: np.ndarray,
            radius: np.ndarray, offsets: np.ndarray, static: np.ndarray, columns: np.ndarray, picks: np.ndarray,
            new_binding: np.ndarray) -> None:
    """Every robot's picks (robots, PICKS) and binding row (robots,) of its kept rows (robots, kept, columns), then
    its block's (robots, instants, columns); ``kept_valid`` and ``valid``: the robot's run has the row. The arrays
    are taken ``unowned`` (the rows' views then cost no reference counts)."""
    kept, kept_valid, block, valid = unowned(kept), unowned(kept_valid), unowned(block), unowned(valid)
    binding, radius, offsets, static = unowned(binding), unowned(radius), unowned(offsets), unowned(static)
    columns, picks, new_binding = unowned(columns), unowned(picks), unowned(new_binding)
    for robot in range(block.shape[0]):
        new_binding[robot] = _robot_picks(kept[robot], kept_valid[robot], block[robot], valid[robot], binding[robot],
                                          radius[robot], offsets[robot], static[robot], columns, picks[robot])


def _gather(kept: np.ndarray, kept_valid: np.ndarray, block: np.ndarray, valid: np.ndarray, picks: np.ndarray,
            binding: np.ndarray, rows: np.ndarray, rows_valid: np.ndarray, rows_binding: np.ndarray) -> None:
    """The picked rows (robots, PICKS, columns) into ``rows``: whether each is one of the robot's, not a repeat of the
    row before it, into ``rows_valid``, and the index of the binding row among them (-1: none) into
    ``rows_binding``."""
    for robot in range(block.shape[0]):
        rows_binding[robot] = -1
        for pick in range(PICKS):
            index = picks[robot, pick]
            rows[robot, pick] = _row(kept[robot], block[robot], index)
            rows_valid[robot, pick] = (_valid(kept_valid[robot], valid[robot], index)
                                       and not (pick and index == picks[robot, pick - 1]))
            if index == binding[robot] and rows_binding[robot] < 0:
                rows_binding[robot] = pick


_row = jit(_row, inline='always')
_valid = jit(_valid, inline='always')
_contact = jit(_contact, inline='always')
_split = jit(_split, inline='always')
_sides = jit(_sides, inline='always')
_sample = jit(_sample, inline='always')
_motor_peaks = jit(_motor_peaks, inline='always')
_wheel_picks = jit(_wheel_picks, inline='always')
_holds = jit(_holds, inline='always')
_figure = jit(_figure)
_binding = jit(_binding)
_robot_picks = jit(_robot_picks)
screen = jit(_screen)
gather = jit(_gather)


def compile_screen() -> None:
    """Compile the screen and the gather (or load them from numba's cache), as a sweep's first block would."""
    kept, block = np.zeros((1, 0, int(COLUMNS.max()) + 4)), np.zeros((1, 2, int(COLUMNS.max()) + 4))
    kept_valid, valid = np.zeros((1, 0), dtype=np.bool_), np.ones((1, 2), dtype=np.bool_)
    picks, binding = np.empty((1, PICKS), dtype=np.int64), np.empty(1, dtype=np.int64)
    screen(kept, kept_valid, block, valid, np.full(1, -1), np.ones(1), np.ones((1, 4, 2)), np.ones(1), COLUMNS, picks,
           binding)
    gather(kept, kept_valid, block, valid, picks, binding, np.empty((1, PICKS, block.shape[2])),
           np.empty((1, PICKS), dtype=np.bool_), np.empty(1, dtype=np.int64))
