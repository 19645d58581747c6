"""Reading wallbot bags (rosbag2, MCAP or SQLite): what is in it, and its messages in time order.

Every failure is a :class:`BagError` with a one-line message naming the path.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

from wallbot_sim.bag.errors import BagError, NotABagError, UnknownTopicError


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag."""

    name: str
    type: str
    count: int
    offered_qos: tuple[Any, ...]
    """rosbags ``Qos`` profiles the publishers offered (as recorded)."""


@dataclass(frozen=True)
class BagInfo:
    """What ``wallbot-sim info`` shows."""

    path: Path
    storage: str
    version: int
    start_ns: int
    duration_ns: int
    message_count: int
    size_bytes: int
    topics: tuple[TopicInfo, ...]
    files: tuple[str, ...]

    @property
    def duration(self) -> float:
        """Seconds between the first and last message."""
        return self.duration_ns * 1e-9

    def topic(self, name: str) -> TopicInfo:
        for topic in self.topics:
            if topic.name == name:
                return topic
        raise UnknownTopicError(f'topic {name} is not in {self.path} (it has: {", ".join(t.name for t in self.topics)})')


def bag_directory(path: Path | str) -> Path:
    """The bag directory of ``path`` (a bag directory or a file inside one), or NotABagError."""
    path = Path(path)
    if not path.exists():
        raise NotABagError(f'{path} does not exist')
    if path.is_file():
        if path.suffix in ('.mcap', '.db3') or path.name == 'metadata.yaml':
            path = path.parent
        else:
            raise NotABagError(f'{path} is not a rosbag2 bag (expected a bag directory)')
    if not (path / 'metadata.yaml').is_file():
        if list(path.glob('*.mcap')):
            raise NotABagError(f'{path} has no metadata.yaml (recording killed?): repair it with '
                               f'`wallbot-sim bag reindex {path}`')
        raise NotABagError(f'{path} is not a rosbag2 bag (no metadata.yaml)')
    return path


def read_metadata(directory: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag's metadata.yaml."""
    import yaml
    try:
        data = yaml.safe_load((Path(directory) / 'metadata.yaml').read_text(encoding='utf-8'))
        return dict(data['rosbag2_bagfile_information'])
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError) as error:
        raise BagError(f'{directory}/metadata.yaml is not rosbag2 metadata ({type(error).__name__}): try '
                       f'`wallbot-sim bag reindex {directory}`') from None


def _open_reader(path: Path | str) -> Any:
    from rosbags.rosbag2 import Reader
    from rosbags.rosbag2.errors import ReaderError

    directory = bag_directory(path)
    read_metadata(directory)
    reader = Reader(directory)
    try:
        reader.open()
    except ReaderError as error:
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise BagError(f'cannot read bag {directory}: {first} (if recording was killed, try '
                       f'`wallbot-sim bag reindex {directory}`)') from None
    except Exception as error:  # malformed YAML/MCAP surfaces as assorted exceptions
        raise BagError(f'cannot read bag {directory}: {type(error).__name__}: {error}') from None
    return reader


def info(path: Path | str) -> BagInfo:
    """Duration, topics with types, counts and QoS, storage and size of the bag at ``path``."""
    reader = _open_reader(path)
    try:
        topics = []
        for name, topic in reader.topics.items():
            qos: list[Any] = []
            for connection in topic.connections:
                qos.extend(getattr(connection.ext, 'offered_qos_profiles', ()) or ())
            topics.append(TopicInfo(name, topic.msgtype or '', topic.msgcount, tuple(qos)))
        directory = bag_directory(path)
        meta = read_metadata(directory)
        size = sum(f.stat().st_size for f in directory.iterdir() if f.is_file())
        count = reader.message_count
        return BagInfo(directory, str(meta.get('storage_identifier', '?')), int(meta.get('version', 0)),
                       reader.start_time if count else 0,
                       max(reader.duration - 1, 0) if count else 0, count, size,
                       tuple(topics), tuple(meta.get('relative_file_paths') or ()))
    finally:
        reader.close()


def topic_spans(path: Path | str) -> dict[str, tuple[int, int]]:
    """Receive time (ns) of the first and the last message of every topic that has one.

    A topic's rate is its count over its own span: a latched topic or one that started late
    says nothing about the rate of the others.
    """
    spans: dict[str, tuple[int, int]] = {}
    for message in messages(path):
        first, last = spans.get(message.topic, (message.timestamp, message.timestamp))
        spans[message.topic] = (min(first, message.timestamp), max(last, message.timestamp))
    return spans


@dataclass(frozen=True)
class RawMessage:
    """One recorded message: topic, type, receive time (ns) and CDR bytes as stored."""

    topic: str
    type: str
    timestamp: int
    data: bytes


def resolve_topics(bag: BagInfo, wanted: Sequence[str] | None) -> list[str]:
    """Bag topic names for ``wanted`` (exact, or a relative name like ``odom``); UnknownTopicError."""
    if not wanted:
        return [t.name for t in bag.topics]
    names = []
    for want in wanted:
        matches = [t.name for t in bag.topics if t.name == want]
        if not matches:
            matches = [t.name for t in bag.topics if t.name.rsplit('/', 1)[-1] == want.strip('/').rsplit('/', 1)[-1]]
        if not matches:
            raise UnknownTopicError(f'topic {want} is not in {bag.path} '
                                    f'(it has: {", ".join(t.name for t in bag.topics)})')
        names.extend(m for m in matches if m not in names)
    return names


def messages(path: Path | str, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
    """The bag's messages on ``topics`` (exact bag names; all if None) in receive-time order."""
    reader = _open_reader(path)
    try:
        wanted = set(topics) if topics is not None else None
        connections = [c for c in reader.connections if wanted is None or c.topic in wanted]
        if not connections:
            return
        try:
            for connection, timestamp, data in reader.messages(connections=connections):
                yield RawMessage(connection.topic, connection.msgtype, timestamp, bytes(data))
        except BagError:
            raise
        except Exception as error:
            raise BagError(f'cannot read messages of {reader.path}: {type(error).__name__}: {error}') from None
    finally:
        reader.close()
