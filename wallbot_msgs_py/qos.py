"""rclpy QoS profiles of the graph's topics (the one ROS-importing companion of topics.py)."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from wallbot_msgs_py.topics import Durability, Topic


def qos_profile(topic: Topic) -> QoSProfile:
    """RELIABLE, KEEP_LAST(topic.depth), with the topic's durability.

    Publishers and recorders use the same profile (but for a topic whose publishers offer more:
    ``offered_qos_profile``); a transient-local topic (the plan, the path, the constraint set) is
    re-delivered to late joiners such as a dynamics node started after the trajectory node.
    """
    return _profile(topic, topic.durability)


def offered_qos_profile(topic: Topic) -> QoSProfile:
    """The profile the topic's publishers offer (``Topic.offered``, else ``qos_profile``); a subscriber asking for it
    also gets what they kept from before it matched."""
    return _profile(topic, topic.offered or topic.durability)


def _profile(topic: Topic, durability: Durability) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=topic.depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if durability is Durability.TRANSIENT_LOCAL
                                  else DurabilityPolicy.VOLATILE))
