"""Reading and building message objects (rclpy's, or rosbags' typestore's) field by field, for tests.

The graph decodes CDR bytes with ``wallbot_msgs_py.codec``; a test that holds a message object from an
independent decoder (rclpy, rosbags) reads it here, so its check does not go through the code it checks.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from wallbot_msgs_py import bagio, codec


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces Time or Duration as integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def seconds(stamp: Any) -> float:
    return stamp_ns(stamp) * 1e-9


def quaternion_yaw(q: Any) -> float:
    """Rotation about Z of a quaternion message, in (-pi, pi]."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def planar_state(msg: Any) -> codec.PlanarState:
    """The planar state of an Odometry message: the child-frame twist rotated into the wall frame."""
    p, twist = msg.pose.pose.position, msg.twist.twist
    theta = quaternion_yaw(msg.pose.pose.orientation)
    c, s = math.cos(theta), math.sin(theta)
    u, v = twist.linear.x, twist.linear.y
    return codec.PlanarState(stamp_ns(msg.header.stamp), p.x, p.y, theta, c * u - s * v, s * u + c * v,
                             twist.angular.z)


def joint_values(msg: Any, names: Sequence[str], field: str) -> tuple[float, ...]:
    """``field`` of a JointState message for ``names`` (NaN where absent)."""
    values, index = list(getattr(msg, field)), {name: i for i, name in enumerate(msg.name)}
    return tuple(float(values[index[n]]) if n in index and index[n] < len(values) else math.nan for n in names)


def wrench_values(msg: Any) -> tuple[float, float, float]:
    """(F_X, F_Y, M_Z) of a WrenchStamped message."""
    return msg.wrench.force.x, msg.wrench.force.y, msg.wrench.torque.z


def diagnostic_values(msg: Any) -> dict[str, str]:
    """Every key/value of a DiagnosticArray message's statuses (a later status's key wins)."""
    return {item.key: item.value for status in msg.status for item in status.values}


def typestore_stamp(t: float) -> Any:
    """A typestore builtin_interfaces/Time of ``t`` seconds."""
    sec, nanosec = divmod(round(t * 1e9), 1_000_000_000)
    return bagio.typestore().types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)


def typestore_header(t: float, frame: str) -> Any:
    return bagio.typestore().types['std_msgs/msg/Header'](stamp=typestore_stamp(t), frame_id=frame)


def odometry_cdr(t: float, x: float, y: float, theta: float, xd: float, yd: float, thd: float,
                 child: str = 'base_link', frame: str = 'wall') -> bytes:
    """One Odometry's CDR bytes from the graph's encoder (wall-frame velocities in, as the dynamics has them)."""
    sec, nanosec = divmod(round(t * 1e9), 1_000_000_000)
    return codec.OdometryEncoder(frame, child).encode(sec, nanosec, (x, y, theta), (xd, yd, thd))
