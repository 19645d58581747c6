"""viewer_node in the running graph: markers over DDS, the live topics over the Foxglove WebSocket
protocol to a plain WebSocket client, its parameters and its one-line errors."""

from __future__ import annotations

import json
import math
import re
import signal
import socket
import struct
import sys
import time

import pytest
import rclpy
from nav_msgs.msg import Odometry
from visualization_msgs.msg import MarkerArray

from cli_helpers import WALLBOT, wait_for_output
from graph_helpers import Graph
from message_fields import odometry_cdr, planar_state
from wallbot_msgs_py import bagio, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.config import load_scenario
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.nodes.viewer import tf_message_type

sync_client = pytest.importorskip('websockets.sync.client')
pytest.importorskip('foxglove')
SUBPROTOCOL = 'foxglove.sdk.v1'
"""What foxglove-sdk's server speaks (the Foxglove WebSocket protocol, renamed from foxglove.websocket.v1)."""
MESSAGE_DATA = 0x01
"""Opcode of a binary server message carrying a message: subscription id (uint32), receive time
(uint64), the message's bytes."""


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def connect(port: int, process_runner, timeout: float = 60.0):
    """A Foxglove WebSocket connection to the run's viewer, once it listens (the run must keep running)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return sync_client.connect(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], open_timeout=5)
        except OSError:
            assert process_runner.processes['run'].poll() is None, process_runner.output('run')
            assert time.monotonic() < deadline, f'nothing listens on {port}: ' + process_runner.output('run')
            time.sleep(0.2)


def channels_of(connection, topics_wanted: set[str], timeout: float = 30.0) -> dict[str, dict]:
    """The advertised channels of ``topics_wanted`` (id, encoding and schema of each), by topic."""
    found: dict[str, dict] = {}
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and set(found) != topics_wanted:
        message = connection.recv(timeout=timeout)
        if isinstance(message, str) and json.loads(message).get('op') == 'advertise':
            found.update({channel['topic']: channel for channel in json.loads(message)['channels']
                          if channel['topic'] in topics_wanted})
    assert set(found) == topics_wanted, f'advertised only {sorted(found)}'
    return found


def markers_received(domain_id: int, timeout: float = 60.0) -> MarkerArray:
    """The first MarkerArray on /wallbot/markers in ``domain_id`` that holds the travelled path."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node('markers_probe', context=context)
    received: list[MarkerArray] = []
    node.create_subscription(MarkerArray, topics.MARKERS.resolve(), received.append, qos_profile(topics.MARKERS))
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            drawn = [msg for msg in received
                     if any(m.ns == 'travelled' and m.action == m.ADD for m in msg.markers)]
            if drawn:
                return drawn[-1]
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    pytest.fail(f'no markers with a travelled path within {timeout:g} s')


