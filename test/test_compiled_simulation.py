"""``Simulation(..., engine='numba')`` against the Python model, robot by robot and step by step.

The compiled engine computes the motion (qdd, Q_c, residual) and the RK4 step by the batch's kernel;
the outputs derived from the motion (drive forces, normal loads, friction use) and everything the
configuration calls do are the model's own. Where the kernel does not apply (modules of your own) the
run is the Python one, bit for bit. Coulomb contact on the kernel: test_compiled_contact.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from batch_helpers import TOLERANCE, assert_agree, perturbed_starts, random_robots
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import (
    BaumgarteGains, Circle, ConstraintSelection, DivergedError, ModelError, ParameterError, Robot, SampledReference,
    Scenario, Simulation, SmoothStop, StepOutputs)
from wallbot_sim.model import compiled
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.compiled import AHEAD_FIRST, AHEAD_MOST
from wallbot_sim.model.constraints import NonLateral
from wallbot_sim.model.outputs import StepBlock, StepTable
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.trajectories import sample_plan

pytestmark = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')

QUANTITIES = ('q', 'qd', 'acceleration', 'constraint_force', 'drive', 'loads', 'use', 'wheel_forces', 'wheel_use',
              'slip_velocity')


def quantities(out: StepOutputs) -> dict[str, np.ndarray]:
    """What a step reports, as arrays: states, motion, drive forces, normal loads, friction use, each wheel's force,
    use and contact velocity, residual."""
    contact = out.contact
    return {'q': out.q, 'qd': out.qd, 'acceleration': out.acceleration, 'constraint_force': out.constraint_force,
            'drive': np.array([out.drive.left, out.drive.right, out.drive.lateral]), 'loads': contact.loads,
            'use': np.array(contact.use), 'wheel_forces': contact.wheel_forces, 'wheel_use': contact.wheel_use,
            'slip_velocity': contact.slip_velocity, 'residual': np.array([out.residual])}


class Pair:
    """The same robot on both engines, stepped together; every step's outputs kept for comparison."""

    def __init__(self, robot: Robot, reference, selection: ConstraintSelection, q0: np.ndarray, qd0: np.ndarray,
                 **options) -> None:
        self.python = Simulation(robot, reference, selection, q0, qd0, **options)
        self.numba = Simulation(robot, reference, selection, q0, qd0, engine='numba', **options)
        self.history: dict[str, list[list[np.ndarray]]] = {'python': [], 'numba': []}

    def both(self, call) -> list:
        return [call(self.python), call(self.numba)]

    def run(self, steps: int) -> None:
        """``steps`` steps; the outputs at two instants of three (so the kernel also computes RK4's first stage)."""
        for step in range(steps):
            if step % 3 != 2:
                for name in ('python', 'numba'):
                    self.history[name].append(quantities(getattr(self, name).outputs()))
            self.python.step()
            self.numba.step()
        assert self.python.steps == self.numba.steps and self.python.t == self.numba.t

    def assert_agree(self, label: str = '') -> None:
        """Every quantity within TOLERANCE of its largest magnitude over the run, the residual on the scale of
        the accelerations (a consistent set's residual is round-off)."""
        python, numba = self.history['python'], self.history['numba']
        assert len(python) == len(numba) > 0
        for key in QUANTITIES:
            assert_agree(f'{label} {key}', np.array([o[key] for o in numba]), np.array([o[key] for o in python]))
        residuals = np.array([[o['residual'][0] for o in python], [o['residual'][0] for o in numba]])
        scale = max(np.max(residuals[0]), max(np.max(np.abs(o['acceleration'])) for o in python))
        assert np.max(np.abs(residuals[1] - residuals[0])) <= TOLERANCE * scale, f'{label} residual'


