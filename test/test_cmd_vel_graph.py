"""Driving the simulation like a ROS robot, through real node processes: cmd_vel_node driving a
square from scripted cmd_vel, joint_bridge_node's joint_states / joint_commands contract, and the
nodes that are not the clock's owner following the robot's clock at factor 0.5 and 0 and through a reset."""

from __future__ import annotations

import math

import pytest

pytest.importorskip('rclpy')

import rclpy.duration  # noqa: E402

from geometry_msgs.msg import TwistStamped  # noqa: E402
from rcl_interfaces.srv import DescribeParameters  # noqa: E402
from graph_helpers import STALL, Graph, ns, start_graph  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from message_fields import planar_state  # noqa: E402
from wallbot_msgs_py import codec, topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402
from wallbot_sim.graph_description import CMD_VEL_STEPS, CONTROL_STEPS  # noqa: E402

DRIVEN = ('trajectory_task:=false', 'belt:=true', 'non_lateral:=true', 'nonslip:=true')
AT_ORIGIN = ('initial_x:=0.0', 'initial_y:=0.0', 'initial_theta:=0.0')
LOCKSTEP = ('wait_for_command:=true', f'lockstep_every:={CMD_VEL_STEPS}')  # cmd_vel_node's period at 1 kHz
PERIOD_NS = CMD_VEL_STEPS * 1_000_000
SIDE, SPEED, TURN_RATE = 0.5, 0.2, 1.0
LEG_TOLERANCE = 0.003
"""m: each leg's length within this of 0.5 m (0.4 mm measured)."""
TURN_DRIFT = 0.02
"""m: how far a turn in place may move the centre (1.3 cm measured: gravity along the heading
as it sweeps through 90 degrees, which the wheel-speed loop follows with a lag)."""
CORNER_TOLERANCE = 0.06
"""m: each corner within this of the ideal square (the turns' drifts add up: 4.3 cm measured at the end)."""
HEADING_TOLERANCE = math.radians(1.0)
"""Every heading and leg direction (0.16 degrees measured)."""
COMMAND_AT, CHECK_AT = 0.1, 1.5
"""s of simulation time: when the clock test commands 0.1 m/s, and when it checks the speed."""


@pytest.fixture
def graph(process_runner):
    g = Graph(process_runner)
    yield g
    g.close()


def keep(graph: Graph, kind, topic: topics.Topic, name: str | None = None) -> list:
    received: list = []
    graph.node.create_subscription(kind, name or topic.resolve(graph.namespace), received.append, qos_profile(topic))
    return received


class Driver:
    """Publishes cmd_vel from this process and reads the pose from odometry."""

    def __init__(self, graph: Graph) -> None:
        self.graph = graph
        self.publisher = graph.node.create_publisher(TwistStamped, topics.CMD_VEL.resolve(graph.namespace),
                                                     qos_profile(topics.CMD_VEL))

    def send(self, linear: float, angular: float) -> None:
        """One command, returned once the subscriber (cmd_vel_node) has acknowledged it."""
        self.graph.wait_for(lambda: self.publisher.get_subscription_count() > 0, STALL, 'cmd_vel_node hearing cmd_vel')
        message = TwistStamped()
        message.twist.linear.x, message.twist.angular.z = linear, angular
        self.publisher.publish(message)
        assert self.publisher.wait_for_all_acked(rclpy.duration.Duration(seconds=10.0))

    def pose(self) -> codec.PlanarState:
        # the newest odometry alone: decoding the whole 1 kHz backlog on every poll starves this
        # process on a loaded machine
        return planar_state(self.graph.wait_for(lambda: self.graph.newest(topics.ODOM.name), 60, 'odometry'))


def wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def test_scripted_cmd_vel_drives_a_square_on_the_wall(graph):
    """0.5 m sides at 0.2 m/s (2.5 s each), 90 degree turns in place at 1 rad/s (pi/2 s), a 1 s stop
    after each, counter-clockwise from the origin facing +X: along, up, across and down the
    vertical wall, as fast as the graph runs (factor 0).

    The script is timed in simulation time, so this process's latency on a loaded machine does not
    enter: the dynamics pauses at the end of each segment (``stop_at``), the next command is
    published (and acknowledged), then ``stop_at`` moves on. cmd_vel_timeout is 10 s, so a command
    published once holds for its segment. Segments last whole control periods, so a turn's rate is
    the one that makes 90 degrees in the periods nearest pi/2 s. The command ramps at the
    acceleration limits, so a leg covers 0.2 m/s x 2.5 s and a turn its 90 degrees like a step
    would; what remains is the wheel-speed loop's lag (gravity pulls along the legs up and down the
    wall).
    """
    graph.start('cmd_vel', 'use_sim_time:=true', 'cmd_vel_timeout:=10.0')
    turn_time = round(math.pi / 2 / TURN_RATE * 1e9 / PERIOD_NS) * PERIOD_NS * 1e-9  # whole control periods
    segments = []
    for _ in range(4):
        segments += [((SPEED, 0.0), SIDE / SPEED), ((0.0, 0.0), 1.0), ((0.0, math.pi / 2 / turn_time), turn_time),
                     ((0.0, 0.0), 1.0)]
    first_pause = 0.1
    start_graph(graph, *AT_ORIGIN, *LOCKSTEP, 'real_time_factor:=0.0', f'stop_at:={first_pause}',
                constraints=DRIVEN, trajectory=None)
    driver = Driver(graph)
    t_ns = round(first_pause * 1e9)
    poses = []
    for (linear, angular), length in segments:
        graph.wait_for(lambda: graph.last_stamp() >= t_ns, 60, f'the pause at {t_ns * 1e-9:.3f} s')
        poses.append(driver.pose())
        driver.send(linear, angular)
        t_ns += round(length * 1e9 / PERIOD_NS) * PERIOD_NS  # a whole number of control periods
        graph.set_parameters('dynamics', stop_at=t_ns * 1e-9)
    graph.wait_for(lambda: graph.last_stamp() >= t_ns, 60, 'the end of the square')
    poses.append(driver.pose())
    stopped = poses[2::2]  # after each segment's stop: leg 1, turn 1, leg 2, ...
    previous = poses[0]
    for k, pose in enumerate(stopped):
        assert math.hypot(pose.xd, pose.yd) < 1e-3 and abs(pose.thd) < 2e-3, (k, pose)  # at rest
        heading = (k + 1) // 2 * math.pi / 2
        moved = math.hypot(pose.x - previous.x, pose.y - previous.y)
        if k % 2 == 0:  # a leg: its length and direction
            assert abs(moved - SIDE) < LEG_TOLERANCE, (k, previous, pose)
            direction = math.atan2(pose.y - previous.y, pose.x - previous.x)
            assert abs(wrap(direction - heading)) < HEADING_TOLERANCE, (k, previous, pose)
        else:  # a turn in place: 90 degrees, the centre pulled a little by gravity as the heading sweeps
            assert moved < TURN_DRIFT, (k, previous, pose)
        assert abs(wrap(pose.theta - heading)) < HEADING_TOLERANCE, (k, pose)
        previous = pose
    ideal = [(SIDE, 0.0), (SIDE, SIDE), (0.0, SIDE), (0.0, 0.0)]
    for pose, (x, y) in zip(stopped[1::2], ideal):
        assert math.hypot(pose.x - x, pose.y - y) < CORNER_TOLERANCE, (pose, x, y)


