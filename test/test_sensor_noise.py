"""Sensor noise on the published odometry and wheel states: seeded, its variance as the odometry
covariance, the exact state beside it on ground_truth/odom, in the bag and in the run data; the
simulation itself integrates the exact state."""

from __future__ import annotations

import dataclasses
import signal
import subprocess
import time

import numpy as np
import pytest

from cli_helpers import WALLBOT
from wallbot_msgs_py import bagio, topics
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim.nodes.sensor_noise import NoiseLevels, SensorNoise

LEVELS = NoiseLevels(position=0.01, heading=0.02, linear=0.03, angular=0.04, encoder=0.05, encoder_velocity=0.5)
NOISY_DYNAMICS = {'odom_noise_position': 0.01, 'odom_noise_heading': 0.02, 'odom_noise_linear': 0.03,
                    'odom_noise_angular': 0.04, 'encoder_noise': 0.05, 'encoder_velocity_noise': 0.5,
                    'noise_seed': 7, 'odom_frame_id': 'map', 'base_frame_id': 'chassis'}


def test_the_noise_has_its_levels_and_the_same_seed_gives_the_same_noise():
    q, qd = np.arange(7.0), np.arange(7.0) + 10.0
    first, again, other = SensorNoise(LEVELS, 3), SensorNoise(LEVELS, 3), SensorNoise(LEVELS, 4)
    draws = [first.sense(q, qd) for _ in range(20_000)]
    assert np.array_equal(q, np.arange(7.0)) and np.array_equal(qd, np.arange(7.0) + 10.0)  # not changed
    deviations = np.array([np.concatenate([d.q - q, d.qd - qd]) for d in draws])
    expected = np.array([0.01, 0.01, 0.02] + [0.05] * 4 + [0.03, 0.03, 0.04] + [0.5] * 4)
    # 20,000 draws: the sample standard deviation is within 2 % (about 3 sigma), the mean near 0
    assert np.all(np.abs(deviations.std(axis=0) / expected - 1.0) < 0.02)
    assert np.all(np.abs(deviations.mean(axis=0)) < 4 * expected / np.sqrt(len(draws)))
    repeated = again.sense(q, qd)
    assert np.array_equal(repeated.q, draws[0].q) and np.array_equal(repeated.qd, draws[0].qd)
    assert not np.array_equal(other.sense(q, qd).q, draws[0].q)
    assert not NoiseLevels().on and LEVELS.on
    exact = SensorNoise(NoiseLevels(), 0).sense(q, qd)
    assert np.array_equal(exact.q, q) and np.array_equal(exact.qd, qd)


