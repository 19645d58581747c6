"""The rows a sweep keeps of each robot's run (``sweep.reduce.DecidingRows``) give the results row the whole run
gives: the run summary and the motor analysis over every row, the reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model_helpers import random_parameters
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import Robot, wheel_forces
from wallbot_sim.model.wheel_forces import split_chassis_wrench
from wallbot_sim.rundata import least_adhesion
from wallbot_sim.rundata.least_adhesion import holds_with, needed_adhesion, needed_adhesion_of
from wallbot_sim.rundata.csv_format import COLUMN, CSV_COLUMNS
from wallbot_sim.sweep import parse_spec, screen
from wallbot_sim.sweep.compute import OUTPUTS, result_row, single_robot_run
from wallbot_sim.sweep.reduce import LATE, DecidingRows, deciding_rows

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


def side_by_side(runs: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the runs (robots, instants, columns), a robot's past its end values no run has, and whether each
    robot's run has the row (robots, instants)."""
    longest = max(len(run.steps) for _, run in runs)
    rows = np.full((len(runs), longest, runs[0][1].steps.shape[1]), 1e9)
    valid = np.zeros((len(runs), longest), dtype=bool)
    for robot, (_, run) in enumerate(runs):
        rows[robot, :len(run.steps)], valid[robot, :len(run.steps)] = run.steps, True
    return rows, valid


@pytest.mark.parametrize('block, compiled', [(16, True), (1000, True), (100_000, True), (1000, False)],
                         ids=['16-screen', '1000-screen', '100000-screen', '1000-numpy'])
def test_kept_rows_give_the_whole_runs_results_rows(whole_runs, block, compiled):
    """Robots of different lengths (lift-offs end some early) side by side, fed ``block`` instants at a time: each
    robot's results row from its kept rows equals the one from all its rows, every column."""
    rows, valid = side_by_side(whole_runs)
    reduced = DecidingRows([params for params, _ in whole_runs], rows.shape[2], compiled)
    for start in range(0, rows.shape[1], block):
        reduced.add(rows[:, start:start + block], valid[:, start:start + block])
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


def _spoiled(runs: list[tuple]) -> list[tuple]:
    """The runs with values a diverging run writes: a tracking error, a drive force, a wheel's load and use not
    finite at some rows, and a negative load."""
    rng = np.random.default_rng(3)
    spoiled = []
    for params, run in runs:
        steps = run.steps.copy()
        for name, value in (('err', math.nan), ('F_left', math.inf), ('N2', math.nan), ('use3', math.inf),
                            ('dphi1', math.nan), ('N4', -1.0), ('fx1', -math.inf)):
            steps[rng.integers(0, len(steps), size=3), COLUMN[name]] = value
        spoiled.append((params, run._replace(steps=steps)))
    return spoiled


@pytest.mark.parametrize('spoil', [False, True], ids=['runs', 'non-finite'])
@pytest.mark.parametrize('block', [61, 1000])
def test_the_compiled_screen_keeps_the_rows_the_numpy_reduce_keeps(whole_runs, block, spoil):
    """The compiled screen (``sweep.screen``) and the NumPy reduce (``deciding_rows``), fed the same blocks of
    coulomb robots that slide and lift off and of an ideal-contact robot under the controller (some blocks a robot at
    a time), keep the same rows of every robot after every block: the same picks and binding row, to the bit."""
    runs = _spoiled(whole_runs) if spoil else whole_runs
    rows, valid = side_by_side(runs)
    robots = [params for params, _ in runs]
    screened, reference = DecidingRows(robots, rows.shape[2]), DecidingRows(robots, rows.shape[2], compiled=False)
    for number, start in enumerate(range(0, rows.shape[1], block)):
        subsets = [slice(None)] if number % 2 == 0 else [slice(robot, robot + 1) for robot in range(len(robots))]
        for robots_now in subsets:
            for reduced in (screened, reference):
                reduced.add(rows[robots_now, start:start + block], valid[robots_now, start:start + block], robots_now)
        np.testing.assert_array_equal(screened.valid, reference.valid)
        np.testing.assert_array_equal(screened.rows[screened.valid], reference.rows[reference.valid])
        np.testing.assert_array_equal(screened.binding, reference.binding)
    assert np.count_nonzero(screened.binding >= 0) >= 3, 'robots with a binding row'


def test_the_screens_least_adhesion_of_a_row_is_the_numpy_ones():
    """Per row, the compiled screen's least adhesion force equals ``needed_adhesion_of``'s to the bit, and its test
    of a row against an adhesion force (``holds_with``) gives the same answer just above and below: for the chassis
    split of ideal contact and for forces that are not, re-shared as coulomb contact's."""
    rng = np.random.default_rng(11)
    for shared_as in ('chassis', 'coulomb'):
        robot = Robot(random_parameters(rng))
        samples = 300
        loads = rng.uniform(-5.0, 60.0, size=(samples, 4))
        forces = split_chassis_wrench(np.zeros(samples), rng.normal(scale=30.0, size=(samples, 3)), loads,
                                      robot.wheel_offsets)
        if shared_as == 'coulomb':
            forces = forces + rng.normal(scale=5.0, size=forces.shape)
        offsets = np.broadcast_to(robot.wheel_offsets, (samples, 4, 2))
        static = np.full(samples, robot.params.wall_friction)
        want = needed_adhesion_of(loads, forces, offsets, static)
        rows = np.zeros((samples, max(COLUMN.values()) + 1))
        rows[:, COLUMN['N1']:COLUMN['N1'] + 4] = loads
        rows[:, COLUMN['fx1']:COLUMN['fx1'] + 4] = forces[:, :, 0]
        rows[:, COLUMN['fy1']:COLUMN['fy1'] + 4] = forces[:, :, 1]
        along, across = tuple(robot.wheel_offsets[:, 0]), tuple(robot.wheel_offsets[:, 1])
        sides = np.sign(robot.wheel_offsets[:, 1])
        same_side = (sides[:, None] == sides[None, :]).astype(float)

        static_friction = robot.params.wall_friction
        got = np.array([screen._figure(row, screen.COLUMNS, along, across, same_side, static_friction, -math.inf)
                        for row in rows])
        np.testing.assert_array_equal(got, want)
        near = want * (1.0 + rng.choice([-1e-9, 1e-9], size=samples))
        held = np.array([screen._figure(row, screen.COLUMNS, along, across, same_side, static_friction, above)
                         == -math.inf for row, above in zip(rows, near)])
        np.testing.assert_array_equal(held, holds_with(loads, forces, offsets, static, near))
        assert 0 < held.sum() < samples


def test_the_screens_constants_are_the_reduces():
    """The screen's own copies of the constants it computes by (numba's cache of it follows its file alone)."""
    assert (screen.LATE, screen.BISECTIONS, screen.CHASSIS_SPLIT, screen.SINGULAR) == (
        LATE, least_adhesion.BISECTIONS, least_adhesion.CHASSIS_SPLIT, wheel_forces._SINGULAR)
    assert screen.PICKS == len(deciding_rows(np.zeros((1, 1, len(CSV_COLUMNS))), np.ones((1, 1), dtype=bool),
                                             [Robot(load_robot_parameters())])[0])
