"""The batched contact against the single-robot Simulation, robot by robot: loads, each wheel's force, use and slip,
detachment."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from model_helpers import random_parameters
from batch_helpers import ENGINES, assert_agree, perturbed_starts, random_robots
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.model.batch import BatchSimulation, kernel
from wallbot_sim.model.contact import CoulombContact, DetachedError
from wallbot_sim.model.errors import ModelError
from wallbot_sim.model.robot import DOF

DRIVEN = ConstraintSelection.structural(trajectory=False)


def mixed_robots(rng: np.random.Generator, count: int) -> list[Robot]:
    """Random robots; every third tall, short and held just about at its tipping limit (it may peel off)."""
    robots = []
    for i in range(count):
        params = random_parameters(rng)
        if i % 3 == 0:
            params = params.replace(com_height=float(rng.uniform(0.12, 0.2)), wall_friction=0.9,
                                    kinetic_friction=0.8, half_wheelbase=float(rng.uniform(0.06, 0.08)))
            limit = Robot(params).adsorption.tipping_limit
        else:
            limit = Robot(params).adsorption.minimum_force
        robots.append(Robot(params.replace(adhesion_force=float(rng.uniform(0.8, 2.0)) * limit)))
    return robots


def mixed_start(seed: int = 5) -> tuple[list[Robot], np.ndarray, np.ndarray]:
    """12 ``mixed_robots`` facing +X or -X under torques: the tall ones turning in place (the heading turns their
    upper wheels' loads away: one lifts off mid-run), the others driven at random (some hold, some slide)."""
    rng = np.random.default_rng(seed)
    robots = mixed_robots(rng, 12)
    q0 = np.zeros((12, DOF))
    q0[:, 2] = rng.choice([0.0, np.pi], 12)
    torques = rng.uniform(-1.5, 1.5, (12, 2))
    turning = np.arange(12) % 3 == 0
    spin = rng.uniform(2.0, 3.0, 12)
    torques[turning] = np.stack((-spin, spin), axis=1)[turning]
    return robots, q0, torques


KEYS = ('q', 'qd', 'acceleration', 'constraint force', 'friction force', 'drive forces', 'loads', 'use',
        'wheel forces', 'wheel use', 'slip velocity')


class LoneRuns(NamedTuple):
    """Each robot stepped alone on the single-robot ``Simulation`` until it detaches or the steps end."""

    history: list[dict[str, np.ndarray]]
    """Per robot, per key of KEYS, its values at each instant it ran (one row an instant)."""
    wheel_slipping: list[np.ndarray]
    """Per robot, its wheels' slipping at each instant (instants, 4)."""
    slipping: list[np.ndarray]
    """Per robot, its channels' slipping at each instant."""
    t_detached: np.ndarray
    """Per robot, the time it detached (nan: never)."""
    wheel: np.ndarray
    """Per robot, the wheel that lifted off (0: none)."""
    spin_inertia: np.ndarray
    """Per robot, its wheels' spin inertia (kg m^2)."""

    @property
    def slipped(self) -> np.ndarray:
        return np.array([bool(np.any(slipping)) for slipping in self.wheel_slipping])


def lone_runs(singles: list[Simulation], steps: int) -> LoneRuns:
    history = [{key: [] for key in KEYS} for _ in singles]
    wheel_slipping: list[list] = [[] for _ in singles]
    slipping: list[list] = [[] for _ in singles]
    t_detached, wheel = np.full(len(singles), np.nan), np.zeros(len(singles), dtype=int)
    for i, single in enumerate(singles):
        for _ in range(steps):
            mine = single.outputs()
            contact = mine.contact
            wheel_slipping[i].append(contact.wheel_slipping)
            slipping[i].append(contact.slipping)
            friction = np.zeros(DOF) if contact.friction_force is None else contact.friction_force
            values = (mine.q, mine.qd, mine.acceleration, mine.constraint_force, friction,
                      [mine.drive.left, mine.drive.right, mine.drive.lateral], contact.loads, contact.use,
                      contact.wheel_forces, contact.wheel_use, contact.slip_velocity)
            for key, value in zip(KEYS, values):
                history[i][key].append(np.asarray(value, dtype=float))
            try:
                single.step()
            except DetachedError as detached:
                t_detached[i], wheel[i] = detached.t, detached.wheel
                break
    return LoneRuns([{key: np.array(values) for key, values in robot.items()} for robot in history],
                    [np.array(robot, dtype=bool) for robot in wheel_slipping],
                    [np.array(robot, dtype=bool) for robot in slipping], t_detached, wheel,
                    np.array([single.robot.params.wheel_spin_inertia for single in singles]))


def compare_contact(batch: BatchSimulation, lone: LoneRuns) -> None:
    """Step the batch as long as the lone robots ran: every robot's outputs agree with its lone run's until it
    detaches, which happens at the same instant and wheel."""
    steps = max(len(robot['q']) for robot in lone.history)
    batch_history = [{key: [] for key in KEYS} for _ in lone.history]
    for k in range(steps):
        out = batch.outputs()
        for i, single_history in enumerate(lone.history):
            if k >= len(single_history['q']):
                continue
            assert tuple(out.wheel_slipping[i]) == tuple(lone.wheel_slipping[i][k]), f'robot {i} wheels at t = {out.t:.3f} s'
            assert tuple(out.slipping[i]) == tuple(lone.slipping[i][k]), f'robot {i} channels at t = {out.t:.3f} s'
            values = (out.q[i], out.qd[i], out.acceleration[i], out.constraint_force[i], out.friction_force[i],
                      out.drive[i], out.loads[i], out.use[i], out.wheel_forces[i], out.wheel_use[i], out.slip_velocity[i])
            for key, value in zip(KEYS, values):
                batch_history[i][key].append(np.asarray(value, dtype=float))
        batch.step()
    for i, single_history in enumerate(lone.history):
        # floors where a quantity is round-off, 1 in its unit (the velocities of a robot that holds) and for the
        # accelerations the scale of those the contact forces make (a holding robot's are what remains of them)
        floors = dict.fromkeys(KEYS, 1.0)
        floors['acceleration'] = max(1.0, np.max(np.abs(single_history['constraint force']))
                                     / lone.spin_inertia[i])
        for key in KEYS:
            expected, got = single_history[key], np.array(batch_history[i][key])
            infinite = ~np.isfinite(expected)  # a wheel of no load with a force: use inf (ideal contact's lift-off)
            assert np.array_equal(got[infinite], expected[infinite]), f'robot {i} {key}'
            assert_agree(f'robot {i} {key}', np.where(infinite, 0.0, got), np.where(infinite, 0.0, expected),
                         floor=floors[key])
    t_detached = lone.t_detached
    assert np.array_equal(np.isnan(batch.t_detached), np.isnan(t_detached))
    assert np.array_equal(batch.t_detached[~np.isnan(t_detached)], t_detached[~np.isnan(t_detached)])
    assert np.array_equal(batch.detached_wheel, lone.wheel)


@pytest.fixture(scope='class')
def mixed_lone_runs() -> LoneRuns:
    """The robots of ``mixed_start`` alone, 400 steps: computed once for both engines' batches."""
    robots, q0, torques = mixed_start()
    singles = [Simulation(robot, None, DRIVEN, q0[i], np.zeros(DOF), contact='coulomb') for i, robot in enumerate(robots)]
    for single, torque in zip(singles, torques):
        single.set_motor_torque(*torque)
    return lone_runs(singles, 400)


class Test_coulomb_against_lone_robots:
    @pytest.mark.parametrize('engine', ENGINES)
    def test_coulomb_batch_agrees_robot_by_robot_through_slip_and_detachment(self, engine, mixed_lone_runs):
        """Driven robots at rest under random torques: some stick, some slide, some peel off; each as alone, its
        wheels' stick/slip transitions and its lift-off at the same instants, the lift-off instant's outputs
        included."""
        robots, q0, torques = mixed_start()
        batch = BatchSimulation(robots, None, DRIVEN, q0, np.zeros((12, DOF)), contact='coulomb', engine=engine)
        batch.set_motor_torque(torques)
        compare_contact(batch, mixed_lone_runs)
        detached = ~np.isnan(mixed_lone_runs.t_detached)
        slipped = mixed_lone_runs.slipped
        assert detached.any() and slipped.any() and np.any(~detached & ~slipped), \
            'the batch should mix robots that detach, slide, and do neither'
        assert np.all(mixed_lone_runs.t_detached[detached] > 0.0), 'a robot should detach mid-run, not at the start'


@pytest.mark.parametrize('engine', ENGINES)
def test_a_detached_robot_stops_and_the_others_go_on(engine):
    """A detached robot keeps its state and the outputs of its lift-off instant; the others go on."""
    robots, q0, torques = mixed_start()
    batch = BatchSimulation(robots, None, DRIVEN, q0, np.zeros((12, DOF)), contact='coulomb', engine=engine)
    batch.set_motor_torque(torques)
    batch.run(360)
    detached = batch.detached.copy()
    assert detached.any() and not detached.all()
    before = batch.outputs()
    batch.run(20)
    after = batch.outputs()
    for field in ('q', 'qd', 'acceleration', 'loads', 'wheel_forces', 'wheel_slipping', 'slip_velocity'):
        assert np.array_equal(getattr(after, field)[detached], getattr(before, field)[detached]), field
    assert np.all(np.min(after.loads[detached], axis=1) < 0.0)  # the lift-off instant's loads
    sliding = before.wheel_slipping.any(axis=1) & ~detached
    assert sliding.any() and np.all(np.any(after.q[sliding] != before.q[sliding], axis=1))
    assert np.all(after.detached == detached)
    assert np.all(batch.detached_wheel[detached] > 0) and np.all(batch.detached_wheel[~detached] == 0)


@pytest.mark.parametrize('engine', ENGINES)
@pytest.mark.parametrize('contact', ['ideal', 'coulomb'])
def test_loads_and_friction_use_of_a_tracking_batch_agree(contact, engine):
    """With the trajectory task the contact is ideal either way (batch and single robot alike); the loads and use are
    still reported."""
    rng = np.random.default_rng(21)
    robots = random_robots(rng, 5)
    scenario = load_scenario('circle')
    q0, qd0 = perturbed_starts(rng, robots, scenario)
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip')
    batch = BatchSimulation(robots, scenario.reference, selection, q0, qd0, contact=contact, engine=engine)
    singles = [Simulation(robot, scenario.reference, selection, q0[i], qd0[i], contact=contact)
               for i, robot in enumerate(robots)]
    lone = lone_runs(singles, 150)
    compare_contact(batch, lone)
    assert not lone.slipped.any() and np.all(np.isnan(lone.t_detached))


def test_an_unknown_contact_model_is_refused():
    robots = random_robots(np.random.default_rng(1), 1)
    with pytest.raises(Exception, match="unknown contact model 'sticky'"):
        BatchSimulation(robots, None, DRIVEN, np.zeros((1, DOF)), np.zeros((1, DOF)), contact='sticky')


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_the_numba_engine_settles_coulomb_contact_in_the_kernel(monkeypatch):
    """Engine 'numba' with coulomb contact: every boundary goes through the kernel's settle and step, never the
    model's ``CoulombContact`` robot by robot (which the numpy engine uses)."""
    calls = {'settle': 0, 'step': 0, 'model': 0}
    for name in ('settle', 'step'):
        def counted(*args, _name=name, _function=getattr(kernel, f'batch_contact_{name}'), **options):
            calls[_name] += 1
            return _function(*args, **options)
        monkeypatch.setattr(kernel, f'batch_contact_{name}', counted)

    def model_settle(self, *args, _settle=CoulombContact.settle):
        calls['model'] += 1
        return _settle(self, *args)
    monkeypatch.setattr(CoulombContact, 'settle', model_settle)
    rng = np.random.default_rng(4)
    robots = mixed_robots(rng, 4)
    q0 = np.zeros((4, DOF))
    for engine in ('numba', 'numpy'):
        batch = BatchSimulation(robots, None, DRIVEN, q0, np.zeros((4, DOF)), contact='coulomb', engine=engine)
        batch.set_motor_torque(rng.uniform(-1.5, 1.5, (4, 2)))
        batch.run(25, lambda out: None)
    assert calls == {'settle': 26, 'step': 25, 'model': 26 * 4}


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_steps_at_held_torques_in_one_kernel_call_are_the_steps_one_by_one():
    """``run_held`` (the sweep's steps between two controller instants) gives, to the bit, the outputs and states
    ``outputs``/``step`` give instant by instant: through slip, a lift-off inside the held steps (the robot
    detached there, with the same instant, wheel and load) and a torque change between calls."""
    robots, q0, torques = mixed_start()
    batches = [BatchSimulation(robots, None, DRIVEN, q0, np.zeros((12, DOF)), contact='coulomb', engine='numba')
               for _ in range(2)]
    one_by_one, held = batches
    fields = ('q', 'qd', 'constraint_force', 'friction_force', 'residual', 'drive', 'loads', 'wheel_forces',
              'wheel_use', 'wheel_slipping', 'tracking_error', 'wheel_torques')
    step, lifted_inside = 0, False
    for length, scale in ((1, 1.0), (97, 0.9), (160, 1.0), (143, 1.0)):
        for batch in batches:
            batch.set_motor_torque(scale * torques)
        first = held.outputs()
        expected = one_by_one.outputs()
        for field in ('q', 'qd', 'loads', 'wheel_forces'):
            assert np.array_equal(getattr(first, field), getattr(expected, field)), field
        detached_before = held.detached.copy()
        table = held.run_held(length)
        assert table.on_wall.shape == (12, length - 1)
        for instant in range(length - 1):
            one_by_one.step()
            out = one_by_one.outputs()
            on_wall = ~out.detached
            assert np.array_equal(table.on_wall[:, instant], on_wall), (step, instant)
            assert table.t[instant] == out.t
            for field in fields:
                value = getattr(table, field)[:, instant]
                assert np.array_equal(value[on_wall], getattr(out, field)[on_wall], equal_nan=True), \
                    (field, step + instant + 1)
        one_by_one.step()
        step += length
        lifted_inside = lifted_inside or bool(np.any(held.detached & ~detached_before))
        assert held.t == one_by_one.t
        assert np.array_equal(held.q, one_by_one.q) and np.array_equal(held.qd, one_by_one.qd)
        assert np.array_equal(held.detached, one_by_one.detached)
        assert np.array_equal(held.detached_wheel, one_by_one.detached_wheel)
        assert np.array_equal(held.t_detached, one_by_one.t_detached, equal_nan=True)
        for robot in np.flatnonzero(held.detached):
            assert held.lift_off(robot).load == one_by_one.lift_off(robot).load
    assert lifted_inside and held.detached.any() and not held.detached.all()
    assert np.any(held.outputs().wheel_slipping)


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_held_steps_raise_what_the_steps_one_by_one_raise_first():
    """A robot whose boundary has no solution one step in (its yaw rate 1e153: Newton's residual overflows): the
    held steps raise the error the steps one by one raise, naming the same robot and residual, and leave the states
    and time where the call began."""
    params = load_robot_parameters().replace(com_offset=(0.03, 0.0))
    robots = [Robot(params), Robot(params)]
    q0, qd0 = np.zeros((2, DOF)), np.zeros((2, DOF))
    qd0[1, 2] = 1e153
    one_by_one = BatchSimulation(robots, None, DRIVEN, q0, qd0, contact='coulomb', engine='numba')
    with pytest.raises(ModelError) as by_step:
        for _ in range(50):
            one_by_one.outputs()
            one_by_one.step()
    assert one_by_one.steps == 1
    held = BatchSimulation(robots, None, DRIVEN, q0, qd0, contact='coulomb', engine='numba')
    settled = held.outputs().qd  # the boundary the call begins at
    with pytest.raises(ModelError) as by_held:
        held.run_held(50)
    assert type(by_held.value) is type(by_step.value) and str(by_held.value) == str(by_step.value)
    assert 'robot(s) [1]: kinetic friction and normal loads did not converge' in str(by_held.value)
    assert held.steps == 0 and np.array_equal(held.qd, settled) and np.array_equal(held.q, q0)
