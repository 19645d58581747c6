"""The per-step messages as CDR bytes: decoded by rosbags (always) and by rclpy (when installed),
they carry the model's outputs with the conventions of REP 103/105, and rclpy re-serializes them
to the same messages."""

from __future__ import annotations

import importlib
import math
from types import SimpleNamespace

import numpy as np
import pytest

from wallbot_msgs_py import bagio, topics
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import ConstraintSelection, Robot, Simulation


def moving_outputs(torque=(0.3, -0.2), t0: float = 0.0):
    """Outputs of a robot turned to 0.7 rad and moving, with motor torque and all structural constraints."""
    q0 = np.array([0.3, -0.2, 0.7, 0.1, 0.2, 0.3, 0.4])
    qd0 = np.array([0.2, 0.1, 0.3, 1.0, 1.0, -1.0, -1.0])
    sim = Simulation(Robot(load_robot_parameters()), None, ConstraintSelection(False, True, False, False), q0, qd0,
                     t0=t0)
    sim.set_motor_torque(*torque)
    for _ in range(3):
        sim.step()
    return sim.outputs()


def rosbags_decode(topic: topics.Topic, data: bytes):
    return bagio.deserialize(data, topic.type)


def rclpy_decode(topic: topics.Topic, data: bytes):
    pytest.importorskip('rclpy')
    from rclpy.serialization import deserialize_message, serialize_message
    package, _msg, name = topic.type.split('/')
    kind = getattr(importlib.import_module(f'{package}.msg'), name)
    msg = deserialize_message(data, kind)
    assert deserialize_message(serialize_message(msg), kind) == msg  # rclpy's own bytes say the same
    return msg


DECODERS = pytest.mark.parametrize('decode', [rosbags_decode, rclpy_decode], ids=['rosbags', 'rclpy'])


