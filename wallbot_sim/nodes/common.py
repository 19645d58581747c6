"""Small helpers shared by the nodes: signal handling, a clean main(), discovery checks, held commands."""

from __future__ import annotations

import ctypes
import math
import os
import signal
import sys
import threading
import time
from typing import Callable, NoReturn, Sequence

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions
from rclpy.timer import Timer

from wallbot_msgs_py import topics
from wallbot_sim.heartbeat import NODE_HEARTBEAT, install_heartbeat
from wallbot_sim.model import ModelError

ROBOT_CLOCK_ARGS = ['--ros-args', '-r', topics.ROBOT_CLOCK_REMAP]
"""Node arguments (``Node(cli_args=...)``) of every node that follows simulation time: its
``use_sim_time`` time source, which rclpy subscribes on the absolute ``/clock``, follows the
robot's own ``clock`` in the node's namespace instead (whatever ``-r __ns:=`` made it), so several
robots in one domain each keep their own time. Node-local rules come before the command line's."""


class StopSignals:
    """SIGINT and SIGTERM as a request to stop, whatever disposition the process inherited.

    A background job of a non-interactive shell (``cmd &`` in a script) starts with SIGINT
    ignored, and Python then installs no SIGINT handler of its own; ``ros2 run`` and ``ros2
    launch`` deliver SIGINT (Ctrl-C to the process group) and SIGTERM. Both handlers are
    installed explicitly and only note the first signal and when it came (``time.time_ns``).

    A Python handler runs only when the main thread runs Python, not while it waits inside an
    executor; so the signal is also written to a wakeup pipe, and a thread reading it calls the
    functions in :attr:`wakers` (e.g. a guard condition's ``trigger``; clear them before it goes):
    the wait returns, the handler runs, the caller's loop sees :attr:`requested`. ``restore()``
    puts the previous handlers back.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.signum: int | None = None
        self.at_ns: int | None = None
        self.wakers: list[Callable[[], None]] = []
        self._pipe_out, self._pipe_in = os.pipe()
        os.set_blocking(self._pipe_in, False)
        self._previous_wakeup_fd = signal.set_wakeup_fd(self._pipe_in)
        self._previous = {signum: signal.signal(signum, self._note) for signum in self.SIGNALS}
        threading.Thread(target=self._watch, name='stop-signals', daemon=True).start()

    def _note(self, signum: int, _frame: object) -> None:
        if self.signum is None:
            self.signum, self.at_ns = signum, time.time_ns()

    def _watch(self) -> None:
        while os.read(self._pipe_out, 16):  # empty once restore() closed the pipe
            for wake in list(self.wakers):
                wake()
        os.close(self._pipe_out)

    @property
    def requested(self) -> bool:
        return self.signum is not None

    @property
    def name(self) -> str:
        """The signal's name (SIGINT, SIGTERM), or '' before one came."""
        return signal.Signals(self.signum).name if self.signum is not None else ''

    def restore(self) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        signal.set_wakeup_fd(self._previous_wakeup_fd)
        self.wakers.clear()
        os.close(self._pipe_in)


def run(factory: Callable[[], Node], args: list[str] | None = None, events: bool = False) -> int:
    """Create the node and spin it until SIGINT or SIGTERM; exit 0 without a traceback.

    The signals are handled by :class:`StopSignals`, not by rclpy's handlers: those shut the
    context down from another thread, which raced with the node's construction (a publisher
    created on an invalid context) and with the executor's wait (a node that never woke up).
    Here a signal during construction lets the node finish building and exit 0, and a signal
    while it spins wakes the executor at once. A configuration error while building the node (e.g. a
    bad robot file) is logged on one line and gives exit status 1.
    """
    return run_nodes(lambda _stop: [factory()], args, events)


EVENTS_SPIN_PERIOD = 1.0
"""Longest wait of an EventsExecutor (s), a safety net: a signal ends the wait at once (:func:`wake_on_stop`),
and every node that sets its exit_status has a timer that ends it. Every wake-up costs Python in an idle node:
at 0.05 s, 20 a second took 0.4 % of a core."""


def wake_on_stop(node: Node, stop: StopSignals) -> None:
    """Have a signal end an EventsExecutor's wait at once. The wait cannot be woken from another thread (its
    wake() does not end spin_once, guard conditions are not supported), but a timer reset from one fires."""
    timer = steady_timer(node, WAKE_DELAY, lambda: timer.cancel())
    timer.cancel()
    stop.wakers.append(timer.reset)


WAKE_DELAY = 1e-3
"""Seconds from a signal to the timer that ends an EventsExecutor's wait (:func:`wake_on_stop`)."""


def events_executor(context: rclpy.Context | None = None) -> Executor:
    """rclpy's EventsExecutor (a callback per event, no wait set rebuilt per wake-up: the executor for
    nodes taking many messages), or the SingleThreadedExecutor where rclpy has none."""
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    except ImportError:  # older rclpy
        return SingleThreadedExecutor(context=context)


