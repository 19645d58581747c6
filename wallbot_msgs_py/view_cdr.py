"""The viewer's messages as CDR bytes, encoded without ROS: visualization_msgs/MarkerArray and
tf2_msgs/TFMessage; and the few fields it draws, read from the per-step messages' CDR bytes.

A viewing frame carries line strips of a few thousand points; a general encoder (rosbags, or
rclpy's message objects) spends a millisecond or more per frame on them, 3-5 % of a core at 30
frames a second. Here the points are written as one block of float64 from a NumPy array. The bytes are
what rosbags serializes for the same message (XCDR1, little endian; checked by test_view.py), so
the viewer publishes them as serialized messages, and the Foxglove relay serves them unchanged.
Reading an Odometry here took 7 us where rclpy's deserialization into a message object took 170 us
(2026-12-01, the project's VM under load; it builds, among others, the two 36-element covariances).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from functools import lru_cache
from typing import NamedTuple, Sequence

import numpy as np

from wallbot_msgs_py import codec
from wallbot_msgs_py.step_cdr import ENCAPSULATION, NS_PER_S, _Template

ARROW, CUBE, CYLINDER, LINE_STRIP = 0, 1, 3, 4
"""visualization_msgs/Marker types used here."""
ADD, DELETE = 0, 2
"""visualization_msgs/Marker actions used here."""

Quaternion = tuple[float, float, float, float]
"""(x, y, z, w)."""
IDENTITY: Quaternion = (0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class MarkerSpec:
    """One visualization_msgs/Marker in plain numbers (fields not named here are empty or zero)."""

    ns: str
    id: int
    type: int
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: Quaternion = IDENTITY
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    """(r, g, b, a), each in [0, 1]."""
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """N x 3 (LINE_STRIP, ARROW from points[0] to points[1])."""
    action: int = ADD


@dataclass(frozen=True)
class TransformSpec:
    """One geometry_msgs/TransformStamped: ``child`` in ``parent``."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: Quaternion


class _Writer(_Template):
    """A message written field by field with its values (the step encoder's CDR layout rules)."""

    def int32(self, value: int) -> None:
        self._align(4)
        self.data += struct.pack('<i', value)

    def float64s(self, values: Sequence[float]) -> None:
        self._align(8)
        self.data += struct.pack(f'<{len(values)}d', *values)

    def boolean(self, value: bool) -> None:
        self.data.append(1 if value else 0)

    def time(self, stamp_ns: int) -> None:
        sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
        self.int32(sec)
        self.uint32(nanosec)

    def stamped_header(self, stamp_ns: int, frame: str) -> None:
        self.time(stamp_ns)
        self.string(frame)

    def point_sequence(self, points: np.ndarray) -> None:
        self.uint32(len(points))
        if len(points):
            self._align(8)
            self.data += np.ascontiguousarray(points, dtype='<f8').tobytes()

    def bytes(self) -> bytes:
        return bytes(self.data)


def marker_array(stamp_ns: int, frame: str, markers: Sequence[MarkerSpec]) -> bytes:
    """``markers`` (visualization_msgs/MarkerArray): every marker stamped ``stamp_ns`` in ``frame``."""
    out = _Writer()
    out.uint32(len(markers))
    sec, nanosec = divmod(int(stamp_ns), NS_PER_S)
    stamp = _STAMP.pack(sec, nanosec)
    for marker in markers:
        out._align(4)  # the header's stamp (after the previous marker's final bool)
        out.data += stamp
        out.data += _marker_names(frame, marker.ns, marker.id, marker.type, marker.action)
        out._align(8)
        out.data += _POSE_SCALE_COLOR.pack(*marker.position, *marker.orientation, *marker.scale, *marker.color)
        out.data += _LIFETIME_FRAME_LOCKED
        out.point_sequence(marker.points)  # ends 4-aligned: the empty rest is always the same bytes
        out.data += _EMPTY_MARKER_END
    return out.bytes()


_STAMP = struct.Struct('<iI')
_POSE_SCALE_COLOR = struct.Struct('<10d4f')
_LIFETIME_FRAME_LOCKED = bytes(9)
"""Lifetime 0 (until replaced), frame_locked false."""


