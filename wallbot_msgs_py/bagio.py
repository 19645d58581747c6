"""What reading and writing a wallbot bag needs without a ROS install.

* :func:`typestore`: the ROS 2 Jazzy message types (rosbags' built-in store), used to embed
  message definitions and type hashes when writing and to decode CDR when reading.
* :func:`offered_qos`: the QoS a graph topic is offered with (from :mod:`topics`), as rosbags
  ``Qos`` for the bag's ``offered_qos_profiles``.
* :func:`decode_stamp` and the ``*_row`` functions: recorded messages into plain numbers, the
  inverse of what the dynamics and trajectory nodes publish (``wallbot_msgs_py.conversions``).
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

from wallbot_msgs_py import topics


@lru_cache(maxsize=None)
def typestore() -> Any:
    """The rosbags typestore of ROS 2 Jazzy (common_interfaces included)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def offered_qos(topic: topics.Topic) -> list[Any]:
    """The offered QoS profile of ``topic`` (RELIABLE, KEEP_LAST depth) as rosbags ``Qos``."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    durability = (QosDurability.TRANSIENT_LOCAL if topic.durability is topics.Durability.TRANSIENT_LOCAL
                  else QosDurability.VOLATILE)
    zero = QosTime(0, 0)
    return [Qos(QosHistory.KEEP_LAST, topic.depth, QosReliability.RELIABLE, durability, zero, zero,
                QosLiveliness.AUTOMATIC, zero, False)]


def qos_from_rclpy(profile: Any) -> Any:
    """An rclpy ``QoSProfile`` (e.g. a publisher's, from the graph) as rosbags ``Qos``."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    def enum(cls: Any, value: Any) -> Any:
        try:
            return cls(int(value))
        except (ValueError, TypeError):
            return cls.UNKNOWN

    def duration(value: Any) -> Any:
        nanoseconds = int(getattr(value, 'nanoseconds', 0))
        if nanoseconds >= 2**63 - 1 or nanoseconds < 0:
            nanoseconds = 0
        return QosTime(nanoseconds // 10**9, nanoseconds % 10**9)

    return Qos(enum(QosHistory, profile.history), int(profile.depth), enum(QosReliability, profile.reliability),
               enum(QosDurability, profile.durability), duration(profile.deadline), duration(profile.lifespan),
               enum(QosLiveliness, profile.liveliness), duration(profile.liveliness_lease_duration),
               bool(profile.avoid_ros_namespace_conventions))


def deserialize(data: bytes | memoryview, msgtype: str) -> Any:
    """A CDR message decoded with the Jazzy typestore."""
    return typestore().deserialize_cdr(bytes(data), msgtype)


def decode_stamp(stamp: Any) -> float:
    """A builtin_interfaces/Time as seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def yaw(orientation: Any) -> float:
    """Rotation about Z of a quaternion (the robot's attitude angle on the wall)."""
    return math.atan2(2.0 * (orientation.w * orientation.z + orientation.x * orientation.y),
                      1.0 - 2.0 * (orientation.y * orientation.y + orientation.z * orientation.z))


def odom_row(msg: Any) -> tuple[float, ...]:
    """(t, x, y, theta, vx, vy, omega) of an Odometry: pose in the wall frame; the twist is in the
    child frame (base_link, ROS convention) and is rotated here into wall-frame velocities."""
    pose, twist = msg.pose.pose, msg.twist.twist
    theta = yaw(pose.orientation)
    u, v = twist.linear.x, twist.linear.y
    c, s = math.cos(theta), math.sin(theta)
    return (decode_stamp(msg.header.stamp), pose.position.x, pose.position.y, theta,
            c * u - s * v, s * u + c * v, twist.angular.z)


def reference_row(msg: Any) -> tuple[float, float, float]:
    """(t, x, y) of a reference Odometry."""
    return decode_stamp(msg.header.stamp), msg.pose.pose.position.x, msg.pose.pose.position.y


def joint_row(msg: Any, names: tuple[str, ...], field: str) -> tuple[float, ...]:
    """``field`` (position, velocity or effort) of a JointState for ``names`` in that order (NaN if absent)."""
    values = list(getattr(msg, field))
    index = {name: i for i, name in enumerate(msg.name)}
    return tuple(float(values[index[n]]) if n in index and index[n] < len(values) else math.nan for n in names)


def wrench_row(msg: Any) -> tuple[float, float, float, float]:
    """(t, F_X, F_Y, M_Z) of a WrenchStamped."""
    return decode_stamp(msg.header.stamp), msg.wrench.force.x, msg.wrench.force.y, msg.wrench.torque.z


def diagnostic_values(msg: Any) -> dict[str, str]:
    """Every key/value of a DiagnosticArray's statuses, keys prefixed by nothing (last one wins)."""
    values: dict[str, str] = {}
    for status in msg.status:
        for item in status.values:
            values[item.key] = item.value
    return values
