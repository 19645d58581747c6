"""Streaming rosbag2 writer: MCAP storage, version 9 metadata, definitions and offered QoS embedded.

A thin layer over ``rosbags.rosbag2.Writer`` that adds what a recorder needs:

* bounded memory and bounded loss on a crash: rosbags keeps one pending MCAP chunk in memory
  (closed at 1 MiB); :meth:`BagWriter.write` and :meth:`BagWriter.flush_if_due` also close it and
  flush the file at least every ``flush_period`` seconds, so a SIGKILL loses at most that much
  (``wallbot-sim bag reindex`` then rebuilds the index and metadata from the chunks on disk);
* one-line :class:`BagError` for every way opening can fail (exists, not writable, ...);
* speed: the message records and the chunks (with their message indexes) are written here, the bytes
  rosbags' MCAP writer writes and the counts it keeps, without its Python calls per message
  (test_bag_writer compares the two bags byte for byte; setup.py holds rosbags to that layout's
  0.11 series). rosbags still opens the bag, registers topics and writes the summary and metadata.
"""

from __future__ import annotations

import io
import os
import struct
import time
from collections import defaultdict
from pathlib import Path
from typing import Any, Sequence

from wallbot_msgs_py import bagio, topics
from wallbot_sim.bag.errors import BagError

FLUSH_PERIOD = 0.1
"""Seconds of messages a crash may lose at most (pending chunk + file buffer). Closing a chunk holds the
recorder's thread, which in a process hosting the dynamics shares the GIL with its 1 kHz loop: the longer the
period, the longer each close (0.55 ms of CPU for 0.1 s of the graph on the project's VM)."""


_MESSAGE_RECORD = struct.Struct('<BQHIQQ')
"""An MCAP Message record's opcode, record length, channel id, sequence (0), log and publish time."""
_MESSAGE_OPCODE = 0x05
_MESSAGE_FIELDS_SIZE = 2 + 4 + 8 + 8
_CHUNK_SIZE = 2**20
"""rosbags closes a chunk once its records pass this many bytes."""
_CHUNK_OPCODE, _MESSAGE_INDEX_OPCODE = 0x06, 0x07
_RECORD_HEAD = struct.Struct('<BQ')
_CHUNK_HEAD = struct.Struct('<QQQII')
"""A Chunk record's message start and end time, uncompressed size, CRC (0) and compression name length."""
_INDEX_HEAD = struct.Struct('<HI')
_OFFSET = struct.Struct('<HQ')
_CHUNK_INDEX_HEAD = struct.Struct('<QQQQI')
_UINT32, _UINT64 = struct.Struct('<I'), struct.Struct('<Q')


def _write_record(out: Any, opcode: int, *parts: bytes) -> None:
    """An MCAP record: opcode, body length, body."""
    out.write(_RECORD_HEAD.pack(opcode, sum(map(len, parts))))
    for part in parts:
        out.write(part)


def check_output_dir(path: Path) -> Path:
    """``path`` if a new bag can be created there; an existing empty directory is accepted."""
    path = Path(path)
    if path.exists():
        if not path.is_dir() or any(path.iterdir()):
            raise BagError(f'{path} exists already (a bag is never overwritten): choose a new directory')
        if not os.access(path, os.W_OK | os.X_OK):
            raise BagError(f'cannot write to {path}: permission denied')
        return path
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise BagError(f'cannot create {path}: {parent} is not a directory')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise BagError(f'cannot create {path}: {parent} is not writable')
    return path