def pairs(seed: int, count: int, scenario, selection: ConstraintSelection) -> list[Pair]:
    rng = np.random.default_rng(seed)
    robots = random_robots(rng, count)
    q0, qd0 = perturbed_starts(rng, robots, scenario)
    reference = scenario.reference if selection.trajectory else None
    return [Pair(robot, reference, selection, q0[i], qd0[i]) for i, robot in enumerate(robots)]


@pytest.mark.parametrize('scenario_name', ['circle', 'figure8'])
def test_full_set_with_the_trajectory_task_agrees(scenario_name):
    for i, pair in enumerate(pairs(21, 3, load_scenario(scenario_name),
                                   ConstraintSelection.parse('belt,non_lateral,nonslip'))):
        pair.run(300)
        pair.assert_agree(f'robot {i}')


def test_driven_set_under_motor_torques_agrees():
    """No trajectory task: belt, non-lateral, nonslip (B of rank 5, the pivoted solve) under torques."""
    rng = np.random.default_rng(22)
    for i, robot in enumerate(random_robots(rng, 3)):
        q0 = np.zeros(DOF)
        q0[2] = rng.uniform(-np.pi, np.pi)
        pair = Pair(robot, None, ConstraintSelection.structural(trajectory=False), q0, rng.normal(0.0, 0.05, DOF))
        pair.both(lambda simulation, torque=rng.uniform(-2.0, 2.0, 2): simulation.set_motor_torque(*torque))
        pair.run(300)
        pair.assert_agree(f'robot {i}')


@pytest.mark.parametrize('constraints, heading', [
    ('belt,non_lateral,nonslip', False),  # the centre task against non-lateral motion: inconsistent, rank-deficient
    ('non_lateral', False),               # inconsistent, full column rank
    ('belt', None),                       # consistent, dependent columns
], ids=['inconsistent-and-rank-deficient', 'inconsistent', 'rank-deficient'])
def test_least_squares_compromise_agrees(constraints, heading):
    selection = ConstraintSelection.parse(constraints, tangent_heading=heading)
    for i, pair in enumerate(pairs(23, 2, load_scenario('circle'), selection)):
        pair.run(300)
        pair.assert_agree(f'robot {i}')
    if constraints.startswith('belt,'):
        assert pair.python.outputs().residual > 1e-3  # the set really cannot hold


def test_a_run_from_a_later_start_with_another_step_agrees():
    """t0 and dt of the simulation's own: the reference instants the kernel is given are the model's."""
    rng = np.random.default_rng(25)
    (robot,) = random_robots(rng, 1)
    figure8 = load_scenario('figure8')
    q0, qd0 = figure8.initial_state(robot)
    pair = Pair(robot, figure8.reference, ConstraintSelection.parse('belt,non_lateral,nonslip'), q0, qd0,
                t0=3.7, dt=2e-3)
    pair.run(300)
    assert pair.numba.t == pytest.approx(3.7 + 300 * 2e-3)
    pair.assert_agree()


def test_a_reference_that_comes_to_rest_agrees_through_the_stop():
    """SmoothStop: the heading task loses its direction as the reference rests."""
    circle = load_scenario('circle')
    stopping = Scenario('stop', SmoothStop(circle.reference, duration=0.1, stop_time=0.2), 1.0, circle.initial)
    (pair,) = pairs(24, 1, stopping, ConstraintSelection.parse('belt,non_lateral,nonslip'))
    pair.run(450)
    pair.assert_agree()


