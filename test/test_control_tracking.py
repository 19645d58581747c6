"""The example tracking controller closes the loop on the model (no ROS): the docs/model.md plant, 200 Hz."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.control import ControllerGains, TrackingController
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.model import ParameterError, Robot, Simulation
from wallbot_sim.model.outputs import side_motor_torques


def closed_loop(scenario_name: str, mass_scale: float, duration: float = 12.0, period: int = 5) -> np.ndarray:
    """Tracking error at every step of a driven plant under the controller (held torques, 1 kHz)."""
    params = load_robot_parameters()
    plant_robot = Robot(params)
    scenario = load_scenario(scenario_name)
    q0, qd0 = scenario.initial_state(plant_robot)
    plant = Simulation(plant_robot, None, DRIVEN, q0, qd0)
    controller = TrackingController(Robot(params.replace(body_mass=params.body_mass * mass_scale)), scenario.reference)
    errors = []
    for k in range(round(duration / plant.dt)):
        if k % period == 0:
            command = controller.update(plant.t, plant.q, plant.qd, period * plant.dt)
            plant.set_motor_torque(command.tau_left, command.tau_right)
        plant.step()
        x, y = scenario.reference.sample(plant.t).position
        errors.append((plant.t, math.hypot(plant.q[0] - x, plant.q[1] - y)))
    return np.array(errors)


@pytest.mark.parametrize('scenario_name, mass_scale, bound', [
    ('circle', 1.0, 5e-3), ('figure8', 1.0, 5e-3), ('circle', 1.2, 2e-2), ('figure8', 0.8, 2e-2)])
def test_controller_tracks_after_ten_seconds(scenario_name, mass_scale, bound):
    errors = closed_loop(scenario_name, mass_scale)
    assert np.max(errors[errors[:, 0] >= 10.0, 1]) < bound


def test_without_integral_a_wrong_mass_leaves_an_error():
    """The integral term is what removes the error a 20 % mass mismatch leaves under gravity."""
    params = load_robot_parameters()
    scenario = load_scenario('figure8')
    robot = Robot(params)
    q0, qd0 = scenario.initial_state(robot)
    plant = Simulation(robot, None, DRIVEN, q0, qd0)
    controller = TrackingController(Robot(params.replace(body_mass=params.body_mass * 1.2)), scenario.reference,
                                    ControllerGains(integral=0.0))
    for k in range(8000):
        if k % 5 == 0:
            command = controller.update(plant.t, plant.q, plant.qd, 0.005)
            plant.set_motor_torque(command.tau_left, command.tau_right)
        plant.step()
    x, y = scenario.reference.sample(plant.t).position
    assert math.hypot(plant.q[0] - x, plant.q[1] - y) > 5e-3


def test_side_motor_torques_give_back_the_applied_torques_in_a_driven_run():
    robot = Robot(load_robot_parameters())
    plant = Simulation(robot, None, DRIVEN, np.array([0, 0, 1.0, 0, 0, 0, 0]), np.zeros(7))
    plant.set_motor_torque(1.7, 2.1)
    for _ in range(200):
        plant.step()
        out = plant.outputs()
        tau = side_motor_torques(out.drive, out.wheel_torques, robot.params.wheel_radius)
        assert tau == pytest.approx((1.7, 2.1), abs=1e-9)


def test_bad_gains_and_missing_reference_are_refused():
    with pytest.raises(ParameterError, match='look_ahead must be'):
        ControllerGains(look_ahead=0.0)
    with pytest.raises(ParameterError, match='integral must be'):
        ControllerGains(integral=-1.0)
    with pytest.raises(ParameterError, match='no reference'):
        TrackingController(Robot(load_robot_parameters())).update(0.0, np.zeros(7), np.zeros(7), 0.005)


def test_the_compiled_law_gives_the_models_torques():
    """engine numba (the kernel's inverse dynamics) against the python engine (the model's modules and
    least-squares solve): the same commands to round-off along a closed loop, and after the gains and
    the robot copy change (its constants must follow)."""
    pytest.importorskip('numba')
    params = load_robot_parameters()
    scenario = load_scenario('figure8')
    plant_robot = Robot(params)
    q0, qd0 = scenario.initial_state(plant_robot)
    plant = Simulation(plant_robot, None, DRIVEN, q0, qd0)
    copy = Robot(params.replace(body_mass=params.body_mass * 1.2))
    model, compiled = (TrackingController(copy, scenario.reference, engine=engine) for engine in ('python', 'numba'))
    changes = {1000: lambda c: setattr(c, 'gains', ControllerGains(alpha=4.0, beta=6.0, look_ahead=0.12)),
               2000: lambda c: setattr(c, 'robot', Robot(params.replace(body_mass=params.body_mass * 0.8)))}
    worst = 0.0
    for k in range(3000):
        if k in changes:
            changes[k](model)
            changes[k](compiled)
        if k % 20 == 0:
            expected = model.update(plant.t, plant.q, plant.qd, 0.02)
            got = compiled.update(plant.t, plant.q, plant.qd, 0.02)
            for name in ('tau_left', 'tau_right'):
                value = getattr(expected, name)
                worst = max(worst, abs(getattr(got, name) - value) / max(1.0, abs(value)))
            for side in ('left', 'right', 'lateral'):
                assert getattr(got.drive, side) == pytest.approx(getattr(expected.drive, side), rel=1e-9, abs=1e-9)
            assert got.tracking_error == expected.tracking_error
            plant.set_motor_torque(expected.tau_left, expected.tau_right)
        plant.step()
    assert worst < 1e-9


def test_an_unknown_engine_and_a_trajectory_task_beside_the_look_ahead_task_are_refused():
    robot = Robot(load_robot_parameters())
    with pytest.raises(ParameterError, match="unknown engine 'fortran'"):
        TrackingController(robot, engine='fortran')
    pytest.importorskip('numba')
    from wallbot_sim.model import BaumgarteGains, ConstraintSelection
    from wallbot_sim.model.compiled import CompiledInverseDynamics
    from wallbot_sim.model.constraints.look_ahead import PointReference
    at_rest = PointReference((0.0, 0.0), (0.0, 0.0), (0.0, 0.0), 0.0)
    with pytest.raises(ParameterError, match='takes the place of the trajectory task'):
        CompiledInverseDynamics().constraint_force(robot, BaumgarteGains(), ConstraintSelection.structural(), at_rest,
                                                   0.05, np.zeros(7), np.zeros(7))
