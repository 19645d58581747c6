"""The coulomb solves in the body axes (``kernel.frame``): a stick/slip set's rows factored once and reused at every
heading give the motion numpy's least squares gives for the world's rows there, set after set, robot after robot."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from batch_helpers import minimum_norm_motion, random_robots
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.kernel import dynamics, frame, friction, layout, problem
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.robot import DOF

pytestmark = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')


def world_problem(constants: np.ndarray, flags: np.ndarray, y: np.ndarray, reference: np.ndarray,
                  sticking: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The row count, rows A, b, W and Q ``_problem`` gives at y with the ``sticking`` wheels."""
    rows, rhs = np.zeros((kernel.MAX_ROWS, DOF)), np.zeros(kernel.MAX_ROWS)
    factor, force = np.zeros((DOF, DOF)), np.zeros(DOF)
    count = problem._problem(y[:DOF], y[DOF:], reference, flags, constants, np.array([0.4, -0.3]), np.full(4, 2.0),
                             True, sticking, np.zeros(8), rows, rhs, factor, force)
    return count, rows, rhs, factor, force


@pytest.mark.parametrize('active', [('belt', 'non_lateral', 'nonslip'),
                                    ('tangent_heading', 'belt', 'non_lateral', 'nonslip'),
                                    ('trajectory', 'belt', 'nonslip')])
def test_the_body_frame_solve_is_the_world_least_squares_at_every_heading(active):
    """Two robots, each in its own workspace, every sticking set twice at new headings and
    speeds (the second time from the factored rows kept): qdd for the rows' b, for a force alone (b = 0) and for
    a batch of forces (the responses) are the minimum-norm motions of the world's rows, to 1e-9 of their size,
    wherever b lies in the rows' range, and refused where it does not. With the trajectory task (rows fixed in the
    world) nothing is kept."""
    rng = np.random.default_rng(11)
    robots = random_robots(rng, 2)
    constants = kernel.robot_constants(RobotBatch(robots), np.full(2, 10.0), np.full(2, 20.0))
    flags, _ = kernel.module_flags(active)
    _, matrix, gram, lower, vectors, scratch = dynamics._workspace()
    reference = rng.normal(size=dynamics.REFERENCE_FIELDS)
    sets = [np.array(bits, dtype=np.bool_) for bits in itertools.product((False, True), repeat=4)]
    for robot in range(2):
        mats, _, ints, *_ = layout._contact_workspace()  # each robot's own, as the batch gives it
        for sticking in sets + sets[::-1]:
            y = rng.normal(size=2 * DOF)
            y[2] = rng.uniform(-np.pi, np.pi)
            count, rows, rhs, factor, force = world_problem(constants[robot], flags, y, reference, sticking)
            rank = frame._frame_rows(y[:DOF], y[DOF:], reference, flags, constants[robot], sticking, rows, factor,
                                     count, mats, ints)
            assert (ints[layout.FRAME, frame.KEY] != 0) == (not flags[layout.TRAJECTORY])
            cos_t, sin_t = np.cos(y[2]), np.sin(y[2])
            for with_rhs, applied in ((True, force), (False, rng.normal(size=DOF))):
                b = rhs[:count] if with_rhs else np.zeros(count)
                consistent = np.allclose(rows[:count] @ np.linalg.lstsq(rows[:count], b, rcond=None)[0], b)
                out = np.full(DOF, np.nan)
                solved = frame._frame_solve(cos_t, sin_t, flags, factor, applied, rhs, with_rhs, count, rank, mats,
                                            ints, vectors, out)
                assert solved == consistent, (robot, sticking, with_rhs)
                if solved:  # else the heading task's b beside two lateral rows: left to the least squares
                    assert_motion(out, factor, applied, rows[:count], b)
            columns, responses = rng.normal(size=(3, DOF)), np.full((3, DOF), np.nan)
            frame._frame_responses(cos_t, sin_t, flags, factor, columns, 0, 3, count, rank, mats, ints, vectors,
                                   responses)
            for column, response in zip(columns, responses):
                assert_motion(response, factor, column, rows[:count], np.zeros(count))


