"""``wallbot-sim info BAG``: duration, topics with types and counts, message rates, storage, size."""

from __future__ import annotations

import argparse
from datetime import datetime, timezone

HELP = 'show what a recorded bag holds: duration, topics, types, counts, rates, storage, size'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('bag', metavar='BAG', help='rosbag2 bag directory')


def _size(n: int) -> str:
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if n < 1024 or unit == 'GiB':
            return f'{n:.1f} {unit}' if unit != 'B' else f'{n} B'
        n /= 1024
    return f'{n} B'


def _rate(count: int, span: tuple[int, int] | None) -> str:
    """Messages per second of receive time over the topic's own first-to-last span."""
    if span is None or count < 2 or span[1] <= span[0]:
        return '        - Hz'
    return f'{(count - 1) / ((span[1] - span[0]) * 1e-9):9.1f} Hz'


def format_info(bag, spans: dict[str, tuple[int, int]]) -> str:
    """The text ``info`` prints for a BagInfo and the topics' spans (``reader.topic_spans``)."""
    start = datetime.fromtimestamp(bag.start_ns * 1e-9, tz=timezone.utc).isoformat(timespec='milliseconds')
    lines = [f'Bag:       {bag.path}',
             f'Storage:   {bag.storage} (rosbag2 metadata version {bag.version}), files: {", ".join(bag.files)}',
             f'Size:      {_size(bag.size_bytes)}',
             f'Duration:  {bag.duration:.3f} s',
             f'Start:     {start} ({bag.start_ns // 10**9}.{bag.start_ns % 10**9:09d} s)',
             f'Messages:  {bag.message_count}',
             'Topics:']
    width = max((len(t.name) for t in bag.topics), default=0)
    twidth = max((len(t.type) for t in bag.topics), default=0)
    for topic in bag.topics:
        rate = _rate(topic.count, spans.get(topic.name))
        qos = topic.offered_qos[0] if topic.offered_qos else None
        qos_text = (f'{qos.reliability.name.lower()}, {qos.durability.name.lower()}, depth {qos.depth}'
                    if qos is not None else 'no offered QoS')
        lines.append(f'  {topic.name:<{width}}  {topic.type:<{twidth}}  {topic.count:8d} msgs  {rate}  [{qos_text}]')
    return '\n'.join(lines)


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.bag.reader import info, topic_spans
    print(format_info(info(args.bag), topic_spans(args.bag)))
    return 0