def test_configuration_calls_mid_run_act_the_same_on_both_engines():
    """Constraint switches (with their projection and new gains), torques, a new reference, the adhesion
    force, reset and restore, between steps: both engines go on agreeing."""
    robot = Robot(load_robot_parameters().replace(com_offset=(0.02, -0.01)))
    circle, figure8 = load_scenario('circle'), load_scenario('figure8')
    q0, qd0 = circle.initial_state(robot)
    pair = Pair(robot, circle.reference, ConstraintSelection.parse('belt'), q0, qd0)
    pair.run(60)
    reports = pair.both(lambda s: s.set_constraints(ConstraintSelection.parse('belt,non_lateral,nonslip')))
    assert reports[1].violation_before == pytest.approx(reports[0].violation_before, rel=TOLERANCE)
    assert reports[0].violation_before > 0.01 and reports[1].violation_after < 1e-12
    pair.run(60)
    pair.both(lambda s: s.set_constraints(ConstraintSelection.structural(trajectory=False), BaumgarteGains(8.0, 6.0)))
    pair.both(lambda s: s.set_motor_torque(1.5, -0.5))
    pair.run(60)
    pair.both(lambda s: s.set_adhesion_force(250.0))
    pair.both(lambda s: s.set_constraints(ConstraintSelection.parse('belt,non_lateral,nonslip')))
    pair.both(lambda s: s.set_reference(figure8.reference))
    pair.run(60)
    saved = (pair.numba.steps, pair.numba.q, pair.numba.qd)
    pair.run(30)
    pair.both(lambda s: s.reset())
    assert pair.numba.t == 0.0 and np.array_equal(pair.numba.q, q0) and np.array_equal(pair.numba.qd, qd0)
    pair.run(30)
    pair.both(lambda s: s.restore(*saved))
    assert pair.numba.steps == saved[0]
    pair.run(60)
    pair.assert_agree()


@pytest.fixture
def kernel_calls(monkeypatch) -> dict[str, int]:
    """How often the engine called the kernel's run (counted, then passed on)."""
    calls = {'robot_run': 0}

    def counted(*args, _function=kernel.robot_run):
        calls['robot_run'] += 1
        return _function(*args)
    monkeypatch.setattr(kernel, 'robot_run', counted)
    return calls


def test_the_numba_engine_steps_by_the_kernel_a_chunk_at_a_time_and_the_python_one_never(kernel_calls):
    robot = Robot(load_robot_parameters())
    circle = load_scenario('circle')
    Simulation(robot, circle.reference, ConstraintSelection(), *circle.initial_state(robot)).run(0.1)
    assert kernel_calls == {'robot_run': 0}
    Simulation(robot, circle.reference, ConstraintSelection(), *circle.initial_state(robot), engine='numba').run(
        0.1, lambda out: None)  # the outputs of every instant, from the chunks
    chunks, covered = 0, 0
    while covered < 101:  # the 101 instants, in chunks of AHEAD_FIRST steps, doubling up to AHEAD_MOST
        covered += min(AHEAD_FIRST * 2 ** chunks, AHEAD_MOST)
        chunks += 1
    assert kernel_calls == {'robot_run': chunks}


def test_modules_of_your_own_run_the_python_model_bit_for_bit(kernel_calls):
    """The kernel knows the project's modules only: with one of your own the numba engine's run is the
    Python run exactly (it falls back), and the kernel is not called."""
    robot = Robot(load_robot_parameters())
    circle = load_scenario('circle')
    q0, qd0 = circle.initial_state(robot)
    lateral = NonLateral(BaumgarteGains())
    alone = [Simulation(robot, circle.reference, ConstraintSelection(), q0, qd0, extra_modules=[lateral],
                        engine=engine).run(0.05) for engine in ('python', 'numba')]
    assert np.array_equal(alone[0].q, alone[1].q) and np.array_equal(alone[0].qd, alone[1].qd)
    assert kernel_calls['robot_run'] == 0


def test_a_diverging_state_stops_with_the_same_error_and_keeps_the_last_finite_state():
    robot = Robot(load_robot_parameters().replace(com_offset=(0.03, 0.0)))
    errors, states = [], []
    for engine in ('python', 'numba'):
        qd0 = np.zeros(DOF)
        qd0[2] = 1e153  # the centripetal force m_b c thd^2 is finite for a step, then overflows
        simulation = Simulation(robot, None, ConstraintSelection(trajectory=False), np.zeros(DOF), qd0, engine=engine)
        with pytest.raises(DivergedError, match='no longer finite') as error:
            for _ in range(50):
                simulation.step()
        errors.append(str(error.value))
        states.append((simulation.steps, simulation.q, simulation.qd))
        assert np.all(np.isfinite(simulation.q)) and np.all(np.isfinite(simulation.qd))
    assert errors[0] == errors[1]
    assert states[0][0] == states[1][0] > 0
    assert np.allclose(states[0][1], states[1][1], rtol=1e-12) and np.allclose(states[0][2], states[1][2], rtol=1e-12)


