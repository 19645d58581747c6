"""Closed loop through the graph (issue 5): tracking_controller_node driving the dynamics over DDS.

Every run is real processes, at real-time factor 1 unless it says otherwise: ``wallbot-sim run --controller`` (its own
domain) for the tracking targets and the controller kill, the nodes started one by one in the
session's domain for two robots side by side. What is checked is what was recorded.
"""

from __future__ import annotations

import math
import os
import re
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('rclpy')

from cli_helpers import WALLBOT  # noqa: E402
from closed_loop import (COMMAND_TIMEOUT, ROBOT, applied_torques, check_commands, check_complete,  # noqa: E402
                         model_closed_loop, recorded)
from wallbot_msgs_py import topics  # noqa: E402
from wallbot_sim.control.tracking import DRIVEN  # noqa: E402
from wallbot_sim.graph_description import CONTROL_STEPS  # noqa: E402
from wallbot_sim.graph import child_processes  # noqa: E402
from wallbot_sim.model import Simulation  # noqa: E402
from wallbot_sim.rundata import load_run  # noqa: E402



def start_run(process_runner, out: Path, scenario: str, duration: float, *extra: str):
    return process_runner.start([*WALLBOT, 'run', scenario, '--controller', '--duration', str(duration),
                                 '--out', str(out), '--no-plots', *extra], 'run')


def finish(process_runner, process, timeout: float = 120.0) -> str:
    try:
        status = process.wait(timeout)
    except Exception:  # noqa: BLE001 - TimeoutExpired: show what the run said
        pytest.fail('the run did not finish:\n' + process_runner.output('run'))
    output = process_runner.output('run')
    assert status == 0, output
    assert 'Traceback' not in output
    return output


# --- 1: tracking targets -------------------------------------------------------------------------
@pytest.mark.parametrize('scenario, mass_scale, bound, factor', [
    ('circle', 1.0, 5e-3, 1.0), ('figure8', 1.0, 5e-3, 0.0), ('circle', 1.2, 2e-2, 0.0), ('figure8', 0.8, 2e-2, 1.0)])
def test_closed_loop_tracks_through_the_graph(tmp_path, process_runner, scenario, mass_scale, bound, factor):
    """Error after 10 s: < 5 mm with the exact parameters, < 2 cm with the controller's mass 20 % off; paced in
    real time and as fast as the lockstep goes (the same loop either way)."""
    duration = 10.5
    out = tmp_path / 'run'
    output = finish(process_runner, start_run(process_runner, out, scenario, duration,
                                              '--controller-mass-scale', str(mass_scale),
                                              '--real-time-factor', str(factor)))
    assert f'under tracking_controller_node (mass scale {mass_scale:g})' in output
    run = load_run(out / 'bag')
    check_complete(run, duration)
    after = run.err[run.t >= 10.0]
    assert np.all(np.isfinite(after)) and np.max(after) < bound, f'error after 10 s: {np.max(after):.3e} m'
    if scenario == 'circle':  # it starts 0.2 m off the path, at rest: the controller brought it there
        assert run.err[0] == pytest.approx(0.2, abs=1e-9)
    check_commands(out / 'bag', duration, output)
    # the loop was closed from t = 0: the first step already had the controller's torque
    tau = applied_torques(run)
    assert np.all(np.abs(tau[1]) > 0.1)
    # lockstep: the graph's loop is the model's loop (the controller without delay), whatever the load
    model = model_closed_loop(scenario, mass_scale, len(run.t) - 1)
    difference = np.max(np.hypot(model[:, 0] - run.x, model[:, 1] - run.y))
    assert difference < 1e-9
    print(f'\n{scenario} mass x{mass_scale}: error after 10 s max {np.max(after) * 1e3:.3f} mm, '
          f'final {run.err[-1] * 1e3:.3f} mm; graph vs model loop {difference:.1e} m')


