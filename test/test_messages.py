"""The message codecs (wallbot_msgs_py.codec) and the model-aware conversions (wallbot_sim.messages),
without ROS; rclpy, where installed, decodes the same bytes to the same fields."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bag_helpers import fields
from message_fields import planar_state, quaternion_yaw, seconds, stamp_ns, typestore_header
from wallbot_msgs_py import bagio, cdr, codec, topics
from wallbot_msgs_py.constraint_modules import CONSTRAINT_MODULES, CONSTRAINT_SWITCHES
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import (
    BaumgarteGains, Circle, ConstraintSelection, FigureEight, Robot, SampledReference, Simulation, SmoothStop)
from wallbot_sim.model.constraint_set import MODULES
from wallbot_sim.model.trajectories import sample_plan


def decode(data: bytes, topic: topics.Topic):
    return bagio.deserialize(data, topic.type)


@pytest.fixture(scope='module')
def robot() -> Robot:
    return Robot(load_robot_parameters())


def test_stamps_are_exact_integer_nanoseconds():
    encoder = codec.ClockEncoder()
    for k in (0, 1, 999, 1000, 1001, 123456789):
        data = encoder.encode(*cdr.split_stamp(cdr.to_nanoseconds(k * 1e-3)))
        assert stamp_ns(decode(data, topics.CLOCK).clock) == k * 1_000_000  # rosbags reads it
        assert codec.decode_clock(data) == codec.leading_stamp_ns(data) == k * 1_000_000
    assert seconds(decode(encoder.encode(*cdr.split_stamp(cdr.to_nanoseconds(12.5))), topics.CLOCK).clock) == 12.5


@pytest.mark.parametrize('reference', [Circle(1.0, 20.0), FigureEight(1.0, 30.0, (0.5, -0.2)),
                                       SmoothStop(Circle(0.5, 7.0), 3.0, 2.0)], ids=['circle', 'figure8', 'stop'])
def test_plan_round_trip_interpolates_the_reference(reference):
    plan = sample_plan(reference, 0.0, 6.0, 0.01)
    msg = decode(messages.trajectory_message(plan), topics.REFERENCE_TRAJECTORY)
    assert msg.header.frame_id == topics.WALL_FRAME and len(msg.points) == len(plan.times) == 601
    parsed = SampledReference(*messages.plan_from_cdr(messages.trajectory_message(plan)))
    direct = messages.sampled_reference(plan)
    worst = 0.0
    for t in np.arange(0.0, 6.0, 0.0013):
        got, want = parsed.sample(t), reference.sample(t)
        assert got == direct.sample(t)  # the headless writer and the node interpolate alike
        worst = max(worst, math.hypot(got.position[0] - want.position[0], got.position[1] - want.position[1]))
        assert np.allclose(got.velocity, want.velocity, atol=1e-6)
    assert worst < 1e-6


def test_overlapping_plans_agree_exactly():
    reference = FigureEight()
    early = messages.sampled_reference(sample_plan(reference, 0.0, 10.0, 0.01))
    late = messages.sampled_reference(sample_plan(reference, 5.0042, 15.0, 0.01))
    assert late.start == 5.0
    for t in np.arange(5.0, 10.0, 0.001):
        assert early.sample(t) == late.sample(t)
    assert early.agrees(late, 5.0, 9.999) and late.agrees(early, 7.3, 7.3)
    # agreement is claimed only where both interpolate: not before the later start, nor at or past an end
    assert not early.agrees(late, 4.999, 6.0) and not early.agrees(late, 9.0, 10.0)


def test_plans_that_differ_in_one_bit_of_a_sample_used_do_not_agree():
    plan = sample_plan(Circle(), 0.0, 1.0, 0.01)
    k = 50  # the sample at 0.5 s, an end of the segments on either side of it
    x, y = plan.positions[k]
    up = math.nextafter(x, math.inf)
    this = messages.sampled_reference(plan)
    that = messages.sampled_reference(plan._replace(positions=[*plan.positions[:k], (up, y), *plan.positions[k + 1:]]))
    assert not this.agrees(that, 0.495, 0.495) and not this.agrees(that, 0.5, 0.5) and not that.agrees(this, 0.3, 0.7)
    assert this.agrees(that, 0.3, 0.489) and this.agrees(that, 0.511, 0.7)
    at_rest, signed = ([SampledReference([0.0, 1.0, 2.0], [(0.0, 0.0), (zero, 0.0), (0.0, 0.0)], [(0.0, 0.0)] * 3,
                                         [(0.0, 0.0)] * 3) for zero in (0.0, -0.0)])
    assert not at_rest.agrees(signed, 0.5, 0.5) and at_rest.sample(0.5) == signed.sample(0.5)  # == cannot tell


def test_final_plan_ends_at_rest():
    moving = sample_plan(Circle(), 0.0, 3.0, 0.01)
    stopping = sample_plan(SmoothStop(Circle(), 2.0, 1.0), 0.0, 3.01, 0.01)
    assert not messages.plan_is_final(moving)
    assert messages.plan_is_final(stopping)


def test_tracking_through_the_plan_matches_the_analytic_reference(robot):
    """The model core's tracking run with the interpolated plan stays within 1e-6 m of the analytic one."""
    q0, qd0 = np.array([0.8, 0, 0, 0, 0, 0, 0.0]), np.zeros(7)
    selection = ConstraintSelection(True, True, True, True)
    plan = SampledReference(*messages.plan_from_cdr(messages.trajectory_message(sample_plan(Circle(), 0.0, 2.0, 0.01))))
    analytic = Simulation(robot, Circle(), selection, q0, qd0)
    sampled = Simulation(robot, plan, selection, q0, qd0)
    for _ in range(1500):
        analytic.step()
        sampled.step()
        assert np.max(np.abs(analytic.q[:2] - sampled.q[:2])) < 1e-6


