"""The robot's sensors in the graph: the dynamics publishes imu, joint_states and chamber_pressure at their rates and
a run records them (docs/model.md 13.5), each sample the state's of the same stamp."""

from __future__ import annotations

import math

from bag_helpers import by_topic, stamp_ns
from cli_helpers import wallbot
from wallbot_msgs_py import topics
from wallbot_sim import paths
from wallbot_sim.model.vacuum import ATMOSPHERE
from wallbot_sim.rundata import load_run

SENSORS = """
adhesion: {chamber_area: 0.02, chamber_volume: 0.002, pump_max_pressure: 12000.0, pump_max_flow: 0.01,
           leak_area: 2.0e-5}
sensors:
  imu: {}
  encoders: {rate: 100.0, counts_per_rev: 1024}
  pressure: {rate: 50.0}
"""


def test_a_run_records_the_sensors_at_their_rates_reading_the_recorded_states(tmp_path):
    robot = tmp_path / 'robot.yaml'
    robot.write_text(paths.robot_yaml().read_text() + SENSORS)
    out = tmp_path / 'run'
    result = wallbot('run', 'circle', '--duration', 0.5, '--real-time-factor', 0, '--no-plots', '--robot', robot,
                     '--out', out)  # no --engine: python, which the vacuum block needs, said in one line
    assert result.returncode == 0, result.stderr
    assert result.stderr.count('wallbot-sim run: engine python (a vacuum block runs on the python engine only)') == 1
    bag = by_topic(out / 'bag')
    for topic, rate in ((topics.IMU, 200), (topics.JOINT_STATES, 100), (topics.CHAMBER_PRESSURE, 50)):
        period = 1_000_000_000 // rate
        assert [stamp_ns(msg) for msg in bag[topic.resolve()]] == [period * k for k in range(round(0.5 * rate) + 1)], topic.name
    odom = {stamp_ns(msg): msg for msg in bag[topics.ODOM.resolve()]}
    wheels = {stamp_ns(msg): msg for msg in bag[topics.WHEEL_STATES.resolve()]}
    for imu in bag[topics.IMU.resolve()]:
        assert imu.angular_velocity.z == odom[stamp_ns(imu)].twist.twist.angular.z  # no noise: the state's turn rate
        assert imu.orientation_covariance[0] == -1.0 and imu.header.frame_id == topics.BASE_FRAME
    count = 2 * math.pi / 1024
    for joints in bag[topics.JOINT_STATES.resolve()]:
        exact = wheels[stamp_ns(joints)].position
        assert list(joints.name) == list(topics.WHEEL_JOINTS) and len(joints.effort) == 0
        assert all(0.0 <= angle - read < count and abs(read / count - round(read / count)) < 1e-9
                   for angle, read in zip(exact, joints.position))
    pressures = [msg.fluid_pressure for msg in bag[topics.CHAMBER_PRESSURE.resolve()]]
    assert all(ATMOSPHERE - 12000.0 < pressure < ATMOSPHERE for pressure in pressures)
    times, dp = load_run(out / 'bag').machine['dp']  # what plot draws: the chamber's pressure difference
    assert times.tolist() == [stamp_ns(msg) * 1e-9 for msg in bag[topics.CHAMBER_PRESSURE.resolve()]]
    assert dp.tolist() == [ATMOSPHERE - pressure for pressure in pressures]