def test_a_run_serves_odom_to_a_foxglove_client_and_markers_to_ros(tmp_path, process_runner):
    """``run --foxglove PORT``: a WebSocket client subscribes odom and decodes the robot on its
    circle; a ROS subscriber in the run's domain receives markers in frame wall."""
    with claim_domain_id() as free:
        chosen = free.domain_id
    port = free_port()
    run = process_runner.start([*WALLBOT, 'run', 'circle', '--duration', '0', '--domain-id', chosen,
                                '--foxglove', port, '--out', tmp_path / 'run', '--no-plots'], 'run')
    wait_for_output(process_runner, 'run', rf'^wallbot-sim run: live view for Foxglove on ws://127.0.0.1:{port}$', 60)
    wait_for_output(process_runner, 'run', r't = +[0-9.]+ s \(until stopped\)', 120)
    with connect(port, process_runner) as connection:
        info = json.loads(connection.recv(timeout=30))
        assert info['op'] == 'serverInfo'  # a read-only view: clients can neither publish nor call
        assert not {'clientPublish', 'services', 'parameters', 'parametersSubscribe'} & set(info['capabilities'])
        channels = channels_of(connection, {topics.ODOM.resolve(), topics.TF.name})
        assert channels[topics.TF.name]['schemaName'] == topics.TF.type  # tf even without tf2_msgs
        odom = channels[topics.ODOM.resolve()]
        assert (odom['encoding'], odom['schemaName'], odom['schemaEncoding']) == ('cdr', topics.ODOM.type, 'ros2msg')
        assert 'MSG: geometry_msgs/Pose' in odom['schema']
        connection.send(json.dumps({'op': 'subscribe', 'subscriptions': [{'id': 7, 'channelId': odom['id']}]}))
        states = []
        while len(states) < 10:
            message = connection.recv(timeout=30)
            if isinstance(message, bytes) and message[0] == MESSAGE_DATA:
                subscription, _receive_ns = struct.unpack_from('<IQ', message, 1)
                assert subscription == 7
                states.append(planar_state(bagio.deserialize(message[13:], topics.ODOM.type)))
    stamps = [state.stamp_ns for state in states]
    assert stamps == sorted(set(stamps))  # the newest odometry each frame, never the same twice
    circle = load_scenario('circle').reference
    for state in states[1:]:  # starting 0.2 m inside the circle, turning onto it
        distance = math.hypot(state.x - circle.center[0], state.y - circle.center[1])
        assert circle.radius - 0.21 < distance < circle.radius + 0.01

    markers = markers_received(chosen)
    assert {m.header.frame_id for m in markers.markers} == {topics.WALL_FRAME}
    drawn = sorted((m.ns, m.id) for m in markers.markers if m.action == m.ADD)
    assert drawn == sorted([('chassis', 0), ('reference_path', 0), ('travelled', 0)]
                           + [(ns, i) for ns in ('wheels', 'wheel_marks', 'contact_forces') for i in range(4)])

    run.send_signal(signal.SIGINT)
    assert run.wait(timeout=60) == 130
    viewer = (tmp_path / 'run' / 'logs' / 'viewer.log').read_text()
    assert 'Traceback' not in viewer and f'serving Foxglove on ws://127.0.0.1:{port}' in viewer
    assert viewer.count('tf2_msgs') == (0 if tf_message_type() is not None else 1)


@pytest.fixture
def viewer(process_runner):
    """A viewer node alone, watched by this test's Graph node."""
    process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.viewer'], 'viewer')
    graph = Graph(process_runner)
    graph.procs['viewer'] = process_runner.processes['viewer']
    try:
        yield graph
    finally:
        graph.close()


def test_a_refused_rate_leaves_the_viewer_running(viewer):
    viewer.wait_for(lambda: viewer.node.count_publishers(topics.MARKERS.resolve()) > 0, 30, 'the viewer')
    for bad in (0.0, 101.0, math.nan):
        refused, = viewer.set_parameters('viewer', rate_hz=bad)
        assert not refused.successful and 'rate_hz out of range' in refused.reason
    accepted, = viewer.set_parameters('viewer', rate_hz=5.0)
    assert accepted.successful
    assert viewer.get_parameters('viewer', 'rate_hz') == [5.0]


def test_malformed_odometry_is_never_drawn_and_the_viewer_goes_on(viewer, process_runner):
    """Bytes that are no Odometry are logged and dropped; the next good one is drawn."""
    received: list[MarkerArray] = []
    viewer.node.create_subscription(MarkerArray, topics.MARKERS.resolve(), received.append,
                                    qos_profile(topics.MARKERS))
    odom = viewer.node.create_publisher(Odometry, topics.ODOM.resolve(), qos_profile(topics.ODOM))
    viewer.wait_for(lambda: odom.get_subscription_count() > 0, 30, 'the viewer subscribing odom')

    def published_until(data: bytes, seen):  # the viewer's reader may match this writer later
        def check():
            odom.publish(data)
            return seen()
        return check

    def logged() -> int:
        return process_runner.output('viewer').count('ignoring a odom message: ')

    good = odometry_cdr(2.0, 0.5, 0.25, 0.0, 0.0, 0.0, 0.0)
    for bad in (good[:30], good[:12] + b'\xff\xff\xff\x7f' + good[16:]):
        count = logged()
        viewer.wait_for(published_until(bad, lambda: logged() > count), 30, 'the malformed odometry logged')
    assert not received
    chassis = viewer.wait_for(published_until(good, lambda: [m for msg in received for m in msg.markers
                                                             if m.ns == 'chassis']), 30, 'markers of good odometry')
    assert (chassis[0].pose.position.x, chassis[0].pose.position.y) == (0.5, 0.25)