def run_nodes(factory: Callable[[StopSignals], Sequence[Node]], args: list[str] | None = None,
              events: bool = False) -> int:
    """:func:`run` for the nodes ``factory`` builds (given the stop, for nodes that act on it), spun
    by one executor (``events``: :func:`events_executor`); on the way out each node's ``close`` (if it
    has one) runs in their order, then they are destroyed.

    A node that cannot go on (it logged why) sets its ``exit_status``: the process then ends as on
    a signal, with that status, once the executor next wakes (every node that sets it has a timer).
    Before the nodes leave DDS, what they published is delivered (:func:`deliver_published`); their
    writers have a heartbeat of ``NODE_HEARTBEAT`` unless the user set a Fast DDS profile file.
    """
    stop = StopSignals()
    install_heartbeat(NODE_HEARTBEAT)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    nodes: Sequence[Node] = ()
    executor = None
    status = 0
    try:
        nodes = factory(stop)
        executor = events_executor() if events else SingleThreadedExecutor()
        for node in nodes:
            executor.add_node(node)
        if events:
            wake_on_stop(nodes[0], stop)
            while not stop.requested and rclpy.ok() and not (status := exit_status(nodes)):
                executor.spin_once(timeout_sec=EVENTS_SPIN_PERIOD)
        else:
            # a triggered guard condition with a callback ends spin_once (executor.wake() would only
            # make it rebuild its wait set and wait again); the callback itself has nothing to do
            wake = nodes[0].create_guard_condition(lambda: None)
            stop.wakers.append(wake.trigger)
            while not stop.requested and rclpy.ok() and not (status := exit_status(nodes)):
                executor.spin_once()  # no timeout: rclpy builds a timer for every wait that has one
    except (ModelError, ValueError, OSError) as error:
        print(f'error: {error}', file=sys.stderr)
        status = 1
    finally:
        stop.wakers.clear()
        if executor is not None:
            executor.shutdown()
        for node in nodes:
            close = getattr(node, 'close', None)
            if close is not None:
                close()
        deliver_published(nodes)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
        stop.restore()
    return status


def exit_process(status: int) -> NoReturn:
    """End a node's process with ``status`` once :func:`run_nodes` has returned (its nodes destroyed: the process
    has left DDS): its output flushed, without Python's teardown and the C++ static destructors. Those add about
    0.2 s to every process's exit (Fast DDS's DomainParticipantFactory sleeps 100 ms in its destructor), and
    ``wallbot-sim run`` waits for its nodes' exits, then for its recorder's, in turn."""
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    ctypes.CDLL(None).fflush(None)  # C's stdio buffers (rcutils' console output), which os._exit does not flush
    os._exit(status)


DELIVERY_WAIT = 2.0
"""Most wall seconds a stopping process waits for its subscribers to acknowledge what it published (a dead
subscriber is waited for this long; a live one behind by a few hundred messages needs well under a second)."""


def deliver_published(nodes: Sequence[Node], wait: float = DELIVERY_WAIT) -> None:
    """Wait, at most ``wait`` seconds in all, until every subscriber of the nodes' publishers has acknowledged
    what they published: a sample a reliable subscriber lost in transit (a starved one's queue overflowing) is
    repaired only while its writer is in DDS, at the writer's next heartbeat. A recorder stopped after the
    other nodes (``wallbot-sim run``) thus holds everything they published."""
    deadline = time.monotonic() + wait
    for node in nodes:
        for publisher in node.publishers:
            if publisher.get_subscription_count():
                publisher.wait_for_all_acked(Duration(seconds=max(0.0, deadline - time.monotonic())))


def exit_status(nodes: Sequence[Node]) -> int:
    """The first non-zero ``exit_status`` a node of ``nodes`` asks the process to end with, or 0."""
    return next((status for node in nodes if (status := getattr(node, 'exit_status', None))), 0)


UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'
"""The node name rmw reports for an endpoint whose node it has not yet discovered."""


def heard_by_every(node: Node, publisher: Publisher, senders_topic: str) -> bool:
    """Whether some node publishes on ``senders_topic``, each such node subscribes ``publisher``'s
    topic, and every discovered subscription of that topic is matched to ``publisher`` (so a
    message published now reaches all of them).

    Endpoints of nodes not yet identified all carry UNKNOWN_NODE, which would make a sender look
    like it subscribes when another unidentified node does: not ready until every sender is known.
    """
    listeners = node.get_subscriptions_info_by_topic(publisher.topic_name)
    return senders_listen(node, senders_topic, publisher.topic_name) and publisher.get_subscription_count() >= len(
        listeners)


def senders_listen(node: Node, senders_topic: str, listened_topic: str) -> bool:
    """Whether some node publishes on ``senders_topic`` and each such node, every one identified, subscribes
    ``listened_topic`` (both resolved names): of the graph as ``node`` has discovered it."""
    senders = {(i.node_namespace, i.node_name) for i in node.get_publishers_info_by_topic(senders_topic)}
    listeners = {(i.node_namespace, i.node_name) for i in node.get_subscriptions_info_by_topic(listened_topic)}
    return bool(senders) and all(name != UNKNOWN_NODE for _namespace, name in senders) and senders <= listeners


