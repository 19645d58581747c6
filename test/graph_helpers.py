"""The node graph as separate processes, watched through an in-process rclpy node (shared by the
graph, fault, fuzz and contact tests).

Every node runs as a real process started through ``process_runner``; a test talks to it with
rclpy like the ROS tools do (``ros2 param set`` = the SetParameters service, ``ros2 topic echo`` =
a subscription).
"""

from __future__ import annotations

import sys
import threading
import time

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry, Path
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import MultiDOFJointTrajectory

from message_fields import stamp_ns
from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile

NODES = {'dynamics': 'wallbot_sim.nodes.dynamics', 'trajectory': 'wallbot_sim.nodes.trajectory',
         'constraint_config': 'wallbot_sim.nodes.constraint_config', 'controller': 'wallbot_sim.nodes.controller',
         'cmd_vel': 'wallbot_sim.nodes.cmd_vel', 'joint_bridge': 'wallbot_sim.nodes.joint_bridge'}
MS = 1_000_000
SUBSCRIBER_DEPTH = 100_000
"""History depth of this test's own subscriptions (the topics' QoS otherwise): DDS keeps what arrives while a
starved test process does not take it (100 s of a 1 kHz topic), so what the test sees is what the nodes
published, however loaded the machine. A depth is not part of QoS compatibility."""
STALL = 30.0
"""Wall seconds a wait gives an event before it fails the test: only a stall takes this long, however loaded
the machine (a passing test never waits it out)."""
ENGINE_PARAMS = {'dynamics': ('engine:=python',), 'controller': ('engine:=python',)}
"""The test graphs' engine (``Graph.start``)."""


def ns(msg) -> int:
    return stamp_ns(msg.header.stamp)


