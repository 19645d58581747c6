"""One encoder and one decoder per message of the graph, in plain numbers, without ROS.

Encoders return CDR bytes built with the ROS 2 Jazzy typestore (rosbags): the nodes publish
them as serialized messages and ``simulate --bag`` writes them, so what a topic carries does
not depend on whether rclpy is installed. Decoders take a message object, from rclpy or from
the typestore alike (they only read fields), and return plain numbers; a malformed message is a
ValueError naming what is wrong. The per-step messages of the dynamics node have a faster
encoder of their own, ``step_cdr``, checked against these decoders.

Conventions (REP 103/105): poses in frame ``wall`` (X right, Y up, Z out of the wall), the robot
frame ``base_link`` at the geometric centre; odometry twists are in the child frame, so
twist.linear = (v_long, v_lat) and twist.angular.z = the turning rate. Every stamp is
simulation time.
"""

from __future__ import annotations

import math
import struct
from typing import Any, Iterable, Mapping, NamedTuple, Sequence

import numpy as np

from wallbot_msgs_py import bagio, topics

NS_PER_S = 1_000_000_000
Vec2 = tuple[float, float]


def _types() -> Any:
    return bagio.typestore().types


# --- time and heading ---------------------------------------------------------------------------
def to_nanoseconds(t: float) -> int:
    """Simulation time (s) as integer nanoseconds (rounded: k * 1 ms stamps come out exact)."""
    return round(t * 1e9)


def stamp(t: float) -> Any:
    """builtin_interfaces/Time of simulation time t (s)."""
    sec, nanosec = divmod(to_nanoseconds(t), NS_PER_S)
    return _types()['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)


def duration(ns: int) -> Any:
    """builtin_interfaces/Duration of ``ns`` nanoseconds."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return _types()['builtin_interfaces/msg/Duration'](sec=sec, nanosec=nanosec)


def stamp_nanoseconds(msg: Any) -> int:
    """A Time or Duration as integer nanoseconds."""
    return _nanoseconds(int(msg.sec), int(msg.nanosec))


def seconds(msg: Any) -> float:
    """A Time or Duration in seconds."""
    return stamp_nanoseconds(msg) * 1e-9


def leading_stamp_ns(data: bytes) -> int | None:
    """The time (ns) a serialized message starts with, read without decoding it: a
    rosgraph_msgs/Clock, or any message whose first field is a std_msgs/Header; None if too short.

    CDR: a 4-byte encapsulation header (byte 1, bit 0: little endian), then int32 sec, uint32 nanosec.
    """
    if len(data) < 12:
        return None
    sec, nanosec = struct.unpack_from('<iI' if data[1] & 1 else '>iI', data, 4)
    return sec * NS_PER_S + nanosec


def header(t: float, frame: str) -> Any:
    return _types()['std_msgs/msg/Header'](stamp=stamp(t), frame_id=frame)


def yaw_quaternion(yaw: float) -> Any:
    """geometry_msgs/Quaternion of a rotation by ``yaw`` about Z."""
    return _types()['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=math.sin(0.5 * yaw), w=math.cos(0.5 * yaw))


def quaternion_yaw(q: Any) -> float:
    """Rotation about Z of a quaternion, in (-pi, pi] (the only rotation this graph uses)."""
    return yaw_of(q.x, q.y, q.z, q.w)


def yaw_of(x: float, y: float, z: float, w: float) -> float:
    """Rotation about Z of the quaternion (x, y, z, w), in (-pi, pi]."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def initial_pose(msg: Any, wall_frame: str = topics.WALL_FRAME) -> tuple[float, float, float]:
    """(x, y, heading) of an ``initialpose`` (PoseWithCovarianceStamped); ValueError naming what is
    wrong: a frame other than ``wall_frame`` (the graph has no tf to convert it), a non-finite number, an
    orientation that is not a turn about the wall's normal Z. The covariance is not used."""
    frame = msg.header.frame_id
    if frame != wall_frame:
        raise ValueError(f'initialpose: frame {frame!r}, not {wall_frame!r} (set the fixed frame to '
                         f'{wall_frame!r})')
    position, q = msg.pose.pose.position, msg.pose.pose.orientation
    values = (position.x, position.y, position.z, q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f'initialpose: a pose value is not finite: {values}')
    norm = math.sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w)
    if norm == 0.0 or math.hypot(q.x, q.y) > 1e-6 * norm:
        raise ValueError(f'initialpose: orientation ({q.x}, {q.y}, {q.z}, {q.w}) is not a turn about Z')
    return float(position.x), float(position.y), math.atan2(2.0 * q.w * q.z, q.w * q.w - q.z * q.z)  # any norm


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
    return _types()['geometry_msgs/msg/Vector3'](x=float(x), y=float(y), z=float(z))