def test_serialized_plan_decodes_to_the_plan():
    plan = sample_plan(FigureEight(1.0, 30.0, (0.5, -0.2)), 3.0, 13.0, 0.05)
    decoded = messages.plan_from_cdr(messages.trajectory_message(plan))
    assert decoded.times == messages.plan_sample_times(plan)
    assert (decoded.positions, decoded.velocities, decoded.accelerations) == \
        (plan.positions, plan.velocities, plan.accelerations)


def plan_of(msg):
    return SampledReference(*messages.plan_from_cdr(bagio.serialize(msg, topics.REFERENCE_TRAJECTORY.type)))


@pytest.mark.parametrize('build, reason', [
    (lambda msg: msg.points.__setitem__(slice(None), msg.points[:1]), '>= 2 points'),
    (lambda msg: msg.points[3].velocities.clear(), 'point 3'),
    (lambda msg: setattr(msg.points[2], 'time_from_start', msg.points[1].time_from_start), 'increase'),
])
def test_bad_plans_are_refused_with_a_reason(build, reason):
    msg = decode(messages.trajectory_message(sample_plan(Circle(), 0.0, 0.1, 0.01)), topics.REFERENCE_TRAJECTORY)
    build(msg)
    with pytest.raises(ValueError, match=reason):
        plan_of(msg)


def plan_in_message(msg) -> tuple:
    """The plan a rosbags-decoded reference_trajectory holds, read from its fields."""
    start = stamp_ns(msg.header.stamp)
    return ([(start + stamp_ns(point.time_from_start)) * 1e-9 for point in msg.points],
            [(p.transforms[0].translation.x, p.transforms[0].translation.y) for p in msg.points],
            [(p.velocities[0].linear.x, p.velocities[0].linear.y) for p in msg.points],
            [(p.accelerations[0].linear.x, p.accelerations[0].linear.y) for p in msg.points])