class Graph:
    """Starts node processes and observes them through an in-process rclpy node."""

    def __init__(self, runner, namespace: str = topics.NAMESPACE) -> None:
        self.runner, self.namespace = runner, namespace
        self.procs = {}
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('graph_test', context=self.context)
        self.lock = threading.Lock()
        self._kinds: dict[str, type] = {}
        self._raw: dict[str, list[bytes]] = {}
        """Messages as received (CDR bytes), not decoded yet: a test process starved on a loaded
        machine must keep up with 1 kHz topics, and rclpy decodes an Odometry in ~0.2 ms."""
        self._decoded: dict[str, list] = {}
        self._cleared: dict[str, int] = {}
        for topic, kind in ((topics.ODOM, Odometry), (topics.WHEEL_STATES, JointState),
                            (topics.DIAGNOSTICS, DiagnosticArray), (topics.CONSTRAINTS, DiagnosticStatus),
                            (topics.REFERENCE_TRAJECTORY, MultiDOFJointTrajectory),
                            (topics.REFERENCE_PATH, Path), (topics.REFERENCE, Odometry)):
            self.subscribe(topic.name, kind, topic.resolve(namespace), topic)
        self._torque_pub = None
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.spinner = threading.Thread(target=self._spin, daemon=True)
        self.spinner.start()

    @property
    def torque_pub(self):
        """This test's wheel_torque_cmd publisher, matched to the dynamics' subscription.

        Created on first use: an idle one would count as a controller for a dynamics with
        wait_for_command, which would then start without waiting for the real one's subscription.
        """
        if self._torque_pub is None:
            self._torque_pub = self.node.create_publisher(
                Float64MultiArray, topics.WHEEL_TORQUE_CMD.resolve(self.namespace), qos_profile(topics.WHEEL_TORQUE_CMD))
        self.wait_for(lambda: self._torque_pub.get_subscription_count() > 0, 15,
                      'the dynamics subscribing wheel_torque_cmd')
        return self._torque_pub

    def subscribe(self, name: str, kind: type, topic_name: str, topic: topics.Topic) -> None:
        """Keep the messages of ``topic_name`` (with ``topic``'s QoS) as ``messages(name)``."""
        self._kinds[name], self._raw[name], self._decoded[name], self._cleared[name] = kind, [], [], 0

        def keep(data: bytes) -> None:
            with self.lock:
                self._raw[name].append(data)
        deep = qos_profile(topic)
        deep.depth = SUBSCRIBER_DEPTH
        self.node.create_subscription(kind, topic_name, keep, deep, raw=True)

    def _spin(self):
        while self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:  # noqa: BLE001 - shutting down
                return

    def start(self, name: str, *params: str, remap: str | None = None, log: str | None = None):
        """Start node ``name`` with ``params`` ('key:=value'); its output in LOG.log (default NAME.log).

        The dynamics and the tracking controller compute on the model as written (``engine:=python``) unless
        ``params`` say ``engine:=numba`` (a later value wins): these graphs compare with the Python model to the
        bit, and run a few simulated seconds, for which loading the compiled kernel (numba's import and first
        use, 0.7-0.8 s more CPU than the python engine's start per process, measured on the project's VM) costs
        more than it saves."""
        args = [sys.executable, '-m', NODES[name], '--ros-args']
        for param in (*ENGINE_PARAMS.get(name, ()), *params):
            args += ['-p', param]
        if remap:
            args += ['-r', remap]
        self.procs[name] = self.runner.start(args, log or name)
        return self.procs[name]

    def messages(self, name: str) -> list:
        """Every message of ``name`` received (since the last ``clear``), decoded."""
        with self.lock:
            pending, self._raw[name] = self._raw[name], []
            cleared = self._cleared[name]
        decoded = [deserialize_message(data, self._kinds[name]) for data in pending]  # outside the lock
        with self.lock:
            if self._cleared[name] == cleared:
                self._decoded[name].extend(decoded)
            return list(self._decoded[name])

    def newest(self, name: str):
        """The newest message of ``name`` received, decoded alone (None before any): a poll that
        needs only the latest state must not decode a kHz topic's backlog on every call."""
        with self.lock:
            if self._raw[name]:
                data = self._raw[name][-1]
            else:
                return self._decoded[name][-1] if self._decoded[name] else None
        return deserialize_message(data, self._kinds[name])

    def clear(self, name: str) -> None:
        with self.lock:
            self._raw[name].clear()
            self._decoded[name].clear()
            self._cleared[name] += 1

    def wait_for(self, predicate, timeout: float = STALL, what: str = 'condition'):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = predicate()
            if value:
                return value
            self._check_alive()
            time.sleep(0.02)
        pytest.fail(f'timed out waiting for {what}')  # the nodes' logs: conftest's report

    def _check_alive(self) -> None:
        for name, proc in self.procs.items():
            if proc.poll() is not None:
                pytest.fail(f'{name} exited with {proc.returncode}:\n{self.runner.output(name)}')

    def last_stamp(self) -> int:
        """The newest odometry stamp received (read from its bytes), -1 before any."""
        name = topics.ODOM.name
        with self.lock:
            if self._raw[name]:
                return codec.leading_stamp_ns(self._raw[name][-1])
            return ns(self._decoded[name][-1]) if self._decoded[name] else -1

    def wait_sim_time(self, t: float, timeout: float = STALL):
        """Wait until odometry reaches simulation time ``t``; fail only if it stops advancing for
        ``timeout`` wall seconds (a stall), however slowly a loaded machine simulates."""
        target, newest = round(t * 1e9), self.last_stamp()
        progressed = time.monotonic()
        while newest < target:
            if time.monotonic() - progressed > timeout:
                pytest.fail(f'simulation time stalled at {newest * 1e-9:.3f} s for {timeout:g} s '
                           f'waiting for {t} s' if newest >= 0 else f'no odometry within {timeout:g} s')
            self._check_alive()
            time.sleep(0.02)
            stamp = self.last_stamp()
            if stamp > newest:
                newest, progressed = stamp, time.monotonic()

    def reported_time(self) -> int:
        """The simulation time (ns) of the dynamics' newest /diagnostics report since the last ``clear`` of
        that topic (-1: none yet): its own time, at most a report period (a wall second) old. Unlike the
        odometry this test may still be taking a backlog of, a report arrives within a round of the executor."""
        reports = self.messages(topics.DIAGNOSTICS.name)
        return ns(reports[-1]) if reports else -1

    def held_at(self, holding, last_published: int = 0, what: str = 'the dynamics holding') -> int:
        """The simulation time (ns) at which the dynamics holds, as it reports it itself.

        ``holding(status)`` picks the /diagnostics status that says it holds (paused, diverged); its
        array's stamp is the simulation time held. Waits for that report, then for odometry up to
        the held time less ``last_published`` (a state the loop could not finish is never
        published), then for the next report (the node publishes one a wall second): that one must
        hold at the same time and no odometry may be newer, i.e. the loop did not step in between.
        Every message sent before the hold has arrived by then, however loaded the machine.
        """
        def held() -> list[int]:
            return [ns(a) for a in self.messages(topics.DIAGNOSTICS.name) if any(holding(s) for s in a.status)]
        t_held = self.wait_for(held, 10, what)[-1]
        self.wait_for(lambda: self.last_stamp() >= t_held - last_published, STALL, 'odometry up to the held time')
        seen = len(held())
        later = self.wait_for(lambda: held()[seen:], STALL, f'a later report of {what}')
        assert later[0] == t_held, f'held at {t_held * 1e-9} s, then reported {later[0] * 1e-9} s'
        assert self.last_stamp() == t_held - last_published, 'odometry went on while the dynamics held'
        return t_held

    def call(self, kind, name: str, request, timeout: float = 5.0):
        client = self.node.create_client(kind, name)
        try:
            assert client.wait_for_service(timeout_sec=timeout), f'service {name} not available'
            future = client.call_async(request)
            self.wait_for(future.done, timeout, f'response of {name}')
            return future.result()
        finally:
            self.node.destroy_client(client)

    def set_parameters(self, node: str, **values):
        """Through the SetParameters service, like ``ros2 param set``; the per-parameter results."""
        request = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                                    for k, v in values.items()])
        return self.call(SetParameters, f'{self.namespace}/{node}/set_parameters', request).results

    def get_parameters(self, node: str, *names: str):
        response = self.call(GetParameters, f'{self.namespace}/{node}/get_parameters',
                             GetParameters.Request(names=list(names)))
        return [parameter_value_to_python(v) for v in response.values]

    def close(self):
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.spinner.join(timeout=2.0)


def start_graph(graph: Graph, *dynamics: str, constraints: tuple[str, ...] = (),
                trajectory: tuple[str, ...] | None = ()):
    """Start the nodes; constraint_config last, once this test's subscriptions see the dynamics node.

    The dynamics node integrates nothing before it has a constraint set, and DDS discovery
    between freshly started processes can take a few seconds, so waiting for the match first
    lets the test see the run from t = 0.
    """
    if trajectory is not None:
        graph.start('trajectory', *trajectory)
    proc = graph.start('dynamics', *dynamics)
    odom = topics.ODOM.resolve(graph.namespace)
    graph.wait_for(lambda: graph.node.count_publishers(odom) > 0, STALL, 'discovery of the dynamics node')
    # a message of the dynamics received here: its endpoints and this test's are matched both ways
    graph.wait_for(lambda: graph.messages(topics.DIAGNOSTICS.name), STALL, 'the first diagnostics (1 Hz)')
    graph.start('constraint_config', *constraints)
    return proc
