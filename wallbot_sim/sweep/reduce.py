"""Each robot's results row reduced as the robots run: the few rows of its run that decide every output.

Every output of a results row (``compute.result_row``: the run summary and the motor analysis of
``wallbot_sim.rundata``) is a value of one row of the run, picked by a peak, a minimum, a first or a last
instant: the first row, the last with a tracking error, each peak |value| (tracking error after 5 s, drive
forces, residual, each side's motor torque, each wheel's friction use), the least load, the first slip and
lift-off, and the row binding the least adhesion force (``least_adhesion``: the largest of a per-row
figure, each row's its own: ``needed_adhesion``). That row is found without bisecting every row: the largest
figure of a few rows (the robot's binding row so far, its least loaded row, each wheel's peak friction use) is
a lower bound, a row holding under that adhesion force (``holds_with``, the bisection's test) needs no more, and
only the others are bisected, every robot's at once. ``DecidingRows`` keeps, per robot, those rows of what it
has seen: a block of instants at a time it picks them again from the rows it kept and the block, so it holds a
few rows per robot whatever the duration, each robot's rows contiguous (robots, rows, columns). ``result_row`` over
the kept rows then gives the row of the whole run: the same summary and motor analysis, over a subset holding every
row that decides them. Where numba is installed the compiled screen (``sweep.screen``) picks the rows, a robot's in
one pass; ``deciding_rows`` here, vectorized over the robots, picks the same rows without numba.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model import Robot, RobotParameters
from wallbot_sim.model.outputs import DriveForces, side_motor_torques
from wallbot_sim.rundata.csv_format import COLUMN
from wallbot_sim.rundata.least_adhesion import holds_with, needed_adhesion_of

PEAKS = ('F_left', 'F_right', 'F_lateral', 'residual')
"""Columns whose peak |value| over the run is an output."""
LATE = 5.0
"""The tracking error's peak is taken from this long after the run's start on (``summarize_run``)."""


def _wheels(rows: np.ndarray, prefix: str) -> np.ndarray:
    start = COLUMN[f'{prefix}1']
    return rows[:, :, start:start + 4]


def _peak(values: np.ndarray, where: np.ndarray) -> np.ndarray:
    """Per robot, the row of the largest finite |value| among ``where`` (rows, robots)."""
    return np.argmax(np.where(where & np.isfinite(values), np.abs(values), -np.inf), axis=0)


def _first(where: np.ndarray) -> np.ndarray:
    return np.argmax(where, axis=0)


def _last(where: np.ndarray) -> np.ndarray:
    return len(where) - 1 - np.argmax(where[::-1], axis=0)


def deciding_rows(rows: np.ndarray, valid: np.ndarray, robots: Sequence[Robot],
                  binding: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per robot, the rows of ``rows`` (rows, robots, columns; ``valid``: the robot's run has that row) that
    decide its results row (the module's docstring): (picks, robots) row indices, each robot's in time order; and
    the row binding each robot's least adhesion force (-1: it has no row with its wheels' contact).

    ``binding`` (robots,): a row of ``rows`` binding the robot's least adhesion force among the rows before them,
    -1 where there is none."""
    column = {name: rows[:, :, COLUMN[name]] for name in ('t', 'err', 'F_lateral', *PEAKS)}
    t, err = column['t'], column['err']
    picks = [np.zeros(rows.shape[1], dtype=int), _last(valid & np.isfinite(err)),
             _peak(err, valid & (t >= t[0] + LATE))]
    picks += [_peak(column[name], valid) for name in PEAKS]
    radius = np.array([robot.params.wheel_radius for robot in robots])
    sides = side_motor_torques(DriveForces(column['F_left'], column['F_right'], column['F_lateral']),
                               np.moveaxis(_wheels(rows, 'tau'), 2, 0), radius)
    rates = _wheels(rows, 'dphi')
    motor = valid & np.isfinite(t) & np.isfinite(column['F_lateral']) & np.all(np.isfinite(rates), axis=2)
    motor &= np.isfinite(sides[0]) & np.isfinite(sides[1])
    picks += [_peak(torque, motor) for torque in sides]
    loads, use, forces = _wheels(rows, 'N'), _wheels(rows, 'use'), np.stack((_wheels(rows, 'fx'),
                                                                            _wheels(rows, 'fy')), axis=3)
    contact = (valid & np.all(np.isfinite(loads), axis=2) & np.all(np.isfinite(use), axis=2)
               & np.all(np.isfinite(forces), axis=(2, 3)))
    peak_use = [_peak(use[:, :, wheel], contact) for wheel in range(4)]
    picks += peak_use
    picks.append(np.argmin(np.where(valid, np.where(np.isnan(loads), np.inf, loads).min(axis=2), np.inf), axis=0))
    picks.append(_first(valid & np.any(np.nan_to_num(_wheels(rows, 'slip')) > 0.5, axis=2)))
    picks.append(_first(valid & (np.nan_to_num(loads, nan=1.0).min(axis=2) < 0.0)))
    least_load = np.argmin(np.where(contact, loads.min(axis=2), np.inf), axis=0)
    starts = np.array([least_load, *peak_use] if binding is None else [binding, least_load, *peak_use])
    binding = _binding(loads, forces, contact, robots, starts)
    picks.append(np.maximum(binding, 0))
    return np.sort(np.array(picks), axis=0), binding