@pytest.mark.parametrize('little_endian', [True, False])
def test_the_plan_read_from_the_bytes_is_the_converted_message_s_in_any_layout(little_endian):
    """plan_from_cdr reads the bytes; rosbags converts them: the same plan, whatever shifts the alignment
    (frame and joint names of any length) or adds elements after the first, in either byte order."""
    msg = decode(messages.trajectory_message(sample_plan(FigureEight(), 1.0, 3.0, 0.05)), topics.REFERENCE_TRAJECTORY)
    for frame, joints, extra in (('wall', ['base_link'], 0), ('w', [], 1), ('odom_', ['a', 'bc', 'def'], 2)):
        msg.header.frame_id, msg.joint_names = frame, joints
        for point in msg.points:
            point.transforms[1:] = [point.transforms[0]] * extra
            point.velocities[1:] = [point.accelerations[0]] * extra
            point.accelerations[1:] = [point.velocities[0]] * (2 * extra)
        data = bytes(bagio.typestore().serialize_cdr(msg, topics.REFERENCE_TRAJECTORY.type,
                                                     little_endian=little_endian))
        assert tuple(messages.plan_from_cdr(data)) == plan_in_message(msg)


def test_a_serialized_plan_cut_anywhere_is_refused_as_malformed():
    data = messages.trajectory_message(sample_plan(Circle(), 0.0, 0.05, 0.01))
    for cut in range(len(data)):
        with pytest.raises(ValueError, match='malformed reference_trajectory'):
            messages.plan_from_cdr(data[:cut])


@pytest.mark.parametrize('cut', [0, 3, 40, -9])
def test_truncated_serialized_plan_is_refused(cut):
    data = messages.trajectory_message(sample_plan(Circle(), 0.0, 0.1, 0.01))
    with pytest.raises(ValueError, match='malformed reference_trajectory'):
        messages.plan_from_cdr(data[:cut])


def test_path_and_reference_odometry():
    plan = sample_plan(Circle(), 0.0, 10.0, 0.01)
    path = decode(messages.path_message(plan, max_poses=100), topics.REFERENCE_PATH)
    assert path.header.frame_id == topics.WALL_FRAME and 50 <= len(path.poses) <= 101
    assert path.poses[-1].pose.position.x == plan.positions[-1][0]
    headings = messages.plan_headings(plan)
    for pose in path.poses:  # along the tangent
        yaw, _rate = headings[round(seconds(pose.header.stamp) / 0.01)]
        assert quaternion_yaw(pose.pose.orientation) == pytest.approx(math.remainder(yaw, 2 * math.pi), abs=1e-12)
    sample = Circle().sample(2.0)
    data, yaw = messages.reference_message(sample, 2.0)
    msg = decode(data, topics.REFERENCE)
    assert msg.child_frame_id == topics.REFERENCE_FRAME
    assert yaw == pytest.approx(2 * math.pi * 2.0 / 20.0 + math.pi / 2, abs=1e-12)
    state = planar_state(msg)
    assert (state.x, state.y, state.xd, state.yd) == pytest.approx((*sample.position, *sample.velocity), abs=1e-12)
    speed = 2 * math.pi / 20.0
    assert msg.twist.twist.linear.x == pytest.approx(speed, abs=1e-12)
    assert msg.twist.twist.linear.y == pytest.approx(0.0, abs=1e-12)
    assert msg.twist.twist.angular.z == pytest.approx(2 * math.pi / 20.0, abs=1e-12)


@pytest.mark.parametrize('frame, child', [('', ''), ('wall', 'base_link'), ('w', 'robot2/base_link'),
                                          ('abc', 'abcdefg')])
@pytest.mark.parametrize('little_endian', [True, False])
def test_odometry_read_from_its_bytes_is_the_decoded_one(frame, child, little_endian):
    """decode_odometry against the typestore's decoding, across string lengths (the alignment of the
    pose after them) and both byte orders; a truncated message is refused, not misread."""
    encoder = codec.OdometryEncoder(frame, child)
    msg = decode(encoder.encode(12, 345_000_000, (0.3, -0.2, 2.5), (0.11, -0.07, 0.9)), topics.ODOM)
    msg.pose.covariance = np.arange(36.0)  # values that must be skipped, not read
    msg.twist.covariance = -np.arange(36.0)
    data = bytes(bagio.typestore().serialize_cdr(msg, topics.ODOM.type, little_endian=little_endian))
    odom = codec.decode_odometry(data)
    assert odom.planar_state() == planar_state(msg)
    twist, pose = msg.twist.twist, msg.pose.pose
    assert (odom.stamp_ns, odom.frame, odom.child) == (12_345_000_000, frame, child)
    assert (odom.x, odom.y, odom.yaw) == (pose.position.x, pose.position.y, quaternion_yaw(pose.orientation))
    assert (odom.forward, odom.sideways, odom.turn) == (twist.linear.x, twist.linear.y, twist.angular.z)
    for cut in (1, 13, len(data) - 1):
        with pytest.raises(ValueError, match=f'malformed odometry \\({cut} bytes\\)'):
            codec.decode_odometry(data[:cut])
    msg.twist.twist.angular.z = math.inf
    with pytest.raises(ValueError, match='not finite'):
        codec.decode_odometry(bytes(bagio.typestore().serialize_cdr(msg, topics.ODOM.type))).planar_state()


