"""joint_bridge_node's first outputs, recorded or not (DDS in one process)."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from recorder_probe import recorder_probe, spin_for, spin_until  # noqa: E402
from wallbot_msgs_py import topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402
from wallbot_sim.nodes.joint_bridge import JointBridgeNode  # noqa: E402


def test_with_wait_for_recorder_nothing_is_forwarded_until_a_recorder_hears_the_outputs(ros_domain):
    """A controller_manager writes joint_commands from the run's start, and the dynamics applies what
    the bridge forwards: a recorded run must not forward a command (or republish a joint state)
    before the recorder hears wheel_torque_cmd and joint_states, or the bag would miss the first ones."""
    context = rclpy.Context()
    rclpy.init(context=context)
    node = probe = user = None
    executor = SingleThreadedExecutor(context=context)
    commands: list[Float64MultiArray] = []
    states: list[JointState] = []
    try:
        node = JointBridgeNode(context=context,
                               parameter_overrides=[Parameter('wait_for_recorder', Parameter.Type.BOOL, True)])
        executor.add_node(node)
        probe = recorder_probe(context, executor)
        # the user's controller_manager and the dynamics' wheel_states, both writing all along
        user = rclpy.create_node('controller_manager', namespace=topics.NAMESPACE, context=context)
        executor.add_node(user)
        command_pub = user.create_publisher(JointState, topics.JOINT_COMMANDS.name, qos_profile(topics.JOINT_COMMANDS))
        wheel_pub = user.create_publisher(JointState, topics.WHEEL_STATES.name, qos_profile(topics.WHEEL_STATES))
        user.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, commands.append,
                                 qos_profile(topics.WHEEL_TORQUE_CMD))
        user.create_subscription(JointState, topics.JOINT_STATES.name, states.append, qos_profile(topics.JOINT_STATES))
        stamp_ms = [0]

        def write() -> None:
            command_pub.publish(JointState(name=list(topics.WHEEL_JOINTS), effort=[0.1, 0.1, 0.2, 0.2]))
            wheel_pub.publish(wheel_states(stamp_ms[0]))
            stamp_ms[0] += 20
        user.create_timer(0.02, write)
        spin_until(executor, lambda: node.state_pub.get_subscription_count() == 1
                   and node.command_pub.get_subscription_count() == 1, 30.0, 'the user node matched to the bridge')
        spin_for(executor, 1.0)  # a recorder known, commands and wheel states written, the recorder deaf to both
        assert node.count_publishers(node.resolve_topic_name(topics.RECORD_PROGRESS.name)) == 1
        assert user.count_subscribers(command_pub.topic_name) == 0 and not commands and not states
        probe.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, lambda _msg: None,
                                  qos_profile(topics.WHEEL_TORQUE_CMD))
        spin_for(executor, 0.5)  # heard on one of its two outputs only: still nothing
        assert user.count_subscribers(command_pub.topic_name) == 0 and not commands and not states
        probe.create_subscription(JointState, topics.JOINT_STATES.name, lambda _msg: None,
                                  qos_profile(topics.JOINT_STATES))
        spin_until(executor, lambda: bool(commands) and bool(states), 30.0,
                   'no wheel_torque_cmd and joint_states after the recorder subscribed both')
        assert list(commands[0].data) == pytest.approx([0.2, 0.4])
        assert tuple(states[0].name) == topics.WHEEL_JOINTS
    finally:
        executor.shutdown()
        for n in (user, probe, node):
            if n is not None:
                n.destroy_node()
        rclpy.shutdown(context=context)


def wheel_states(stamp_ms: int) -> JointState:
    """A wheel_states message stamped ``stamp_ms`` of simulation time."""
    msg = JointState(name=list(topics.WHEEL_JOINTS), position=[0.0] * 4, velocity=[0.0] * 4, effort=[0.0] * 4)
    msg.header.stamp = Time(sec=stamp_ms // 1000, nanosec=(stamp_ms % 1000) * 1_000_000)
    return msg