def test_a_state_diverging_through_an_unfactorable_mass_matrix_stops_as_the_python_engine_does():
    """A reference jumping 1 cm between two samples 1 ms apart drives the tracked state to NaN; on the way the
    kernel's solves fail and its LU fallback meets the non-finite matrix. That is a divergence, within two steps
    of where the python engine meets it, not numba's LinAlgError. The engines agree until the state passes
    ~1e16 (a step or two after the jump); from there the blow-up (10^5 to 10^100 a step) is round-off, and
    where it overflows depends on the solve: the kernel solves these rows, of full column rank, from A's own
    normal equations, the python engine by the general form (seen: steps 78 and 80)."""
    plan = sample_plan(Circle(radius=0.8, period=20.0), 0.0, 0.3, 0.001)
    jumped = [(x + 0.01, y) if t >= 0.075 else (x, y) for t, (x, y) in zip(plan.times, plan.positions)]
    reference = SampledReference(plan.times, jumped, plan.velocities, plan.accelerations)
    selection = ConstraintSelection(belt=False, non_lateral=True, nonslip=True)
    q0 = np.array([0.8, 0.0, np.pi / 2, 0.0, 0.0, 0.0, 0.0])
    stopped = []
    for engine in ('python', 'numba'):
        simulation = Simulation(Robot(load_robot_parameters()), reference, selection, q0, np.zeros(DOF),
                                gains=BaumgarteGains(5.0, 5.0), engine=engine)
        with pytest.raises(DivergedError, match='no longer finite') as error:
            for _ in range(200):
                simulation.step()
        stopped.append(simulation.steps)
        assert str(error.value) == f'state is no longer finite at t = {simulation.t + simulation.dt:.3f} s'
    assert abs(stopped[0] - stopped[1]) <= 2 and min(stopped) > 75


def test_an_unknown_engine_is_refused_by_name():
    robot = Robot(load_robot_parameters())
    with pytest.raises(ParameterError, match="unknown engine 'fortran'"):
        Simulation(robot, None, ConstraintSelection(trajectory=False), np.zeros(DOF), np.zeros(DOF), engine='fortran')


def step_by_step(simulation: Simulation, steps: int) -> list[StepOutputs]:
    outputs = []
    simulation.run(steps * simulation.dt, outputs.append)
    return outputs


def tabulated(simulation: Simulation, steps: int, chunk: int) -> tuple[list[StepTable], StepOutputs]:
    tables = []
    final = simulation.run_table(steps * simulation.dt, tables.append, chunk=chunk)
    return tables, final


def assert_table_is_the_steps(tables: list[StepTable], outputs: list[StepOutputs]) -> None:
    """Every row equals its step's outputs to the bit."""
    rows = {field: np.concatenate([getattr(table, field) for table in tables]) for field in StepTable._fields
            if field != 'reference_position'}
    assert len(rows['t']) == len(outputs)
    expected = {'t': [o.t for o in outputs], 'q': [o.q for o in outputs], 'qd': [o.qd for o in outputs],
                'acceleration': [o.acceleration for o in outputs],
                'constraint_force': [o.constraint_force for o in outputs], 'residual': [o.residual for o in outputs],
                'drive': [(o.drive.left, o.drive.right, o.drive.lateral) for o in outputs],
                'loads': [o.contact.loads for o in outputs], 'use': [o.contact.use for o in outputs],
                'slipping': [o.contact.slipping for o in outputs],
                'wheel_forces': [o.contact.wheel_forces for o in outputs],
                'wheel_use': [o.contact.wheel_use for o in outputs],
                'wheel_slipping': [o.contact.wheel_slipping for o in outputs],
                'slip_velocity': [o.contact.slip_velocity for o in outputs]}
    for field, values in expected.items():
        assert np.array_equal(rows[field], np.array(values)), field
    errors = np.concatenate([table.tracking_error for table in tables])
    assert np.array_equal(errors, [o.tracking_error for o in outputs], equal_nan=True)


