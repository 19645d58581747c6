"""``wallbot-sim play BAG [--rate R] [--loop] [--topics ...] [--clock]``: republish a recorded run.

The stored CDR bytes are published as they are (rclpy publishers accept serialized bytes), at the
recorded receive times scaled by ``--rate``, with each topic's QoS taken from the bag's offered
QoS (reliability, durability; depth from the bag, or the interface layer when not recorded).
Every half history depth a topic's publisher waits until its readers have acknowledged, so a
replay faster than a subscriber can take is slowed down instead of losing messages.
``--clock`` publishes the bag's time (at most ``--clock-rate`` Hz) on the domain's /clock and on
the robot's clock (/wallbot/clock), so ROS tools and this project's nodes with ``use_sim_time``
follow the replay.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from wallbot_msgs_py import cdr, codec
from wallbot_msgs_py import topics as graph
from wallbot_sim.cli.errors import CliError
from wallbot_sim.cli.options import number
from wallbot_sim.model.numbers import NON_NEGATIVE, POSITIVE

HELP = 'publish a recorded bag again with its recorded timing (serialized bytes as stored)'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('bag', metavar='BAG', help='rosbag2 bag directory')
    parser.add_argument('--rate', type=number(POSITIVE), default=1.0, help='playback speed factor (> 0, default 1)')
    parser.add_argument('--loop', action='store_true', help='start again at the end, until interrupted')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', help='only these topics (default: all)')
    parser.add_argument('--clock', action='store_true', help='publish /clock with the bag time')
    parser.add_argument('--clock-rate', type=number(POSITIVE), default=100.0, help='/clock rate in Hz (default 100)')
    parser.add_argument('--delay', type=number(NON_NEGATIVE), default=1.0,
                        help='seconds to wait after creating the publishers, for discovery (default 1)')
    parser.add_argument('--wait-subscribers', type=number(NON_NEGATIVE), default=0.0, metavar='S',
                        help='wait up to S seconds until every played topic has a subscriber (default: don\'t)')
    parser.add_argument('--quiet', action='store_true', help='no progress line')


def publisher_qos(offered: tuple[Any, ...], topic_name: str) -> Any:
    """rclpy QoS for republishing: the recorded offer (reliability, durability, depth)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    try:
        fallback = graph.by_name(topic_name)
    except KeyError:
        fallback = None
    depth = fallback.depth if fallback is not None else 1000
    reliability, durability = ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE
    if fallback is not None and fallback.durability is graph.Durability.TRANSIENT_LOCAL:
        durability = DurabilityPolicy.TRANSIENT_LOCAL
    if offered:
        qos = offered[0]
        if qos.reliability.name == 'BEST_EFFORT':
            reliability = ReliabilityPolicy.BEST_EFFORT
        if qos.durability.name == 'TRANSIENT_LOCAL':
            durability = DurabilityPolicy.TRANSIENT_LOCAL
        elif qos.durability.name == 'VOLATILE':
            durability = DurabilityPolicy.VOLATILE
        if qos.history.name == 'KEEP_LAST' and qos.depth > 0:
            depth = qos.depth
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability, durability=durability)


ACK_SLICE = 0.05
"""Seconds of one wait for acknowledgements: a signal is handled between two (not during one)."""


