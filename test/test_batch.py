"""The batched core against the single-robot Simulation, robot by robot, and its solver against pinv."""

from __future__ import annotations

import numpy as np
import pytest

from batch_helpers import ENGINES, TOLERANCE, assert_agree, perturbed_starts, random_robots
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import (
    ConstraintSelection, DivergedError, ParameterError, Robot, Scenario, Simulation, SmoothStop, tangent_heading)
from wallbot_sim.model.batch import (
    BATCH_MODULES, BatchRecorder, BatchSimulation, RobotBatch, batch_constrained_acceleration,
    minimum_norm_least_squares)
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.constraints import wrap_angles
from wallbot_sim.model.constraint_set import MODULES
from wallbot_sim.model.constraints import wrap_angle
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.solver import constrained_acceleration

def run_both(robots: list[Robot], scenario, selection: ConstraintSelection, q0: np.ndarray, qd0: np.ndarray,
             steps: int, torques: np.ndarray | None = None, every: int = 50, engine: str = 'numpy') -> None:
    """Step the batch and one Simulation per robot side by side, comparing states and forces every ``every`` steps.

    Between comparisons the batch runs ``run`` (the compiled engine's steps in one call).
    """
    reference = scenario.reference if selection.trajectory else None
    batch = BatchSimulation(robots, reference, selection, q0, qd0, engine=engine)
    singles = [Simulation(robot, reference, selection, q0[i], qd0[i]) for i, robot in enumerate(robots)]
    if torques is not None:
        batch.set_motor_torque(torques)
        for single, torque in zip(singles, torques):
            single.set_motor_torque(*torque)
    keys = ('q', 'qd', 'acceleration', 'force', 'residual')
    history = {i: {key: [] for key in keys} for i in range(len(robots))}
    batch_history = {i: {key: [] for key in keys} for i in range(len(robots))}
    for step in range(steps + 1):
        if step % every == 0:
            outputs = batch.outputs()
            assert outputs.t == singles[0].t
            for i, single in enumerate(singles):
                single_out = single.outputs()
                for store, values in ((history[i], (single_out.q, single_out.qd, single_out.acceleration,
                                                    single_out.constraint_force, single_out.residual)),
                                      (batch_history[i], (outputs.q[i], outputs.qd[i], outputs.acceleration[i],
                                                          outputs.constraint_force[i], outputs.residual[i]))):
                    for key, value in zip(keys, values):
                        store[key].append(value)
        if step < steps:
            if step % every == 0:
                batch.run(min(every, steps - step))
            for single in singles:
                single.step()
    for i in range(len(robots)):
        for key in ('q', 'qd', 'acceleration', 'force'):
            assert_agree(f'robot {i} {key}', np.array(batch_history[i][key]), np.array(history[i][key]))
        # a consistent set's residual is round-off: it agrees on the scale of the accelerations it measures
        residual_scale = max(np.max(history[i]['residual']), np.max(np.abs(history[i]['acceleration'])))
        assert np.max(np.abs(np.subtract(batch_history[i]['residual'], history[i]['residual']))) <= (
            TOLERANCE * residual_scale), f'robot {i} residual'


@pytest.mark.parametrize('scenario_name', ['circle', 'figure8'])
@pytest.mark.parametrize('engine', ENGINES)
def test_full_set_with_the_trajectory_task_agrees_robot_by_robot(scenario_name, engine):
    """simulate --scenario circle --constraints belt,non_lateral,nonslip, for random robots from random starts."""
    rng = np.random.default_rng(11)
    robots = random_robots(rng, 6)
    scenario = load_scenario(scenario_name)
    q0, qd0 = perturbed_starts(rng, robots, scenario)
    run_both(robots, scenario, ConstraintSelection.parse('belt,non_lateral,nonslip'), q0, qd0, steps=400,
             engine=engine)


@pytest.mark.parametrize('engine', ENGINES)
def test_driven_set_without_the_trajectory_task_agrees_robot_by_robot(engine):
    """Belt, non-lateral, nonslip, motor torques per robot: A has dependent rows, so B has dependent columns."""
    rng = np.random.default_rng(12)
    robots = random_robots(rng, 6)
    q0 = np.zeros((6, DOF))
    q0[:, 2] = rng.uniform(-np.pi, np.pi, 6)
    qd0 = rng.normal(0.0, 0.05, (6, DOF))
    run_both(robots, load_scenario('circle'), ConstraintSelection.structural(trajectory=False), q0, qd0, steps=400,
             torques=rng.uniform(-2.0, 2.0, (6, 2)), engine=engine)