@pytest.mark.parametrize('scenario_name, constraints, chunk', [
    ('circle', 'none', 1000), ('figure8', 'belt,non_lateral,nonslip', 7), ('circle', 'belt,non_lateral', 1)])
def test_a_tabulated_run_is_the_step_by_step_run_to_the_bit(scenario_name, constraints, chunk):
    """run_table (the kernel's robot_run a chunk at a time, its outputs by the kernel's ideal_outputs)
    against run's outputs step by step: chunks of 1 and 7 steps and one longer than the run, both ends."""
    scenario = load_scenario(scenario_name)
    rng = np.random.default_rng(31)
    (robot,) = random_robots(rng, 1)
    q0, qd0 = perturbed_starts(rng, [robot], scenario)
    selection = ConstraintSelection.parse(constraints)
    runs = [Simulation(robot, scenario.reference, selection, q0[0], qd0[0], engine='numba') for _ in range(2)]
    outputs = step_by_step(runs[0], 250)
    assert runs[1].tabulates
    tables, final = tabulated(runs[1], 250, chunk)
    assert_table_is_the_steps(tables, outputs)
    assert len(tables) == -(-251 // chunk)
    assert runs[1].steps == 250 and runs[1].t == runs[0].t and np.array_equal(final.q, runs[0].q)


def test_a_tabulated_driven_run_under_torques_is_the_step_by_step_run():
    rng = np.random.default_rng(32)
    (robot,) = random_robots(rng, 1)
    runs = []
    for _ in range(2):
        runs.append(Simulation(robot, None, ConstraintSelection.structural(trajectory=False), np.zeros(DOF),
                               np.zeros(DOF), engine='numba'))
        runs[-1].set_motor_torque(1.5, -0.7)
    outputs = step_by_step(runs[0], 120)
    tables, _final = tabulated(runs[1], 120, 50)
    assert_table_is_the_steps(tables, outputs)
    assert all(table.reference_position is None for table in tables)


def diverging_pair() -> tuple[list[Simulation], np.ndarray]:
    """Two numba simulations of a spin that is finite for a step, then overflows (as the diverging test
    above), and their initial velocities."""
    robot = Robot(load_robot_parameters().replace(com_offset=(0.03, 0.0)))
    qd0 = np.zeros(DOF)
    qd0[2] = 1e153
    return [Simulation(robot, None, ConstraintSelection(trajectory=False), np.zeros(DOF), qd0, engine='numba')
            for _ in range(2)], qd0


def test_a_tabulated_run_stops_at_a_diverging_state_as_the_steps_do():
    runs, _qd0 = diverging_pair()
    outputs, tables = [], []
    with pytest.raises(DivergedError) as by_steps:
        runs[0].run(0.05, outputs.append)
    with pytest.raises(DivergedError) as by_table:
        runs[1].run_table(0.05, tables.append, chunk=4)
    assert str(by_table.value) == str(by_steps.value)
    assert_table_is_the_steps(tables, outputs)
    assert runs[1].steps == runs[0].steps and np.array_equal(runs[1].q, runs[0].q)


def test_only_the_compiled_ideal_engine_tabulates():
    robot = Robot(load_robot_parameters())
    still = np.zeros(DOF)
    driven = ConstraintSelection.structural(trajectory=False)
    assert not Simulation(robot, None, driven, still, still).tabulates
    assert not Simulation(robot, None, driven, still, still, engine='numba', contact='coulomb').tabulates
    with pytest.raises(ModelError, match='run_table needs the numba engine'):
        Simulation(robot, None, driven, still, still).run_table(0.01, lambda _table: None)
    with pytest.raises(ModelError, match='advance needs the numba engine'):
        Simulation(robot, None, driven, still, still).advance(10)


def test_steps_taken_ahead_are_the_steps_one_at_a_time_through_every_change(monkeypatch):
    """The numba engine takes steps ahead in chunks; a run with torque changes, a constraint switch, a new
    reference, a new adhesion force and a restore between steps, its outputs asked at some instants only,
    equals to the bit the same run taken one kernel step per call (chunks of one)."""
    robot = Robot(load_robot_parameters())
    figure8 = load_scenario('figure8')
    q0, qd0 = figure8.initial_state(robot)

    def history() -> list[dict[str, np.ndarray]]:
        simulation = Simulation(robot, figure8.reference, ConstraintSelection.parse('belt'), q0, qd0, engine='numba')
        seen = []
        for step in range(400):
            if step % 3 == 0:
                seen.append(quantities(simulation.outputs()))
            if step % 37 == 5:
                simulation.set_motor_torque(0.1 * (step % 7), -0.05 * (step % 5))
            if step == 100:
                simulation.set_constraints(ConstraintSelection.parse('belt,non_lateral,nonslip'))
            if step == 160:
                simulation.set_reference(load_scenario('circle').reference)
            if step == 220:
                simulation.set_adhesion_force(150.0)
            if step == 300:
                simulation.restore(250, seen[-20]['q'], seen[-20]['qd'])
            simulation.step()
        seen.append(quantities(simulation.outputs()))
        return seen

    ahead = history()
    monkeypatch.setattr(compiled, 'AHEAD_FIRST', 1)
    monkeypatch.setattr(compiled, 'AHEAD_MOST', 1)
    one_by_one = history()
    assert len(ahead) == len(one_by_one)
    for i, (a, b) in enumerate(zip(ahead, one_by_one)):
        assert all(np.array_equal(a[key], b[key]) for key in a), i


def advanced(simulation: Simulation, sizes: list[int], how: str) -> tuple[list[StepBlock], list[StepOutputs]]:
    """Blocks of ``sizes`` steps, a single step and its outputs between each two; the outputs after each block.
    ``how``: 'advance', or each block computed (``compute_block``, which must leave the simulation as it was),
    then taken ('compute_block-take'), its reference sampled beforehand for more steps ('sampled-...')."""
    blocks, after = [], []
    for size in sizes:
        if how != 'advance':
            sampled = simulation.sample_reference(size + 3) if how.startswith('sampled') else None
            steps, outputs = simulation.steps, simulation.outputs()
            blocks.append(simulation.compute_block(size, sampled))
            assert simulation.steps == steps
            assert_outputs_equal(simulation.outputs(), outputs)
            simulation.take(blocks[-1])
        else:
            blocks.append(simulation.advance(size))
        after.append(simulation.outputs())
        simulation.step()
    return blocks, after


def assert_outputs_equal(got: StepOutputs, expected: StepOutputs) -> None:
    assert got.t == expected.t and got.residual == expected.residual and got.motor_torque == expected.motor_torque
    for field in ('q', 'qd', 'acceleration', 'constraint_force', 'wheel_torques'):
        assert np.array_equal(getattr(got, field), getattr(expected, field)), field
    assert got.drive == expected.drive and got.reference == expected.reference
    assert np.array_equal(got.contact.loads, expected.contact.loads)
    assert (got.contact.use, got.contact.limits, got.contact.slipping, got.contact.friction_force) == (
        expected.contact.use, expected.contact.limits, expected.contact.slipping, expected.contact.friction_force)


@pytest.mark.parametrize('how', ['advance', 'compute_block-take', 'sampled-compute_block-take'])
@pytest.mark.parametrize('scenario_name, torque', [('circle', None), ('figure8', None), (None, (1.5, -0.7))])
def test_steps_advanced_in_blocks_are_the_steps_one_at_a_time_to_the_bit(scenario_name, torque, how):
    """advance (a block of steps by one kernel call, its outputs as arrays) against step and outputs one at a
    time: every row, what its messages carry (wheel torques), and the outputs after it.
    The same for a block computed without moving the simulation, then taken (what a paced loop does), and
    for one whose reference was sampled beforehand."""
    rng = np.random.default_rng(33)
    (robot,) = random_robots(rng, 1)
    if scenario_name is None:
        reference, selection = None, ConstraintSelection.structural(trajectory=False)
        q0, qd0 = np.zeros(DOF), np.zeros(DOF)
    else:
        scenario = load_scenario(scenario_name)
        reference, selection = scenario.reference, ConstraintSelection.parse('belt,non_lateral,nonslip')
        (q0,), (qd0,) = perturbed_starts(rng, [robot], scenario)
    runs = [Simulation(robot, reference, selection, q0, qd0, engine='numba') for _ in range(2)]
    for run in runs:
        run.set_motor_torque(*(torque or (0.0, 0.0)))
    sizes = [1, 7, 50, 2, 31]
    outputs = step_by_step(runs[0], sum(sizes) + len(sizes))
    blocks, after = advanced(runs[1], sizes, how)
    first = 1
    for block, size, last in zip(blocks, sizes, after):
        rows = outputs[first:first + size]
        assert_table_is_the_steps([block.table], rows)
        assert np.array_equal(block.wheel_torques, [o.wheel_torques for o in rows])
        assert np.array_equal(block.chassis_wrench, [o.chassis_wrench for o in rows])
        assert_outputs_equal(last, rows[-1])
        first += size + 1
    assert runs[1].steps == runs[0].steps and np.array_equal(runs[1].q, runs[0].q)


def test_a_block_uses_the_reference_sampled_beforehand_only_if_sampled_for_it(monkeypatch):
    """compute_block takes sample_reference's rows instead of sampling (the Python part of its work) when they
    were sampled from its first step for the reference in force; otherwise it samples its own."""
    robot, circle = Robot(load_robot_parameters()), load_scenario('circle')
    simulation = Simulation(robot, circle.reference, ConstraintSelection(), *circle.initial_state(robot),
                            engine='numba')
    elsewhere = simulation.sample_reference(10)
    simulation.take(simulation.compute_block(5))
    here = simulation.sample_reference(12)
    samplings = []
    monkeypatch.setattr(kernel, 'reference_samples', lambda *args, _sample=kernel.reference_samples: (
        samplings.append(args[2]), _sample(*args))[1])
    fresh = simulation.compute_block(10)
    assert samplings == [5]  # from its first step
    for sampled, sampling in ((here, False), (elsewhere, True)):
        block = simulation.compute_block(10, sampled)
        assert all(np.array_equal(a, b) for a, b in zip(block.table, fresh.table) if a is not None)
        assert samplings == [5, 5] if sampling else samplings == [5]
    simulation.set_reference(Circle(radius=0.5))
    simulation.compute_block(10, here)
    assert samplings == [5, 5, 5]  # sampled for the reference before


def test_a_block_reaching_a_diverging_state_leaves_the_simulation_where_it_was():
    runs, qd0 = diverging_pair()
    with pytest.raises(DivergedError) as by_steps:
        runs[0].run(0.05)
    assert runs[1].advance(20) is None
    assert runs[1].steps == 0 and np.array_equal(runs[1].qd, qd0)
    with pytest.raises(DivergedError) as after_the_block:
        runs[1].run(0.05)
    assert str(after_the_block.value) == str(by_steps.value) and np.array_equal(runs[1].q, runs[0].q)
