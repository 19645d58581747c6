"""The rows a sweep keeps of each robot's run (``sweep.reduce.DecidingRows``) give the results row the whole run
gives: the run summary and the motor analysis over every row, the reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model_helpers import random_parameters
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import Robot
from wallbot_sim.model.wheel_forces import split_chassis_wrench
from wallbot_sim.rundata.least_adhesion import holds_with, needed_adhesion, needed_adhesion_of
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


def test_the_least_adhesion_of_robots_side_by_side_is_each_robots_own():
    """``needed_adhesion_of`` over samples of three robots of their own (the chassis split of ideal contact, and
    forces that are not, re-shared as coulomb contact's) gives each robot's ``needed_adhesion``, and
    ``holds_with``, the test the reduce screens rows by, holds just above (the bisection's last interval, within
    round-off of F - F_run) and not just below."""
    rng = np.random.default_rng(7)
    robots = [Robot(random_parameters(rng)) for _ in range(3)]
    samples = 40
    loads = rng.uniform(-5.0, 60.0, size=(3, samples, 4))
    wrench = rng.normal(scale=30.0, size=(3, samples, 3))
    forces = [split_chassis_wrench(np.zeros(samples), wrench[i], loads[i], robot.wheel_offsets)
              for i, robot in enumerate(robots)]
    forces[1] = forces[1] + rng.normal(scale=5.0, size=forces[1].shape)
    want = np.concatenate([needed_adhesion(loads[i], forces[i], robot) for i, robot in enumerate(robots)])
    owner = np.repeat(np.arange(3), samples)
    offsets = np.array([robot.wheel_offsets for robot in robots])[owner]
    static = np.array([robot.params.wall_friction for robot in robots])[owner]
    every_load, every_force = loads.reshape(-1, 4), np.concatenate(forces)
    np.testing.assert_allclose(needed_adhesion_of(every_load, every_force, offsets, static), want, rtol=1e-12)
    margin = 1e-9 * np.maximum(np.abs(want), 1.0)
    assert np.all(holds_with(every_load, every_force, offsets, static, want + margin))
    below = want - margin
    assert not np.any(holds_with(every_load, every_force, offsets, static, below))
