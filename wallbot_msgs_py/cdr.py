"""The one CDR writer and reader of the interface, and the registry of its message codecs.

Every message of the graph is written by :class:`Writer` and read by :class:`Reader`: XCDR1 (the
encoding rmw_fastrtps and rosbags use), a 4-byte encapsulation header, then each field aligned to
its own size counted from the end of that header. The writer writes little endian (what
rmw_fastrtps writes); the reader reads either byte order.

Each message family (``codec``: odometry, joint states, the plan, diagnostics, ...) registers its
one encoder and its one decoder here with :func:`encoder` and :func:`decoder`; registering a
second one for a family is an error at import, so a family cannot be encoded or decoded two ways
(test_codec_registry.py also checks that nothing outside the codec builds or reads CDR).
"""

from __future__ import annotations

import functools
import struct
from dataclasses import dataclass
from typing import Any, Callable, Sequence, TypeVar

import numpy as np

ENCAPSULATION = b'\x00\x01\x00\x00'
"""CDR, little endian."""
NS_PER_S = 1_000_000_000

_LITTLE = {code: struct.Struct('<' + code) for code in ('I', 'i', 'iI', '2d')}
_BIG = {code: struct.Struct('>' + code) for code in ('I', 'i', 'iI', '2d')}
_STAMP = _LITTLE['iI']


def to_nanoseconds(t: float) -> int:
    """Simulation time (s) as integer nanoseconds (rounded: k * 1 ms stamps come out exact)."""
    return round(t * 1e9)


def split_stamp(stamp_ns: int) -> tuple[int, int]:
    """(sec, nanosec) of a builtin_interfaces/Time of ``stamp_ns``."""
    return divmod(int(stamp_ns), NS_PER_S)


def leading_stamp_ns(data: bytes) -> int | None:
    """The time (ns) a serialized message starts with, read without decoding it: a
    rosgraph_msgs/Clock, or any message whose first field is a std_msgs/Header; None if too short."""
    if len(data) < 12:
        return None
    sec, nanosec = (_LITTLE if data[1] & 1 else _BIG)['iI'].unpack_from(data, 4)
    return sec * NS_PER_S + nanosec


class Writer:
    """A message written field by field, in order. The methods that write numbers return the
    offset of the first, so a template's numbers can be overwritten in place later."""

    def __init__(self) -> None:
        self.data = bytearray(ENCAPSULATION)

    def align(self, size: int) -> None:
        self.data += bytes(-(len(self.data) - len(ENCAPSULATION)) % size)

    def uint32(self, value: int) -> int:
        self.align(4)
        offset = len(self.data)
        self.data += _LITTLE['I'].pack(value)
        return offset

    def int32(self, value: int) -> int:
        self.align(4)
        offset = len(self.data)
        self.data += _LITTLE['i'].pack(value)
        return offset

    def octet(self, value: int) -> None:
        self.data.append(value)

    def time(self, stamp_ns: int = 0) -> int:
        """builtin_interfaces/Time (or Duration): int32 sec, uint32 nanosec."""
        self.align(4)
        offset = len(self.data)
        self.data += _STAMP.pack(*split_stamp(stamp_ns))
        return offset

    def string(self, text: str) -> None:
        encoded = text.encode()
        self.uint32(len(encoded) + 1)
        self.data += encoded + b'\x00'

    def strings(self, texts: Sequence[str]) -> None:
        self.uint32(len(texts))
        for text in texts:
            self.string(text)

    def float64s(self, values: Sequence[float]) -> int:
        """A fixed number of float64 fields (an array, or consecutive fields)."""
        if len(values):
            self.align(8)
        offset = len(self.data)
        self.data += struct.pack(f'<{len(values)}d', *values)
        return offset

    def float64_sequence(self, values: Sequence[float]) -> int:
        self.uint32(len(values))
        return self.float64s(values)

    def float64_block(self, values: np.ndarray) -> None:
        """An array of float64 (any shape, row-major) written at once, without its length."""
        if values.size:
            self.align(8)
            self.data += np.ascontiguousarray(values, dtype='<f8').tobytes()

    def header(self, stamp_ns: int, frame: str) -> int:
        """std_msgs/Header; the offset of its stamp."""
        offset = self.time(stamp_ns)
        self.string(frame)
        return offset

    def float64_multiarray(self, dims: Sequence[tuple[str, int, int]], values: Sequence[float]) -> None:
        """std_msgs/Float64MultiArray: layout dims (label, size, stride), data_offset 0, data."""
        self.uint32(len(dims))
        for label, size, stride in dims:
            self.string(label)
            self.uint32(size)
            self.uint32(stride)
        self.uint32(0)
        self.float64_sequence(values)

    def bytes(self) -> bytes:
        return bytes(self.data)