def test_joint_states_and_joint_commands_follow_the_ros2_control_topic_conventions(graph):
    states = keep(graph, JointState, topics.JOINT_STATES)
    commands = keep(graph, Float64MultiArray, topics.WHEEL_TORQUE_CMD)
    graph.start('joint_bridge', 'use_sim_time:=true')
    start_graph(graph, *AT_ORIGIN, 'real_time_factor:=0.5', constraints=DRIVEN, trajectory=None)
    graph.wait_for(lambda: len(states) >= 5, 30, 'joint_states')
    # joint_state_broadcaster's shape: the URDF's four wheel joints, position, velocity, effort each
    first = states[:5]
    for msg in first:
        assert tuple(msg.name) == topics.WHEEL_JOINTS
        assert len(msg.position) == len(msg.velocity) == len(msg.effort) == 4
    # 50 Hz of simulation time, each the wheel_states of its stamp
    stamps = [ns(msg) for msg in first]
    assert all(b - a == 20_000_000 for a, b in zip(stamps, stamps[1:]))
    # the test hears wheel_states on a subscription of its own, which may lag the bridge's
    def wheel_states() -> dict:
        return {ns(msg): msg for msg in graph.messages(topics.WHEEL_STATES.name)}
    graph.wait_for(lambda: set(stamps) <= wheel_states().keys(), 30, 'the wheel_states of the first joint_states')
    twins = wheel_states()
    for msg in first:
        twin = twins[ns(msg)]
        assert (list(msg.position), list(msg.velocity), list(msg.effort)) == (
            list(twin.position), list(twin.velocity), list(twin.effort))

    publisher = graph.node.create_publisher(JointState, topics.JOINT_COMMANDS.resolve(graph.namespace),
                                            qos_profile(topics.JOINT_COMMANDS))
    graph.wait_for(lambda: publisher.get_subscription_count() > 0, STALL, 'joint_bridge subscribing joint_commands')
    malformed = JointState(name=list(topics.WHEEL_JOINTS[:3]), effort=[0.5, 0.5, 0.5])
    publisher.publish(malformed)
    graph.wait_for(lambda: 'rejected: joint_commands must name each of' in graph.runner.output('joint_bridge'), 10,
                   'the refusal of a malformed joint_commands')
    assert commands == []  # a refused message never reaches the simulation
    # nor one with a NaN effort (its log line may be throttled): the first command is the good one after it
    publisher.publish(JointState(name=list(topics.WHEEL_JOINTS), effort=[0.5, math.nan, 0.5, 0.5]))
    # the order of the names is the message's: the right side gets 0.6 + 0.4, the left 0.3 + 0.2
    lf, lr, rf, rr = topics.WHEEL_JOINTS
    good = JointState(name=[rr, lf, rf, lr], effort=[0.4, 0.3, 0.6, 0.2])
    start_x = planar_state(graph.newest(topics.ODOM.name)).x

    def applied() -> bool:
        publisher.publish(good)  # as a controller_manager writes every update
        return bool(commands)
    graph.wait_for(applied, STALL, 'wheel_torque_cmd from joint_commands')
    assert list(commands[0].data) == pytest.approx([0.5, 1.0], abs=1e-12)
    assert all(len(line) < 250 for line in graph.runner.output('joint_bridge').splitlines() if 'rejected' in line)

    def moved() -> bool:
        publisher.publish(good)
        odom = graph.newest(topics.ODOM.name)
        return planar_state(odom).x > start_x + 0.01 and odom.twist.twist.angular.z > 0
    graph.wait_for(moved, 30, 'the robot driving forward, turning left (more torque on the right)')


