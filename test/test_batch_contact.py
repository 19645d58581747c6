"""The batched contact against the single-robot Simulation, robot by robot: loads, friction use, slip, detachment."""

from __future__ import annotations

import numpy as np
import pytest

from model_helpers import random_parameters
from batch_helpers import ENGINES, assert_agree, perturbed_starts, random_robots
from wallbot_sim.config import load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.model.batch import BatchSimulation, kernel
from wallbot_sim.model.batch.contact import BatchCoulomb
from wallbot_sim.model.contact import DetachedError
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


def compare_contact(batch: BatchSimulation, singles: list[Simulation], steps: int) -> dict[str, np.ndarray]:
    """Step both side by side; every robot's outputs agree until it detaches, which happens at the same instant.

    Returns per robot whether it slipped, and the detachment time and wheel the single robots gave.
    """
    size = len(singles)
    keys = ('q', 'qd', 'acceleration', 'constraint force', 'friction force', 'drive forces', 'loads', 'use')
    single_history = [{key: [] for key in keys} for _ in range(size)]
    batch_history = [{key: [] for key in keys} for _ in range(size)]
    slipped = np.zeros(size, dtype=bool)
    t_detached, wheel = np.full(size, np.nan), np.zeros(size, dtype=int)
    for _ in range(steps):
        out = batch.outputs()
        for i, single in enumerate(singles):
            if not np.isnan(t_detached[i]):
                continue
            mine = single.outputs()
            assert tuple(out.slipping[i]) == mine.contact.slipping, f'robot {i} slip flags at t = {out.t:.3f} s'
            slipped[i] |= any(mine.contact.slipping)
            friction = np.zeros(DOF) if mine.contact.friction_force is None else mine.contact.friction_force
            for history, values in (
                    (single_history[i], (mine.q, mine.qd, mine.acceleration, mine.constraint_force, friction,
                                         [mine.drive.left, mine.drive.right, mine.drive.lateral], mine.contact.loads,
                                         mine.contact.use)),
                    (batch_history[i], (out.q[i], out.qd[i], out.acceleration[i], out.constraint_force[i],
                                        out.friction_force[i], out.drive[i], out.loads[i], out.use[i]))):
                for key, value in zip(keys, values):
                    history[key].append(np.asarray(value, dtype=float))
            try:
                single.step()
            except DetachedError as detached:
                t_detached[i], wheel[i] = detached.t, detached.wheel
        batch.step()
    for i in range(size):
        for key in keys:
            assert_agree(f'robot {i} {key}', np.array(batch_history[i][key]), np.array(single_history[i][key]))
    assert np.array_equal(np.isnan(batch.t_detached), np.isnan(t_detached))
    assert np.array_equal(batch.t_detached[~np.isnan(t_detached)], t_detached[~np.isnan(t_detached)])
    assert np.array_equal(batch.detached_wheel, wheel)
    return {'slipped': slipped, 't_detached': t_detached}


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_the_coulomb_batch_engines_agree_robot_by_robot_through_slip_and_detachment():
    """Driven robots at rest under random torques, on the batch's NumPy engine and its kernel: some stick, some slip,
    some peel off; every output alike until each detaches, at the same instant.

    The batch's coulomb contact limits friction per channel; a single ``Simulation`` limits it per wheel
    (test_model_contact.py), so here the batch's two engines are held to each other.
    0.4 s: a robot whose channels all slip with one wheel's slip velocity near zero is integrated
    unstably by the fixed-step RK4 (alone, it amplifies its own round-off), so no longer horizon
    can ask two computations of it to agree to 1e-9.
    """
    rng = np.random.default_rng(3)
    robots = mixed_robots(rng, 12)
    q0, qd0 = np.zeros((12, DOF)), np.zeros((12, DOF))
    q0[:, 2] = rng.uniform(-np.pi, np.pi, 12)
    torques = rng.uniform(-1.5, 1.5, (12, 2))
    batches = [BatchSimulation(robots, None, DRIVEN, q0, qd0, contact='coulomb', engine=engine)
               for engine in ('numpy', 'numba')]
    keys = ('q', 'qd', 'acceleration', 'constraint_force', 'friction_force', 'drive', 'loads', 'use')
    histories = [{key: [] for key in keys} for _ in batches]
    live = np.ones(12, dtype=bool)
    slipped = np.zeros(12, dtype=bool)
    for batch in batches:
        batch.set_motor_torque(torques)
    for _ in range(400):
        numpy_out, numba_out = (batch.outputs() for batch in batches)
        assert np.array_equal(numpy_out.slipping[live], numba_out.slipping[live]), f't = {numpy_out.t:.3f} s'
        slipped |= numpy_out.slipping.any(axis=1) & live
        for history, out in zip(histories, (numpy_out, numba_out)):
            for key in keys:
                history[key].append(np.where(live.reshape((-1,) + (1,) * (getattr(out, key).ndim - 1)),
                                             getattr(out, key), 0.0))
        for batch in batches:
            batch.step()
        assert np.array_equal(batches[0].detached, batches[1].detached)
        live = ~batches[0].detached
    for key in keys:
        expected, got = np.array(histories[0][key]), np.array(histories[1][key])
        for i in range(12):
            assert_agree(f'robot {i} {key}', got[:, i], expected[:, i])
    assert np.array_equal(batches[0].t_detached, batches[1].t_detached, equal_nan=True)
    assert np.array_equal(batches[0].detached_wheel, batches[1].detached_wheel)
    detached = batches[0].detached
    assert detached.any() and slipped.any() and np.any(~detached & ~slipped), \
        'the batch should mix robots that detach, slip, and do neither'
    assert np.all(batches[0].t_detached[detached] > 0.0), 'a robot should detach mid-run, not at the start'