def test_an_unwatched_viewer_reads_only_the_odometry_and_the_reference_path(viewer):
    """The wheels' and contact topics (1 kHz each) are subscribed only while markers have a subscriber."""
    def viewer_reads(topic: topics.Topic) -> bool:
        return any(info.node_name == '_viewer_inputs'
                   for info in viewer.node.get_subscriptions_info_by_topic(topic.resolve()))
    per_step = (topics.WHEEL_STATES, topics.WHEEL_CONTACT)
    viewer.wait_for(lambda: viewer_reads(topics.ODOM) and viewer_reads(topics.REFERENCE_PATH), 30, 'the viewer')
    assert not any(viewer_reads(topic) for topic in per_step + (topics.DRIVE_FORCES,))
    markers = viewer.node.create_subscription(MarkerArray, topics.MARKERS.resolve(), lambda _msg: None,
                                              qos_profile(topics.MARKERS))
    viewer.wait_for(lambda: all(viewer_reads(topic) for topic in per_step), 30, 'the viewer reading them all')
    assert not viewer_reads(topics.DRIVE_FORCES)  # the arrows are wheel_contact's forces
    viewer.node.destroy_subscription(markers)
    viewer.wait_for(lambda: not any(viewer_reads(topic) for topic in per_step), 30, 'the viewer dropping them')
    assert viewer_reads(topics.ODOM)


def test_a_viewer_renamed_on_its_command_line_is_the_only_node_of_its_name(process_runner):
    """``ros2 launch`` starts a node with ``-r __node:=NAME`` (and ``-r __ns:=NS``): the name is the viewer's
    alone, so the graph has one node of it, and the viewer's hidden input node reads the viewer's topics."""
    process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.viewer', '--ros-args', '-r', '__node:=viewer',
                          '-r', '__ns:=/robot2'], 'viewer')
    graph = Graph(process_runner, namespace='/robot2')
    try:
        graph.wait_for(lambda: any(info.node_namespace == '/robot2'
                                   for info in graph.node.get_subscriptions_info_by_topic('/robot2/odom')), 30,
                       'the viewer reading /robot2/odom')
        names = graph.node.get_node_names_and_namespaces()
        assert sorted(name for name, namespace in names if namespace == '/robot2') == ['_viewer_inputs', 'viewer']
        assert [info.node_name for info in graph.node.get_subscriptions_info_by_topic('/robot2/odom')
                if info.node_namespace == '/robot2'] == ['_viewer_inputs']
    finally:
        graph.close()


def test_a_port_in_use_is_one_line_and_exit_status_1(process_runner):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        viewer = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.viewer', '--ros-args',
                                       '-p', f'foxglove_port:={port}'], 'viewer')
        assert viewer.wait(timeout=60) == 1
    errors = [line for line in process_runner.output('viewer').splitlines() if line.startswith('error:')]
    assert len(errors) == 1 and errors[0].startswith(f'error: cannot serve Foxglove on 127.0.0.1:{port}: ')
    assert 'Traceback' not in process_runner.output('viewer')


def test_a_run_goes_on_without_its_viewer(tmp_path, process_runner):
    """The viewer only shows the run: when it cannot start (its port is taken), the run says so and
    goes on until stopped."""
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        run = process_runner.start([*WALLBOT, 'run', 'circle', '--duration', '0', '--foxglove', port,
                                    '--out', tmp_path / 'run', '--no-plots'], 'run')
        log = tmp_path / 'run' / 'logs' / 'viewer.log'
        wait_for_output(process_runner, 'run', re.escape(f'node viewer exited with status 1 (its log: {log}); '
                                                         'no markers or live view from now on, the run goes on'), 120)
    shown = len(re.findall(r't = +[0-9.]+ s \(until stopped\)', process_runner.output('run')))
    wait_for_output(process_runner, 'run', r'(?s)(t = +[0-9.]+ s \(until stopped\).*){%d}' % (shown + 2), 60)
    run.send_signal(signal.SIGINT)
    assert run.wait(timeout=60) == 130
    assert 'tracking error:' in process_runner.output('run') and 'Traceback' not in process_runner.output('run')
