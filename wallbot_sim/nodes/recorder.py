"""``recorder_node`` (node ``/wallbot/recorder``): the graph's topics into a rosbag2 MCAP bag.

Parameters (read-only, ``ros2 param get /wallbot/recorder output`` shows them)
  output (string, required): bag directory to create (must not exist, or be empty).
  topics (string[], default: topics.RECORDED): topic names, relative ones resolve in the namespace.

Design (see docs/bags.md):
* raw subscriptions: the CDR bytes are written as they came, never decoded on the hot path;
* every subscription is RELIABLE with KEEP_ALL history (depth from topics.py as the resource hint),
  transient-local topics are subscribed transient-local so their latched sample is recorded;
* record_progress (rosgraph_msgs/Clock): the newest stamp up to which /clock and every per-step
  topic (topics.STEP_STAMPED) have been written, whenever it has advanced PROGRESS_STEP_NS and
  from a 50 ms timer; at every real-time factor the dynamics node stays within its
  backpressure_window of it, which is what makes recording lossless (KEEP_ALL alone is not);
* the offered QoS recorded for a topic is the publishers' (from the graph) when its first message
  arrives, else the profile of topics.py;
* the dynamics' keeper: it holds the newest ``state_snapshot`` not past the steps it received
  (``SnapshotKeeper``) and republishes it (transient-local,
  every KEEP_PERIOD when it changed) on ``resume_state``, with the newest step stamp it received as
  ``seen_until``, so a dynamics restarted after a SIGKILL continues where the bag ends
  (``wallbot_msgs_py.snapshot``);
* SIGINT/SIGTERM (handled however the process was started, see ``common.StopSignals``): the
  moment the signal is handled is the end of the recording. The message whose callback the
  handler ran in front of was received before it and is written; what DDS had received before it
  and the executor had not taken yet is taken directly from the subscriptions with its DDS receive
  time and written with that time, and everything received later is left unwritten. Then the bag
  is closed (metadata.yaml with ``wallbot.recorder.stop_signal`` and ``wallbot.recorder.stop_time_ns``,
  MCAP summary) and the node exits 0, within a second whatever the rest of the graph still publishes. The writer
  flushes a closed chunk at least every 0.5 s, so after a SIGKILL ``wallbot-sim bag reindex``
  recovers all but the last half second;
* composed with the dynamics in one process (``nodes.dynamics_recorder``): the dynamics' per-step
  topics come from an in-process tap (``nodes.step_tap``) instead of DDS subscriptions, the same
  CDR bytes logged when the dynamics sent them; the tap is drained every TAP_PERIOD, before any
  message received over DDS is written and at the stop, where steps logged after the signal are
  left unwritten like late DDS messages. There is no keeper: it would die with the dynamics.
"""

from __future__ import annotations

import importlib
import time
from pathlib import Path
from typing import Any, Sequence

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from wallbot_msgs_py import bagio, cdr, codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_msgs_py.snapshot import SnapshotKeeper, decode_snapshot
from wallbot_sim.bag.writer import FLUSH_PERIOD
from wallbot_sim.nodes.common import ROBOT_CLOCK_ARGS
from wallbot_sim.nodes.parameters import declare_typed
from wallbot_sim.nodes.step_tap import StepTap
from wallbot_sim.settings.config import RECORDER, RecorderSettings

NODE_NAME = topics.NODE_RECORDER
PROGRESS_STEP_NS = 20_000_000
"""Publish record_progress whenever it has advanced this much simulation time (20 steps at 1 kHz,
well inside the dynamics' backpressure_window whatever its /clock rate), or gone back (a reset);
and from a 50 ms timer."""
PROGRESS_PERIOD = 0.05
"""Wall seconds between republications of record_progress (when it changed)."""
KEEP_PERIOD = 0.05
"""Wall seconds between republications of the kept snapshot (when it changed)."""
TAP_PERIOD = 0.01
"""Wall seconds between drains of the in-process tap (``StepTap``) of a composed recorder: the
bytes of at most this much simulation wait in memory, and record_progress follows at this pace."""
STAMPED = (*topics.STEP_STAMPED, topics.CLOCK)
"""The topics whose stamps record_progress follows."""


