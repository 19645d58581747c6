"""``wallbot-sim simulate --controller``: the example controller closing the loop headless.

The headless loop is the graph's lockstep loop (``run --controller``, compared state by state);
with coulomb contact it is how slip under a controller is seen without DDS, and the slip it
reports is checked against the friction cone computed from the CSV's own columns.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from closed_loop import check_complete
from closed_loop import recorded as recorded_messages
from wallbot_msgs_py import topics
from wallbot_msgs_py.codec import PlanarState
from wallbot_sim.bag.reader import info
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model.contact import WHEEL_POSITIONS
from wallbot_sim.control import TrackingController
from wallbot_sim.control.sampling import CONTROL_RATE_HZ, Rewind, SampledController, controller_robot
from wallbot_sim.model.contact import WHEEL_POSITIONS
from wallbot_sim.paths import scenario_yaml
from wallbot_sim.rundata import format_summary, load_run, summarize

WALLBOT = [sys.executable, '-m', 'wallbot_sim.cli.main']
PARAMS = load_robot_parameters()


def wallbot(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*WALLBOT, *args], capture_output=True, text=True, timeout=timeout)


def headless(out: Path, *args: str) -> object:
    """The run of ``simulate --controller ARGS`` written to ``out`` (a CSV)."""
    result = wallbot('simulate', '--controller', '--csv', str(out), '--quiet', *args)
    assert result.returncode == 0, result.stderr
    return load_run(out)


def qos_terms(qos) -> tuple:
    """What a recorded offered QoS says a replay needs: reliability, durability, history and depth."""
    return qos.reliability.name, qos.durability.name, qos.history.name, qos.depth


def fast_circle(tmp_path: Path) -> Path:
    """The circle scenario at twice its speed (half the period)."""
    scenario = yaml.safe_load(scenario_yaml('circle').read_text())
    scenario['name'] = 'circle_fast'
    scenario['reference']['period'] /= 2
    path = tmp_path / 'circle_fast.yaml'
    path.write_text(yaml.safe_dump(scenario))
    return path


# --- the same loop as the graph's ---------------------------------------------------------------
@pytest.mark.parametrize('contact, engine, pacing', [
    ('ideal', 'python', ['--real-time-factor', '0', '--no-compose']),
    ('coulomb', 'python', ['--real-time-factor', '0']),
    ('ideal', 'numba', ['--real-time-factor', '0', '--no-compose']), ('ideal', 'numba', ['--real-time-factor', '0']),
    ('coulomb', 'numba', ['--real-time-factor', '0']), ('ideal', 'numba', ['--real-time-factor', '1'])],
    ids=['ideal-python-separate', 'coulomb-python', 'ideal-numba-separate', 'ideal-numba', 'coulomb-numba',
         'ideal-numba-paced'])
def test_the_headless_loop_is_the_graph_lockstep_loop(tmp_path, contact, engine, pacing):
    """run --controller at factor 0 and simulate --controller: the same states at the same stamps,
    and in their bags the same wheel_torque_cmd (type, offered QoS, the command of each control
    instant in order).

    With coulomb contact (at 250 N of adhesion: the default's wheels spin up until one lifts off) the
    circle's start (0.2 m off the path, at rest) slides every wheel from the first instant: the
    transitions are part of what must agree. On the numba engine the
    dynamics and the controller's law are the compiled kernel's in both; composed (the recorder in the
    dynamics' process, ``run``'s default) it takes blocks of steps between the controller's answers,
    at factor 0 published at once, paced one state at a time.
    """
    pytest.importorskip('rclpy')
    if engine == 'numba':
        pytest.importorskip('numba')
    duration = 1.0
    adhesion = ['--adhesion-force', '250'] if contact == 'coulomb' else []
    graph = wallbot('run', 'circle', '--controller', '--contact', contact, '--engine', engine, *pacing, *adhesion,
                    '--duration', str(duration), '--out', str(tmp_path / 'run'), '--no-plots', timeout=180)
    assert graph.returncode == 0, graph.stderr + graph.stdout
    assert f'tracking controller at {CONTROL_RATE_HZ} Hz of simulation time, {engine} engine' in (
        tmp_path / 'run' / 'logs' / 'controller.log').read_text()
    recorded = load_run(tmp_path / 'run' / 'bag')
    headless_bag = tmp_path / 'headless'
    computed = headless(tmp_path / 'headless.csv', '--contact', contact, '--engine', engine, *adhesion,
                        '--duration', str(duration), '--bag', str(headless_bag))

    check_complete(recorded, duration)  # every 1 ms state from 0 to the end, each once
    assert np.array_equal(np.round(recorded.t * 1e9).astype(np.int64), np.round(computed.t * 1e9).astype(np.int64))
    # the graph's commands are the headless ones to round-off, not to the bit (seen: 3e-11 N m at the first
    # instant); sliding wheels carry that apart to about 1e-9 of a speed: relative, as the wheels' below
    scale = {'ideal': 0.0, 'coulomb': 1.0}[contact]
    for name in ('x', 'y', 'vx', 'vy', 'omega'):
        expected = getattr(computed, name)
        assert np.max(np.abs(getattr(recorded, name) - expected)) < 1e-9 * max(1.0, scale * np.max(np.abs(expected)))
    assert np.max(np.abs(np.angle(np.exp(1j * (recorded.theta - computed.theta))))) < 1e-9  # odometry's yaw is wrapped
    # slipping wheels spin up to hundreds of rad/s; a sticking wheel's use is its share of the constraint force by
    # the load-weighted least-norm split, which carries the round-off about seven times further than the loads
    # (seen: loads 1.5e-10, use 0.95e-9 to 1.06e-9 as Newton's start changed)
    for name, tolerance in (('phi', 1e-9), ('dphi', 1e-9), ('loads', 1e-9), ('use', 1e-8)):
        expected = getattr(computed, name)
        assert np.max(np.abs(getattr(recorded, name) - expected)) < tolerance * max(1.0, np.max(np.abs(expected))), \
            name
    assert np.array_equal(recorded.slip, computed.slip)
    slipped = computed.slip.any(axis=0)
    assert slipped.tolist() == [contact == 'coulomb'] * 4

    name = topics.WHEEL_TORQUE_CMD.resolve()
    graph_topic, headless_topic = info(tmp_path / 'run' / 'bag').topic(name), info(headless_bag).topic(name)
    assert graph_topic.type == headless_topic.type == topics.WHEEL_TORQUE_CMD.type
    assert [qos_terms(q) for q in graph_topic.offered_qos] == [qos_terms(q) for q in headless_topic.offered_qos]
    graph_commands, headless_commands = (np.array([m.data for m in recorded_messages(bag, 'wheel_torque_cmd')])
                                         for bag in (tmp_path / 'run' / 'bag', headless_bag))
    assert len(headless_commands) == round(duration * CONTROL_RATE_HZ) + 1  # every instant from t = 0 to the end
    # the graph's recorder may stop before the answer to the last state reaches it
    assert len(headless_commands) - 1 <= len(graph_commands) <= len(headless_commands)
    # functions of states that agree to 1e-9, relative as the wheels' (seen: 2.4e-9 N m apart at 4.98 N m, slipping)
    scale = max(1.0, np.max(np.abs(headless_commands)))
    assert np.max(np.abs(graph_commands - headless_commands[:len(graph_commands)])) < 1e-9 * scale


# --- slip under the controller ------------------------------------------------------------------
def slip_velocities(run) -> np.ndarray:
    """(T, 4, 2): each wheel's contact point velocity on the wall along x_p and y_p (docs/model.md 11.3: -h_i,
    w_i) from the run's own columns."""
    cos_t, sin_t = np.cos(run.theta), np.sin(run.theta)
    v_long, v_lat = cos_t * run.vx + sin_t * run.vy, -sin_t * run.vx + cos_t * run.vy
    a, b, r = PARAMS.half_wheelbase, PARAMS.half_track, PARAMS.wheel_radius
    return np.stack([np.stack((v_long - s * run.omega - r * run.dphi[:, i], v_lat + x * run.omega), axis=1)
                     for i, (x, s) in enumerate(((a, b), (-a, b), (a, -b), (-a, -b)))], axis=1)


