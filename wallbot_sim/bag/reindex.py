"""Repair a bag whose recording was killed: ``wallbot-sim bag reindex BAG``.

A killed recorder leaves an MCAP file without summary and footer (maybe cut inside a record) and
no metadata.yaml. The MCAP data section is self-describing: every chunk holds the schema and
channel records before the messages that use them. This module scans the file(s) record by record
(no index needed, stdlib only), keeps every complete chunk, and writes a new bag with full index,
summary and version 9 metadata. What is lost is what never reached the disk: at most the writer's
flush period (0.5 s) plus a chunk cut by the kill.
"""

from __future__ import annotations

import shutil
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Iterator

from wallbot_msgs_py import bagio
from wallbot_sim.bag.errors import BagError, NotABagError

MAGIC = b'\x89MCAP0\r\n'
OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_DATA_END, OP_FOOTER = 0x03, 0x04, 0x05, 0x06, 0x0F, 0x02
UNKNOWN_HASH = 'RIHS01_' + '0' * 64


@dataclass
class ReindexReport:
    """What a repair found."""

    path: Path
    messages: int
    chunks: int
    truncated: bool
    """True if a record at the end was incomplete (the kill cut it)."""
    duration: float
    replaced: tuple[str, ...] = ()
    """The names of the .mcap files rebuilt (removed)."""
    written: tuple[str, ...] = ()
    """The names of the files written in their place (the .mcap and metadata.yaml)."""


class _Cursor:
    def __init__(self, data: bytes | memoryview) -> None:
        self.data, self.pos = memoryview(data), 0

    def u16(self) -> int:
        (v,) = struct.unpack_from('<H', self.data, self.pos)
        self.pos += 2
        return v

    def u32(self) -> int:
        (v,) = struct.unpack_from('<I', self.data, self.pos)
        self.pos += 4
        return v

    def u64(self) -> int:
        (v,) = struct.unpack_from('<Q', self.data, self.pos)
        self.pos += 8
        return v

    def bytes(self, n: int) -> memoryview:
        if self.pos + n > len(self.data):
            raise struct.error('record overruns its data')
        v = self.data[self.pos:self.pos + n]
        self.pos += n
        return v

    def string(self) -> str:
        return bytes(self.bytes(self.u32())).decode('utf-8')

    def string_map(self) -> dict[str, str]:
        end = self.u32() + self.pos
        out = {}
        while self.pos < end:
            key = self.string()
            out[key] = self.string()
        return out


def _records(data: bytes | memoryview) -> Iterator[tuple[int, memoryview]]:
    """(opcode, body) of each complete record in ``data``; stops at a cut record."""
    view, pos = memoryview(data), 0
    while pos + 9 <= len(view):
        opcode = view[pos]
        (length,) = struct.unpack_from('<Q', view, pos + 1)
        if pos + 9 + length > len(view):
            raise EOFError
        yield opcode, view[pos + 9:pos + 9 + length]
        pos += 9 + length
    if pos != len(view):
        raise EOFError


def _decompress(kind: str, data: memoryview, size: int) -> bytes | memoryview:
    if kind == '':
        return data
    if kind == 'zstd':
        try:
            from compression import zstd  # type: ignore[import-not-found]
        except ImportError:
            from backports import zstd  # type: ignore[no-redef]
        return zstd.decompress(bytes(data))
    if kind == 'lz4':
        import lz4.frame
        return lz4.frame.decompress(bytes(data))
    raise BagError(f'MCAP chunk compression {kind!r} is not supported')


class _Scan:
    """Records of one MCAP file, tolerant of a cut end."""

    def __init__(self, stream: BinaryIO, name: str) -> None:
        self.stream, self.name = stream, name
        self.truncated = False
        self.chunks = 0

    def __iter__(self) -> Iterator[tuple[int, memoryview]]:
        if self.stream.read(8) != MAGIC:
            raise NotABagError(f'{self.name} is not an MCAP file (bad magic)')
        while True:
            head = self.stream.read(9)
            if len(head) < 9:
                self.truncated = len(head) > 0
                return
            opcode = head[0]
            (length,) = struct.unpack_from('<Q', head, 1)
            body = self.stream.read(length)
            if len(body) < length:
                self.truncated = True
                return
            if opcode in (OP_DATA_END, OP_FOOTER):
                return
            if opcode == OP_CHUNK:
                cursor = _Cursor(body)
                cursor.u64(), cursor.u64()
                size = cursor.u64()
                cursor.u32()
                kind = cursor.string()
                records = _decompress(kind, cursor.bytes(cursor.u64()), size)
                try:
                    inner = list(_records(records))
                except EOFError:
                    self.truncated = True
                    return
                self.chunks += 1
                yield from inner
            elif opcode in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE):
                yield opcode, memoryview(body)