# --- 2: controller killed --------------------------------------------------------------------------
def test_killed_controller_falls_back_to_zero_torque_and_the_robot_moves_as_the_model_says(
        tmp_path, process_runner):
    duration = 8.0  # 2-4 s of zero torque: several 1 Hz diagnostics even when the machine is slow
    out = tmp_path / 'run'
    process = start_run(process_runner, out, 'circle', duration)
    deadline = time.monotonic() + 90
    while True:  # kill once more than 2 s are recorded (run prints a line every 2 s outside a terminal)
        assert process.poll() is None, process_runner.output('run')
        assert time.monotonic() < deadline, 'the graph did not come up: ' + process_runner.output('run')
        shown = re.findall(r't = +([0-9.]+) /', process_runner.output('run'))
        if shown and float(shown[-1]) > 2.0:
            break
        time.sleep(0.05)
    controller = [pid for pid, cmd in child_processes(process.pid).items() if 'wallbot_sim.nodes.controller' in cmd]
    assert len(controller) == 1
    os.kill(controller[0], signal.SIGKILL)
    output = finish(process_runner, process)
    assert 'node controller exited with status -9' in output and 'the run goes on' in output

    run = load_run(out / 'bag')
    check_complete(run, duration)  # nothing lost around the kill
    tau = applied_torques(run)
    assert np.all(np.isfinite(tau))
    zero = np.all(np.abs(tau) < 1e-9, axis=1)
    assert not zero[1] and zero[-1]
    first_zero = int(np.argmax(zero & (run.t > 1.0)))
    assert np.all(zero[first_zero:]), 'torque came back after the fallback'
    held = tau[first_zero - 1]
    last_change = first_zero - 1
    while np.max(np.abs(tau[last_change - 1] - held)) < 1e-6:  # recovered torques agree to ~1e-9
        last_change -= 1
    # the last command was held command_timeout of simulation time, then zero torque
    held_for = run.t[first_zero] - run.t[last_change]
    assert COMMAND_TIMEOUT - 2e-3 <= held_for <= COMMAND_TIMEOUT + 2e-3, held_for
    assert 2.0 < run.t[last_change] < 6.0  # killed when the run's line showed > 2 s: up to 2 s later

    # /diagnostics said so (1 Hz wall: the zero-torque segment lasts > 1 s)
    statuses = [s for m in recorded(out / 'bag', 'diagnostics') for s in m.status if s.name.endswith('simulation')]
    timed_out = [s for s in statuses if {kv.key: kv.value for kv in s.values}.get('command') == 'timed out, zero torque']
    seen = [(m.header.stamp.sec, {kv.key: kv.value for kv in s.values}.get('command')) for m in recorded(
        out / 'bag', 'diagnostics') for s in m.status]
    assert timed_out and all(s.level == 1 for s in timed_out), seen  # WARN
    assert 'zero torque' in timed_out[0].message

    # the model from the recorded state at the fallback, under zero torque: the same motion
    k = first_zero - 1  # the state from which the first zero-torque step starts
    q0 = np.r_[run.x[k], run.y[k], run.theta[k], run.phi[k]]
    qd0 = np.r_[run.vx[k], run.vy[k], run.omega[k], run.dphi[k]]
    model = Simulation(ROBOT, None, DRIVEN, q0, qd0, t0=run.t[k])
    predicted = []
    for _ in range(len(run.t) - 1 - k):
        model.step()
        predicted.append(model.q[:2].copy())
    predicted = np.array(predicted)
    actual = np.c_[run.x[k + 1:], run.y[k + 1:]]
    assert np.max(np.abs(predicted - actual)) < 1e-6
    # unpowered, the robot coasts along its heading under gravity and rolling resistance (the
    # model above); whether it climbs on or rolls back within the run depends on its heading at
    # the kill, which depends on when the kill came
    assert np.max(np.abs(np.diff(actual, axis=0))) > 0.0, 'the robot does not move after the fallback'
    print(f'\nfallback {held_for:.3f} s after the last command; model vs graph over '
          f'{run.t[-1] - run.t[k]:.2f} s: {np.max(np.abs(predicted - actual)):.2e} m')


# --- 3: two robots in one domain -------------------------------------------------------------------
ROBOTS = {  # namespace: scenario as parameters (different shapes and places: cross-talk would show)
    '/r1': {'trajectory': ('shape:=figure8', 'period:=30.0'),
            'dynamics': ('initial_x:=0.0', 'initial_y:=0.0', 'initial_theta:=0.7853981633974483',
                         'initial_at_rest:=false')},
    '/r2': {'trajectory': ('shape:=circle', 'period:=20.0', 'center_x:=3.0'),
            'dynamics': ('initial_x:=3.8', 'initial_y:=0.0', 'initial_theta:=0.0', 'initial_at_rest:=true')},
}