def joint_state_cdr(names, position, velocity, effort, t: float = 2.5) -> bytes:
    """A JointState's CDR bytes serialized by rosbags' typestore (not the codec's encoder)."""
    kind = bagio.typestore().types[topics.WHEEL_CONTACT.type]
    return bagio.serialize(kind(header=typestore_header(t, ''), name=list(names), position=np.array(position, float),
                                velocity=np.array(velocity, float), effort=np.array(effort, float)),
                           topics.WHEEL_CONTACT.type)


def test_wheel_contact_round_trip_per_wheel():
    """The encoder's bytes as rosbags reads them carry the documented layout; decode_wheel_contact reads back
    every wheel's load, use, slip flag, force and contact velocity, from the encoder's bytes and from a message
    rosbags serialized with the names in another order; a message naming the wheels but not their directions
    gives their loads and NaN for the rest."""
    rng = np.random.default_rng(7)
    loads, use, forces, velocities = rng.uniform(20, 60, 4), rng.uniform(0, 1.2, 4), rng.normal(size=(4, 2)), \
        rng.normal(size=(4, 2))
    slipping = (True, False, False, True)
    data = codec.WheelContactEncoder().encode(2, 500_000_000, loads.tolist(), use.tolist(), slipping, forces,
                                              velocities)
    msg = decode(data, topics.WHEEL_CONTACT)
    wheels = list(topics.WHEEL_JOINTS)
    assert list(msg.name) == wheels + [f'{w}/x' for w in wheels] + [f'{w}/y' for w in wheels]
    assert list(msg.position) == [*use, *[0.0] * 8]
    assert list(msg.velocity) == [1.0, 0.0, 0.0, 1.0, *velocities[:, 0], *velocities[:, 1]]
    assert list(msg.effort) == [*loads, *forces[:, 0], *forces[:, 1]]
    expected = codec.WheelContact(2_500_000_000, tuple(loads), tuple(use), (1.0, 0.0, 0.0, 1.0),
                                  tuple(forces[:, 0]), tuple(forces[:, 1]), tuple(velocities[:, 0]),
                                  tuple(velocities[:, 1]))
    assert codec.decode_wheel_contact(data) == expected
    order = rng.permutation(12)
    shuffled = joint_state_cdr(np.array(msg.name)[order], msg.position[order], msg.velocity[order],
                               msg.effort[order])
    assert codec.decode_wheel_contact(shuffled) == expected
    loads_only = codec.decode_wheel_contact(joint_state_cdr(wheels + ['drive_left'], [0.0] * 5, [0.0] * 5,
                                                            [*loads, 70.0]))
    assert loads_only.loads == tuple(loads)
    assert all(math.isnan(value) for field in loads_only[2:] for value in field)


def test_constraints_message_round_trip():
    switches = {'trajectory_task': True, 'belt': True, 'non_lateral': True, 'nonslip': False,
                'tangent_heading': True}
    msg = decode(messages.constraints_message(switches, BaumgarteGains(4.0, 6.0)), topics.CONSTRAINTS)
    assert msg.message == 'trajectory+tangent_heading+belt+non_lateral'
    values = {kv.key: kv.value for kv in msg.values}
    assert values['nonslip'] == 'false' and values['baumgarte_beta'] == '6.0'
    assert values['active'] == 'trajectory,tangent_heading,belt,non_lateral'
    selection, gains = messages.constraints_from_cdr(messages.constraints_message(switches, BaumgarteGains(4.0, 6.0)))
    assert selection == ConstraintSelection(True, True, True, False, None)
    assert gains == BaumgarteGains(4.0, 6.0)
    off = messages.constraints_message({**switches, 'tangent_heading': False}, BaumgarteGains())
    assert messages.constraints_from_cdr(off)[0].heading is False