class Malformed(ValueError):
    """Bytes that are not the CDR of the message being read."""


class Reader:
    """Fields read in order from CDR bytes of either byte order. Reading past the end raises
    Malformed, struct.error or IndexError, which a registered decoder turns into one ValueError."""

    __slots__ = ('data', 'offset', '_little', '_uint32')

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[0] != 0 or data[1] > 1:
            raise Malformed('not CDR (bad encapsulation header)')
        self.data, self.offset, self._little = data, 4, data[1] == 1
        self._uint32 = (_LITTLE if self._little else _BIG)['I'].unpack_from

    def align(self, size: int) -> None:
        self.offset += -(self.offset - 4) % size

    def unpacker(self, code: str) -> Callable[[bytes, int], tuple]:
        """``struct`` ``unpack_from`` of ``code`` (one of 'I', 'i', 'iI', '2d') in the bytes' order, for
        a decoder whose loop over many elements reads ``data`` at offsets it aligns itself."""
        return (_LITTLE if self._little else _BIG)[code].unpack_from

    def uint32(self) -> int:
        offset = self.offset + (-(self.offset - 4) % 4)
        self.offset = offset + 4
        return self._uint32(self.data, offset)[0]

    def octet(self) -> int:
        value = self.data[self.offset]
        self.offset += 1
        return value

    def time_ns(self) -> int:
        """builtin_interfaces/Time (or Duration) as integer nanoseconds."""
        offset = self.offset + (-(self.offset - 4) % 4)
        sec, nanosec = (_LITTLE if self._little else _BIG)['iI'].unpack_from(self.data, offset)
        self.offset = offset + 8
        return sec * NS_PER_S + nanosec

    def string(self) -> str:
        data, offset = self.data, self.offset + (-(self.offset - 4) % 4)
        size = self._uint32(data, offset)[0]
        start = offset + 4
        end = start + size
        if size == 0 or end > len(data):
            raise Malformed(f'a string of {size} bytes at offset {offset}')
        self.offset = end
        return data[start:end - 1].decode()

    def strings(self) -> tuple[str, ...]:
        """A string sequence. A message type's names (joint names, say) are mostly the same bytes every
        time: those seen before are not decoded again."""
        self.align(4)
        start = self.offset
        count = self.uint32()
        data, offset, uint32 = self.data, self.offset, self._uint32
        for _ in range(count):
            offset += -(offset - 4) % 4 + 4 + uint32(data, offset + (-(offset - 4) % 4))[0]
        key = data[start:offset]
        texts = _STRINGS.get(key)
        if texts is None:
            string = self.string
            texts = tuple([string() for _ in range(count)])
            if len(_STRINGS) >= 256:
                _STRINGS.clear()
            _STRINGS[key] = texts
        self.offset = offset
        return texts

    def float64s(self, count: int) -> tuple[float, ...]:
        if not count:
            return ()
        offset = self.offset + (-(self.offset - 4) % 8)
        self.offset = offset + 8 * count
        structs = _FLOAT64S_LITTLE if self._little else _FLOAT64S_BIG
        unpack = structs.get(count)
        if unpack is None:
            unpack = structs[count] = struct.Struct(('<' if self._little else '>') + f'{count}d').unpack_from
        return unpack(self.data, offset)

    def float64_sequence(self) -> tuple[float, ...]:
        return self.float64s(self.uint32())

    def skip_float64s(self, count: int) -> None:
        if count:
            self.offset += -(self.offset - 4) % 8 + 8 * count

    def header(self) -> tuple[int, str]:
        """std_msgs/Header: (stamp ns, frame)."""
        return self.time_ns(), self.string()

    def float64_multiarray(self) -> tuple[list[tuple[str, int, int]], tuple[float, ...]]:
        """std_msgs/Float64MultiArray: its layout dims (label, size, stride) and data."""
        dims = [(self.string(), self.uint32(), self.uint32()) for _ in range(self.uint32())]
        self.uint32()  # data_offset
        return dims, self.float64_sequence()


