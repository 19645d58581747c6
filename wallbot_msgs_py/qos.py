"""rclpy QoS profiles of the graph's topics (the one ROS-importing companion of topics.py)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from wallbot_msgs_py.topics import Durability, Topic


def qos_profile(topic: Topic) -> QoSProfile:
    """RELIABLE, KEEP_LAST(topic.depth), with the topic's durability.

    Publishers and recorders use the same profile; a transient-local topic (the plan, the
    path, the constraint set) is re-delivered to late joiners such as a dynamics node
    started after the trajectory node.
    """
    durability = (DurabilityPolicy.TRANSIENT_LOCAL if topic.durability is Durability.TRANSIENT_LOCAL
                  else DurabilityPolicy.VOLATILE)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=topic.depth,
                      reliability=ReliabilityPolicy.RELIABLE, durability=durability)