@pytest.mark.parametrize('selection', [ConstraintSelection(), ConstraintSelection(True, True, True, True),
                                       ConstraintSelection(True, True, True, False, False),
                                       ConstraintSelection(False, True, True, True)], ids=lambda s: s.label())
def test_a_selection_survives_its_switches(selection):
    """What simulate --bag writes for its selection decodes to that selection in the dynamics node."""
    data = messages.constraints_message(messages.switches_from_selection(selection), BaumgarteGains())
    decoded, _gains = messages.constraints_from_cdr(data)
    assert decoded.active_names() == selection.active_names()


def test_each_switch_names_a_module_of_the_model():
    """The interface's one list of constraint modules and the model's are the same modules: every switch
    on activates every module, and each switch off removes the module it is keyed by."""
    assert sorted(CONSTRAINT_MODULES) == sorted(MODULES)
    all_on = {switch.parameter: True for switch in CONSTRAINT_MODULES.values()}
    assert messages.selection_from_switches(all_on).active_names() == list(MODULES)
    for module, switch in CONSTRAINT_MODULES.items():
        assert module not in messages.selection_from_switches({**all_on, switch.parameter: False}).active_names()


@pytest.mark.parametrize('key, value, reason', [('belt', 'yes', 'belt'), ('baumgarte_alpha', '-1', 'alpha'),
                                                ('baumgarte_beta', 'nan', 'beta')])
def test_bad_constraints_message(key, value, reason):
    msg = decode(messages.constraints_message({name: False for name in CONSTRAINT_SWITCHES}, BaumgarteGains()),
                 topics.CONSTRAINTS)
    for kv in msg.values:
        if kv.key == key:
            kv.value = value
    with pytest.raises(ValueError, match=reason):
        messages.constraints_from_cdr(bagio.serialize(msg, topics.CONSTRAINTS.type))


def test_torque_command_validation():
    def command(data):
        return bagio.serialize(bagio.typestore().types['std_msgs/msg/Float64MultiArray'](
            layout=bagio.typestore().types['std_msgs/msg/MultiArrayLayout'](dim=[], data_offset=0),
            data=np.array(data, dtype=np.float64)), topics.WHEEL_TORQUE_CMD.type)

    assert codec.decode_wheel_torque_cmd(command([0.5, -1.0]), 2.0) == (0.5, -1.0)
    for data, reason in [([1.0], 'got 1 values'), ([1.0, 2.0, 3.0], 'got 3'), ([math.nan, 0.0], 'tau_L is not finite'),
                         ([0.0, math.inf], 'tau_R is not finite'), ([0.0, -2.5], 'beyond max_wheel_torque')]:
        with pytest.raises(ValueError, match=reason):
            codec.decode_wheel_torque_cmd(command(data), 2.0)


def test_the_torque_command_encoder_writes_what_rclpy_serializes():
    """wheel_torque_cmd as ``simulate --bag`` writes it: rclpy's serialization of the controller's
    Float64MultiArray but for the alignment padding before the data (rclpy leaves it unset)."""
    pytest.importorskip('rclpy')
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64MultiArray

    ours = codec.wheel_torque_cmd(0.1234567, -4.5)
    theirs = serialize_message(Float64MultiArray(data=[0.1234567, -4.5]))
    padding = slice(16, 20)  # after the encapsulation header (4) and three counts (12): float64 data is 8-aligned
    assert len(ours) == len(theirs) == 36
    assert ours[:padding.start] + ours[padding.stop:] == theirs[:padding.start] + theirs[padding.stop:]
    assert codec.decode_wheel_torque_cmd(theirs, 5.0) == (0.1234567, -4.5)