@lru_cache(maxsize=256)
def _marker_names(frame: str, ns: str, marker_id: int, marker_type: int, action: int) -> bytes:
    """A Marker's header frame, ns, id, type and action: the same bytes after any stamp (4-aligned
    fields only)."""
    out = _Writer()
    out.string(frame)
    out.string(ns)
    out.int32(marker_id)
    out.int32(marker_type)
    out.int32(action)
    return out.bytes()[len(ENCAPSULATION):]


def _empty_marker_end() -> bytes:
    """A Marker's fields after ``points``, all empty, from a 4-aligned offset (none needs more)."""
    out = _Writer()
    out.uint32(0)  # colors
    out.string('')  # texture_resource
    out.stamped_header(0, '')  # texture: sensor_msgs/CompressedImage, empty
    out.string('')
    out.uint32(0)
    out.uint32(0)  # uv_coordinates
    out.string('')  # text
    out.string('')  # mesh_resource
    out.string('')  # mesh_file: filename, data
    out.uint32(0)
    out.boolean(False)  # mesh_use_embedded_materials
    return out.bytes()[len(ENCAPSULATION):]


_EMPTY_MARKER_END = _empty_marker_end()


def tf_message(stamp_ns: int, transforms: Sequence[TransformSpec]) -> bytes:
    """``/tf`` (tf2_msgs/TFMessage): every transform stamped ``stamp_ns``."""
    out = _Writer()
    out.uint32(len(transforms))
    for transform in transforms:
        out.stamped_header(stamp_ns, transform.parent)
        out.string(transform.child)
        out.float64s((*transform.translation, *transform.rotation))
    return out.bytes()


# --- reading the per-step messages the viewer draws ------------------------------------------------
class JointArrays(NamedTuple):
    """A sensor_msgs/JointState's names and values (under the message's field names)."""

    stamp_ns: int
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


class OdometryPose(NamedTuple):
    """A nav_msgs/Odometry's frames, stamp and planar pose (its yaw in (-pi, pi])."""

    stamp_ns: int
    frame: str
    child: str
    x: float
    y: float
    yaw: float


class _Reader:
    """Fields read in order from CDR bytes (either byte order); ValueError when the bytes end early."""

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[:2] not in (b'\x00\x00', b'\x00\x01'):
            raise ValueError('not CDR (bad encapsulation header)')
        self.data, self.offset = data, 4
        self.order = '<' if data[1] & 1 else '>'

    def _unpack(self, size: int, fmt: str) -> tuple:
        self.offset += -(self.offset - 4) % size
        values = struct.unpack_from(self.order + fmt, self.data, self.offset)
        self.offset += struct.calcsize(fmt)
        return values

    def uint32(self) -> int:
        return self._unpack(4, 'I')[0]

    def stamp_ns(self) -> int:
        sec, nanosec = self._unpack(4, 'iI')
        return sec * NS_PER_S + nanosec

    def string(self) -> str:
        length = self.uint32()
        if length == 0 or self.offset + length > len(self.data):
            raise ValueError(f'a string of {length} bytes at offset {self.offset}')
        text = self.data[self.offset:self.offset + length - 1].decode()
        self.offset += length
        return text

    def doubles(self, count: int) -> tuple[float, ...]:
        return self._unpack(8, f'{count}d') if count else ()

    def double_sequence(self) -> tuple[float, ...]:
        return self.doubles(self.uint32())


def _read(decode):
    """``decode`` with any failure of short or garbled bytes as a ValueError."""
    def read(data: bytes):
        try:
            return decode(_Reader(bytes(data)))
        except (struct.error, UnicodeDecodeError) as error:
            raise ValueError(f'malformed message: {error}') from None
    read.__doc__ = decode.__doc__
    return read


@_read
def odometry_pose(message: _Reader) -> OdometryPose:
    """The stamp, frames and planar pose of a serialized nav_msgs/Odometry."""
    stamp_ns, frame = message.stamp_ns(), message.string()
    child = message.string()
    x, y, _z, qx, qy, qz, qw = message.doubles(7)
    return OdometryPose(stamp_ns, frame, child, x, y, codec.yaw_of(qx, qy, qz, qw))


@_read
def joint_arrays(message: _Reader) -> JointArrays:
    """The stamp, names and values of a serialized sensor_msgs/JointState."""
    stamp_ns = message.stamp_ns()
    message.string()  # frame_id: joint states carry none of use here
    names = tuple(message.string() for _ in range(message.uint32()))
    return JointArrays(stamp_ns, names, message.double_sequence(), message.double_sequence(),
                       message.double_sequence())
