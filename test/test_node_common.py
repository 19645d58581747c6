"""nodes.common: run exits cleanly on a signal while the node is built or while an EventsExecutor waits,
still raises a real failure, and delivers what its node published before it leaves DDS; heard_by_every."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.node import Node  # noqa: E402

from cli_helpers import wait_for_output  # noqa: E402
from wallbot_sim.heartbeat import PROFILES_ENV  # noqa: E402
from wallbot_sim.nodes import common  # noqa: E402

PROBE = Path(__file__).with_name('delivery_probe.py')


@pytest.fixture(autouse=True)
def own_profile_setting(monkeypatch):
    """common.run gives this process a heartbeat profile: gone again after each test, as it came."""
    monkeypatch.delenv(PROFILES_ENV, raising=False)


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_node_is_built_is_a_clean_exit(signum):
    before = signal.getsignal(signum)
    built = []

    def build() -> Node:
        os.kill(os.getpid(), signum)  # handled before the node exists (rclpy's handlers raced here)
        built.append(Node('signalled_while_built'))
        return built[0]

    started = time.monotonic()
    assert common.run(build, []) == 0
    assert time.monotonic() - started < 5.0, 'a stall, not a timing figure'
    assert built and signal.getsignal(signum) is before


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_a_signal_ends_an_events_executors_wait_at_once(monkeypatch, signum):
    monkeypatch.setattr(common, 'EVENTS_SPIN_PERIOD', 30.0)  # without the wake the wait would end only after this
    spinning = threading.Event()
    signalled = []

    def build() -> Node:
        node = Node('signalled_while_spinning')
        first = node.create_timer(0.01, lambda: (first.cancel(), spinning.set()))
        return node

    def signal_when_spinning() -> None:
        if spinning.wait(30.0):
            signalled.append(time.monotonic())
            os.kill(os.getpid(), signum)

    sender = threading.Thread(target=signal_when_spinning)
    sender.start()
    assert common.run(build, [], events=True) == 0
    sender.join()
    assert signalled, 'the node never spun'
    assert time.monotonic() - signalled[0] < 10.0, 'a stall, not a timing figure'


def test_an_error_while_running_is_not_hidden():
    def fail() -> None:
        raise RuntimeError('callback failed')

    def build() -> Node:
        node = Node('real_failure')
        node.create_timer(0.01, fail)
        return node

    with pytest.raises(RuntimeError, match='callback failed'):
        common.run(build, [])


BURST = 5000
"""Messages of about 1 kB published at once: a stopped listener of the project's VM got 2,500-4,000 of
3,000-5,000 (2026-12-03), the rest only at the sender's next heartbeat."""


def test_a_node_process_ends_with_its_status_and_all_it_wrote(process_runner, tmp_path):
    """A node's process ends at once when its nodes have left DDS (common.exit_process: Python's teardown and Fast
    DDS's, which sleeps 100 ms, would add about 0.2 s to each exit), its output flushed first: here the recorder's
    log lines, the last written as it stops, through C's fully buffered stdout into a file (RCUTILS_LOGGING_USE_STDOUT),
    with Python's output buffered as well."""
    bag = tmp_path / 'bag'
    recorder = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args', '-p',
                                     f'output:={bag}'], 'recorder',
                                    env={'PYTHONUNBUFFERED': '', 'RCUTILS_LOGGING_USE_STDOUT': '1'})
    deadline = time.monotonic() + 60
    while not any(bag.glob('*.mcap')):
        assert recorder.poll() is None, process_runner.output('recorder')
        assert time.monotonic() < deadline, 'no bag opened: a stall'
        time.sleep(0.05)
    assert process_runner.stop(recorder) == 0, process_runner.output('recorder')
    output = process_runner.output('recorder')
    assert 'recording ' in output and 'stopped by SIGTERM' in output, output
    assert (bag / 'metadata.yaml').is_file()