@pytest.mark.parametrize('engine', ['numba', 'python'])
def test_a_fast_circle_slips_and_the_csv_and_summary_say_so(tmp_path, engine):
    """Twice the circle's speed at 200 N of adhesion: the controller's start demands more traction than
    friction gives, the wheels spin up and the robot slides away from the path (at the default's 189 N
    the spin-up unloads a wheel until it lifts off). Each sliding wheel's force, from the CSV's own columns, is
    kinetic friction: at most mu_k N_i, mu_k N_i where the wheel slides well above eps, against the slip it has at
    the end of the step (the next row: the implicit direction of docs/model.md 11.3), so never adding energy."""
    out = tmp_path / 'slip.csv'
    run = headless(out, '--scenario', str(fast_circle(tmp_path)), '--contact', 'coulomb', '--adhesion-force', '200',
                   '--engine', engine, '--duration', '2')
    slip = run.slip > 0.5
    assert np.all(slip.sum(axis=0) > 1000), slip.sum(axis=0)
    first = int(np.flatnonzero(slip.any(axis=1))[0])
    names = ', '.join(name for name, flag in zip(WHEEL_POSITIONS, slip[first]) if flag)
    assert f'first slip at t = {run.t[first]:.3f} s ({names})' in format_summary(summarize(out))
    assert run.err[-1] > 0.5  # lost: the controller does nothing about slip

    mu_k, mu_s = PARAMS.kinetic_friction, PARAMS.wall_friction
    force, load, sliding = run.wheel_forces[:-1], run.loads[:-1], slip[:-1]
    after = slip_velocities(run)[1:]
    size, speed = np.linalg.norm(force, axis=2), np.linalg.norm(after, axis=2)
    assert np.all(size[sliding] <= mu_k * load[sliding] * (1 + 1e-9))
    # (a wheel that stops at the end of its step has a slip of round-off there: eps is the scale of a slip)
    reach = 1e-9 * size * np.maximum(speed, PARAMS.velocity_epsilon)
    assert np.all(np.sum(force * after, axis=2)[sliding] <= reach[sliding])
    fast = sliding & (speed > 20 * PARAMS.velocity_epsilon)
    assert fast.sum() > 4000
    assert np.allclose(size[fast], mu_k * load[fast], rtol=1e-4)
    assert np.allclose(run.use[:-1][fast], mu_k / mu_s, rtol=1e-4)
    # a sticking wheel stays inside its friction disc
    assert np.all(run.use[~slip] <= 1.0 + 1e-12)