@pytest.mark.parametrize('constraints, heading', [
    ('belt,non_lateral,nonslip', False),  # centre task against non-lateral motion, and a spin free: both
    ('non_lateral', False),               # inconsistent, full column rank
    ('belt', None),                       # consistent, dependent columns (the spins the belt leaves free)
    ('none', None),                       # the trajectory task alone
], ids=['inconsistent-and-rank-deficient', 'inconsistent', 'rank-deficient', 'trajectory-only'])
@pytest.mark.parametrize('engine', ENGINES)
def test_least_squares_compromise_per_robot_agrees(constraints, heading, engine):
    rng = np.random.default_rng(13)
    robots = random_robots(rng, 5)
    scenario = load_scenario('circle')
    q0, qd0 = perturbed_starts(rng, robots, scenario)
    selection = ConstraintSelection.parse(constraints, tangent_heading=heading)
    run_both(robots, scenario, selection, q0, qd0, steps=300, engine=engine)


def test_the_inconsistent_case_really_is_a_compromise():
    """The first case above leaves a residual (the set cannot hold) and B a dependent column."""
    rng = np.random.default_rng(13)
    robots = random_robots(rng, 5)
    scenario = load_scenario('circle')
    q0, qd0 = perturbed_starts(rng, robots, scenario)
    batch = BatchSimulation(robots, scenario.reference,
                            ConstraintSelection.parse('belt,non_lateral,nonslip', tangent_heading=False), q0, qd0)
    force, rows, rhs = batch._problem(batch.t, batch.q, batch.qd)
    matrices = rows @ batch.robots.mass_inverse_factor(batch.q)
    assert all(np.linalg.matrix_rank(matrix) < DOF for matrix in matrices)
    assert np.all(batch.outputs().residual > 1e-3)