def _point(x: float, y: float) -> Any:
    return _types()['geometry_msgs/msg/Point'](x=float(x), y=float(y), z=0.0)


def _serialize(msg: Any, topic: topics.Topic) -> bytes:
    return bagio.serialize(msg, topic.type)


# --- odometry (odom, reference) --------------------------------------------------------------------
class PlanarState(NamedTuple):
    """The planar state an Odometry carries, velocities in the wall frame."""

    stamp_ns: int
    x: float
    y: float
    theta: float
    """Yaw of the pose quaternion, in (-pi, pi] (the simulation's angle is unwrapped)."""
    xd: float
    yd: float
    thd: float

    @property
    def t(self) -> float:
        return self.stamp_ns * 1e-9


def odometry(t: float, x: float, y: float, theta: float, xd: float, yd: float, thd: float,
             child: str = topics.BASE_FRAME, frame: str = topics.WALL_FRAME) -> bytes:
    """nav_msgs/Odometry: pose in ``frame`` (the wall), the wall-frame velocity (xd, yd) rotated into ``child``."""
    types = _types()
    c, s = math.cos(theta), math.sin(theta)
    pose = types['geometry_msgs/msg/Pose'](position=_point(x, y), orientation=yaw_quaternion(theta))
    twist = types['geometry_msgs/msg/Twist'](linear=_vector(c * xd + s * yd, -s * xd + c * yd),
                                             angular=_vector(0.0, 0.0, thd))
    zeros = np.zeros(36, dtype=np.float64)
    msg = types['nav_msgs/msg/Odometry'](
        header=header(t, frame), child_frame_id=child,
        pose=types['geometry_msgs/msg/PoseWithCovariance'](pose=pose, covariance=zeros),
        twist=types['geometry_msgs/msg/TwistWithCovariance'](twist=twist, covariance=zeros.copy()))
    return _serialize(msg, topics.ODOM)


def planar_state(msg: Any) -> PlanarState:
    """Decode an Odometry (``odom`` or ``reference``): pose in ``wall``, twist in the child frame
    rotated back to wall-frame velocities. ValueError if a value is not finite."""
    p, q, twist = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist
    return _planar(stamp_nanoseconds(msg.header.stamp), p.x, p.y, q.x, q.y, q.z, q.w,
                   twist.linear.x, twist.linear.y, twist.angular.z)


_POSE_AND_TWIST = '7d288x6d288x'
"""An Odometry's CDR from its pose to its end: position, orientation, the pose covariance (36 doubles,
skipped), the twist (linear, angular) and its covariance (skipped, but there): doubles back to back."""


def planar_state_from_cdr(data: bytes) -> PlanarState:
    """``planar_state`` of a serialized Odometry (what a raw subscription takes), read from the
    bytes: the same numbers, without converting the whole message (covariances included) first,
    which costs a controller more than the rest of its callback."""
    x, y, _z, qx, qy, qz, qw, u, v, _w, _p, _q, r = _pose_and_twist(data)
    return _planar(leading_stamp_ns(data), x, y, qx, qy, qz, qw, u, v, r)


def body_twist_from_cdr(data: bytes) -> tuple[float, float, float]:
    """(linear.x, linear.y, angular.z) of a serialized Odometry's twist (in its child frame), read
    from the bytes as ``planar_state_from_cdr`` reads them. ValueError if malformed."""
    u, v, _w, _p, _q, r = _pose_and_twist(data)[7:]
    return u, v, r


def _pose_and_twist(data: bytes) -> tuple[float, ...]:
    """The 13 doubles of a serialized Odometry's pose (position, orientation) and twist (linear, angular)."""
    try:
        order = '<' if data[1] & 1 else '>'
        offset = _past_string(data, order, _past_string(data, order, 12))  # header.frame_id, child_frame_id
        return struct.unpack_from(order + _POSE_AND_TWIST, data, _aligned(offset, 8))
    except (struct.error, IndexError):
        raise ValueError(f'malformed odometry ({len(data)} bytes)') from None


