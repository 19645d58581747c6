"""What reading and writing a wallbot bag needs without a ROS install.

* :func:`typestore`: the ROS 2 Jazzy message types (rosbags' built-in store), used to embed
  message definitions and type hashes when writing and to encode and decode CDR.
* :func:`serialize`, :func:`deserialize`: typestore messages <-> CDR bytes.
* :func:`offered_qos`, :func:`qos_from_rclpy`: a graph topic's QoS (from :mod:`topics`, or as a
  live publisher offers it) as rosbags ``Qos`` for the bag's ``offered_qos_profiles``.

What the messages mean, field by field, is :mod:`codec`'s.
"""

from __future__ import annotations

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
    """A CDR message decoded with the Jazzy typestore.

    Tolerates trailing bytes: rclpy/Fast-CDR serialization (what the recorder stores) may end a
    message with up to 8 bytes of padding, which rosbags' ``deserialize_cdr`` rejects as a size
    mismatch (seen on sensor_msgs/JointState with empty sequences).
    """
    raw = bytes(data)
    store = typestore()
    if len(raw) < 4 or raw[:2] not in (b'\x00\x00', b'\x00\x01'):
        raise ValueError(f'{msgtype}: not CDR (bad encapsulation header)')
    msgdef = store.get_msgdef(msgtype)
    decode = msgdef.deserialize_cdr_le if raw[1] else msgdef.deserialize_cdr_be
    message, _end = decode(raw[4:], 0, msgdef.cls, store)
    return message


def serialize(msg: Any, msgtype: str) -> bytes:
    """CDR bytes of a typestore message."""
    return bytes(typestore().serialize_cdr(msg, msgtype))