def mcap_files(directory: Path) -> list[Path]:
    """The bag's MCAP files: as listed in metadata.yaml if readable, else every *.mcap in it."""
    import yaml
    try:
        meta = yaml.safe_load((directory / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        files = [directory / name for name in meta['relative_file_paths']]
        if files and all(f.is_file() and f.suffix == '.mcap' for f in files):
            return files
    except Exception:  # missing or damaged metadata: that's why we are here
        pass
    return sorted(directory.glob('*.mcap'))


class _Copy:
    """MCAP records copied into a bag writer: each message under a connection made from its channel and schema
    records (as they came before it), its log time and bytes unchanged."""

    def __init__(self, writer: object) -> None:
        self.writer = writer
        self.store = bagio.typestore()
        self.schemas: dict[int, tuple[str, str]] = {}
        self.channels: dict[int, tuple[str, str, str, str, str]] = {}
        self.connections: dict[int, object] = {}
        self.first: int | None = None
        self.last: int | None = None

    def record(self, opcode: int, body: memoryview) -> None:
        cursor = _Cursor(body)
        if opcode == OP_SCHEMA:
            sid = cursor.u16()
            name = cursor.string()
            cursor.string()  # the schema's encoding: ros2msg, which the writer always uses
            self.schemas[sid] = (name, bytes(cursor.bytes(cursor.u32())).decode('utf-8'))
        elif opcode == OP_CHANNEL:
            cid, sid = cursor.u16(), cursor.u16()
            topic, encoding = cursor.string(), cursor.string()
            metadata = cursor.string_map()
            msgtype, msgdef = self.schemas.get(sid, ('', ''))
            self.channels[cid] = (topic, msgtype, msgdef, metadata.get('offered_qos_profiles', ''), encoding)
        elif opcode == OP_MESSAGE:
            self._message(cursor)

    def _message(self, cursor: _Cursor) -> None:
        cid = cursor.u16()
        cursor.u32()
        log_time = cursor.u64()
        cursor.u64()
        connection = self._connection(cid)
        if connection is None:
            return  # its channel record was lost with a cut chunk
        self.writer._writer.write(connection, log_time, cursor.data[cursor.pos:])
        self.writer.count += 1
        self.first = log_time if self.first is None else min(self.first, log_time)
        self.last = log_time if self.last is None else max(self.last, log_time)

    def _connection(self, cid: int) -> object | None:
        from rosbags.rosbag2.metadata import parse_qos
        if cid not in self.connections:
            if cid not in self.channels:
                return None
            topic, msgtype, msgdef, qos_text, encoding = self.channels[cid]
            try:
                qos = parse_qos(qos_text) if qos_text else []
            except Exception:
                qos = []
            known = msgtype in self.store.fielddefs
            self.connections[cid] = self.writer._writer.add_connection(
                topic, msgtype, typestore=self.store if known else None, msgdef=None if known else msgdef,
                rihs01=None if known else UNKNOWN_HASH, serialization_format=encoding or 'cdr',
                offered_qos_profiles=qos)
        return self.connections[cid]


def _bag_directory(path: Path | str) -> Path:
    """The bag directory ``path`` is or holds the .mcap of; NotABagError if there is none."""
    directory = Path(path)
    if directory.is_file() and directory.suffix == '.mcap':
        directory = directory.parent
    if not directory.is_dir():
        raise NotABagError(f'{path} does not exist' if not directory.exists() else f'{path} is not a bag directory')
    return directory


def reindex(path: Path | str) -> ReindexReport:
    """Rebuild ``path`` (a bag directory, or its .mcap) in place from its MCAP data; a report."""
    from wallbot_sim.bag.writer import BagWriter

    directory = _bag_directory(path)
    sources = mcap_files(directory)
    if not sources:
        raise NotABagError(f'{directory} holds no .mcap file to reindex')
    work = directory / '.reindex-tmp'
    if work.exists():
        shutil.rmtree(work)
    work.mkdir()
    target = work / directory.name
    truncated, chunks = False, 0
    try:
        writer = BagWriter(target, flush_period=3600.0)
        copy = _Copy(writer)
        for source in sources:
            with open(source, 'rb') as stream:
                scan = _Scan(stream, str(source))
                for opcode, body in scan:
                    copy.record(opcode, body)
                truncated = truncated or scan.truncated
                chunks += scan.chunks
        writer.set_custom_data('wallbot.reindexed', 'true' + (' (truncated input)' if truncated else ''))
        writer.close()
        for source in sources:
            source.unlink()
        (directory / 'metadata.yaml').unlink(missing_ok=True)
        written = tuple(sorted(produced.name for produced in target.iterdir()))
        for name in written:
            (target / name).replace(directory / name)
    except BagError:
        raise
    except (OSError, struct.error, UnicodeDecodeError, ValueError) as error:
        raise BagError(f'cannot reindex {directory}: {type(error).__name__}: {error}') from None
    finally:
        shutil.rmtree(work, ignore_errors=True)
    duration = (copy.last - copy.first) * 1e-9 if copy.first is not None else 0.0
    return ReindexReport(directory, writer.count, chunks, truncated, duration, tuple(source.name for source in sources),
                         written)


def repair_unclosed(bag: Path) -> str:
    """Rebuild the index and metadata.yaml of a bag its recorder could not close (it was killed, or the dynamics in
    its process was); what was done, to append to a run's error ('' if the bag was closed, or holds no MCAP file)."""
    if (bag / 'metadata.yaml').is_file() or not any(bag.glob('*.mcap')):
        return ''
    try:
        repaired = reindex(bag)
    except BagError as error:
        return f' (its recorder did not close it, and reindexing failed: {error})'
    return f' (its recorder did not close it; reindexed: {repaired.messages} messages, {repaired.duration:.3f} s)'