def _aligned(offset: int, size: int) -> int:
    """``offset`` in a CDR buffer moved on to a multiple of ``size`` (counted after the 4-byte encapsulation)."""
    return 4 + -(-(offset - 4) // size) * size


def _planar(stamp_ns: int, x: float, y: float, qx: float, qy: float, qz: float, qw: float,
            u: float, v: float, r: float) -> PlanarState:
    theta = yaw_of(qx, qy, qz, qw)
    c, s = math.cos(theta), math.sin(theta)
    state = PlanarState(stamp_ns, x, y, theta, c * u - s * v, s * u + c * v, r)
    if not all(math.isfinite(value) for value in state[1:]):
        raise ValueError(f'odometry at t = {state.t:.3f} s is not finite')
    return state


# --- joint states and wrench (decoders; step_cdr encodes them) ------------------------------------
def joint_values(msg: Any, names: Sequence[str], field: str) -> tuple[float, ...]:
    """``field`` (position, velocity or effort) of a JointState for ``names`` in that order (NaN if absent)."""
    values = list(getattr(msg, field))
    index = {name: i for i, name in enumerate(msg.name)}
    return tuple(float(values[index[n]]) if n in index and index[n] < len(values) else math.nan for n in names)


def wrench_values(msg: Any) -> tuple[float, float, float]:
    """(F_X, F_Y, M_Z) of a WrenchStamped."""
    return msg.wrench.force.x, msg.wrench.force.y, msg.wrench.torque.z


# --- plan and path ---------------------------------------------------------------------------------
class PlanSamples(NamedTuple):
    """A reference plan: sample times and the centre's position, velocity and acceleration there."""

    times: list[float]
    positions: list[Vec2]
    velocities: list[Vec2]
    accelerations: list[Vec2]


def trajectory(plan: PlanSamples, headings: Sequence[tuple[float, float]], frame: str = topics.WALL_FRAME) -> bytes:
    """``reference_trajectory``: the plan as one MultiDOFJointTrajectory.

    header.stamp = the first sample time, ``frame`` (the wall); one joint (``base_link``) whose
    points carry the position (transforms[0].translation), velocity (velocities[0].linear)
    and acceleration (accelerations[0].linear) of the centre at header.stamp +
    time_from_start. ``headings`` (angle, rate) per sample fill the rotation and angular
    velocity, for display only: a follower interpolates p, v, a alone.
    """
    types = _types()
    start_ns = to_nanoseconds(plan.times[0])
    points = []
    for t, p, v, a, (yaw, rate) in zip(plan.times, plan.positions, plan.velocities, plan.accelerations, headings):
        points.append(types['trajectory_msgs/msg/MultiDOFJointTrajectoryPoint'](
            transforms=[types['geometry_msgs/msg/Transform'](translation=_vector(p[0], p[1]),
                                                             rotation=yaw_quaternion(yaw))],
            velocities=[types['geometry_msgs/msg/Twist'](linear=_vector(v[0], v[1]), angular=_vector(0.0, 0.0, rate))],
            accelerations=[types['geometry_msgs/msg/Twist'](linear=_vector(a[0], a[1]), angular=_vector())],
            time_from_start=duration(to_nanoseconds(t) - start_ns)))
    msg = types['trajectory_msgs/msg/MultiDOFJointTrajectory'](
        header=header(plan.times[0], frame), joint_names=[topics.BASE_FRAME], points=points)
    return _serialize(msg, topics.REFERENCE_TRAJECTORY)


def plan_samples(msg: Any) -> PlanSamples:
    """The plan in a ``reference_trajectory`` message; ValueError if it is not a usable plan."""
    if len(msg.points) < 2:
        raise ValueError(f'a reference trajectory needs >= 2 points, got {len(msg.points)}')
    start_ns = stamp_nanoseconds(msg.header.stamp)
    plan = PlanSamples([], [], [], [])
    for i, point in enumerate(msg.points):
        if not (len(point.transforms) and len(point.velocities) and len(point.accelerations)):
            raise ValueError(f'reference trajectory point {i} lacks a transform, velocity or acceleration')
        p, v, a = point.transforms[0].translation, point.velocities[0].linear, point.accelerations[0].linear
        plan.times.append((start_ns + stamp_nanoseconds(point.time_from_start)) * 1e-9)
        plan.positions.append((p.x, p.y))
        plan.velocities.append((v.x, v.y))
        plan.accelerations.append((a.x, a.y))
    return plan


def plan_samples_from_cdr(data: bytes) -> PlanSamples:
    """``plan_samples`` of a serialized ``reference_trajectory`` (what a raw subscription takes), read from the
    bytes as ``planar_state_from_cdr`` reads an Odometry: the numbers a follower uses, without converting
    the rest. A plan of 200 points takes 0.35 ms where converting it first took 3 ms (rosbags) of Python in
    the dynamics' executor thread, which shares the GIL with its 1 kHz loop thread; rclpy's C conversion
    would hold the GIL throughout."""
    try:
        order = '<' if data[1] & 1 else '>'
        start_ns = _nanoseconds(*struct.unpack_from(order + 'iI', data, 4))
        offset = _past_string(data, order, 12)  # header.frame_id
        offset, names = _count(data, order, offset)
        for _name in range(names):
            offset = _past_string(data, order, offset)
        offset, points = _count(data, order, offset)
        if points < 2:
            raise ValueError(f'a reference trajectory needs >= 2 points, got {points}')
        length, pair, stamp = (struct.Struct(order + code).unpack_from for code in ('I', '2d', 'iI'))
        plan = PlanSamples([], [], [], [])
        firsts: list[Any] = [None] * 3
        for i in range(points):  # aligned by hand: this loop is the reader's whole cost
            for field, size in enumerate((_TRANSFORM, _TWIST, _TWIST)):  # transforms, velocities, accelerations
                offset += -offset % 4
                count = length(data, offset)[0]
                if not count:
                    raise ValueError(f'reference trajectory point {i} lacks a transform, velocity or acceleration')
                offset += 4 + (offset & 4)  # on to the first double (offsets count the 4-byte encapsulation)
                firsts[field] = pair(data, offset)
                offset += count * size
            offset += -offset % 4
            plan.times.append((start_ns + _nanoseconds(*stamp(data, offset))) * 1e-9)
            offset += 8
            plan.positions.append(firsts[0])
            plan.velocities.append(firsts[1])
            plan.accelerations.append(firsts[2])
    except (struct.error, IndexError):
        raise ValueError(f'malformed reference_trajectory ({len(data)} bytes)') from None
    return plan


_TRANSFORM, _TWIST = 7 * 8, 6 * 8
"""Bytes of a geometry_msgs Transform (translation, rotation) and Twist (linear, angular) in CDR: doubles."""


def _count(data: bytes, order: str, offset: int) -> tuple[int, int]:
    """The offset after a sequence's length at ``offset`` (aligned first), and the length."""
    offset = _aligned(offset, 4)
    return offset + 4, struct.unpack_from(order + 'I', data, offset)[0]


def _past_string(data: bytes, order: str, offset: int) -> int:
    """The offset after the string at ``offset`` (aligned first)."""
    offset, size = _count(data, order, offset)
    return offset + size


def _nanoseconds(sec: int, nanosec: int) -> int:
    return sec * NS_PER_S + nanosec


def path(stamped_poses: Iterable[tuple[float, float, float, float]], t: float, frame: str = topics.WALL_FRAME) -> bytes:
    """``reference_path`` stamped ``t``: poses (time, x, y, yaw) in ``frame`` (the wall)."""
    types = _types()
    poses = [types['geometry_msgs/msg/PoseStamped'](
        header=header(tp, frame),
        pose=types['geometry_msgs/msg/Pose'](position=_point(x, y), orientation=yaw_quaternion(yaw)))
        for tp, x, y, yaw in stamped_poses]
    return _serialize(types['nav_msgs/msg/Path'](header=header(t, frame), poses=poses),
                      topics.REFERENCE_PATH)


# --- the constraint set ----------------------------------------------------------------------------
CONSTRAINTS_STATUS_NAME = 'wallbot constraints'
GAINS = ('baumgarte_alpha', 'baumgarte_beta')


class ConstraintSwitches(NamedTuple):
    """What a ``constraints`` message says: every switch, the Baumgarte gains."""

    switches: dict[str, bool]
    alpha: float
    beta: float


def constraints(switches: Mapping[str, bool], alpha: float, beta: float, active: Sequence[str], label: str) -> bytes:
    """``constraints``: a DiagnosticStatus whose values hold every switch ('true'/'false'), the
    gains (repr of the float) and 'active' (the active modules, comma-separated); its message
    is ``label``, e.g. 'trajectory+belt'."""
    values = {name: 'true' if switches[name] else 'false' for name in topics.CONSTRAINT_SWITCHES}
    values.update({'baumgarte_alpha': repr(float(alpha)), 'baumgarte_beta': repr(float(beta)),
                   'active': ','.join(active)})
    return _serialize(_status(Status(CONSTRAINTS_STATUS_NAME, 'ok', label, list(values.items()))), topics.CONSTRAINTS)


def robot_description(urdf: str) -> bytes:
    """``robot_description``: the URDF document as a std_msgs/String (decoded as ``msg.data``)."""
    return _serialize(_types()['std_msgs/msg/String'](data=urdf), topics.ROBOT_DESCRIPTION)


def constraint_switches(msg: Any) -> ConstraintSwitches:
    """The switches and gains of a ``constraints`` message; ValueError naming what is wrong."""
    values = {kv.key: kv.value for kv in msg.values}
    switches = {}
    for name in topics.CONSTRAINT_SWITCHES:
        text = values.get(name, '').strip().lower()
        if text not in ('true', 'false'):
            raise ValueError(f'constraints message: {name} must be true or false, got {values.get(name)!r}')
        switches[name] = text == 'true'
    gains = []
    for name in GAINS:
        try:
            gains.append(float(values[name]))
        except (KeyError, ValueError):
            raise ValueError(f'constraints message: {name} must be a number, got {values.get(name)!r}') from None
    return ConstraintSwitches(switches, *gains)


# --- diagnostics -------------------------------------------------------------------------------------
LEVELS = {'ok': 0, 'warn': 1, 'error': 2, 'stale': 3}
HARDWARE_ID = 'wallbot_sim'


class Status(NamedTuple):
    """One diagnostic_msgs/DiagnosticStatus: level one of LEVELS' keys, values in order."""

    name: str
    level: str
    message: str
    values: Sequence[tuple[str, object]]


def _text(value: object) -> str:
    return f'{value:.6g}' if isinstance(value, float) else str(value)


def _status(status: Status) -> Any:
    types = _types()
    return types['diagnostic_msgs/msg/DiagnosticStatus'](
        level=LEVELS[status.level], name=status.name, message=status.message, hardware_id=HARDWARE_ID,
        values=[types['diagnostic_msgs/msg/KeyValue'](key=str(k), value=_text(v)) for k, v in status.values])


def diagnostics(t: float, statuses: Sequence[Status]) -> bytes:
    """``/diagnostics`` stamped with simulation time t; floats written with 6 significant digits."""
    msg = _types()['diagnostic_msgs/msg/DiagnosticArray'](header=header(t, ''), status=[_status(s) for s in statuses])
    return _serialize(msg, topics.DIAGNOSTICS)


def diagnostic_values(msg: Any) -> dict[str, str]:
    """Every key/value of a DiagnosticArray's statuses (a later status's key wins)."""
    return {item.key: item.value for status in msg.status for item in status.values}


# --- commands ----------------------------------------------------------------------------------------
_TORQUE_COMMAND = struct.Struct('<4s3I4x2d')
"""A Float64MultiArray of two values with an empty layout, little-endian CDR: the encapsulation, the
layout's dim count and data_offset, the data's count, padding to 8, the two doubles."""
_LITTLE_ENDIAN_CDR = b'\x00\x01\x00\x00'


def wheel_torque_cmd(tau_left: float, tau_right: float) -> bytes:
    """``wheel_torque_cmd``: the side motor torques (N m) as a std_msgs/Float64MultiArray
    ``[tau_L, tau_R]`` with an empty layout, the bytes rclpy serializes such a message to (what a
    controller publishes, without building and converting an rclpy message each control instant)."""
    return _TORQUE_COMMAND.pack(_LITTLE_ENDIAN_CDR, 0, 0, 2, tau_left, tau_right)


def torque_command(msg: Any, max_torque: float) -> tuple[float, float]:
    """(tau_L, tau_R) of a ``wheel_torque_cmd`` Float64MultiArray.

    ValueError with the reason for a wrong length, NaN or inf, or |tau| > max_torque.
    """
    data = list(msg.data)
    if len(data) != 2:
        raise ValueError(f'wheel_torque_cmd needs data = [tau_L, tau_R], got {len(data)} values')
    for side, value in zip(('tau_L', 'tau_R'), data):
        if not math.isfinite(value):
            raise ValueError(f'wheel_torque_cmd {side} is not finite ({value})')
        if abs(value) > max_torque:
            raise ValueError(f'wheel_torque_cmd {side} = {value:g} N m is beyond max_wheel_torque {max_torque:g} N m')
    return float(data[0]), float(data[1])