@pytest.mark.parametrize('factor', ['0.5', '0.0'])
@pytest.mark.parametrize('drive', ['cmd_vel', 'controller'])
def test_the_drives_and_the_trajectory_node_follow_the_clock_through_a_reset(graph, drive, factor):
    """The dynamics in lockstep with a drive (cmd_vel_node or the tracking controller at their
    default rates), beside the trajectory node, all with use_sim_time, at factor 0.5 and 0 (as fast as
    possible): simulated time advances only as the drive answers, the drive acts in simulation time
    (the robot at the commanded speed, or closing on the circle), the trajectory node's reference
    poses keep up with the clock, and after ``~/reset`` (time back to 0) all of them carry on
    without a restart: no lockstep wait timed out, the same behaviour again.

    cmd_vel is timed in simulation time, as in the square: the dynamics pauses at COMMAND_AT (``stop_at``),
    the command is published and acknowledged, and the run goes on to CHECK_AT; cmd_vel_timeout is
    10 s, so that one command holds, however late this process runs on a loaded machine."""
    if drive == 'cmd_vel':
        graph.start('cmd_vel', 'use_sim_time:=true', 'cmd_vel_timeout:=10.0')
        dynamics = (*AT_ORIGIN, *LOCKSTEP, f'stop_at:={COMMAND_AT}')
    else:
        graph.start('controller', 'use_sim_time:=true')
        dynamics = ('wait_for_command:=true', f'lockstep_every:={CONTROL_STEPS}')  # starts 0.2 m inside the unit circle
    start_graph(graph, *dynamics, f'real_time_factor:={factor}', constraints=DRIVEN,
                trajectory=('use_sim_time:=true',))
    driver = Driver(graph)

    def check_segment(segment: str) -> None:
        if drive == 'cmd_vel':
            graph.wait_sim_time(COMMAND_AT, timeout=30)
            driver.send(0.1, 0.0)
            graph.set_parameters('dynamics', stop_at=CHECK_AT)
        graph.wait_sim_time(CHECK_AT, timeout=30)
        state = driver.pose()
        if drive == 'cmd_vel':
            assert state.stamp_ns == round(CHECK_AT * 1e9), segment  # paused there
            assert state.xd == pytest.approx(0.1, abs=0.002), segment  # reached 0.1 s after the command, settled
            graph.set_parameters('dynamics', stop_at=COMMAND_AT)  # the next run pauses there again
        reference = graph.wait_for(lambda: [m for m in graph.messages(topics.REFERENCE.name)
                                            if abs(ns(m) - state.stamp_ns) <= 10_000_000],
                                   30, f'{segment}: the reference pose of the clock (100 Hz)')
        if drive == 'controller':
            ref = planar_state(min(reference, key=lambda m: abs(ns(m) - state.stamp_ns)))
            error = math.hypot(state.x - ref.x, state.y - ref.y)
            assert error < 0.1, (segment, error)  # from 0.2 m at t = 0

    check_segment('first run')
    graph.clear(topics.REFERENCE.name)
    assert graph.call(Trigger, f'{graph.namespace}/dynamics/reset', Trigger.Request()).success
    graph.wait_for(lambda: graph.last_stamp() < 500_000_000, 30, 'time going back at the reset')
    check_segment('after the reset')
    assert min(ns(msg) for msg in graph.messages(topics.REFERENCE.name)) < 1_000_000_000  # replanned from t ~ 0
    restarted = 'velocity loop restarted' if drive == 'cmd_vel' else 'controller restarted'
    assert restarted in graph.runner.output(drive)
    assert 'no wheel_torque_cmd within' not in graph.runner.output('dynamics')


def test_cmd_vel_parameters_have_ranges_and_a_refusal_leaves_the_node_running(graph):
    graph.start('cmd_vel', 'use_stamped_vel:=false')
    topic = topics.CMD_VEL.resolve(graph.namespace)
    subscriptions = graph.wait_for(lambda: graph.node.get_subscriptions_info_by_topic(topic), STALL,
                                   'cmd_vel subscribed')
    assert [info.topic_type for info in subscriptions] == [topics.CMD_VEL_UNSTAMPED_TYPE]
    response = graph.call(DescribeParameters, f'{graph.namespace}/{topics.NODE_CMD_VEL}/describe_parameters',
                          DescribeParameters.Request(names=['linear.x.max_acceleration', 'wheel_radius',
                                                            'wheel_speed_kp', 'rate_hz', 'use_stamped_vel']))
    acceleration, radius, kp, rate, stamped = response.descriptors
    assert acceleration.floating_point_range[0].to_value == 1e3 and radius.floating_point_range[0].to_value == 10.0
    assert kp.floating_point_range[0].from_value == 0.0
    assert rate.integer_range[0].from_value == 1 and rate.read_only and stamped.read_only
    assert graph.get_parameters(topics.NODE_CMD_VEL, 'wheel_radius', 'wheel_separation') == [0.04, 0.24]

    refused, = graph.set_parameters(topics.NODE_CMD_VEL, **{'linear.x.max_acceleration': 0.0})
    # refused by rclpy (outside the descriptor's range), with the name in its one-line reason
    assert not refused.successful and 'linear.x.max_acceleration' in refused.reason and '\n' not in refused.reason
    refused, = graph.set_parameters(topics.NODE_CMD_VEL, **{'linear.x.max_acceleration': 1e3 * (1 + 1e-7)})
    # within rclpy's tolerance of the end: refused by the node's own check
    assert not refused.successful and refused.reason.startswith('linear.x.max_acceleration must be in [1e-06, 1000]')
    accepted, = graph.set_parameters(topics.NODE_CMD_VEL, **{'linear.x.max_acceleration': 2.5})
    assert accepted.successful
    assert graph.get_parameters(topics.NODE_CMD_VEL, 'linear.x.max_acceleration') == [2.5]
