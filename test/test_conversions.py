"""Model <-> message conversions of wallbot_msgs_py.conversions (no DDS traffic)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from wallbot_msgs_py import conversions, topics  # noqa: E402
from wallbot_sim.config import load_robot_parameters  # noqa: E402
from wallbot_sim.model import (  # noqa: E402
    BaumgarteGains, Circle, ConstraintSelection, FigureEight, Robot, SampledReference, Simulation, SmoothStop)
from wallbot_sim.model.trajectories import sample_plan  # noqa: E402


@pytest.fixture(scope='module')
def robot() -> Robot:
    return Robot(load_robot_parameters())


def moving_outputs(robot: Robot, torque=(0.3, -0.2)):
    """Outputs of a robot turned to 0.7 rad and moving, with motor torque and all structural constraints."""
    q0 = np.array([0.3, -0.2, 0.7, 0.1, 0.2, 0.3, 0.4])
    qd0 = np.array([0.2, 0.1, 0.3, 1.0, 1.0, -1.0, -1.0])
    sim = Simulation(robot, None, ConstraintSelection(False, True, False, False), q0, qd0)
    sim.set_motor_torque(*torque)
    for _ in range(3):
        sim.step()
    return sim.outputs()


def test_stamps_are_exact_integer_nanoseconds():
    for k in (0, 1, 999, 1000, 1001, 123456789):
        msg = conversions.stamp(k * 1e-3)
        assert conversions.stamp_nanoseconds(msg) == k * 1_000_000
    assert conversions.seconds(conversions.stamp(12.5)) == 12.5


@pytest.mark.parametrize('reference', [Circle(1.0, 20.0), FigureEight(1.0, 30.0, (0.5, -0.2)),
                                       SmoothStop(Circle(0.5, 7.0), 3.0, 2.0)], ids=['circle', 'figure8', 'stop'])
def test_plan_round_trip_interpolates_the_reference(reference):
    plan = sample_plan(reference, 0.0, 6.0, 0.01)
    msg = conversions.trajectory_message(plan)
    assert msg.header.frame_id == topics.WALL_FRAME and len(msg.points) == len(plan.times) == 601
    parsed = conversions.reference_from_trajectory(msg)
    direct = conversions.sampled_reference(plan)
    worst = 0.0
    for t in np.arange(0.0, 6.0, 0.0013):
        got, want = parsed.sample(t), reference.sample(t)
        assert got == direct.sample(t)  # the headless writer and the node interpolate alike
        worst = max(worst, math.hypot(got.position[0] - want.position[0], got.position[1] - want.position[1]))
        assert np.allclose(got.velocity, want.velocity, atol=1e-6)
    assert worst < 1e-6


def test_overlapping_plans_agree_exactly():
    reference = FigureEight()
    early = conversions.sampled_reference(sample_plan(reference, 0.0, 10.0, 0.01))
    late = conversions.sampled_reference(sample_plan(reference, 5.0042, 15.0, 0.01))
    assert late.start == 5.0
    for t in np.arange(5.0, 10.0, 0.001):
        assert early.sample(t) == late.sample(t)


def test_final_plan_ends_at_rest():
    moving = sample_plan(Circle(), 0.0, 3.0, 0.01)
    stopping = sample_plan(SmoothStop(Circle(), 2.0, 1.0), 0.0, 3.01, 0.01)
    assert not conversions.plan_is_final(moving)
    assert conversions.plan_is_final(stopping)


def test_tracking_through_the_plan_matches_the_analytic_reference(robot):
    """The model core's tracking run with the interpolated plan stays within 1e-6 m of the analytic one."""
    q0, qd0 = np.array([0.8, 0, 0, 0, 0, 0, 0.0]), np.zeros(7)
    selection = ConstraintSelection(True, True, True, True)
    plan = conversions.reference_from_trajectory(
        conversions.trajectory_message(sample_plan(Circle(), 0.0, 2.0, 0.01)))
    analytic = Simulation(robot, Circle(), selection, q0, qd0)
    sampled = Simulation(robot, plan, selection, q0, qd0)
    for _ in range(1500):
        analytic.step()
        sampled.step()
        assert np.max(np.abs(analytic.q[:2] - sampled.q[:2])) < 1e-6


def test_serialized_plan_decodes_to_the_same_plan():
    """The dynamics node takes plans raw (plan_from_cdr); they must equal rclpy's decoding."""
    plan = sample_plan(FigureEight(1.0, 30.0, (0.5, -0.2)), 3.0, 13.0, 0.05)
    msg = conversions.trajectory_message(plan)
    assert conversions.plan_from_cdr(serialize_message(msg)) == conversions.plan_from_trajectory(msg)