def _binding(loads: np.ndarray, forces: np.ndarray, contact: np.ndarray, robots: Sequence[Robot],
             starts: np.ndarray) -> np.ndarray:
    """Per robot, the row of the largest ``needed_adhesion`` among its ``contact`` rows (-1: none), from the
    largest figure of its rows ``starts`` (starts, robots; -1 or a row without contact: none): only the rows not
    holding under it are bisected."""
    offsets = np.array([robot.wheel_offsets for robot in robots])
    static = np.array([robot.params.wall_friction for robot in robots])
    binding = np.full(contact.shape[1], -1)
    figure = np.full(contact.shape[1], -np.inf)
    owner = np.broadcast_to(np.arange(contact.shape[1]), starts.shape)
    usable = (starts >= 0) & contact[starts.clip(0), owner]
    _raise(binding, figure, starts[usable], owner[usable], loads, forces, offsets, static)
    row, robot = np.nonzero(contact)
    open_rows = ~holds_with(loads[row, robot], forces[row, robot], offsets[robot], static[robot], figure[robot])
    _raise(binding, figure, row[open_rows], robot[open_rows], loads, forces, offsets, static)
    return binding


def _raise(binding: np.ndarray, figure: np.ndarray, row: np.ndarray, robot: np.ndarray, loads: np.ndarray,
           forces: np.ndarray, offsets: np.ndarray, static: np.ndarray) -> None:
    """Each robot's ``binding`` row and its ``figure`` raised to the largest ``needed_adhesion`` of its (row, robot)
    pairs."""
    if not row.size:
        return
    needed = needed_adhesion_of(loads[row, robot], forces[row, robot], offsets[robot], static[robot])
    order = np.lexsort((-needed, robot))  # by robot, each robot's largest first
    leading = order[np.r_[True, robot[order][1:] != robot[order][:-1]]]
    larger = needed[leading] > figure[robot[leading]]
    binding[robot[leading][larger]] = row[leading][larger]
    figure[robot[leading][larger]] = needed[leading][larger]


class DecidingRows:
    """Per robot, the rows deciding its results row of what it has seen so far (``deciding_rows``): picked by the
    compiled screen (``screen``) where numba is installed, else (or not ``compiled``) by ``deciding_rows``, the same
    picks."""

    def __init__(self, robots: Sequence[RobotParameters], columns: int, compiled: bool = True) -> None:
        # imported here: the screen loads numba, which the CLI's other verbs, importing the sweep's spec, do not need
        from wallbot_sim.model.batch import kernel
        from wallbot_sim.sweep import screen
        self._screen = screen
        self._compiled = compiled and kernel.available()
        self.robots = [Robot(params) for params in robots]
        self._radius = np.array([params.wheel_radius for params in robots])
        self._offsets = np.array([robot.wheel_offsets for robot in self.robots])
        self._static = np.array([params.wall_friction for params in robots])
        self.rows = np.empty((len(robots), 0, columns))
        """The kept rows of each robot (robots, kept, columns), in time order."""
        self.valid = np.empty((len(robots), 0), dtype=bool)
        """Whether a kept row is one of the robot's (not a repeat, nor past its end)."""
        self.binding = np.full(len(robots), -1)
        """The kept row binding each robot's least adhesion force (-1: none yet)."""

    def add(self, rows: np.ndarray, valid: np.ndarray, robots: slice = slice(None)) -> None:
        """The next instants (robots, instants, columns) of the robots ``robots`` (all of them: every robot, once
        before the others); ``valid``: the robot's run has that row."""
        rows, valid = np.ascontiguousarray(rows), np.ascontiguousarray(valid)  # one layout: one compiled screen
        kept, kept_valid, binding = self.rows[robots], self.valid[robots], self.binding[robots]
        if kept.shape[1] == 0 and len(kept) < len(self.rows):
            raise ValueError("a robot's first rows are added with every robot's")
        picks = np.empty((len(rows), self._screen.PICKS), dtype=np.int64)
        if self._compiled:
            found = np.empty(len(rows), dtype=np.int64)
            self._screen.screen(kept, kept_valid, rows, valid, binding, self._radius[robots], self._offsets[robots],
                                self._static[robots], self._screen.COLUMNS, picks, found)
        else:
            both = np.concatenate((kept, rows), axis=1)
            every = np.concatenate((kept_valid, valid), axis=1)
            chosen, found = deciding_rows(both.transpose(1, 0, 2), every.T, self.robots[robots], binding)
            picks[:] = chosen.T
        new_rows = np.empty((len(rows), self._screen.PICKS, rows.shape[2]))
        new_valid = np.empty((len(rows), self._screen.PICKS), dtype=bool)
        new_binding = np.empty(len(rows), dtype=np.int64)
        self._screen.gather(kept, kept_valid, rows, valid, picks, found, new_rows, new_valid, new_binding)
        if kept.shape[1] == 0:
            self.rows, self.valid, self.binding = new_rows, new_valid, new_binding
        else:
            self.rows[robots], self.valid[robots], self.binding[robots] = new_rows, new_valid, new_binding

    def run(self, robot: int) -> np.ndarray:
        """The kept rows of robot ``robot``, in time order."""
        return self.rows[robot, self.valid[robot]]
