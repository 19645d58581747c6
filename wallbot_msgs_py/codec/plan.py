"""The trajectory node's plan: ``reference_trajectory`` (trajectory_msgs/MultiDOFJointTrajectory) and
``reference_path`` (nav_msgs/Path)."""

from __future__ import annotations

from typing import Iterable, NamedTuple, Sequence

from wallbot_msgs_py import cdr, topics
from wallbot_msgs_py.codec.odometry import yaw_of, yaw_quaternion

TRAJECTORY = 'trajectory_msgs/msg/MultiDOFJointTrajectory'
PATH = 'nav_msgs/msg/Path'
Vec2 = tuple[float, float]


class PlanSamples(NamedTuple):
    """A reference plan: sample times and the centre's position, velocity and acceleration there."""

    times: list[float]
    positions: list[Vec2]
    velocities: list[Vec2]
    accelerations: list[Vec2]


@cdr.encoder('reference_trajectory', TRAJECTORY)
def trajectory(plan: PlanSamples, headings: Sequence[tuple[float, float]], frame: str = topics.WALL_FRAME) -> bytes:
    """``reference_trajectory``: the plan as one MultiDOFJointTrajectory.

    header.stamp = the first sample time, ``frame`` (the wall); one joint (``base_link``) whose
    points carry the position (transforms[0].translation), velocity (velocities[0].linear)
    and acceleration (accelerations[0].linear) of the centre at header.stamp +
    time_from_start. ``headings`` (angle, rate) per sample fill the rotation and angular
    velocity, for display only: a follower interpolates p, v, a alone.
    """
    out = cdr.Writer()
    start_ns = cdr.to_nanoseconds(plan.times[0])
    out.header(start_ns, frame)
    out.strings((topics.BASE_FRAME,))
    out.uint32(len(plan.times))
    for t, p, v, a, (yaw, rate) in zip(plan.times, plan.positions, plan.velocities, plan.accelerations, headings):
        out.uint32(1)
        out.float64s((p[0], p[1], 0.0, *yaw_quaternion(yaw)))
        out.uint32(1)
        out.float64s((v[0], v[1], 0.0, 0.0, 0.0, rate))
        out.uint32(1)
        out.float64s((a[0], a[1], 0.0, 0.0, 0.0, 0.0))
        out.time(cdr.to_nanoseconds(t) - start_ns)  # time_from_start
    return out.bytes()


_TRANSFORM, _TWIST = 7, 6
"""float64 fields of a geometry_msgs Transform (translation, rotation) and Twist (linear, angular)."""


@cdr.decoder('reference_trajectory', TRAJECTORY)
def decode_plan(message: cdr.Reader) -> PlanSamples:
    """The plan in a serialized ``reference_trajectory``: what a follower uses (each point's first
    transform, velocity and acceleration), the rest skipped. ValueError if it is not a usable plan."""
    start_ns, _frame = message.header()
    message.strings()  # joint_names
    points = message.uint32()
    if points < 2:
        raise ValueError(f'a reference trajectory needs >= 2 points, got {points}')
    plan = PlanSamples([], [], [], [])
    columns = ((plan.positions, 8 * _TRANSFORM), (plan.velocities, 8 * _TWIST), (plan.accelerations, 8 * _TWIST))
    # aligned here rather than field by field: this loop is the decoder's whole cost (200 points, 0.4 ms),
    # and it runs in the dynamics' executor, which shares the GIL with the 1 kHz loop
    data, offset = message.data, message.offset
    length, pair, stamp = (message.unpacker(code) for code in ('I', '2d', 'iI'))
    for i in range(points):
        for column, size in columns:
            offset += -(offset - 4) % 4
            count = length(data, offset)[0]
            if not count:
                raise ValueError(f'reference trajectory point {i} lacks a transform, velocity or acceleration')
            offset += 4 + -offset % 8  # on to the first float64 (offsets count the 4-byte encapsulation)
            column.append(pair(data, offset))
            offset += count * size
        offset += -(offset - 4) % 4
        sec, nanosec = stamp(data, offset)
        offset += 8
        plan.times.append((start_ns + sec * cdr.NS_PER_S + nanosec) * 1e-9)
    message.offset = offset
    return plan


class PathMessage(NamedTuple):
    """A Path's stamp and frame, and its poses as (stamp ns, x, y, yaw)."""

    stamp_ns: int
    frame: str
    poses: list[tuple[int, float, float, float]]


@cdr.encoder('reference_path', PATH)
def path(stamped_poses: Iterable[tuple[float, float, float, float]], t: float, frame: str = topics.WALL_FRAME) -> bytes:
    """``reference_path`` stamped ``t``: poses (time, x, y, yaw) in ``frame`` (the wall)."""
    out = cdr.Writer()
    out.header(cdr.to_nanoseconds(t), frame)
    poses = list(stamped_poses)
    out.uint32(len(poses))
    for tp, x, y, yaw in poses:
        out.header(cdr.to_nanoseconds(tp), frame)
        out.float64s((x, y, 0.0, *yaw_quaternion(yaw)))
    return out.bytes()


@cdr.decoder('reference_path', PATH)
def decode_path(message: cdr.Reader) -> PathMessage:
    stamp_ns, frame = message.header()
    poses = []
    for _ in range(message.uint32()):
        pose_ns, _pose_frame = message.header()
        x, y, _z, qx, qy, qz, qw = message.float64s(7)
        poses.append((pose_ns, x, y, yaw_of(qx, qy, qz, qw)))
    return PathMessage(stamp_ns, frame, poses)