@pytest.mark.parametrize('args, words', [
    (['--controller', '--scenario', 'rest'], 'rest has none'),
    (['--controller', '--constraints', 'belt'], 'drop --constraints'),
    (['--controller', '--controller-mass-scale', '0'], 'argument --controller-mass-scale: must be in [0.001, 1000], got 0.0'),
    (['--controller-mass-scale', '1.2'], '--controller-mass-scale needs --controller'),
])
def test_bad_closed_loop_arguments_are_one_line_errors(tmp_path, args, words):
    result = wallbot('simulate', '--csv', str(tmp_path / 'x.csv'), *args)
    assert result.returncode == 2 and words in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / 'x.csv').exists()


# --- the sampling the node and simulate share (no DDS) ------------------------------------------
def state(t_ns: int, x: float = 0.8) -> PlanarState:
    return PlanarState(t_ns, x, 0.0, 0.0, 0.0, 0.0, 0.0)


def sampled(max_wheel_torque: float = 5.0) -> SampledController:
    from wallbot_sim.config import load_scenario
    reference = load_scenario('circle').reference
    return SampledController(TrackingController(controller_robot(PARAMS, 1.0), reference), 200,  # a 5 ms period
                             max_wheel_torque=max_wheel_torque)


def test_the_controller_acts_on_the_first_state_of_each_period():
    loop = sampled()
    acted = []
    for stamp in (0, 1_000_000, 4_000_000, 5_000_000, 7_000_000, 9_999_999, 11_000_000, 15_000_000):
        assert loop.observe(stamp) is None
        if loop.due(stamp):
            loop.command(state(stamp))
            acted.append(stamp)
    assert acted == [0, 5_000_000, 11_000_000, 15_000_000]  # 10 ms had no state: the first after it


def test_time_going_back_restarts_or_carries_on():
    """A reset (back into the first period) clears the integral; a resume keeps it."""
    loop = sampled()
    for stamp in range(0, 300_000_000, 1_000_000):  # 0.3 s near the path: the error is integrated
        loop.observe(stamp)
        if loop.due(stamp):
            loop.command(state(stamp, x=0.99))
    probe = state(205_000_000, x=0.99)
    fresh = sampled().command(probe)
    assert loop.observe(201_000_000) is Rewind.RESUME  # a resumed dynamics publishes states again
    assert not loop.due(201_000_000) and not loop.due(204_000_000) and loop.due(205_000_000)
    assert loop.command(probe).requested != fresh.requested
    assert loop.observe(1_000_000) is Rewind.RESTART
    assert loop.due(1_000_000) and loop.command(probe).requested == fresh.requested


def test_commands_are_clamped_and_say_so():
    loop = sampled(max_wheel_torque=0.5)
    command = loop.command(state(0))  # at rest below the path: the controller asks for more than 0.5 N m
    assert command.clamped and max(abs(tau) for tau in command.requested) > 0.5
    assert (command.tau_left, command.tau_right) == tuple(math.copysign(min(0.5, abs(tau)), tau)
                                                          for tau in command.requested)
    unclamped = sampled(max_wheel_torque=100.0).command(state(0))
    assert not unclamped.clamped and (unclamped.tau_left, unclamped.tau_right) == command.requested