@pytest.mark.parametrize('driven', [True, False], ids=['each_with_its_controller', 'each_on_its_trajectory_task'])
def test_two_robots_side_by_side(tmp_path, process_runner, driven):
    """Two robots in one domain started with nothing but ``-r __ns:=``: each robot's nodes follow
    its own clock (both dynamics also publish the domain's /clock, as nobody set domain_clock
    false: no node of a robot listens to it), and each tracks its path."""
    import rclpy
    duration = 10.5
    context = rclpy.Context()
    rclpy.init(context=context)
    from rosgraph_msgs.msg import Clock

    from wallbot_msgs_py.qos import qos_profile
    probe = rclpy.create_node('two_robot_probe', context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(probe)
    progress = {ns: -1.0 for ns in ROBOTS}
    for ns in ROBOTS:  # how far each robot's recorder got (the newest clock it wrote)
        probe.create_subscription(Clock, f'{ns}/record_progress',
                                  lambda msg, ns=ns: progress.__setitem__(ns, msg.clock.sec + msg.clock.nanosec * 1e-9),
                                  qos_profile(topics.RECORD_PROGRESS))
    procs = {}

    def start(ns: str, name: str, module: str, *params: str):
        args = [sys.executable, '-m', f'wallbot_sim.nodes.{module}', '--ros-args', '-r', f'__ns:={ns}']
        for param in params:
            args += ['-p', param]
        procs[f'{ns[1:]}_{name}'] = process_runner.start(args, f'{ns[1:]}_{name}')

    def wait_for(predicate, timeout, what):
        deadline = time.monotonic() + timeout
        while not predicate():
            for name, proc in procs.items():
                assert proc.poll() is None, f'{name} exited:\n{process_runner.output(name)}'
            if time.monotonic() > deadline:
                pytest.fail(f'timed out waiting for {what}')  # the nodes' logs: conftest's report
            executor.spin_once(timeout_sec=0.1)

    try:
        for ns, config in ROBOTS.items():
            start(ns, 'recorder', 'recorder', f'output:={tmp_path / ns[1:]}', 'topics:=[' + ','.join(
                t.name for t in (*topics.RECORDED, topics.WHEEL_TORQUE_CMD)) + ']')
            start(ns, 'constraint_config', 'constraint_config', f'trajectory_task:={str(not driven).lower()}',
                  'belt:=true', 'non_lateral:=true', 'nonslip:=true')
            start(ns, 'trajectory', 'trajectory', *config['trajectory'])
            if driven:
                start(ns, 'controller', 'controller')
        for ns in ROBOTS:  # recorder and controller hear odom before the dynamics starts
            wait_for(lambda ns=ns: probe.count_subscribers(f'{ns}/odom') == 1 + driven
                     and probe.count_publishers(f'{ns}/wheel_torque_cmd') == driven, 30,
                     f'{ns} recorder and controller')
        for ns, config in ROBOTS.items():
            start(ns, 'dynamics', 'dynamics', *config['dynamics'], 'wait_for_recorder:=true', f'stop_at:={duration}',
                  *(('wait_for_command:=true', f'lockstep_every:={CONTROL_STEPS}') if driven else ()))
        for ns in ROBOTS:
            wait_for(lambda ns=ns: progress[ns] >= duration - 1e-9, 60, f'{ns} recorded up to {duration} s')
            # one publisher per robot topic: nobody answers on the other robot's topics
            assert probe.count_publishers(f'{ns}/odom') == 1 and probe.count_publishers(f'{ns}/clock') == 1
            assert probe.count_publishers(f'{ns}/wheel_torque_cmd') == driven
        # the robots' nodes follow their own clocks, none the domain's /clock both dynamics publish
        assert probe.count_publishers('/clock') == 2
        assert not [i.node_namespace for i in probe.get_subscriptions_info_by_topic('/clock')
                    if i.node_namespace in ROBOTS]
    finally:
        for name, proc in procs.items():  # recorders with SIGINT: a closed bag
            if name.endswith('recorder'):
                proc.send_signal(signal.SIGINT)
        for name, proc in procs.items():
            if name.endswith('recorder'):
                proc.wait(15)
        executor.shutdown()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)

    results = {}
    for ns, start_x in (('/r1', 0.0), ('/r2', 3.8)):
        run = load_run(tmp_path / ns[1:])
        assert run.t[0] == 0.0 and np.all(np.diff(np.round(run.t * 1e9)) == 1e6)
        assert run.x[0] == start_x
        after = run.err[run.t >= 10.0]
        assert run.t[-1] >= duration - 1e-9 and np.max(after) < 5e-3, f'{ns}: {np.max(after):.3e} m'
        results[ns] = run
        if driven:
            check_commands(tmp_path / ns[1:], duration)
    # no cross-talk: each robot stays around its own path (the figure-8 within |x| <= 1 m, the circle around x = 3)
    assert np.max(np.abs(results['/r1'].x)) < 1.01 and np.min(results['/r2'].x) > 1.95
    errors = {ns: np.max(run.err[run.t >= 10]) * 1e3 for ns, run in results.items()}
    print(f'\ntwo robots ({"driven" if driven else "trajectory task"}): error after 10 s {errors["/r1"]:.3f} mm (r1), '
          f'{errors["/r2"]:.3f} mm (r2)')


