"""Reading two bags message by message to compare them (shared by the bag tests)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

import message_fields
from wallbot_msgs_py import bagio
from wallbot_sim.bag.reader import messages

WALL_CLOCK_KEYS = ('achieved rate (Hz)', 'real-time factor', 'step time mean (ms)', 'step time max (ms)',
                   'lateness max (ms)', 'late steps (> 2 ms)', 'loop priority')
"""The dynamics' diagnostics measured in wall-clock time: they differ between runs of the same model."""


def by_topic(bag: Path) -> dict[str, list[Any]]:
    """Every message of the bag, decoded, by topic, in receive order."""
    result: dict[str, list[Any]] = {}
    for raw in messages(bag):
        result.setdefault(raw.topic, []).append(bagio.deserialize(raw.data, raw.type))
    return result


def fields(msg: Any) -> Any:
    """A message as nested tuples of (field name, value), arrays as tuples: comparable with ==.
    NaN compares equal to NaN here."""
    if hasattr(msg, '__dataclass_fields__'):
        return tuple((name, fields(getattr(msg, name))) for name in msg.__dataclass_fields__
                     if not name.startswith('__') and not name.isupper())  # upper case: the type's constants
    if isinstance(msg, (list, tuple, np.ndarray)):
        return tuple(fields(item) for item in msg)
    if isinstance(msg, float) and math.isnan(msg):
        return 'nan'
    if isinstance(msg, np.generic):
        return fields(msg.item())
    return msg


def stamp_ns(msg: Any) -> int:
    return message_fields.stamp_ns(msg.header.stamp if hasattr(msg, 'header') else msg.clock)


def diagnostics_without_wall_clock(msg: Any, same_moments: bool) -> Any:
    """A DiagnosticArray's statuses without their wall-clock values. Unless the two runs sent their
    diagnostics at the same simulation times (``same_moments``), what depends on that moment
    (simulation time, status, the residuals of its window) is left out too."""
    left_out = set(WALL_CLOCK_KEYS)
    if not same_moments:
        left_out |= {'simulation time', 'status', 'constraint residual', 'constraint residual max',
                     'constraint residual max after 0.1 s',
                     'normal loads (N)', 'friction use (left front, left rear, right front, right rear)',
                     'slipping wheels'}
    return tuple((status.level, status.name, status.hardware_id, tuple(kv.key for kv in status.values),
                  tuple((kv.key, kv.value) for kv in status.values if kv.key not in left_out))
                 for status in msg.status)
