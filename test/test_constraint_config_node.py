"""The constraint_config node's first constraint set, recorded or not (DDS in one process)."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from recorder_probe import recorder_probe, spin_for, spin_until  # noqa: E402
from wallbot_msgs_py import topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402
from wallbot_sim import messages  # noqa: E402
from wallbot_sim.nodes.constraint_config import ConstraintConfigNode  # noqa: E402


def test_with_wait_for_recorder_the_first_set_waits_until_a_recorder_hears_constraints(ros_domain):
    """The dynamics starts on the first set: a short recorded run must not start before the recorder's
    constraints subscription is matched to this node. A switch set meanwhile is in the first set."""
    context = rclpy.Context()
    rclpy.init(context=context)
    node = probe = listener = None
    executor = SingleThreadedExecutor(context=context)
    received: list[bytes] = []
    try:
        node = ConstraintConfigNode(context=context,
                                    parameter_overrides=[Parameter('wait_for_recorder', Parameter.Type.BOOL, True)])
        executor.add_node(node)
        probe = recorder_probe(context, executor)
        listener = rclpy.create_node('listener', namespace=topics.NAMESPACE, context=context)
        executor.add_node(listener)
        listener.create_subscription(DiagnosticStatus, topics.CONSTRAINTS.name, received.append,
                                     qos_profile(topics.CONSTRAINTS), raw=True)
        spin_for(executor, 1.0)  # a recorder known, a listener on constraints, the recorder not on them: nothing
        assert node.count_publishers(node.resolve_topic_name(topics.RECORD_PROGRESS.name)) == 1
        assert node.publisher.get_subscription_count() == 1 and node.held and not received
        node.set_parameters([Parameter('nonslip', Parameter.Type.BOOL, False)])
        probe.create_subscription(DiagnosticStatus, topics.CONSTRAINTS.name, lambda _msg: None,
                                  qos_profile(topics.CONSTRAINTS))
        spin_until(executor, lambda: bool(received), 30.0, 'no constraint set after the recorder subscribed constraints')
        assert not node.held and len(received) == 1
        switches, _gains = messages.constraints_from_cdr(received[0])
        assert 'nonslip' not in switches.active_names()
    finally:
        executor.shutdown()
        for n in (listener, probe, node):
            if n is not None:
                n.destroy_node()
        rclpy.shutdown(context=context)
