"""The viewer's messages as CDR bytes, encoded without ROS: visualization_msgs/MarkerArray and
tf2_msgs/TFMessage.

A viewing frame carries line strips of a few thousand points; a general encoder (rosbags, or
rclpy's message objects) spends a millisecond or more per frame on them, 3-5 % of a core at 30
frames a second. Here the points are written as one block of float64 from a NumPy array. The bytes are
what rosbags serializes for the same message (XCDR1, little endian; checked by test_view.py), so
the viewer publishes them as serialized messages, and the Foxglove relay serves them unchanged.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

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

    def float32s(self, values: Sequence[float]) -> None:
        self._align(4)
        self.data += struct.pack(f'<{len(values)}f', *values)

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
    for marker in markers:
        out.stamped_header(stamp_ns, frame)
        out.string(marker.ns)
        out.int32(marker.id)
        out.int32(marker.type)
        out.int32(marker.action)
        out.float64s((*marker.position, *marker.orientation, *marker.scale))
        out.float32s(marker.color)
        out.time(0)  # lifetime 0: until replaced
        out.boolean(False)  # frame_locked
        out.point_sequence(marker.points)  # ends 4-aligned: the empty rest is always the same bytes
        out.data += _EMPTY_MARKER_END
    return out.bytes()


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
