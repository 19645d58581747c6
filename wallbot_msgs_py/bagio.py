"""What reading and writing a wallbot bag needs without a ROS install.

* :func:`typestore`: the ROS 2 Jazzy message types (rosbags' built-in store), used to embed
  message definitions and type hashes when writing and to decode CDR when reading.
* :func:`offered_qos`: the QoS a graph topic is offered with (from :mod:`topics`), as rosbags
  ``Qos`` for the bag's ``offered_qos_profiles``.
* :func:`decode_stamp` and the ``*_row`` functions: recorded messages into plain numbers, the
  inverse of what the dynamics and trajectory nodes publish (``step_cdr``, ``conversions``).
* the remaining builders: the latched topics, diagnostics and reference pose of a headless
  ``simulate --bag`` (its per-step messages come from ``step_cdr``, which needs no ROS either).
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


# --- encoding without ROS (``simulate --bag``) -------------------------------------------------
# The field layout mirrors the decoders above and the trajectory node's conversions: odometry
# pose in the wall frame, twist in the child frame.

def _types() -> Any:
    return typestore().types


def stamp(t: float) -> Any:
    """builtin_interfaces/Time of t seconds (rounded to the ns)."""
    sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return _types()['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)


def header(t: float, frame: str) -> Any:
    return _types()['std_msgs/msg/Header'](stamp=stamp(t), frame_id=frame)


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
    return _types()['geometry_msgs/msg/Vector3'](x=float(x), y=float(y), z=float(z))


def odometry(t: float, x: float, y: float, theta: float, vx: float, vy: float, omega: float,
             frame: str = topics.WALL_FRAME, child: str = topics.BASE_FRAME, twist_in_child: bool = True) -> Any:
    """nav_msgs/Odometry: pose in ``frame``; twist rotated into ``child`` unless twist_in_child is False."""
    import numpy as np
    types = _types()
    if twist_in_child:
        c, s = math.cos(theta), math.sin(theta)
        vx, vy = c * vx + s * vy, -s * vx + c * vy
    pose = types['geometry_msgs/msg/Pose'](
        position=types['geometry_msgs/msg/Point'](x=float(x), y=float(y), z=0.0),
        orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=math.sin(theta / 2.0), w=math.cos(theta / 2.0)))
    twist = types['geometry_msgs/msg/Twist'](linear=_vector(vx, vy), angular=_vector(0.0, 0.0, omega))
    zeros = np.zeros(36, dtype=np.float64)
    return types['nav_msgs/msg/Odometry'](
        header=header(t, frame), child_frame_id=child,
        pose=types['geometry_msgs/msg/PoseWithCovariance'](pose=pose, covariance=zeros),
        twist=types['geometry_msgs/msg/TwistWithCovariance'](twist=twist, covariance=zeros.copy()))


def path(t: float, points: list[tuple[float, float, float]], frame: str = topics.WALL_FRAME) -> Any:
    """nav_msgs/Path of (t, x, y) points."""
    types = _types()
    identity = types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)
    poses = [types['geometry_msgs/msg/PoseStamped'](
        header=header(tp, frame), pose=types['geometry_msgs/msg/Pose'](
            position=types['geometry_msgs/msg/Point'](x=float(px), y=float(py), z=0.0), orientation=identity))
        for tp, px, py in points]
    return types['nav_msgs/msg/Path'](header=header(t, frame), poses=poses)


def diagnostic_status(name: str, message: str, values: dict[str, str], level: int = 0,
                      hardware_id: str = 'wallbot') -> Any:
    types = _types()
    return types['diagnostic_msgs/msg/DiagnosticStatus'](
        level=int(level), name=name, message=message,
        hardware_id=hardware_id,
        values=[types['diagnostic_msgs/msg/KeyValue'](key=str(k), value=str(v)) for k, v in values.items()])


def diagnostic_array(t: float, statuses: list[Any]) -> Any:
    return _types()['diagnostic_msgs/msg/DiagnosticArray'](header=header(t, ''), status=statuses)


def serialize(msg: Any, msgtype: str) -> bytes:
    """CDR bytes of a typestore message."""
    return bytes(typestore().serialize_cdr(msg, msgtype))
