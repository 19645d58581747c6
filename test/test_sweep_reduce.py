"""The rows a sweep keeps of each robot's run (``sweep.reduce.DecidingRows``) give the results row the whole run
gives: the run summary and the motor analysis over every row, the reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_sim.config import load_robot_parameters
from wallbot_sim.rundata.csv_format import COLUMN
from wallbot_sim.sweep import parse_spec
from wallbot_sim.sweep.compute import OUTPUTS, result_row, single_robot_run
from wallbot_sim.sweep.reduce import DecidingRows

COULOMB = {'scenario': 'circle', 'contact': 'coulomb', 'controller': True, 'controller_mass_scale': 1.2,
           'duration': 0.3, 'grid': {'adhesion_force': [100.0, 200.0], 'com_height': [0.05, 0.4]}}
"""Robots that slide and hold, slide and lift off, and tip off at once."""
LONG = {'scenario': 'circle', 'contact': 'ideal', 'controller': True, 'controller_mass_scale': 0.8,
        'duration': 6.0, 'grid': {'adhesion_force': [200.0]}}
"""A run past 5 s: its peak tracking error after 5 s is an output."""


@pytest.fixture(scope='module')
def whole_runs() -> list[tuple]:
    """(params, its run on the single-robot path: every row) of each robot of COULOMB and LONG."""
    runs = []
    for values in (COULOMB, LONG):
        spec = parse_spec(values)
        for robot in spec.robots:
            params = load_robot_parameters().replace(**robot)
            runs.append((params, single_robot_run(spec.settings, params)))
    params, run = runs[-1]
    bumped = run.steps.copy()  # its error grows to the end: a bump makes its late peak a row in the middle
    bumped[np.isclose(bumped[:, COLUMN['t']], 5.5), COLUMN['err']] *= 10.0
    runs[-1] = (params, run._replace(steps=bumped))
    return runs


@pytest.mark.parametrize('block', [16, 1000, 100_000])
def test_kept_rows_give_the_whole_runs_results_rows(whole_runs, block):
    """Robots of different lengths (lift-offs end some early) side by side, fed ``block`` instants at a time: each
    robot's results row from its kept rows equals the one from all its rows, every column."""
    longest = max(len(run.steps) for _, run in whole_runs)
    columns = whole_runs[0][1].steps.shape[1]
    rows = np.full((longest, len(whole_runs), columns), 1e9)  # past a robot's end: values no run has
    valid = np.zeros((longest, len(whole_runs)), dtype=bool)
    for robot, (_, run) in enumerate(whole_runs):
        rows[:len(run.steps), robot], valid[:len(run.steps), robot] = run.steps, True
    reduced = DecidingRows([params for params, _ in whole_runs], columns)
    for start in range(0, longest, block):
        reduced.add(rows[start:start + block], valid[start:start + block])
    outcomes = set()
    for robot, (params, run) in enumerate(whole_runs):
        kept = reduced.run(robot)
        assert len(kept) <= 20 and np.all(np.diff(kept[:, 0]) > 0.0), 'a few rows, in time order'
        want = result_row(run, params)
        got = result_row(run._replace(steps=kept), params)
        for name, mine, theirs in zip(OUTPUTS, got, want):
            assert mine == pytest.approx(theirs, rel=1e-12, abs=1e-12, nan_ok=True), (robot, name)
        outcomes.add(tuple(dict(zip(OUTPUTS, want))[name] for name in ('slipped', 'detached')))
    assert {(1, 0), (1, 1), (0, 0)} <= outcomes, 'robots that slide, lift off, and do neither'
    assert not math.isnan(dict(zip(OUTPUTS, result_row(*reversed(whole_runs[-1]))))['peak_err_after_5s'])
