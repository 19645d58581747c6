"""Each robot's results row reduced as the robots run: the few rows of its run that decide every output.

Every output of a results row (``compute.result_row``: the run summary and the motor analysis of
``wallbot_sim.rundata``) is a value of one row of the run, picked by a peak, a minimum, a first or a last
instant: the first row, the last with a tracking error, each peak |value| (tracking error after 5 s, drive
forces, residual, each side's motor torque, each wheel's friction use), the least load, the first slip and
lift-off, and the row binding the least adhesion force (``least_adhesion``: the largest of a per-row
figure). ``DecidingRows`` keeps, per robot, those rows of what it has seen: a block of instants at a time
it picks them again from the rows it kept and the block, so it holds a few rows per robot whatever the
duration. ``result_row`` over the kept rows then gives the row of the whole run: the same summary and
motor analysis, over a subset holding every row that decides them.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model import Robot, RobotParameters
from wallbot_sim.model.outputs import DriveForces, side_motor_torques
from wallbot_sim.rundata.csv_format import COLUMN
from wallbot_sim.rundata.least_adhesion import least_adhesion

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


def deciding_rows(rows: np.ndarray, valid: np.ndarray, robots: Sequence[Robot]) -> np.ndarray:
    """Per robot, the rows of ``rows`` (rows, robots, columns; ``valid``: the robot's run has that row) that
    decide its results row (the module's docstring): (picks, robots) row indices, each robot's in time order."""
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
    picks += [_peak(use[:, :, wheel], contact) for wheel in range(4)]
    picks.append(np.argmin(np.where(valid, np.where(np.isnan(loads), np.inf, loads).min(axis=2), np.inf), axis=0))
    picks.append(_first(valid & np.any(np.nan_to_num(_wheels(rows, 'slip')) > 0.5, axis=2)))
    picks.append(_first(valid & (np.nan_to_num(loads, nan=1.0).min(axis=2) < 0.0)))
    binding = np.zeros(rows.shape[1], dtype=int)
    for robot, model in enumerate(robots):
        samples = np.flatnonzero(contact[:, robot])
        if samples.size:
            binding[robot] = samples[least_adhesion(loads[samples, robot], forces[samples, robot], model)[1]]
    picks.append(binding)
    return np.sort(np.array(picks), axis=0)


class DecidingRows:
    """Per robot, the rows deciding its results row of what it has seen so far (``deciding_rows``)."""

    def __init__(self, robots: Sequence[RobotParameters], columns: int) -> None:
        self.robots = [Robot(params) for params in robots]
        self.rows = np.empty((0, len(robots), columns))
        self.valid = np.empty((0, len(robots)), dtype=bool)
        """Whether a kept row is one of the robot's (not a repeat, nor past its end)."""

    def add(self, rows: np.ndarray, valid: np.ndarray) -> None:
        """The next instants of every robot (instants, robots, columns); ``valid``: the robot's run has that row."""
        rows, valid = np.concatenate((self.rows, rows)), np.concatenate((self.valid, valid))
        picks = deciding_rows(rows, valid, self.robots)
        self.rows = np.take_along_axis(rows, picks[:, :, None], axis=0)
        self.valid = np.take_along_axis(valid, picks, axis=0)
        self.valid[1:] &= picks[1:] != picks[:-1]

    def run(self, robot: int) -> np.ndarray:
        """The kept rows of robot ``robot``, in time order."""
        return self.rows[self.valid[:, robot], robot]