def nanoseconds(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@DECODERS
def test_odometry_pose_in_wall_twist_in_base_link(decode):
    out = moving_outputs()
    msg = decode(topics.ODOM, dict(StepEncoder().encode(out))[topics.ODOM])
    assert (msg.header.frame_id, msg.child_frame_id) == (topics.WALL_FRAME, topics.BASE_FRAME)
    assert nanoseconds(msg.header.stamp) == 3_000_000
    x, y, th = out.q[:3]
    xd, yd, thd = out.qd[:3]
    pose, twist = msg.pose.pose, msg.twist.twist
    assert (pose.position.x, pose.position.y, pose.position.z) == (x, y, 0.0)
    assert (pose.orientation.x, pose.orientation.y) == (0.0, 0.0)
    assert 2.0 * math.atan2(pose.orientation.z, pose.orientation.w) == pytest.approx(th, abs=1e-15)
    # REP 105: twist in the child frame; rotating it back gives the wall-frame velocity
    vx, vy = twist.linear.x, twist.linear.y
    assert math.cos(th) * vx - math.sin(th) * vy == pytest.approx(xd, abs=1e-15)
    assert math.sin(th) * vx + math.cos(th) * vy == pytest.approx(yd, abs=1e-15)
    assert (twist.linear.z, twist.angular.x, twist.angular.y, twist.angular.z) == (0.0, 0.0, 0.0, thd)
    assert not np.any(msg.pose.covariance) and not np.any(msg.twist.covariance)


@DECODERS
def test_wheels_wrench_drive_forces_and_clock(decode):
    out = moving_outputs(torque=(0.3, -0.2), t0=12.5)
    messages = {topic: decode(topic, data) for topic, data in StepEncoder().encode(out)}
    wheels = messages[topics.WHEEL_STATES]
    assert list(wheels.name) == list(topics.WHEEL_JOINTS)
    assert list(wheels.position) == list(out.q[3:]) and list(wheels.velocity) == list(out.qd[3:])
    expected_effort = out.constraint_force[3:] + np.array([0.15, 0.15, -0.1, -0.1])  # half the side torque each
    assert np.allclose(list(wheels.effort), expected_effort, atol=1e-15)
    wrench = messages[topics.CONSTRAINT_WRENCH]
    assert wrench.header.frame_id == topics.WALL_FRAME
    force, torque = wrench.wrench.force, wrench.wrench.torque
    assert (force.x, force.y, torque.z) == tuple(out.constraint_force[:3])
    assert (force.z, torque.x, torque.y) == (0.0, 0.0, 0.0)
    drive = messages[topics.DRIVE_FORCES]
    assert list(drive.name) == list(topics.DRIVE_JOINTS)
    assert list(drive.effort) == [out.drive.left, out.drive.right, out.drive.lateral]
    assert len(drive.position) == len(drive.velocity) == 0
    contact = messages[topics.WHEEL_CONTACT]
    wheels = list(topics.WHEEL_JOINTS)
    assert list(contact.name) == wheels + [f'{w}/x' for w in wheels] + [f'{w}/y' for w in wheels]
    state = out.contact
    forces, velocities = state.wheel_forces, state.slip_velocity
    assert list(contact.effort) == [*state.loads, *forces[:, 0], *forces[:, 1]]
    assert list(contact.position) == [*state.wheel_use, *[0.0] * 8]
    assert list(contact.velocity) == [*map(float, state.wheel_slipping), *velocities[:, 0], *velocities[:, 1]]
    assert velocities[0, 0] != 0.0 and forces[0, 1] != 0.0  # the moving robot's wheels slip and are pushed
    stamps = [nanoseconds(msg.clock if topic is topics.CLOCK else msg.header.stamp) for topic, msg in messages.items()]
    assert stamps == [12_503_000_000] * 6


def test_publishing_order_ends_with_the_clock_and_bytes_are_not_reused():
    encoder = StepEncoder()
    first = encoder.encode(moving_outputs(torque=(0.3, -0.2)))
    kept = [data for _, data in first]
    second = encoder.encode(moving_outputs(torque=(-1.0, 1.0), t0=1.0))
    assert [topic for topic, _ in first] == [topics.ODOM, topics.WHEEL_STATES, topics.CONSTRAINT_WRENCH,
                                             topics.DRIVE_FORCES, topics.WHEEL_CONTACT, topics.CLOCK]
    assert [data for _, data in first] == kept  # a later step does not change bytes already handed out
    assert all(a != b for (_, a), (_, b) in zip(first, second))


@pytest.mark.parametrize('ground_truth', [False, True])
def test_steps_encoded_as_rows_are_the_steps_encoded_one_by_one(ground_truth):
    """encode_rows (array assignments into copies of each template) against encode per step: the same
    bytes in the same order, with turns either way, slipping flags set, other frame names."""
    rng = np.random.default_rng(5)
    count = 9
    t = 12.345 + 1e-3 * np.arange(count)
    q, qd = rng.normal(size=(count, 7)), rng.normal(size=(count, 7))
    q[:, 2] = np.linspace(-7.0, 7.0, count)
    rows = SimpleNamespace(t=t, q=q, qd=qd, wheel_torques=rng.normal(size=(count, 4)),
                           chassis_wrench=rng.normal(size=(count, 3)), drive=rng.normal(size=(count, 3)),
                           loads=rng.normal(size=(count, 4)), wheel_use=rng.uniform(size=(count, 4)),
                           wheel_slipping=rng.uniform(size=(count, 4)) < 0.5,
                           wheel_forces=rng.normal(size=(count, 4, 2)), slip_velocity=rng.normal(size=(count, 4, 2)))
    steps = [SimpleNamespace(t=float(t[k]), q=q[k], qd=qd[k], wheel_torques=rows.wheel_torques[k],
                             chassis_wrench=rows.chassis_wrench[k],
                             drive=SimpleNamespace(left=rows.drive[k, 0], right=rows.drive[k, 1],
                                                   lateral=rows.drive[k, 2]),
                             contact=SimpleNamespace(loads=rows.loads[k], wheel_use=rows.wheel_use[k],
                                                     wheel_slipping=tuple(rows.wheel_slipping[k]),
                                                     wheel_forces=rows.wheel_forces[k],
                                                     slip_velocity=rows.slip_velocity[k]))
             for k in range(count)]
    one_by_one = StepEncoder(odom_frame='map', base_frame='robot2/base_link', ground_truth=ground_truth)
    as_rows = StepEncoder(odom_frame='map', base_frame='robot2/base_link', ground_truth=ground_truth)
    assert as_rows.encode_rows(rows) == [one_by_one.encode(step) for step in steps]