# --- the node's own checks (no closed loop) ------------------------------------------------------
def test_cdr_stamp_and_odometry_decoding():
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message, serialize_message

    from message_fields import planar_state
    from wallbot_msgs_py import codec, topics
    from wallbot_msgs_py.step_cdr import StepEncoder
    from wallbot_msgs_py.codec import leading_stamp_ns
    plant = Simulation(ROBOT, None, DRIVEN, np.array([0.3, -0.2, 2.5, 0, 0, 0, 0]), np.zeros(7), t0=12.345)
    plant.set_motor_torque(1.0, 2.0)
    for _ in range(50):
        plant.step()
    data = dict(StepEncoder().encode(plant.outputs()))[topics.ODOM]
    msg = deserialize_message(data, Odometry)
    assert leading_stamp_ns(data) == round(plant.t * 1e9)
    assert leading_stamp_ns(b'\0\1') is None
    state = codec.decode_odometry(data).planar_state()  # what the controller node reads
    assert state == planar_state(msg)  # what rclpy reads
    assert state.stamp_ns == round(plant.t * 1e9)
    assert np.allclose([state.x, state.y, state.theta, state.xd, state.yd, state.thd], plant.q[:3].tolist()
                       + plant.qd[:3].tolist(), atol=1e-12)
    msg.twist.twist.linear.x = math.nan
    with pytest.raises(ValueError, match='not finite'):
        codec.decode_odometry(serialize_message(msg)).planar_state()


@pytest.mark.parametrize('param, reason', [('alpha:=-1.0', 'alpha must be in [0.001, 10000]'),
                                           ('mass_scale:=0.0', 'mass_scale must be in [0.001, 1000]'),
                                           ('integral:=-2.0', 'integral must be in [0, 1e+06]'),
                                           ('max_wheel_torque:=.nan', 'max_wheel_torque must be a finite number'),
                                           ('engine:=fortran', 'engine must be one of python, numba')])
def test_controller_refuses_bad_parameters_with_a_reason(process_runner, param, reason):
    proc = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.controller', '--ros-args', '-p', param],
                                'controller')
    assert proc.wait(30) == 1
    assert reason in process_runner.output('controller')


@pytest.mark.parametrize('node', ['controller', 'cmd_vel'])
def test_a_commander_waits_for_a_recorder_before_subscribing_odom(ros_domain, node):
    """run --controller, run rest --drive cmd_vel: the dynamics starts once its commander subscribes
    odom; with wait_for_recorder the commander does that only when a recorder hears its commands,
    so the bag holds every command from t = 0.

    The commander runs in this process, so what it has done is read off the node itself: a
    record_progress publisher that does not hear wheel_torque_cmd is in the commander's own view of
    the graph and its recorder check has run since, and it has no odom subscription; once that
    publisher's node also subscribes wheel_torque_cmd, the commander subscribes odom."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64MultiArray

    from wallbot_msgs_py.qos import qos_profile
    from wallbot_sim.nodes.cmd_vel import CmdVelNode
    from wallbot_sim.nodes.common import WhenRecorded
    from wallbot_sim.nodes.controller import ControllerNode
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        commander = {'controller': ControllerNode, 'cmd_vel': CmdVelNode}[node](
            context=context, parameter_overrides=[Parameter('wait_for_recorder', value=True)])
        probe = rclpy.create_node('recorder_probe', namespace=topics.NAMESPACE, context=context)
        executor.add_node(commander)
        executor.add_node(probe)
        odom, progress = topics.ODOM.resolve(), topics.RECORD_PROGRESS.resolve()
        check = next(timer for timer in commander.timers
                     if isinstance(getattr(timer.callback, '__self__', None), WhenRecorded))

        def spin_until(predicate, what: str) -> None:
            deadline = time.monotonic() + 30  # a stall
            while not predicate():
                assert time.monotonic() < deadline, f'timed out waiting for {what}'
                executor.spin_once(timeout_sec=0.05)

        def subscribed_odom() -> bool:
            return any(subscription.topic_name == odom for subscription in commander.subscriptions)

        assert not subscribed_odom()
        probe.create_publisher(Clock, topics.RECORD_PROGRESS.name, qos_profile(topics.RECORD_PROGRESS))
        spin_until(lambda: commander.count_publishers(progress) == 1, 'the commander seeing record_progress')
        seen = time.monotonic_ns()
        spin_until(lambda: time.monotonic_ns() - check.time_since_last_call() > seen,
                   "the commander's recorder check after that")
        assert not subscribed_odom(), 'subscribed odom with no recorder hearing wheel_torque_cmd'
        probe.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, lambda _msg: None,
                                  qos_profile(topics.WHEEL_TORQUE_CMD))
        spin_until(subscribed_odom, 'the odom subscription once a recorder hears the commands')
    finally:
        executor.shutdown()
        rclpy.try_shutdown(context=context)