@pytest.mark.parametrize('torques', [(0.1234567, -4.5), (-0.0, 5.0), (1e-300, -math.pi)])
def test_the_torque_command_encoder_writes_what_the_typestore_serializes(torques):
    """The hand-packed bytes are the typestore's serialization, padding included."""
    store = bagio.typestore().types
    msg = store['std_msgs/msg/Float64MultiArray'](layout=store['std_msgs/msg/MultiArrayLayout'](dim=[], data_offset=0),
                                                  data=np.array(torques, dtype=np.float64))
    assert codec.wheel_torque_cmd(*torques) == bagio.serialize(msg, topics.WHEEL_TORQUE_CMD.type)


def test_initial_pose_validation():
    types = bagio.typestore().types

    def pose(frame='wall', x=0.3, y=-0.4, q=(0.0, 0.0, math.sin(-1.2), math.cos(-1.2))):
        return bagio.serialize(types['geometry_msgs/msg/PoseWithCovarianceStamped'](
            header=typestore_header(0.0, frame),
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=types['geometry_msgs/msg/Pose'](position=types['geometry_msgs/msg/Point'](x=x, y=y, z=0.0),
                                                     orientation=types['geometry_msgs/msg/Quaternion'](*q)),
                covariance=np.zeros(36))), topics.INITIALPOSE.type)

    x, y, heading = codec.decode_initial_pose(pose())
    assert (x, y) == (0.3, -0.4) and heading == pytest.approx(-2.4, abs=1e-12)
    assert codec.decode_initial_pose(pose(q=(0.0, 0.0, 3.0, 0.0)))[2] == pytest.approx(math.pi)  # any norm
    for bad, reason in [(pose(frame='map'), "frame 'map', not 'wall'"), (pose(frame=''), "frame '', not 'wall'"),
                        (pose(x=math.nan), 'not finite'), (pose(q=(0.0, 0.0, 0.0, 0.0)), 'not a turn about Z'),
                        (pose(q=(0.1, 0.0, 0.0, 0.995)), 'not a turn about Z')]:
        with pytest.raises(ValueError, match=reason):
            codec.decode_initial_pose(bad)
    # a graph whose odom_frame_id is 'map' takes poses in 'map' and refuses 'wall'
    assert codec.decode_initial_pose(pose(frame='map'), 'map')[:2] == (0.3, -0.4)
    with pytest.raises(ValueError, match="frame 'wall', not 'map'"):
        codec.decode_initial_pose(pose(), 'map')


def test_diagnostics_builder():
    status = codec.Status('x', 'error', 'diverged', [('rate', 999.123456), ('set', 'belt')])
    data = codec.diagnostics(1.5, [status])
    array = decode(data, topics.DIAGNOSTICS)
    assert seconds(array.header.stamp) == 1.5
    assert array.status[0].level == codec.LEVELS['error'] and array.status[0].hardware_id == codec.HARDWARE_ID
    assert [(kv.key, kv.value) for kv in array.status[0].values] == [('rate', '999.123'), ('set', 'belt')]
    assert codec.decode_diagnostics(data) == (1_500_000_000, [('x', 'error', 'diverged', [('rate', '999.123'),
                                                                                         ('set', 'belt')])])


def test_a_fault_event_reads_back_with_its_time_its_node_what_changed_why_and_every_value():
    data = codec.fault_event(5.0, '/r2/dynamics', ['motor_efficiency_left', 'adhesion_scale'], 'parameter',
                             [('motor_efficiency_left', '0.0'), ('adhesion_scale', '0.6'), ('drop_odom', 'false')],
                             'warn')
    array = decode(data, topics.FAULTS)
    assert seconds(array.header.stamp) == 5.0 and array.status[0].level == codec.LEVELS['warn']
    assert array.status[0].message == 'motor_efficiency_left, adhesion_scale (parameter)'
    assert codec.decode_fault_event(data) == (5_000_000_000, '/r2/dynamics', ('motor_efficiency_left', 'adhesion_scale'),
                                              'parameter', {'motor_efficiency_left': '0.0', 'adhesion_scale': '0.6',
                                                            'drop_odom': 'false'})
    with pytest.raises(ValueError, match='without a fault event'):
        codec.decode_fault_event(codec.diagnostics(1.0, [codec.Status('x', 'ok', 'm', [])]))


