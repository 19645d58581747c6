"""rosgraph_msgs/Clock: a robot's ``clock``, the domain's ``/clock`` and a recorder's ``record_progress``."""

from __future__ import annotations

import struct

import numpy as np

from wallbot_msgs_py import cdr

TYPE = 'rosgraph_msgs/msg/Clock'
_STAMP = struct.Struct('<iI')


@cdr.encoder('clock', TYPE)
class ClockEncoder:
    """Clock bytes: a template whose stamp is overwritten."""

    def __init__(self) -> None:
        clock = cdr.Writer()
        self._stamp = clock.time(0)
        self.template = clock.bytes()
        self._buffer = bytearray(self.template)
        self._rows = cdr.Rows(self.template, cdr.stamped(self._stamp))

    def encode(self, sec: int, nanosec: int) -> bytes:
        data = self._buffer
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray) -> list[bytes]:
        return self._rows.fill(len(sec), sec=sec, nanosec=nanosec)


@cdr.decoder('clock', TYPE)
def decode_clock(message: cdr.Reader) -> int:
    """The time (ns) a serialized Clock carries."""
    return message.time_ns()