def assert_motion(out: np.ndarray, factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> None:
    """``out`` is the minimum-norm motion under ``force`` and the rows, to 1e-9 of its size or of the free motion's."""
    expected = minimum_norm_motion(factor, force, rows, rhs)
    scale = max(np.max(np.abs(factor @ (factor.T @ force))), np.max(np.abs(expected)))
    assert np.allclose(out, expected, rtol=0.0, atol=1e-9 * scale)


@pytest.mark.parametrize('active', [('belt', 'non_lateral', 'nonslip'), ('tangent_heading', 'belt', 'nonslip'),
                                    ('trajectory', 'belt', 'nonslip')])
def test_the_sliding_components_responses_and_newtons_blocks_kept_per_set_are_the_worlds(active):
    """Each sliding component's response and Newton's blocks dt J_S D and -L D, from the set's body-axes constants
    kept while it holds (every set twice, robot after robot), are the world's: the minimum-norm motion under the
    component's unit force J_S^T e_k, and J_S(theta), L(theta) times it, to 1e-9 of their size. With the trajectory
    task they are left to the caller."""
    rng = np.random.default_rng(12)
    robots = random_robots(rng, 2)
    constants = kernel.robot_constants(RobotBatch(robots), np.full(2, 10.0), np.full(2, 20.0))
    flags, _ = kernel.module_flags(active)
    reference, dt = rng.normal(size=dynamics.REFERENCE_FIELDS), 1e-3
    directions = [direction for direction in range(2) if flags[layout.HELD_BY[direction]]]
    sets = [np.array(bits, dtype=np.bool_) for bits in itertools.product((False, True), repeat=4)]
    for robot in range(2):
        contact = kernel.contact_constants(robots[robot])
        mats, _, ints, *_ = layout._contact_workspace()
        for sticking in sets + sets[::-1]:
            y = rng.normal(size=2 * DOF)
            y[2] = rng.uniform(-np.pi, np.pi)
            components = [(wheel, direction) for wheel in range(4) if not sticking[wheel] for direction in directions]
            for k, (wheel, direction) in enumerate(components):
                ints[layout.WHEEL_OF, k], ints[layout.DIRECTION_OF, k] = wheel, direction
            count, rows, rhs, factor, force = world_problem(constants[robot], flags, y, reference, sticking)
            frame._frame_rows(y[:DOF], y[DOF:], reference, flags, constants[robot], sticking, rows, factor, count,
                              mats, ints)
            responses = np.full((layout.COLUMNS, DOF), np.nan)
            kept = frame._sliding_responses(np.cos(y[2]), np.sin(y[2]), flags, constants[robot], contact, dt,
                                            len(components), mats, ints, responses)
            assert kept == (not flags[layout.TRAJECTORY])
            if not kept:
                continue
            slip_rows, gain = np.zeros((len(components), DOF)), np.zeros((4, DOF))
            for k, (wheel, direction) in enumerate(components):
                friction._contact_row(np.cos(y[2]), np.sin(y[2]), constants[robot], wheel, direction, slip_rows[k])
            friction._load_gain(y[2], constants[robot], contact, gain)
            expected = np.array([minimum_norm_motion(factor, row, rows[:count], np.zeros(count))
                                 for row in slip_rows]).reshape(-1, DOF)
            scale = np.max(np.abs(factor @ factor.T))
            assert np.allclose(responses[1:1 + len(components)], expected, rtol=0.0, atol=1e-9 * scale)
            size = len(components)
            assert np.allclose(mats[layout.SLIP_BY_FRICTION, :size, :size], dt * slip_rows @ expected.T, rtol=0.0,
                               atol=1e-9 * dt * scale)
            load_scale = scale * np.max(np.abs(gain))
            assert np.allclose(mats[layout.LOAD_BY_FRICTION, :4, :size], -gain @ expected.T, rtol=0.0,
                               atol=1e-9 * load_scale)
