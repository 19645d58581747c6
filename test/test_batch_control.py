"""The batched tracking controller in the loop against the single-robot closed loop (``simulate --controller``)."""

from __future__ import annotations

import numpy as np
import pytest

from batch_helpers import ENGINES, assert_agree
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.control import ControllerGains, TrackingController
from wallbot_sim.control.sampling import (
    CONTROL_RATE_HZ, MAX_WHEEL_TORQUE, SampledController, close_loop, controller_robot)
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.model import Robot, Simulation
from wallbot_sim.model.batch import BatchSimulation, BatchTrackingController, kernel
from wallbot_sim.model.contact import DetachedError


def closed_loops(contact: str, seed: int, count: int, steps: int, engine: str = 'numpy',
                 singles: bool = True) -> tuple[list[dict], list[dict], np.ndarray]:
    """Robots of the robot file with their mass, CoM height and adhesion varied, each controller's mass off by its own
    scale; the batch and (``singles``) one Simulation + SampledController per robot, run as ``simulate --controller``
    runs."""
    rng = np.random.default_rng(seed)
    base = load_robot_parameters()
    scenario = load_scenario('figure8')
    plant_params = [base.replace(body_mass=float(rng.uniform(6.0, 12.0)), com_height=float(rng.uniform(0.03, 0.08)),
                                 adhesion_force=float(rng.uniform(60.0, 300.0))) for _ in range(count)]
    scales = rng.uniform(0.7, 1.3, count)
    plants = [Robot(params) for params in plant_params]
    controllers = [controller_robot(params, scale) for params, scale in zip(plant_params, scales)]
    batch = BatchSimulation.from_scenario(plants, scenario, DRIVEN, contact=contact, engine=engine)
    loop = BatchTrackingController(controllers, scenario.reference, ControllerGains(), CONTROL_RATE_HZ,
                                   MAX_WHEEL_TORQUE)
    keys = ('q', 'qd', 'constraint force', 'motor torque', 'loads', 'wheel forces', 'sliding')
    batch_history = [{key: [] for key in keys} for _ in range(count)]
    slipped = np.zeros(count, dtype=bool)

    def record(out) -> None:
        slipped[:] |= out.wheel_slipping.any(axis=1) & ~out.detached
        for i in range(count):
            for key, value in zip(keys, (out.q[i], out.qd[i], out.constraint_force[i], out.motor_torque[i],
                                         out.loads[i], out.wheel_forces[i], out.wheel_slipping[i])):
                batch_history[i][key].append(value)
    hook = loop.hook(batch)
    batch.run(steps, lambda out: (record(out), hook(out)))
    single_history = [{key: [] for key in keys} for _ in range(count)]
    for i in range(count if singles else 0):
        q0, qd0 = scenario.initial_state(plants[i])
        single = Simulation(plants[i], scenario.reference, DRIVEN, q0, qd0, contact=contact)
        answer = close_loop(single, SampledController(TrackingController(controllers[i], single.reference)))

        def on_step(out, history=single_history[i]) -> None:
            for key, value in zip(keys, (out.q, out.qd, out.constraint_force, out.motor_torque, out.contact.loads,
                                         out.contact.wheel_forces, out.contact.wheel_slipping)):
                history[key].append(np.asarray(value, dtype=float))
            answer(out)
        try:
            single.run(steps * single.dt, on_step)
        except DetachedError:
            pass
    return batch_history, single_history, slipped


@pytest.mark.parametrize('engine', ENGINES)
@pytest.mark.parametrize('contact', ['ideal', 'coulomb'])
def test_closed_loop_batch_agrees_robot_by_robot(contact, engine):
    """Each robot of the batch as ``simulate --controller`` runs it alone: states, commands, loads and each wheel's
    force and slip, up to the instant a wheel lifts off where one does."""
    batch_history, single_history, slipped = closed_loops(contact, seed=4, count=6, steps=500, engine=engine)
    for i, (mine, theirs) in enumerate(zip(batch_history, single_history)):
        instants = len(theirs['q'])  # the single run ends at its lift-off instant
        assert np.array_equal(np.array(mine['sliding'][:instants]), np.array(theirs['sliding'])), f'robot {i}'
        for key in mine:
            # floor: 1 in the quantity's unit, where it is round-off (the forces of a wheel without friction)
            assert_agree(f'robot {i} {key}', np.array(mine[key][:instants]), np.array(theirs[key]), floor=1.0)
    torques = np.array([history['motor torque'][-1] for history in batch_history])
    assert len(np.unique(np.round(torques, 6), axis=0)) == len(torques), 'each robot commanded on its own'
    if contact == 'coulomb':
        assert slipped.any() and not slipped.all(), 'some robots should slide under the controller, others not'


def test_commands_come_at_the_control_rate_and_are_clamped():
    scenario = load_scenario('circle')
    base = load_robot_parameters()
    robots = [Robot(base), Robot(base.replace(body_mass=base.body_mass * 40.0))]
    loop = BatchTrackingController(robots, scenario.reference, ControllerGains(), 200, 0.5)
    states = [scenario.initial_state(robot) for robot in robots]
    q, qd = np.array([s[0] for s in states]), np.array([s[1] for s in states])
    assert loop.due(0)
    torques = loop.command(0, q, qd)
    assert np.all(np.abs(torques) <= 0.5) and np.any(np.abs(torques) == 0.5)
    assert not loop.due(4_000_000) and loop.due(5_000_000)


@pytest.mark.skipif(not kernel.available(), reason='numba is not installed')
def test_the_compiled_inverse_dynamics_is_numpys_batched_solve(monkeypatch):
    """The controller's constraint force robot by robot in the kernel equals the NumPy batched solve (the path
    without numba) at random states of robots with their masses scaled, to 1e-9 of its size."""
    rng = np.random.default_rng(5)
    base = load_robot_parameters()
    robots = [controller_robot(base.replace(body_mass=float(rng.uniform(6.0, 12.0))), float(rng.uniform(0.7, 1.3)))
              for _ in range(5)]
    loop = BatchTrackingController(robots, load_scenario('figure8').reference, ControllerGains(), CONTROL_RATE_HZ,
                                   MAX_WHEEL_TORQUE)
    q, qd = rng.normal(size=(5, 7)), rng.normal(size=(5, 7))
    compiled = loop._constraint_force(1.3, q, qd)
    monkeypatch.setattr(kernel, 'available', lambda: False)
    batched = loop._constraint_force(1.3, q, qd)
    assert np.allclose(compiled, batched, rtol=0.0, atol=1e-9 * np.max(np.abs(batched)))