class BagWriter:
    """A new rosbag2 bag (MCAP, version 9) at ``path``, written as messages arrive."""

    def __init__(self, path: Path | str, flush_period: float = FLUSH_PERIOD) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.errors import WriterError

        self.path = check_output_dir(Path(path))
        if self.path.exists():
            self.path.rmdir()  # empty: rosbags wants to create it itself
        self.flush_period = flush_period
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        try:
            self._writer.open()
        except (WriterError, OSError) as error:
            raise BagError(f'cannot create bag {self.path}: {error}') from None
        self._connections: dict[str, Any] = {}
        self._channels: dict[int, Any] = {}
        """The connections added here by their ids, which are the MCAP channel ids."""
        self._last_flush = time.monotonic()
        self.count = 0

    # --- topics ----------------------------------------------------------------------------
    def add_topic(self, name: str, msgtype: str, qos: Sequence[Any] | None = None) -> Any:
        """Register ``name`` (absolute) with its type and offered QoS (rosbags ``Qos`` list)."""
        if name in self._connections:
            return self._connections[name]
        store = bagio.typestore()
        if msgtype not in store.fielddefs:
            raise BagError(f'message type {msgtype} of {name} is not a ROS 2 Jazzy type known to rosbags')
        connection = self._writer.add_connection(name, msgtype, typestore=store, serialization_format='cdr',
                                                 offered_qos_profiles=list(qos or ()))
        self._connections[name] = connection
        self._channels[connection.id] = connection
        return connection

    def add_graph_topic(self, topic: topics.Topic, namespace: str = topics.NAMESPACE,
                        qos: Sequence[Any] | None = None) -> Any:
        """Register a topic of the graph with its type and its offered QoS from topics.py."""
        return self.add_topic(topic.resolve(namespace), topic.type, qos or bagio.offered_qos(topic))

    def connection(self, name: str) -> Any | None:
        """The connection of topic ``name`` if registered."""
        return self._connections.get(name)

    def set_custom_data(self, key: str, value: str) -> None:
        """A key/value in the metadata's custom_data."""
        self._writer.set_custom_data(key, str(value))

    # --- messages --------------------------------------------------------------------------
    def write(self, connection: Any, timestamp_ns: int, data: bytes | memoryview) -> None:
        """Append serialized ``data`` (CDR, as received) with its receive time in ns."""
        timestamp_ns = int(timestamp_ns)
        if self._channels.get(connection.id) is connection and self._writer.storage is not None:
            self._append_message(connection.id, timestamp_ns, data)
        else:  # rosbags checks it: an equal connection is written, another or a closed bag raises its error
            self._writer.write(connection, timestamp_ns, data)
        self.count += 1
        self.flush_if_due()

    def _append_message(self, channel: int, timestamp_ns: int, data: bytes | memoryview) -> None:
        """What rosbags' ``Writer.write`` and ``McapWriter.write`` do for a message, the same bytes and the same
        counts, in one step: rosbags builds each record through a dozen Python calls (5.8 us a message against
        2.2 here), and at real-time factor 0 the recorder's writes were most of the Python in the process that
        also steps the dynamics. test_bag_writer compares the two bags byte for byte."""
        writer, storage = self._writer, self._writer.storage
        chunk = storage.chunk
        bio = chunk.bio
        chunk.msgs[channel].append((timestamp_ns, bio.tell()))
        bio.write(_MESSAGE_RECORD.pack(_MESSAGE_OPCODE, _MESSAGE_FIELDS_SIZE + len(data), channel, 0,
                                       timestamp_ns, timestamp_ns))
        bio.write(data)
        storage.channel_stats[channel] += 1
        writer.counts[channel] += 1
        if timestamp_ns < chunk.message_start_time:
            chunk.message_start_time = timestamp_ns
        if timestamp_ns > chunk.message_end_time:
            chunk.message_end_time = timestamp_ns
        if timestamp_ns < storage.message_start_time:
            storage.message_start_time = timestamp_ns
        if timestamp_ns > storage.message_end_time:
            storage.message_end_time = timestamp_ns
        if timestamp_ns < writer.min_timestamp:
            writer.min_timestamp = timestamp_ns
        if timestamp_ns > writer.max_timestamp:
            writer.max_timestamp = timestamp_ns
        if bio.tell() > _CHUNK_SIZE:
            self._close_chunk()

    def _close_chunk(self) -> None:
        """What rosbags' ``McapWriter.close_chunk`` writes and keeps, with each channel's message index packed at
        once: rosbags writes two integers a message through Python calls, 1.0-1.5 ms for a chunk of 0.1 s of the
        graph, in the thread that shares the GIL with the dynamics' loop. Compared byte for byte in test_bag_writer."""
        storage = self._writer.storage
        chunk, out = storage.chunk, storage.bio
        records = chunk.bio.getvalue()
        compressed = storage.compressor(records)
        compression = storage.compression.encode()
        chunk_start = out.tell()
        _write_record(out, _CHUNK_OPCODE, _CHUNK_HEAD.pack(chunk.message_start_time, chunk.message_end_time,
                                                           len(records), 0, len(compression)),
                      compression, _UINT64.pack(len(compressed)), compressed)
        chunk_end = out.tell()
        offsets = []
        for channel, messages in chunk.msgs.items():
            offsets.append(_OFFSET.pack(channel, out.tell()))
            pairs = [value for message in messages for value in message]
            _write_record(out, _MESSAGE_INDEX_OPCODE, _INDEX_HEAD.pack(channel, 8 * len(pairs)),
                          struct.pack(f'<{len(pairs)}Q', *pairs))
        index = io.BytesIO()  # the Chunk Index record's body, which rosbags writes in the summary at the end
        index.write(b''.join((_CHUNK_INDEX_HEAD.pack(chunk.message_start_time, chunk.message_end_time, chunk_start,
                                                     chunk_end - chunk_start, _OFFSET.size * len(offsets)),
                              *offsets, _UINT64.pack(out.tell() - chunk_end), _UINT32.pack(len(compression)),
                              compression, _UINT64.pack(len(compressed)), _UINT64.pack(len(records)))))
        storage.chunks.append(index)
        storage.chunk = type(chunk)(2**63 - 1, 0, io.BytesIO(), defaultdict(list))

    def flush_if_due(self) -> None:
        """Flush if the last flush is older than ``flush_period`` (call it from a timer when idle)."""
        if time.monotonic() - self._last_flush >= self.flush_period:
            self.flush()

    def flush(self) -> None:
        """Close the pending chunk and push the file buffer to the OS (survives a SIGKILL)."""
        storage = self._writer.storage
        self._last_flush = time.monotonic()
        if storage is None:
            return
        if storage.chunk.msgs:  # rosbags' McapWriter: a chunk with messages pending
            self._close_chunk()
        storage.bio.flush()

    def close(self) -> None:
        """Write the MCAP summary and metadata.yaml. Idempotent."""
        if self._writer.storage is not None:
            try:
                self._writer.close()
            except OSError as error:
                raise BagError(f'cannot finish bag {self.path}: {error}') from None

    @property
    def closed(self) -> bool:
        return self._writer.storage is None

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