class RecorderOptionError(ValueError):
    """The recorder's parameters cannot be recorded with (missing output, unknown topic, unusable bag directory)."""


def message_class(type_name: str) -> Any:
    """The rclpy message class of a rosbag2 type name like ``nav_msgs/msg/Odometry``."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


def subscription_qos(topic: topics.Topic) -> QoSProfile:
    """RELIABLE, KEEP_ALL (lossless, with back-pressure), the topic's durability."""
    durability = (DurabilityPolicy.TRANSIENT_LOCAL if topic.durability is topics.Durability.TRANSIENT_LOCAL
                  else DurabilityPolicy.VOLATILE)
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=topic.depth,
                      reliability=ReliabilityPolicy.RELIABLE, durability=durability)


def graph_topics(names: Sequence[str]) -> list[topics.Topic]:
    """The graph topics called ``names``; RecorderOptionError naming an unknown one."""
    found = []
    for name in names:
        try:
            found.append(topics.by_name(name))
        except KeyError:
            known = ', '.join(t.name for t in topics.RECORDED)
            raise RecorderOptionError(f'unknown topic {name!r} (recordable: {known})') from None
    return found


def open_bag(output: Path, program: str) -> Any:
    """A BagWriter creating ``output``, its metadata naming ``program``; RecorderOptionError if it cannot."""
    from wallbot_sim.bag.errors import BagError
    from wallbot_sim.bag.writer import BagWriter
    try:
        writer = BagWriter(output)
    except BagError as error:
        raise RecorderOptionError(str(error)) from None
    writer.set_custom_data('wallbot.recorder', program)
    return writer