_STRINGS: dict[bytes, tuple[str, ...]] = {}
"""String sequences read, by their bytes (count, lengths and text, from a 4-aligned start)."""
_FLOAT64S_LITTLE: dict[int, Any] = {}
_FLOAT64S_BIG: dict[int, Any] = {}
"""``unpack_from`` of so many float64, by count."""


class Rows:
    """The messages of many steps from one template at once: a structured view of copies of its bytes,
    one field per number that changes (``fields``: name -> (offset, numpy format))."""

    def __init__(self, template: bytes | bytearray, fields: dict[str, tuple[int, Any]]) -> None:
        self._template = np.frombuffer(bytes(template), dtype=np.uint8)
        self._dtype = np.dtype({'names': list(fields), 'formats': [form for _offset, form in fields.values()],
                                'offsets': [offset for offset, _form in fields.values()], 'itemsize': len(template)})

    def fill(self, count: int, **values: Any) -> list[bytes]:
        """``count`` messages, field ``name`` of message k ``values[name][k]``."""
        raw = np.tile(self._template, count)
        rows = raw.view(self._dtype)
        for name, value in values.items():
            rows[name] = value
        data, size = raw.tobytes(), len(self._template)
        return [data[start:start + size] for start in range(0, count * size, size)]


def stamped(stamp_offset: int, **fields: tuple[int, Any]) -> dict[str, tuple[int, Any]]:
    """``Rows`` fields of a message with a stamp at ``stamp_offset`` (sec, nanosec) and ``fields``."""
    return {'sec': (stamp_offset, '<i4'), 'nanosec': (stamp_offset + 4, '<u4'), **fields}


def doubles(count: int) -> tuple[str, tuple[int]]:
    """The numpy format of ``count`` consecutive float64 fields."""
    return ('<f8', (count,))


# --- the registry of codecs -----------------------------------------------------------------------
@dataclass
class Family:
    """A message family: the ROS type of its messages, its one encoder and its one decoder."""

    name: str
    type: str
    encoder: Any = None
    decoder: Any = None


FAMILIES: dict[str, Family] = {}
"""Every registered family by name."""


class CodecConflict(RuntimeError):
    """A second encoder or decoder for a family, or a family registered under two types."""


def _register(family: str, msgtype: str, role: str, implementation: Any) -> None:
    entry = FAMILIES.setdefault(family, Family(family, msgtype))
    if entry.type != msgtype:
        raise CodecConflict(f'family {family} is {entry.type}, not {msgtype}')
    existing = getattr(entry, role)
    if existing is not None:
        raise CodecConflict(f'family {family} has a {role} already: {existing.__module__}.{existing.__qualname__}')
    setattr(entry, role, implementation)


Implementation = TypeVar('Implementation')


def encoder(family: str, msgtype: str) -> Callable[[Implementation], Implementation]:
    """Register the decorated function (bytes out) or template class as ``family``'s encoder."""
    def register(implementation: Implementation) -> Implementation:
        _register(family, msgtype, 'encoder', implementation)
        return implementation
    return register


def decoder(family: str, msgtype: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Register the decorated function as ``family``'s decoder. It is called with a Reader at the
    first field; bytes that end early or are not CDR become a ValueError naming the family."""
    def register(read: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(read)
        def decode(data: bytes, *args: Any) -> Any:
            try:
                return read(Reader(data), *args)
            except (Malformed, struct.error, IndexError, UnicodeDecodeError):
                raise ValueError(f'malformed {family} ({len(data)} bytes)') from None
        _register(family, msgtype, 'decoder', decode)
        return decode
    return register