def wait_acked(publisher: Any, seconds: float) -> bool:
    """Whether every reader of ``publisher`` acknowledged within ``seconds``."""
    from rclpy.duration import Duration
    deadline = time.monotonic() + seconds
    while not publisher.wait_for_all_acked(Duration(seconds=ACK_SLICE)):
        if time.monotonic() >= deadline:
            return False
    return True


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.bag.reader import info, resolve_topics

    bag = info(args.bag)
    names = resolve_topics(bag, args.topics)
    if args.clock:
        # the clock comes from the replay itself (a robot's clock, or a bag's /clock)
        names = [n for n in names if n.rsplit('/', 1)[-1] != graph.CLOCK.name]
    if not names:
        raise CliError(f'{args.bag}: nothing to play')

    from wallbot_sim.heartbeat import FLOW_CONTROL_HEARTBEAT, install_heartbeat
    install_heartbeat(FLOW_CONTROL_HEARTBEAT)  # each wait_for_all_acked: ~5 ms, not up to a 3 s heartbeat

    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = rclpy.create_node('player', namespace=graph.NAMESPACE, start_parameter_services=False)
        publishers = create_publishers(node, bag, names)
        clock = BagClock(node, args.clock_rate) if args.clock else None
        wait_for_subscribers(publishers, args.wait_subscribers)
        time.sleep(args.delay)
        total = 0
        while True:
            total += replay(bag.path, publishers, clock, args.rate)
            if not args.loop:
                break
        for publisher in publishers.values():
            wait_acked(publisher, 2.0)
        if not args.quiet:
            print(f'played {total} messages on {len(publishers)} topics from {bag.path}', file=sys.stderr)
        return 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def create_publishers(node: Any, bag: Any, names: list[str]) -> dict[str, Any]:
    """A publisher of each bag topic in ``names``, with its recorded QoS; CliError for a type not installed."""
    from wallbot_sim.nodes.recorder import message_class
    publishers = {}
    for name in names:
        topic = bag.topic(name)
        try:
            publishers[name] = node.create_publisher(message_class(topic.type), name,
                                                     publisher_qos(topic.offered_qos, name))
        except (ImportError, AttributeError, ValueError):
            raise CliError(f'{name}: message type {topic.type} is not installed') from None
    return publishers


def wait_for_subscribers(publishers: dict[str, Any], seconds: float) -> None:
    """Wait up to ``seconds`` until every publisher has a subscriber; CliError naming those without one."""
    deadline = time.monotonic() + seconds
    while seconds and time.monotonic() < deadline and not all(p.get_subscription_count() > 0
                                                              for p in publishers.values()):
        time.sleep(0.05)
    missing = [name for name, publisher in publishers.items() if publisher.get_subscription_count() == 0]
    if seconds and missing:
        raise CliError(f'no subscriber on {", ".join(missing)} after {seconds:g} s')


class BagClock:
    """The bag's time on the robot's clock and the domain's /clock, at most ``rate_hz`` messages a wall second."""

    def __init__(self, node: Any, rate_hz: float) -> None:
        from rclpy.qos import QoSProfile

        from wallbot_sim.nodes.recorder import message_class
        self.publishers = [node.create_publisher(message_class(clock.type), clock.name, QoSProfile(depth=clock.depth))
                           for clock in (graph.CLOCK, graph.DOMAIN_CLOCK)]
        self.period, self.sent = 1.0 / rate_hz, -math.inf
        self.encoder = codec.ClockEncoder()

    def at(self, stamp_ns: int) -> None:
        """The bag is at ``stamp_ns``: published if the period since the last one is up."""
        if time.monotonic() - self.sent >= self.period:
            message = self.encoder.encode(*cdr.split_stamp(stamp_ns))
            for publisher in self.publishers:
                publisher.publish(message)
            self.sent = time.monotonic()


def replay(path: Any, publishers: dict[str, Any], clock: BagClock | None, rate: float) -> int:
    """Publish the bag's messages on ``publishers`` at their recorded times divided by ``rate``; how many.
    Every half history depth a topic's publisher waits for its readers (back-pressure: never overrun one)."""
    from wallbot_sim.bag.reader import messages
    sent = dict.fromkeys(publishers, 0)
    windows = {name: max(1, publisher.qos_profile.depth // 2) for name, publisher in publishers.items()}
    wall0, bag0 = time.monotonic(), None
    for raw in messages(path, list(publishers)):
        if bag0 is None:
            bag0 = raw.timestamp
        delay = wall0 + (raw.timestamp - bag0) * 1e-9 / rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        if clock is not None:
            clock.at(raw.timestamp)
        publisher = publishers[raw.topic]
        publisher.publish(raw.data)
        sent[raw.topic] += 1
        if sent[raw.topic] % windows[raw.topic] == 0:
            wait_acked(publisher, 1.0)
    return sum(sent.values())
