"""What a closed-loop run recorded, and what the model alone says it should be.

Shared by the closed-loop graph tests (one host, two hosts): the torques the dynamics applied,
decoded messages of one topic, the same loop run on the model without DDS, and the checks that a
bag holds every 1 ms step and the controller's commands.
"""

from __future__ import annotations

from collections.abc import Collection

from pathlib import Path

import numpy as np
import pytest

from wallbot_msgs_py import bagio
from wallbot_sim.bag.reader import messages
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.control import TrackingController
from wallbot_sim.control.sampling import CONTROL_RATE_HZ
from wallbot_sim.graph_description import CONTROL_STEPS
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.model import DriveForces, Robot, Simulation
from wallbot_sim.model.outputs import side_motor_torques

COMMAND_TIMEOUT = 0.5
"""The dynamics' default command_timeout (s of simulation time)."""
MAX_TORQUE = 5.0
"""The dynamics' and the controller's default max_wheel_torque (N m)."""
ROBOT = Robot(load_robot_parameters())


def applied_torques(run) -> np.ndarray:
    """(tau_L, tau_R) the dynamics applied at each recorded step: from drive forces and wheel efforts."""
    radius = ROBOT.params.wheel_radius
    return np.array([side_motor_torques(DriveForces(*drive), efforts, radius)
                     for drive, efforts in zip(np.c_[run.F_left, run.F_right, run.F_lateral], run.tau)])


def recorded(bag: Path, leaf: str) -> list:
    """Decoded messages of the topic ``.../leaf`` (or ``/leaf``) in recording order."""
    return [bagio.deserialize(raw.data, raw.type) for raw in messages(bag)
            if raw.topic.rsplit('/', 1)[-1] == leaf]


def model_closed_loop(scenario_name: str, mass_scale: float, steps: int) -> np.ndarray:
    """Centre positions of the same loop on the model alone: torques from the state at each control
    instant (the controller's default rate), clamped to the limit, held until the next."""
    return model_loop_states(scenario_name, mass_scale, steps)[:, :2]


def model_loop_states(scenario_name: str, mass_scale: float, steps: int, lost_answers: Collection[int] = ()) -> np.ndarray:
    """The states (x, y, theta, xd, yd, thd) after each of ``steps`` steps, from the start, of the loop
    of ``model_closed_loop``. ``lost_answers``: the steps of control instants whose commands never
    arrive (the controller still computed them): the command before runs on over their periods."""
    params, scenario = ROBOT.params, load_scenario(scenario_name)
    plant = Simulation(ROBOT, None, DRIVEN, *scenario.initial_state(ROBOT))
    controller = TrackingController(Robot(params.replace(body_mass=params.body_mass * mass_scale)), scenario.reference)
    states = [np.r_[plant.q[:3], plant.qd[:3]]]
    held = (0.0, 0.0)
    for k in range(steps):
        if k % CONTROL_STEPS == 0:
            command = controller.update(plant.t, plant.q, plant.qd, CONTROL_STEPS * plant.dt)
            answer = tuple(min(MAX_TORQUE, max(-MAX_TORQUE, tau)) for tau in (command.tau_left, command.tau_right))
            if k not in lost_answers:
                held = answer
                plant.set_motor_torque(*held)
        plant.step()
        states.append(np.r_[plant.q[:3], plant.qd[:3]])
    return np.array(states)


def check_complete(run, duration: float) -> None:
    """The run holds every 1 ms state from t = 0 to ``duration``, each once."""
    stamps = np.round(run.t * 1e9).astype(np.int64)
    assert stamps[0] == 0 and len(stamps) == round(duration * 1000) + 1
    assert np.all(np.diff(stamps) == 1_000_000), 'odometry stamps are not consecutive'


def check_commands(bag: Path, duration: float, output: str = '') -> None:
    """wheel_torque_cmd is recorded: about the controller's rate, finite, within the limit."""
    commands = np.array([list(m.data) for m in recorded(bag, 'wheel_torque_cmd')])
    assert commands.shape[1] == 2 and np.all(np.isfinite(commands))
    assert np.max(np.abs(commands)) <= MAX_TORQUE
    if not 0.9 * CONTROL_RATE_HZ * duration <= len(commands) <= CONTROL_RATE_HZ * duration + 2:
        received = {leaf: [raw.timestamp for raw in messages(bag) if raw.topic.rsplit('/', 1)[-1] == leaf]
                    for leaf in ('odom', 'wheel_torque_cmd')}
        first_odom, command_times = received['odom'][0], np.array(received['wheel_torque_cmd'])
        warnings = '\n'.join(line for line in output.splitlines() if 'WARN' in line or 'ERROR' in line)
        pytest.fail(f'{len(commands)} commands recorded; the first {(command_times[0] - first_odom) * 1e-9:.3f} s '
                    f'after the first odom, largest gap {np.max(np.diff(command_times)) * 1e-9:.3f} s; '
                    f'warnings:\n{warnings}')