def test_a_node_delivers_what_a_starved_subscriber_lost_before_it_leaves(process_runner):
    """A subscriber stopped while a node publishes loses what arrives once its queue is full: here the
    end of a burst, and a last message on a topic of its own (a controller's last command among the
    dynamics' 1 kHz traffic). Reliability repairs a loss only while the writer is in DDS: when the
    subscriber NACKs what the writer's heartbeats announced. A burst carries heartbeats of its own, the
    last message none, so only the writer's periodic heartbeat brings it. The node, stopped as soon as
    the subscriber runs again, must deliver everything before it leaves: common.run waits for every
    subscriber's acknowledgement (deliver_published, at most DELIVERY_WAIT), and the node's heartbeat
    (NODE_HEARTBEAT) brings it within that; Fast DDS's default heartbeat, every 3 s, would not."""
    listener = process_runner.start([sys.executable, PROBE, 'listen'], 'listener')
    sender = process_runner.start([sys.executable, PROBE, 'send', str(BURST)], 'sender')
    wait_for_output(process_runner, 'sender', 'matched', 60)

    os.kill(listener.pid, signal.SIGSTOP)
    try:
        os.kill(sender.pid, signal.SIGUSR1)
        wait_for_output(process_runner, 'sender', f'sent {BURST}', 30)
    finally:
        os.kill(listener.pid, signal.SIGCONT)
    os.kill(sender.pid, signal.SIGTERM)
    assert sender.wait(30) == 0, process_runner.output('sender')

    def received() -> list[str]:
        return [line.split()[1] for line in process_runner.output('listener').splitlines()
                if line.startswith('received ')]
    expected = [str(number) for number in range(1, BURST + 1)] + ['last']
    deadline = time.monotonic() + 10  # the sender has left: what the listener has not taken yet is all it gets
    while len(received()) < len(expected) and time.monotonic() < deadline:
        time.sleep(0.02)
    got = received()
    assert sorted(got) == sorted(expected), f'{len(got)} of {len(expected)} delivered'
    assert [number for number in got if number != 'last'] == expected[:BURST], 'the burst out of order'


class FakeGraph:
    """The graph queries heard_by_every makes, answered from fixed endpoint lists."""

    def __init__(self, senders, listeners):
        self.senders, self.listeners = senders, listeners

    def get_publishers_info_by_topic(self, topic):
        return [SimpleNamespace(node_namespace=ns, node_name=name) for ns, name in self.senders]

    def get_subscriptions_info_by_topic(self, topic):
        return [SimpleNamespace(node_namespace=ns, node_name=name) for ns, name in self.listeners]


def publisher(matched: int):
    return SimpleNamespace(topic_name='/wallbot/odom', get_subscription_count=lambda: matched)


CONTROLLER, RECORDER = ('/wallbot', 'controller'), ('/wallbot', 'recorder')
UNKNOWN = ('_NODE_NAMESPACE_UNKNOWN_', common.UNKNOWN_NODE)


@pytest.mark.parametrize('senders, listeners, matched, heard', [
    ([CONTROLLER], [CONTROLLER, RECORDER], 2, True),
    ([], [RECORDER], 1, False),                             # nobody sends yet
    ([CONTROLLER], [RECORDER], 1, False),                   # the sender does not listen
    ([CONTROLLER], [CONTROLLER, RECORDER], 1, False),       # a listener not matched yet
    ([UNKNOWN], [UNKNOWN, RECORDER], 2, False),             # two unidentified nodes are not one
])
def test_heard_by_every(senders, listeners, matched, heard):
    assert common.heard_by_every(FakeGraph(senders, listeners), publisher(matched), '/wallbot/cmd') is heard


class FakeCommander(FakeGraph):
    """A node as HeldCommands uses it: graph queries (counted), a timer, a publisher."""

    def __init__(self, senders, listeners):
        super().__init__(senders, listeners)
        self.queries = 0
        self.published = []
        self.timer = SimpleNamespace(canceled=True)
        self.timer.cancel = lambda: setattr(self.timer, 'canceled', True)
        self.timer.reset = lambda: setattr(self.timer, 'canceled', False)
        self.timer.is_canceled = lambda: self.timer.canceled
        self.publisher = SimpleNamespace(topic_name='/wallbot/cmd', publish=self.published.append,
                                         get_subscription_count=lambda: len(self.listeners))

    def get_publishers_info_by_topic(self, topic):
        self.queries += 1
        return super().get_publishers_info_by_topic(topic)

    def resolve_topic_name(self, name):
        return name

    def create_timer(self, period, callback, clock=None):
        self.timer.callback = callback
        return self.timer


def test_held_commands_ask_the_graph_after_a_pause_only(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(common.time, 'monotonic', lambda: now[0])
    dynamics, restarted = ('/wallbot', 'dynamics'), ('/wallbot', 'dynamics_restarted')
    node = FakeCommander([dynamics], [dynamics])
    commands = common.HeldCommands(node, node.publisher, '/wallbot/odom')

    for k in range(50):  # a steady stream at 50 Hz: the graph is asked at the first send only
        assert commands.send(k)
        now[0] += 0.02
    assert node.published == list(range(50)) and node.queries == 1

    node.senders, node.listeners = [restarted], []  # the dynamics restarted; it has not subscribed yet
    now[0] += 2.0
    assert not commands.send('first answer') and not commands.send('newest answer')
    assert node.queries == 3 and node.published[-1] == 49  # asked at each send while held
    assert not node.timer.is_canceled()
    node.timer.callback()
    assert node.published[-1] == 49, 'sent before the restarted dynamics hears it'
    node.listeners = [restarted]
    node.timer.callback()
    assert node.published[-1] == 'newest answer' and node.timer.is_canceled()
    now[0] += 0.02
    assert commands.send('next') and node.published[-1] == 'next'