def test_a_detached_robot_stops_and_the_others_go_on():
    rng = np.random.default_rng(3)
    robots = mixed_robots(rng, 12)
    q0 = np.zeros((12, DOF))
    q0[:, 2] = rng.uniform(-np.pi, np.pi, 12)
    batch = BatchSimulation(robots, None, DRIVEN, q0, np.zeros((12, DOF)), contact='coulomb')
    batch.set_motor_torque(rng.uniform(-1.5, 1.5, (12, 2)))
    batch.run(320)
    detached = batch.detached.copy()
    assert detached.any() and not detached.all()
    states = batch.q, batch.qd
    batch.run(20)
    assert np.array_equal(batch.q[detached], states[0][detached])
    assert np.array_equal(batch.qd[detached], states[1][detached])
    assert np.all(np.any(batch.q[~detached] != states[0][~detached], axis=1))
    assert np.all(batch.outputs().detached == detached)
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
    found = compare_contact(batch, singles, 150)
    assert not found['slipped'].any() and np.all(np.isnan(found['t_detached']))


def test_an_unknown_contact_model_is_refused():
    robots = random_robots(np.random.default_rng(1), 1)
    with pytest.raises(Exception, match="unknown contact model 'sticky'"):
        BatchSimulation(robots, None, DRIVEN, np.zeros((1, DOF)), np.zeros((1, DOF)), contact='sticky')


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_the_numba_engine_settles_coulomb_contact_in_the_kernel(monkeypatch):
    """Engine 'numba' with coulomb contact: every boundary goes through the kernel's settle and step, never
    the NumPy stick/slip (which the numpy engine uses)."""
    calls = {'settle': 0, 'step': 0, 'numpy': 0}
    for name in ('settle', 'step'):
        def counted(*args, _name=name, _function=getattr(kernel, f'batch_contact_{name}'), **options):
            calls[_name] += 1
            return _function(*args, **options)
        monkeypatch.setattr(kernel, f'batch_contact_{name}', counted)

    def numpy_settle(self, *args, _settle=BatchCoulomb.settle):
        calls['numpy'] += 1
        return _settle(self, *args)
    monkeypatch.setattr(BatchCoulomb, 'settle', numpy_settle)
    rng = np.random.default_rng(4)
    robots = mixed_robots(rng, 4)
    q0 = np.zeros((4, DOF))
    for engine in ('numba', 'numpy'):
        batch = BatchSimulation(robots, None, DRIVEN, q0, np.zeros((4, DOF)), contact='coulomb', engine=engine)
        batch.set_motor_torque(rng.uniform(-1.5, 1.5, (4, 2)))
        batch.run(25, lambda out: None)
    assert calls == {'settle': 26, 'step': 25, 'numpy': 26}