def test_the_status_of_a_robot_s_dynamics_is_told_from_another_robot_s():
    """/diagnostics is one topic for every robot of a domain: a reader picks the status of the dynamics in
    its own namespace by the status's name, the node's fully qualified name."""
    statuses = [codec.Status(codec.simulation_status_name(node), 'ok', node, []) for node in
                ('/robot2/dynamics', '/wallbot/sub/dynamics', '/wallbot/dynamics')]
    assert codec.simulation_status(statuses, '/wallbot').message == '/wallbot/dynamics'
    assert codec.simulation_status(statuses, '/robot2/').message == '/robot2/dynamics'
    assert codec.simulation_status(statuses, '/robot3') is None
    assert codec.simulation_status([codec.Status('/dynamics: simulation', 'ok', 'root', [])], '/').message == 'root'


def test_rclpy_decodes_the_codec_bytes_to_the_same_fields():
    """The nodes publish these bytes as serialized messages: rclpy subscribers must read the same."""
    pytest.importorskip('rclpy')
    import importlib

    from rclpy.serialization import deserialize_message

    plan = sample_plan(FigureEight(), 0.0, 1.0, 0.05)
    encoded = {
        topics.REFERENCE_TRAJECTORY: messages.trajectory_message(plan),
        topics.REFERENCE_PATH: messages.path_message(plan),
        topics.REFERENCE: messages.reference_message(FigureEight().sample(0.3), 0.3)[0],
        topics.CONSTRAINTS: messages.constraints_message(messages.switches_from_selection(ConstraintSelection()),
                                                         BaumgarteGains()),
        topics.DIAGNOSTICS: codec.diagnostics(2.0, [codec.Status('n', 'warn', 'm', [('k', 1.5)])]),
        topics.WHEEL_TORQUE_CMD: codec.wheel_torque_cmd(0.1234567, -4.5),
        topics.FAULTS: codec.fault_event(1.25, '/wallbot/dynamics', ['drop_odom'], 'scheduled',
                                         [('drop_odom', 'true'), ('adhesion_scale', '0.6')], 'warn'),
        topics.ROBOT_DESCRIPTION: codec.robot_description('<?xml version="1.0"?>\n<robot name="r" />\n'),
    }
    for topic, data in encoded.items():
        ours = decode(data, topic)
        package, _msg, name = topic.type.split('/')
        theirs = deserialize_message(data, getattr(importlib.import_module(f'{package}.msg'), name))
        assert rclpy_fields(theirs) == fields(ours), topic.name


def rclpy_fields(msg):
    """An rclpy message in the shape of bag_helpers.fields."""
    if hasattr(msg, 'get_fields_and_field_types'):
        return tuple((name, rclpy_fields(getattr(msg, name))) for name in msg.get_fields_and_field_types())
    if isinstance(msg, (list, tuple, np.ndarray)) or type(msg).__name__ == 'array':
        return tuple(rclpy_fields(item) for item in msg)
    if isinstance(msg, bytes) and len(msg) == 1:  # rclpy's byte fields (a status level)
        return msg[0]
    return msg


def test_every_topic_of_the_contract_has_a_standard_type():
    """`ros2 topic list -t` of the graph shows only types a standard Jazzy install has."""
    from wallbot_msgs_py import topics

    declared = [value for value in vars(topics).values() if isinstance(value, topics.Topic)]
    assert len(declared) > 20
    unusual = {topic.name: topic.type for topic in declared
               if topic.type.split('/')[0] not in topics.STANDARD_PACKAGES or topic.type.split('/')[1] != 'msg'}
    assert not unusual


@pytest.mark.parametrize('command', [0.0, 0.37, 1.0])
def test_a_pump_command_reads_back_and_rosbags_reads_the_same_float64(command):
    data = codec.pump_command(command)
    assert codec.decode_pump_command(data) == command == decode(data, topics.PUMP_COMMAND).data


@pytest.mark.parametrize('command', [1.5, -0.1, math.nan, math.inf])
def test_a_pump_command_outside_0_1_is_refused_naming_the_value(command):
    with pytest.raises(ValueError, match=r'^pump_command must be in \[0, 1\], got '):
        codec.decode_pump_command(codec.pump_command(command))
