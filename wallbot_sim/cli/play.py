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
    from wallbot_sim.bag.reader import info, messages, resolve_topics

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

    from wallbot_sim.nodes.recorder import message_class

    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = rclpy.create_node('player', namespace=graph.NAMESPACE, start_parameter_services=False)
        publishers = {}
        for name in names:
            topic = bag.topic(name)
            try:
                publishers[name] = node.create_publisher(message_class(topic.type), name,
                                                         publisher_qos(topic.offered_qos, name))
            except (ImportError, AttributeError, ValueError):
                raise CliError(f'{name}: message type {topic.type} is not installed') from None
        clock_pubs = []
        if args.clock:
            from rclpy.qos import QoSProfile
            clock_pubs = [node.create_publisher(message_class(clock.type), clock.name, QoSProfile(depth=clock.depth))
                          for clock in (graph.CLOCK, graph.DOMAIN_CLOCK)]
            clock_encoder = codec.ClockEncoder()
        deadline = time.monotonic() + args.wait_subscribers
        while args.wait_subscribers and time.monotonic() < deadline and \
                not all(p.get_subscription_count() > 0 for p in publishers.values()):
            time.sleep(0.05)
        if args.wait_subscribers and not all(p.get_subscription_count() > 0 for p in publishers.values()):
            missing = [n for n, p in publishers.items() if p.get_subscription_count() == 0]
            raise CliError(f'no subscriber on {", ".join(missing)} after {args.wait_subscribers:g} s')
        time.sleep(args.delay)
        total = 0
        sent = {name: 0 for name in names}
        windows = {name: max(1, publishers[name].qos_profile.depth // 2) for name in names}
        while True:
            wall0, bag0, last_clock = time.monotonic(), None, -math.inf
            for raw in messages(bag.path, names):
                if bag0 is None:
                    bag0 = raw.timestamp
                due = wall0 + (raw.timestamp - bag0) * 1e-9 / args.rate
                delay = due - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                if clock_pubs and time.monotonic() - last_clock >= 1.0 / args.clock_rate:
                    clock = clock_encoder.encode(*cdr.split_stamp(raw.timestamp))
                    for clock_pub in clock_pubs:
                        clock_pub.publish(clock)
                    last_clock = time.monotonic()
                publisher = publishers[raw.topic]
                publisher.publish(raw.data)
                total += 1
                sent[raw.topic] += 1
                if sent[raw.topic] % windows[raw.topic] == 0:  # back-pressure: never overrun a reader
                    wait_acked(publisher, 1.0)
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