class Recorder(Node):
    """Raw subscriptions (and, composed with the dynamics, its tap) writing the recorded topics into a bag
    until ``stop`` (a ``common.StopSignals``).

    ``tappable``: topics that a dynamics in the same process hands over in process (the ``tap``
    attribute, a StepTap) instead of over DDS, where recorded; with a tap the node keeps no snapshots.
    ``writer``: where to write (a BagWriter; by default one creating the ``output`` parameter's directory).
    """

    def __init__(self, stop: Any, tappable: Sequence[topics.Topic] = (), writer: Any = None,
                 program: str = 'recorder_node', **kwargs: Any) -> None:
        super().__init__(NODE_NAME, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)  # log times
        self.stop, self.writer = stop, None
        try:
            settings: RecorderSettings = declare_typed(self, RecorderSettings, RECORDER)
            output, recorded = settings.output, graph_topics(list(settings.topics))
            if writer is None and not output:
                raise RecorderOptionError('parameter output (bag directory) is required: --ros-args -p output:=DIR')
            self.writer = writer if writer is not None else open_bag(Path(output), program)
            self._start(recorded, [t for t in recorded if t in tappable])
        except BaseException:
            if self.writer is not None:
                self.writer.close()
            self.destroy_node()
            raise

    def _start(self, recorded: list[topics.Topic], tapped: list[topics.Topic]) -> None:
        self.received = self.refused = 0
        self.last_log_ns = 0
        self._subscriptions_by_name: dict[str, Any] = {}
        self._topics_by_name: dict[str, topics.Topic] = {}
        self.tap: StepTap | None = None
        self._tapped_stamped = [self.resolve_topic_name(t.name) for t in tapped if t in STAMPED]
        if tapped:
            self.tap = StepTap({t: self.resolve_topic_name(t.name) for t in tapped}, self._tap_time)
            self.create_timer(TAP_PERIOD, self._drain_tap)
        for topic in recorded:
            if topic not in tapped:
                self._subscribe(topic)
        self.create_timer(FLUSH_PERIOD, self.writer.flush_if_due)
        self._start_progress(recorded)
        self.keeper: SnapshotKeeper | None = None
        self._keeper_stamped: set[str] = set()
        if not tapped:
            self._keep_dynamics_state(recorded)
        via_tap = f' ({len(tapped)} of them in process)' if tapped else ''
        self.get_logger().info(f'recording {len(recorded)} topics{via_tap} to {self.writer.path}')

    def _subscribe(self, topic: topics.Topic) -> None:
        name = self.resolve_topic_name(topic.name)
        self._topics_by_name[name] = topic
        self._subscriptions_by_name[name] = self.create_subscription(
            message_class(topic.type), name, lambda data: self._on_message(topic, name, data),
            subscription_qos(topic), raw=True)

    def _start_progress(self, recorded: list[topics.Topic]) -> None:
        """Back-pressure for the dynamics node (topics.RECORD_PROGRESS): the newest /clock stamp up to
        which every message has been written. The per-step topics arrive on readers of their own and
        may lag /clock (seen: odometry 0.48 s behind under load), so it is the oldest of the newest
        stamps of /clock and each per-step topic."""
        self.progress_ns: int | None = None
        self._newest_stamps: dict[str, int] = {}
        self._stamped = {self.resolve_topic_name(t.name) for t in STAMPED if t in recorded}
        self._progress_sent: int | None = None
        self._progress_pub = None
        if topics.CLOCK in recorded:
            self._progress_encoder = codec.ClockEncoder()
            self._progress_pub = self.create_publisher(Clock, topics.RECORD_PROGRESS.name,
                                                       qos_profile(topics.RECORD_PROGRESS))
            self.create_timer(PROGRESS_PERIOD, self._publish_progress)

    def _keep_dynamics_state(self, recorded: list[topics.Topic]) -> None:
        self.keeper = SnapshotKeeper()
        self._keeper_stamped = {self.resolve_topic_name(t.name) for t in topics.STEP_STAMPED if t in recorded}
        self.create_subscription(Float64MultiArray, topics.STATE_SNAPSHOT.name, self._on_snapshot,
                                 qos_profile(topics.STATE_SNAPSHOT), raw=True)
        self._resume_pub = self.create_publisher(Float64MultiArray, topics.RESUME_STATE.name,
                                                 qos_profile(topics.RESUME_STATE))
        self.create_timer(KEEP_PERIOD, self._publish_kept)

    def _on_snapshot(self, data: bytes) -> None:
        try:
            snapshot = decode_snapshot(data)
        except ValueError as error:
            self.get_logger().error(f'ignoring state_snapshot: {error}')
            return
        if snapshot is not None:
            self.keeper.snapshot(snapshot)

    def _publish_kept(self) -> None:
        message = self.keeper.due()
        if message is not None:
            self._resume_pub.publish(message)

    def _on_message(self, topic: topics.Topic, name: str, data: bytes, received_ns: int | None = None) -> None:
        if received_ns is None:  # from the executor
            received_ns = self._callback_time()
        self._write(topic, name, data, received_ns)
        stamp = codec.leading_stamp_ns(data) if name in self._stamped else None
        if stamp is not None:  # one parse feeds the keeper and the progress
            self._note_stamp((name,), stamp)

    def _callback_time(self) -> int:
        """The log time of a message an executor callback is handed.

        The time is read before the stop is checked: the handler may run between any two bytecodes,
        and a time read after the check could follow a stop it did not see. A callback that finds
        the stop requested is the one the signal handler ran in front of (one callback per
        spin_once, and the loop ends after it): its message was taken, so received, before the
        handler noted the stop."""
        received_ns = self.get_clock().now().nanoseconds
        if self.stop.requested:
            received_ns = min(received_ns, self._log_time(self.stop.at_ns))
        if self.tap is not None:  # the steps logged before it go first
            self._drain_tap()
            received_ns = max(received_ns, self.last_log_ns)
        return received_ns

    def _write(self, topic: topics.Topic, name: str, data: bytes, log_ns: int) -> None:
        connection = self.writer.connection(name)
        if connection is None:
            connection = self.writer.add_topic(name, topic.type, self._offered_qos(topic, name))
        self.writer.write(connection, log_ns, data)
        self.last_log_ns = log_ns
        self.received += 1

    def _note_stamp(self, names: Sequence[str], stamp: int) -> None:
        """Messages of ``names`` with header stamp ``stamp`` were written: the keeper and the progress."""
        for name in names:
            if name in self._keeper_stamped:
                self.keeper.stamp(name, stamp)
            self._newest_stamps[name] = stamp
        if self._progress_pub is not None:
            self.progress_ns = progress = min(self._newest_stamps.values())
            sent = self._progress_sent
            if sent is None or progress < sent or progress - sent >= PROGRESS_STEP_NS:
                self._publish_progress()

    def finish(self) -> None:
        """After the stop: write what DDS received up to the stop and nobody took yet.

        Taken directly from each subscription, oldest first, with its DDS receive time, until
        one received after the stop (the rest of that queue is later still). The tap first: the
        dynamics' loop has stopped, so it holds every step logged up to the stop.
        """
        if self.tap is not None:
            self._drain_tap()
        for name, subscription in self._subscriptions_by_name.items():
            topic = self._topics_by_name[name]
            while True:
                with subscription.handle:
                    taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
                if taken is None:
                    break
                data, info = taken
                if info['received_timestamp'] > self.stop.at_ns:
                    self.refused += 1  # the queue behind it is later still: left there
                    break
                self._on_message(topic, name, data, self._log_time(info['received_timestamp']))

    def _tap_time(self) -> int:
        """The log time of a step put on the tap now (dynamics' loop thread): what a DDS
        callback would read, the node clock, wall time unless it follows simulation time."""
        clock = self.get_clock()
        return clock.now().nanoseconds if clock.ros_time_is_active else time.time_ns()

    def _drain_tap(self) -> None:
        # a step's messages share the step's stamp, which the tap carries: no parse per message
        stamped = self.tap.newest_stamp_ns
        self.refused += self.tap.drain(self._write, self.last_log_ns, lambda: self.stop.at_ns)
        if self.tap.newest_stamp_ns != stamped:
            self._note_stamp(self._tapped_stamped, self.tap.newest_stamp_ns)

    def close(self) -> None:
        """End the recording: after a stop signal what was received up to it (``finish``) and
        the stop in the metadata; then close the bag."""
        if self.stop.requested:
            self.finish()
            self.writer.set_custom_data('wallbot.recorder.stop_signal', self.stop.name)
            self.writer.set_custom_data('wallbot.recorder.stop_time_ns', str(self.stop.at_ns))
        self.get_logger().info(f'stopped by {self.stop.name or "shutdown"}: {self.received} messages recorded '
                               f'to {self.writer.path}, {self.refused} received after the signal left out')
        self.writer.close()

    def _log_time(self, received_ns: int) -> int:
        """The DDS receive time (wall clock; the node clock's now under use_sim_time), but not
        before the last log time written: a message written by its callback carries the later
        callback time, and readers take a bag in log-time order (a step back would read as a
        second life of the dynamics)."""
        clock = self.get_clock()
        return max(clock.now().nanoseconds if clock.ros_time_is_active else received_ns, self.last_log_ns)

    def _publish_progress(self) -> None:
        if self.progress_ns is None or self.progress_ns == self._progress_sent:
            return
        self._progress_pub.publish(self._progress_encoder.encode(*cdr.split_stamp(self.progress_ns)))
        self._progress_sent = self.progress_ns

    def _offered_qos(self, topic: topics.Topic, name: str) -> list[Any]:
        from rosbags.interfaces import QosHistory
        try:
            profiles = [bagio.qos_from_rclpy(info.qos_profile)
                        for info in self.get_publishers_info_by_topic(name)]
        except Exception:  # graph query failed: fall back to the interface layer's profile
            profiles = []
        # discovery does not carry history/depth: take them from the interface layer
        return [p._replace(history=QosHistory.KEEP_LAST, depth=topic.depth)
                if p.history in (QosHistory.UNKNOWN, QosHistory.SYSTEM_DEFAULT) else p
                for p in profiles] or bagio.offered_qos(topic)


def main(argv: Sequence[str] | None = None) -> int:
    """``recorder_node``: 0 after SIGINT/SIGTERM, 1 (one line on stderr) if it cannot record as asked."""
    from wallbot_sim.nodes.common import run_nodes
    return run_nodes(lambda stop: [Recorder(stop)], None if argv is None else list(argv), events=True)


if __name__ == '__main__':
    from wallbot_sim.nodes.common import exit_process
    exit_process(main())
