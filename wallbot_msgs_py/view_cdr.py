"""The viewer's messages as CDR bytes, encoded without ROS: visualization_msgs/MarkerArray and
tf2_msgs/TFMessage (nothing in the graph reads them back: RViz and Foxglove do).

A viewing frame carries line strips of a few thousand points; a general encoder (rosbags, or
rclpy's message objects) spends a millisecond or more per frame on them, 3-5 % of a core at 30
frames a second. Here the points are written as one block of float64 from a NumPy array. The bytes are
what rosbags serializes for the same message (XCDR1, little endian; checked by test_view.py), so
the viewer publishes them as serialized messages, and the Foxglove relay serves them unchanged.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Sequence

import numpy as np

from wallbot_msgs_py import cdr

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


@cdr.encoder('markers', 'visualization_msgs/msg/MarkerArray')
def marker_array(stamp_ns: int, frame: str, markers: Sequence[MarkerSpec]) -> bytes:
    """``markers`` (visualization_msgs/MarkerArray): every marker stamped ``stamp_ns`` in ``frame``."""
    out = cdr.Writer()
    out.uint32(len(markers))
    stamp = _STAMP.pack(*cdr.split_stamp(stamp_ns))
    for marker in markers:
        out.align(4)  # the header's stamp (after the previous marker's final bool)
        out.data += stamp
        out.data += _marker_names(frame, marker.ns, marker.id, marker.type, marker.action)
        out.align(8)
        out.data += _POSE_SCALE_COLOR.pack(*marker.position, *marker.orientation, *marker.scale, *marker.color)
        out.data += _LIFETIME_FRAME_LOCKED
        out.uint32(len(marker.points))
        out.float64_block(marker.points)  # ends 4-aligned: the empty rest is always the same bytes
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
    out = cdr.Writer()
    out.string(frame)
    out.string(ns)
    out.int32(marker_id)
    out.int32(marker_type)
    out.int32(action)
    return out.bytes()[len(cdr.ENCAPSULATION):]


def _empty_marker_end() -> bytes:
    """A Marker's fields after ``points``, all empty, from a 4-aligned offset (none needs more)."""
    out = cdr.Writer()
    out.uint32(0)  # colors
    out.string('')  # texture_resource
    out.header(0, '')  # texture: sensor_msgs/CompressedImage, empty
    out.string('')
    out.uint32(0)
    out.uint32(0)  # uv_coordinates
    out.string('')  # text
    out.string('')  # mesh_resource
    out.string('')  # mesh_file: filename, data
    out.uint32(0)
    out.octet(0)  # mesh_use_embedded_materials: false
    return out.bytes()[len(cdr.ENCAPSULATION):]


_EMPTY_MARKER_END = _empty_marker_end()


@cdr.encoder('tf', 'tf2_msgs/msg/TFMessage')
def tf_message(stamp_ns: int, transforms: Sequence[TransformSpec]) -> bytes:
    """``/tf`` (tf2_msgs/TFMessage): every transform stamped ``stamp_ns``."""
    out = cdr.Writer()
    out.uint32(len(transforms))
    for transform in transforms:
        out.header(stamp_ns, transform.parent)
        out.string(transform.child)
        out.float64s((*transform.translation, *transform.rotation))
    return out.bytes()