def pinv_solutions(matrices: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    return np.array([np.linalg.pinv(matrix) @ r for matrix, r in zip(matrices, rhs)])


@pytest.mark.parametrize('rank', [7, 6, 5, 3, 0])
def test_minimum_norm_least_squares_is_pinv_robot_by_robot(rank):
    """Random B of a given rank (dependent rows and columns, inconsistent right sides) against pinv."""
    rng = np.random.default_rng(rank)
    count, rows, columns = 50, 10, 7
    left = rng.normal(size=(count, rows, rank))
    right = rng.normal(size=(count, rank, columns))
    matrices = left @ right
    rhs = rng.normal(size=(count, rows))
    expected = pinv_solutions(matrices, rhs)
    solved = minimum_norm_least_squares(matrices, rhs)
    assert np.allclose(solved, expected, rtol=0.0, atol=1e-9 * max(1.0, np.max(np.abs(expected))))


def test_a_batch_mixing_ranks_solves_each_robot_alone():
    """Full-rank, rank-deficient and zero matrices in one batch: each gets its own minimum-norm solution."""
    rng = np.random.default_rng(5)
    matrices = rng.normal(size=(3, 8, 7))
    matrices[1, :, 4] = 2.0 * matrices[1, :, 1] - matrices[1, :, 0]
    matrices[2] = 0.0
    rhs = rng.normal(size=(3, 8))
    assert np.allclose(minimum_norm_least_squares(matrices, rhs), pinv_solutions(matrices, rhs), atol=1e-12)


def test_batched_acceleration_matches_the_single_solver_on_random_problems():
    """W, Q, A, b drawn at random (A with a repeated row): qdd as the model's constrained_acceleration gives it."""
    rng = np.random.default_rng(7)
    count = 40
    mass = rng.normal(size=(count, DOF, DOF))
    mass = mass @ np.swapaxes(mass, 1, 2) + DOF * np.eye(DOF)
    factors = np.linalg.cholesky(np.linalg.inv(mass))
    forces = rng.normal(size=(count, DOF))
    rows = rng.normal(size=(count, 5, DOF))
    rows[:, 4] = rows[:, 0]
    rhs = rng.normal(size=(count, 5))
    expected = np.array([constrained_acceleration(*problem) for problem in zip(factors, forces, rows, rhs)])
    assert np.allclose(batch_constrained_acceleration(factors, forces, rows, rhs), expected, rtol=1e-10, atol=1e-12)


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
@pytest.mark.parametrize('rank', [7, 5, 0])
def test_compiled_solves_match_the_numpy_ones_robot_by_robot(rank):
    """The robots' own factors W and rows making B = A W random of a given rank (so of moderate condition):
    qdd as the NumPy engine gives it."""
    rng = np.random.default_rng(17 + rank)
    robots = RobotBatch(random_robots(rng, 30))
    factors = robots.mass_inverse_factor(rng.normal(size=(30, DOF)))
    forces = rng.normal(size=(30, DOF))
    rows = rng.normal(size=(30, 9, rank)) @ rng.normal(size=(30, rank, DOF)) @ np.linalg.inv(factors)
    rhs = rng.normal(size=(30, 9))
    expected = batch_constrained_acceleration(factors, forces, rows, rhs)
    assert np.allclose(kernel.constrained_accelerations(factors, forces, rows, rhs), expected, rtol=1e-9,
                       atol=1e-9 * np.max(np.abs(expected)))


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
@pytest.mark.parametrize('rank', [7, 6])
def test_rows_of_full_column_rank_decide_the_acceleration_whatever_mass_and_force(rank):
    """The kernel's shortcut (``linalg._full_rank_solve``): sparse rows (a module's touch few coordinates), some
    repeating others, with inconsistent right sides; where they have full column rank, qdd is the Udwadia-Kalaba
    acceleration of numpy's SVD least squares for each of several W and Q; where they do not, it is refused."""
    from wallbot_sim.model.batch.kernel import dynamics, linalg
    rng = np.random.default_rng(23 + rank)
    sparse = rng.normal(size=(7, DOF)) * (rng.random(size=(7, DOF)) < 0.4) + np.eye(DOF)
    sparse[:, rank:] = sparse[:, :rank] @ rng.normal(size=(rank, DOF - rank)) if rank < DOF else sparse[:, rank:]
    rows = np.vstack((sparse, 2.0 * sparse[1], sparse[3] - sparse[5]))
    rhs = rng.normal(size=len(rows))
    padded_rows, padded_rhs = np.zeros((kernel.MAX_ROWS, DOF)), np.zeros(kernel.MAX_ROWS)
    padded_rows[:len(rows)], padded_rhs[:len(rows)] = rows, rhs
    _, _, gram, lower, _, _ = dynamics._workspace()
    out = np.full(DOF, np.nan)
    solved = linalg._full_rank_solve(padded_rows, padded_rhs, len(rows), gram, lower, out)
    assert solved == (np.linalg.matrix_rank(rows) == DOF) == (rank == DOF)
    if not solved:
        return
    robots = RobotBatch(random_robots(rng, 3))
    for factor, force in zip(robots.mass_inverse_factor(rng.normal(size=(3, DOF))), rng.normal(size=(3, DOF))):
        scaled, matrix = factor.T @ force, rows @ factor
        expected = factor @ (scaled + np.linalg.lstsq(matrix, rhs - matrix @ scaled, rcond=None)[0])
        assert np.allclose(out, expected, rtol=0.0, atol=1e-10 * np.max(np.abs(expected)))


def test_mass_matrix_and_factor_match_the_robot_model():
    rng = np.random.default_rng(3)
    robots = random_robots(rng, 8)
    batch = BatchSimulation(robots, None, ConstraintSelection.structural(trajectory=False),
                            rng.normal(size=(8, DOF)), np.zeros((8, DOF)))
    q, qd = batch.q, rng.normal(size=(8, DOF))
    torques = rng.normal(size=(8, 2))
    for i, robot in enumerate(robots):
        assert np.allclose(batch.robots.mass_matrix(q)[i], robot.mass_matrix(q[i]), rtol=1e-14, atol=0.0)
        assert np.allclose(batch.robots.mass_inverse_factor(q)[i], robot.mass_inverse_factor(q[i]), rtol=1e-13,
                           atol=1e-15)
        assert np.allclose(batch.robots.applied_force(q, qd, torques)[i], robot.applied_force(q[i], qd[i], torques[i]),
                           rtol=1e-13, atol=1e-13)


def test_a_batch_of_one_robot_repeated_holds_what_a_batch_of_its_copies_holds():
    robot = random_robots(np.random.default_rng(5), 1)[0]
    copies, repeated = RobotBatch([robot] * 3), RobotBatch.repeated(robot, 3)
    assert repeated.size == 3 and repeated.robots == copies.robots
    assert vars(repeated).keys() == vars(copies).keys()
    for name, value in vars(copies).items():
        if isinstance(value, np.ndarray):
            assert np.array_equal(getattr(repeated, name), value), name


def test_every_constraint_module_has_a_batched_form():
    assert list(BATCH_MODULES) == list(MODULES)


def test_bad_batches_are_refused_with_a_reason():
    robot = Robot(load_robot_parameters())
    selection = ConstraintSelection.parse('belt')
    reference = load_scenario('circle').reference
    with pytest.raises(ParameterError, match="unknown engine 'cuda'"):
        BatchSimulation([robot], reference, selection, np.zeros((1, DOF)), np.zeros((1, DOF)), engine='cuda')
    with pytest.raises(ParameterError, match='at least one robot'):
        BatchSimulation([], reference, selection, np.zeros((0, DOF)), np.zeros((0, DOF)))
    with pytest.raises(ParameterError, match=r'shape \(2, 7\)'):
        BatchSimulation([robot, robot], reference, selection, np.zeros((2, DOF)), np.zeros(DOF))
    with pytest.raises(ParameterError, match='finite'):
        BatchSimulation([robot], reference, selection, np.full((1, DOF), np.nan), np.zeros((1, DOF)))
    with pytest.raises(ParameterError, match='needs a reference'):
        BatchSimulation([robot], None, selection, np.zeros((1, DOF)), np.zeros((1, DOF)))


@pytest.mark.parametrize('engine', ENGINES)
def test_a_diverging_robot_stops_the_batch_unchanged_and_is_named(engine):
    """A robot whose state stops being finite is reported by index; no robot's state moves."""
    params = load_robot_parameters()
    robots = [Robot(params), Robot(params)]
    q0, qd0 = np.zeros((2, DOF)), np.zeros((2, DOF))
    qd0[1, 2] = 1e200  # its centripetal and resistance terms overflow at once
    batch = BatchSimulation(robots, None, ConstraintSelection.parse('none', trajectory=False), q0, qd0, engine=engine)
    with pytest.raises(DivergedError, match=r'robot\(s\) \[1\]'):
        batch.step()
    assert batch.steps == 0 and np.array_equal(batch.qd, qd0)


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_a_compiled_run_that_diverges_stops_every_robot_at_the_step_before():
    """One robot overflows after some steps: the batch is left at the step before, as step by step."""
    params = load_robot_parameters().replace(com_offset=(0.03, 0.0))
    robots = [Robot(params), Robot(params)]
    q0, qd0 = np.zeros((2, DOF)), np.zeros((2, DOF))
    qd0[1, 2] = 1e153  # its centripetal force m_b c thd^2 is finite for a step, then overflows
    selection = ConstraintSelection.parse('none', trajectory=False)
    stepped = BatchSimulation(robots, None, selection, q0, qd0)
    with pytest.raises(DivergedError) as by_step:
        for _ in range(50):
            stepped.step()
    compiled = BatchSimulation(robots, None, selection, q0, qd0, engine='numba')
    with pytest.raises(DivergedError) as by_run:
        compiled.run(50)
    assert str(by_run.value) == str(by_step.value)
    assert compiled.steps == stepped.steps > 0
    assert np.allclose(compiled.q, stepped.q, rtol=1e-12) and np.allclose(compiled.qd, stepped.qd, rtol=1e-12)


@pytest.mark.parametrize('engine', ENGINES)
def test_a_reference_that_comes_to_rest_agrees_through_the_stop(engine):
    """SmoothStop: the heading task has no direction once the reference rests, and holds the heading."""
    rng = np.random.default_rng(14)
    robots = random_robots(rng, 4)
    circle = load_scenario('circle')
    stopping = Scenario('stop', SmoothStop(circle.reference, duration=0.1, stop_time=0.2), 1.0, circle.initial)
    q0, qd0 = perturbed_starts(rng, robots, stopping)
    assert tangent_heading(stopping.reference.sample(0.35)) is None
    run_both(robots, stopping, ConstraintSelection.parse('belt,non_lateral,nonslip'), q0, qd0, steps=450,
             engine=engine)


def test_wrapped_angles_match_the_single_robot_wrap():
    angles = np.concatenate((np.random.default_rng(15).uniform(-40.0, 40.0, 200),
                             [0.0, np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 2 * np.pi, np.nextafter(np.pi, 4.0)]))
    expected = [wrap_angle(angle) for angle in angles]
    assert np.allclose(wrap_angles(angles), expected, rtol=0.0, atol=1e-14)
    assert np.all((wrap_angles(angles) > -np.pi) & (wrap_angles(angles) <= np.pi))


def test_the_recorder_keeps_per_robot_time_series_of_the_instants_asked():
    rng = np.random.default_rng(16)
    robots = random_robots(rng, 3)
    scenario = load_scenario('circle')
    batch = BatchSimulation.from_scenario(robots, scenario, ConstraintSelection.parse('belt'))
    recorder = BatchRecorder(('q', 'tracking_error', 'loads'), every=10)
    final = batch.run(30, recorder)
    series = recorder.series()
    assert np.allclose(series['t'], [0.0, 0.01, 0.02, 0.03])
    assert series['q'].shape == (4, 3, DOF) and series['loads'].shape == (4, 3, 4)
    assert np.array_equal(series['q'][-1], final.q)
    assert np.array_equal(series['tracking_error'][-1], final.tracking_error)
    again = BatchSimulation.from_scenario(robots, scenario, ConstraintSelection.parse('belt'))
    again.run(20)
    assert np.array_equal(series['q'][2], again.q)
    with pytest.raises(ParameterError, match="no field 'torque'"):
        BatchRecorder(('q', 'torque'))