def test_the_odometry_carries_the_noise_variance_and_the_truth_goes_beside_it():
    from wallbot_sim.config import load_robot_parameters
    from wallbot_sim.model import Circle, ConstraintSelection, Robot, Simulation

    sim = Simulation(Robot(load_robot_parameters()), Circle(), ConstraintSelection.parse('belt'),
                     np.array([0.8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), np.zeros(7))
    for _ in range(5):
        sim.step()
    out = sim.outputs()
    encoder = StepEncoder('map', 'chassis', LEVELS.pose_variances(), LEVELS.twist_variances(), ground_truth=True)
    sensed = SensorNoise(LEVELS, 1).sense(out.q, out.qd)
    encoded = encoder.encode(out, sensed)
    assert [topic for topic, _ in encoded] == [topics.ODOM, topics.WHEEL_STATES, topics.CONSTRAINT_WRENCH,
                                               topics.DRIVE_FORCES, topics.WHEEL_CONTACT, topics.GROUND_TRUTH_ODOM,
                                               topics.CLOCK]
    data = {topic: bagio.deserialize(raw, topic.type) for topic, raw in encoded}
    odom, truth, wheels = data[topics.ODOM], data[topics.GROUND_TRUTH_ODOM], data[topics.WHEEL_STATES]
    assert (odom.header.frame_id, odom.child_frame_id) == ('map', 'chassis')
    assert data[topics.CONSTRAINT_WRENCH].header.frame_id == 'map'
    pose_cov, twist_cov = np.reshape(odom.pose.covariance, (6, 6)), np.reshape(odom.twist.covariance, (6, 6))
    assert np.array_equal(pose_cov, np.diag([1e-4, 1e-4, 0.0, 0.0, 0.0, 4e-4]))
    assert np.array_equal(twist_cov, np.diag([9e-4, 9e-4, 0.0, 0.0, 0.0, 1.6e-3]))
    assert not np.any(truth.pose.covariance) and not np.any(truth.twist.covariance)
    assert (truth.pose.pose.position.x, truth.pose.pose.position.y) == (out.q[0], out.q[1])
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (sensed.q[0], sensed.q[1])
    assert np.array_equal(wheels.position, sensed.q[3:]) and np.array_equal(wheels.velocity, sensed.qd[3:])
    plain = dict(StepEncoder().encode(out))  # without noise: no ground truth, zero covariance
    assert topics.GROUND_TRUTH_ODOM not in plain
    assert not np.any(bagio.deserialize(plain[topics.ODOM], topics.ODOM.type).pose.covariance)


def test_a_noisy_run_records_the_truth_and_simulates_it(tmp_path, process_runner):
    """The graph with noise on: the bag has the noisy odom and ground_truth/odom; the run data's
    state is the truth, the same states ``simulate`` computes without noise (the noise never
    reaches the simulation), and its sensed odometry differs from it by the noise."""
    rclpy = pytest.importorskip('rclpy')
    from rosgraph_msgs.msg import Clock

    from wallbot_msgs_py.qos import qos_profile
    from wallbot_sim.bag.reader import messages
    from wallbot_sim.config import load_scenario
    from wallbot_sim.graph_description import describe_graph
    from wallbot_sim.model import ConstraintSelection
    from wallbot_sim.rundata import load_run

    duration, constraints = 1.0, 'belt,non_lateral,nonslip'
    specs = describe_graph(load_scenario('circle'), ConstraintSelection.parse(constraints), duration=duration,
                           real_time_factor=0.0, bag=tmp_path / 'bag')
    context = rclpy.Context()
    rclpy.init(context=context)
    probe = rclpy.create_node('noise_probe', context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(probe)
    progress = []
    probe.create_subscription(Clock, topics.RECORD_PROGRESS.resolve(), lambda msg: progress.append(
        msg.clock.sec + msg.clock.nanosec * 1e-9), qos_profile(topics.RECORD_PROGRESS))
    procs = {}
    try:
        for spec in specs:
            if spec.name == 'dynamics':
                spec = dataclasses.replace(spec, parameters={**spec.parameters, **NOISY_DYNAMICS})
            procs[spec.name] = process_runner.start(spec.command(), spec.name)
        deadline = time.monotonic() + 120
        while not (progress and progress[-1] >= duration - 1e-9):
            assert time.monotonic() < deadline, '\n'.join(process_runner.output(n)[-2000:] for n in procs)
            for name, proc in procs.items():
                assert proc.poll() is None, f'{name} exited:\n{process_runner.output(name)}'
            executor.spin_once(timeout_sec=0.1)
        procs['recorder'].send_signal(signal.SIGINT)
        assert procs['recorder'].wait(20) == 0
    finally:
        executor.shutdown()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)

    run = load_run(tmp_path / 'bag')
    headless = tmp_path / 'headless'
    assert subprocess.run([*WALLBOT, 'simulate', '--scenario', 'circle', '--constraints', constraints,
                           '--duration', str(duration), '--bag', str(headless), '--quiet'],
                          capture_output=True, timeout=120).returncode == 0
    exact = load_run(headless)
    assert len(run) == len(exact) == round(duration * 1000) + 1 and np.array_equal(run.t, exact.t)
    for name in ('x', 'y', 'theta', 'vx', 'vy', 'omega'):
        assert np.max(np.abs(getattr(run, name) - getattr(exact, name))) < 1e-9, name
    assert exact.sensed.size == 0
    deviation = run.sensed - np.column_stack([run.x, run.y, run.theta, run.vx, run.vy, run.omega])
    expected = np.array([0.01, 0.01, 0.02, 0.03, 0.03, 0.04])
    assert np.all(np.abs(deviation.std(axis=0) / expected - 1.0) < 0.15)  # 1001 draws: within 15 %
    phi_noise = run.phi - exact.phi
    assert abs(phi_noise.std() / 0.05 - 1.0) < 0.1
    first_odom = next(raw for raw in messages(tmp_path / 'bag', [topics.ODOM.resolve()]))
    odom = bagio.deserialize(first_odom.data, first_odom.type)
    assert (odom.header.frame_id, odom.child_frame_id) == ('map', 'chassis')  # the frame parameters
    covariance = np.reshape(odom.pose.covariance, (6, 6))
    assert np.allclose(np.diag(covariance), [1e-4, 1e-4, 0.0, 0.0, 0.0, 4e-4], rtol=0, atol=1e-18)