def steady_timer(node: Node, period: float, callback: Callable[[], None]) -> Timer:
    """A timer of ``node`` on the steady clock: every ``period`` wall seconds, also in a node that
    follows simulation time (whose own clock stands still while the simulation waits)."""
    return node.create_timer(period, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


class WhenRecorded:
    """Runs ``action`` once, when a recorder hears every one of ``publishers`` (a node's ``wait_for_recorder``).

    A recorder is a node publishing record_progress; it hears a publisher once it subscribes its
    topic and every discovered subscription of that topic is matched to it (``heard_by_every``),
    checked on a steady timer. Until then the node holds back what would start the run (the
    controller's odom subscription, the trajectory node's first plan, the joint bridge's inputs),
    so the bag misses nothing of what it publishes from the start.
    """

    CHECK_PERIOD = 0.02
    """Wall seconds between checks."""

    def __init__(self, node: Node, publishers: Sequence[Publisher], action: Callable[[], None], done: str) -> None:
        self.node, self.publishers, self.action, self.done = node, tuple(publishers), action, done
        self.progress_topic = node.resolve_topic_name(topics.RECORD_PROGRESS.name)
        self.timer = steady_timer(node, self.CHECK_PERIOD, self._check)

    @property
    def waiting(self) -> bool:
        """Whether ``action`` is still to run."""
        return self.timer is not None

    def _check(self) -> None:
        if not all(heard_by_every(self.node, publisher, self.progress_topic) for publisher in self.publishers):
            return
        self.node.destroy_timer(self.timer)
        self.timer = None
        self.node.get_logger().info(self.done)
        self.action()


def subscribe_odom_when_recorded(node: Node, wait_for_recorder: bool, command_pub: Publisher,
                                 subscribe_odom: Callable[[], None]) -> None:
    """A commander's (tracking controller, cmd_vel node) ``wait_for_recorder``: with it, ``subscribe_odom`` runs
    once a recorder hears ``command_pub``; without, at once.

    A dynamics waiting for its commander (its wait_for_command) starts when the commander
    subscribes odom: the recorder must hear the run's first commands.
    """
    if wait_for_recorder:
        WhenRecorded(node, [command_pub], subscribe_odom, 'a recorder hears wheel_torque_cmd: subscribing odom')
    else:
        subscribe_odom()


class HeldCommands:
    """A command publisher whose messages go out only once the sender of ``state_topic`` hears them.

    A lockstep dynamics publishes a state once its odometry reaches the controller; a command
    answering it is lost if the command publisher has not matched the dynamics' subscription yet
    (discovery is per direction), and the dynamics would wait for it. So until the publisher is
    heard by every node publishing ``state_topic`` (``heard_by_every``) the newest command is held,
    and a steady timer, running only while one is held, sends it once it will be heard. A commander
    that is heard thus has no timer waking it between its control instants (a 50 Hz timer took
    1.9 % of a core on the project's VM, more than the idle node itself).

    The graph is asked again at a send that follows the previous one by more than RECHECK_AFTER: a
    dynamics restarted or replaced leaves a longer pause in the states its commander answers (a
    process takes seconds to start), and a steady stream of sends asks nothing.
    """

    CHECK_PERIOD = 0.02
    """Wall seconds between checks while a command is held."""
    RECHECK_AFTER = 0.25
    """Wall seconds between two sends after which the graph is asked again. A graph query once per control
    instant runs from cold caches: 0.1 ms of CPU on the project's VM, 0.4 % of a core at 50 Hz."""

    def __init__(self, node: Node, publisher: Publisher, state_topic: str) -> None:
        self.node, self.publisher = node, publisher
        self.state_topic = node.resolve_topic_name(state_topic)
        self.heard = False
        self.unsent = None
        self.sent_at = -math.inf
        """time.monotonic() of the last send."""
        self.retry = steady_timer(node, self.CHECK_PERIOD, self._check)
        self.retry.cancel()

    def _heard(self) -> bool:
        if not self.heard:
            self.heard = heard_by_every(self.node, self.publisher, self.state_topic)
        return self.heard

    def send(self, message: object) -> bool:
        """Publish ``message`` now if it will be heard (True), else hold it as the newest (False)."""
        previous, self.sent_at = self.sent_at, time.monotonic()
        if self.sent_at - previous > self.RECHECK_AFTER:
            self.heard = False
        if self._heard():
            self.unsent = None
            self.publisher.publish(message)
            return True
        self.unsent = message
        if self.retry.is_canceled():
            self.retry.reset()
        return False

    def _check(self) -> None:
        if self.unsent is not None and self._heard():
            message, self.unsent = self.unsent, None
            self.publisher.publish(message)
        if self.unsent is None:
            self.retry.cancel()