def from_bytes(msg):
    return SampledReference(*conversions.plan_from_cdr(serialize_message(msg)))


@pytest.mark.parametrize('decode', [conversions.reference_from_trajectory, from_bytes], ids=['message', 'cdr'])
@pytest.mark.parametrize('build, reason', [
    (lambda msg: msg.points.__setitem__(slice(None), msg.points[:1]), '>= 2 points'),
    (lambda msg: msg.points[3].velocities.clear(), 'point 3'),
    (lambda msg: setattr(msg.points[2], 'time_from_start', msg.points[1].time_from_start), 'increase'),
])
def test_bad_plans_are_refused_with_a_reason(decode, build, reason):
    msg = conversions.trajectory_message(sample_plan(Circle(), 0.0, 0.1, 0.01))
    build(msg)
    with pytest.raises(ValueError, match=reason):
        decode(msg)


@pytest.mark.parametrize('cut', [0, 3, 40, -9])
def test_truncated_serialized_plan_is_refused(cut):
    data = serialize_message(conversions.trajectory_message(sample_plan(Circle(), 0.0, 0.1, 0.01)))
    with pytest.raises(ValueError, match='malformed reference_trajectory'):
        conversions.plan_from_cdr(data[:cut])


def test_path_and_reference_odometry():
    plan = sample_plan(Circle(), 0.0, 10.0, 0.01)
    path = conversions.path_message(plan, max_poses=100)
    assert path.header.frame_id == topics.WALL_FRAME and 50 <= len(path.poses) <= 101
    assert path.poses[-1].pose.position.x == plan.positions[-1][0]
    sample = Circle().sample(2.0)
    msg = conversions.reference_odometry_message(sample, 2.0)
    assert msg.child_frame_id == topics.REFERENCE_FRAME
    speed = 2 * math.pi / 20.0
    assert msg.twist.twist.linear.x == pytest.approx(speed, abs=1e-12)
    assert msg.twist.twist.linear.y == pytest.approx(0.0, abs=1e-12)
    assert msg.twist.twist.angular.z == pytest.approx(2 * math.pi / 20.0, abs=1e-12)


def test_constraints_message_round_trip():
    switches = {'trajectory_task': True, 'belt': True, 'non_lateral': True, 'nonslip': False,
                'tangent_heading': True}
    msg = conversions.constraints_message(switches, BaumgarteGains(4.0, 6.0))
    assert msg.message == 'trajectory+tangent_heading+belt+non_lateral'
    values = {kv.key: kv.value for kv in msg.values}
    assert values['nonslip'] == 'false' and values['baumgarte_beta'] == '6.0'
    selection, gains = conversions.constraints_from_message(msg)
    assert selection == ConstraintSelection(True, True, True, False, None)
    assert gains == BaumgarteGains(4.0, 6.0)
    off = conversions.constraints_message({**switches, 'tangent_heading': False}, BaumgarteGains())
    assert conversions.constraints_from_message(off)[0].heading is False


@pytest.mark.parametrize('key, value, reason', [('belt', 'yes', 'belt'), ('baumgarte_alpha', '-1', 'alpha'),
                                                ('baumgarte_beta', 'nan', 'beta')])
def test_bad_constraints_message(key, value, reason):
    msg = conversions.constraints_message({name: False for name in conversions.SWITCHES}, BaumgarteGains())
    for kv in msg.values:
        if kv.key == key:
            kv.value = value
    with pytest.raises(ValueError, match=reason):
        conversions.constraints_from_message(msg)


def test_torque_command_validation():
    assert conversions.parse_torque_command(Float64MultiArray(data=[0.5, -1.0]), 2.0) == (0.5, -1.0)
    for data, reason in [([1.0], 'got 1 values'), ([1.0, 2.0, 3.0], 'got 3'), ([math.nan, 0.0], 'tau_L is not finite'),
                         ([0.0, math.inf], 'tau_R is not finite'), ([0.0, -2.5], 'beyond max_wheel_torque')]:
        with pytest.raises(ValueError, match=reason):
            conversions.parse_torque_command(Float64MultiArray(data=data), 2.0)


def test_diagnostics_builder():
    status = conversions.diagnostic_status('x', 'error', 'diverged', [('rate', 999.123456), ('set', 'belt')])
    assert status.level == DiagnosticStatus.ERROR
    assert [(kv.key, kv.value) for kv in status.values] == [('rate', '999.123'), ('set', 'belt')]
    array = conversions.diagnostics_message(1.5, [status])
    assert conversions.seconds(array.header.stamp) == 1.5
