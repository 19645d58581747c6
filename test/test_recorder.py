"""recorder_node and play against small synthetic ROS processes (isolated domain, process_runner).

* SIGTERM / SIGINT: the bag is complete (metadata, summary) and holds every message.
* SIGKILL: `bag reindex` repairs it with at most the last second lost.
* play: a subscriber receives every recorded odometry message, in order.
* a signal handled in the middle of a callback never leaves a message logged after the stop.
"""

from __future__ import annotations

import shutil
import signal
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip('rclpy')
mcap_reader = pytest.importorskip('mcap.reader')

from wallbot_msgs_py import bagio  # noqa: E402
from wallbot_sim.bag.errors import BagError  # noqa: E402
from wallbot_sim.bag.reader import info  # noqa: E402
from wallbot_sim.bag.reindex import reindex  # noqa: E402
from wallbot_sim.cli.main import main as cli  # noqa: E402
from wallbot_sim.control.sampling import CONTROL_RATE_HZ  # noqa: E402

PUBLISHER = r'''
import sys, time
from wallbot_sim.heartbeat import FLOW_CONTROL_HEARTBEAT, install_heartbeat
install_heartbeat(FLOW_CONTROL_HEARTBEAT)
import rclpy
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy
from nav_msgs.msg import Odometry, Path
count, period = int(sys.argv[1]), float(sys.argv[2])
rclpy.init()
node = rclpy.create_node('synthetic', namespace='/wallbot')
odom = node.create_publisher(Odometry, 'odom', QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
latched = node.create_publisher(Path, 'reference_path', QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
latched.publish(Path())
deadline = time.monotonic() + 20
while node.count_subscribers('odom') == 0 and time.monotonic() < deadline:
    time.sleep(0.05)
print('matched', flush=True)
msg = Odometry()
start = time.monotonic()
for i in range(count):
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(i * 1_000_000, 1_000_000_000)
    msg.pose.pose.position.x = float(i)
    odom.publish(msg)
    if i % 200 == 199:
        odom.wait_for_all_acked(Duration(seconds=5))  # back-pressure: this publisher waits for the recorder
    if period:
        time.sleep(max(0.0, start + (i + 1) * period - time.monotonic()))
odom.wait_for_all_acked(Duration(seconds=5))
print('published', count, flush=True)
time.sleep(float(sys.argv[3]) if len(sys.argv) > 3 else 0)
'''

SUBSCRIBER = r'''
import sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from nav_msgs.msg import Odometry
rclpy.init()
node = rclpy.create_node('counter')
xs = []
node.create_subscription(Odometry, '/wallbot/odom',
                         lambda m: xs.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec),
                         QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
print('ready', flush=True)
expected, deadline = int(sys.argv[1]), time.monotonic() + float(sys.argv[2])
while len(xs) < expected and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
print('received', len(xs), 'in_order', xs == [i * 1_000_000 for i in range(len(xs))], flush=True)
'''


LATCHED_SUBSCRIBER = r'''
import sys, time
import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, String
rclpy.init()
node = rclpy.create_node('latched_counter')
descriptions, commands = [], []
# a transient-local reader matches only a transient-local writer: it hears play only if play latches
node.create_subscription(String, '/wallbot/robot_description', lambda m: descriptions.append(m.data), QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
node.create_subscription(Float64MultiArray, '/wallbot/wheel_torque_cmd', lambda m: commands.append(list(m.data)),
                         QoSProfile(depth=10, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
print('ready', flush=True)
expected, deadline = int(sys.argv[1]), time.monotonic() + float(sys.argv[2])
while (len(commands) < expected or not descriptions) and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
print('descriptions', len(descriptions), 'commands', repr(commands), flush=True)
print('urdf', repr(descriptions[0] if descriptions else None), flush=True)
'''


def wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f'timed out waiting for {what}')


def odom_xs(bag: Path) -> list[float]:
    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        reader = mcap_reader.make_reader(stream)
        return [bagio.deserialize(m.data, s.name).pose.pose.position.x
                for s, _c, m in reader.iter_messages(topics=['/wallbot/odom'])]


def start_recorder(process_runner, bag: Path, name: str = 'recorder'):
    return process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args',
                                 '-p', f'output:={bag}'], name)


def start_publisher(process_runner, tmp_path: Path, count: int, period: float, linger: float = 0.0):
    script = tmp_path / 'publisher.py'
    script.write_text(PUBLISHER)
    return process_runner.start([sys.executable, str(script), str(count), str(period), str(linger)], 'publisher')


@pytest.mark.parametrize('stop_signal', [signal.SIGTERM, signal.SIGINT])
def test_signal_closes_a_complete_bag_with_every_message(process_runner, tmp_path, stop_signal):
    bag = tmp_path / 'bag'
    recorder = start_recorder(process_runner, bag)
    publisher = start_publisher(process_runner, tmp_path, 3000, 0.0)  # as fast as it goes
    assert publisher.wait(timeout=60) == 0, process_runner.output('publisher')
    recorder.send_signal(stop_signal)
    assert recorder.wait(timeout=20) == 0, process_runner.output('recorder')
    meta = info(bag)
    assert meta.topic('/wallbot/odom').count == 3000
    assert meta.topic('/wallbot/reference_path').count == 1  # transient-local, recorded
    assert odom_xs(bag) == [float(i) for i in range(3000)]


def flushed_odometry(bag: Path, scratch: Path) -> int:
    """How many odometry messages a reindex recovers from what the recorder has put on disk so far
    (read from a copy, so the live bag is never touched)."""
    shutil.rmtree(scratch, ignore_errors=True)
    shutil.copytree(bag, scratch)
    try:
        reindex(scratch)
    except BagError:
        return 0  # not a single chunk on disk yet
    return len(odom_xs(scratch))


def test_sigkill_then_reindex_keeps_everything_flushed_before_the_kill(process_runner, tmp_path):
    """What the recorder had flushed when it was killed is recovered, contiguous from the first message;
    how far behind the stream the flushed part runs is a measurement (bench/bench_signals.py)."""
    bag = tmp_path / 'bag'
    recorder = start_recorder(process_runner, bag)
    publisher = start_publisher(process_runner, tmp_path, 6000, 0.001)  # 1 kHz for 6 s
    wait_for(lambda: 'matched' in process_runner.output('publisher'), 30, 'publisher to match')
    flushed = {'count': 0}

    def some_flushed() -> bool:
        flushed['count'] = flushed_odometry(bag, tmp_path / 'scratch') if bag.is_dir() else 0
        return flushed['count'] >= 500
    wait_for(some_flushed, 60, 'the recorder flushing 500 messages to disk')
    recorder.send_signal(signal.SIGKILL)
    recorder.wait(timeout=10)
    assert publisher.poll() is None, 'the recorder must be killed mid-stream'
    assert not (bag / 'metadata.yaml').exists()
    report = reindex(bag)
    assert report.messages > 0
    xs = odom_xs(bag)
    assert len(xs) >= flushed['count']
    assert xs == [float(i) for i in range(len(xs))]  # nothing missing before the cut


def test_the_bag_and_topics_are_parameters_of_the_recorder_node(process_runner, tmp_path):
    """``ros2 param get /wallbot/recorder output`` (the GetParameters service) answers what the recorder
    records, and ``ros2 param set`` cannot change it while it records."""
    from graph_helpers import Graph
    bag = tmp_path / 'bag'
    process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args', '-p', f'output:={bag}',
                          '-p', 'topics:=[odom, /wallbot/clock]'], 'recorder')
    graph = Graph(process_runner)
    try:
        assert graph.get_parameters('recorder', 'output', 'topics') == [str(bag), ['odom', '/wallbot/clock']]
        refused, = graph.set_parameters('recorder', output=str(tmp_path / 'other'))
        assert not refused.successful and 'read-only' in refused.reason
    finally:
        graph.close()


def test_unknown_topic_parameter_is_refused(process_runner, tmp_path):
    proc = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args',
                                 '-p', f'output:={tmp_path / "bag"}', '-p', 'topics:=[odom, nope]'], 'rec')
    assert proc.wait(timeout=30) == 1
    assert 'unknown topic' in process_runner.output('rec') and 'Traceback' not in process_runner.output('rec')


def test_play_republishes_every_message(process_runner, tmp_path):
    bag = tmp_path / 'run'
    assert cli(['simulate', '--scenario', 'circle', '--duration', '1.0', '--bag', str(bag), '--quiet']) == 0
    script = tmp_path / 'subscriber.py'
    script.write_text(SUBSCRIBER)
    subscriber = process_runner.start([sys.executable, str(script), '1001', '40'], 'subscriber')
    wait_for(lambda: 'ready' in process_runner.output('subscriber'), 30, 'subscriber')
    player = process_runner.start([sys.executable, '-m', 'wallbot_sim.cli.main', 'play', str(bag),
                                   '--rate', '4', '--topics', 'odom', '--wait-subscribers', '30',
                                   '--delay', '0.5', '--clock'], 'play')
    assert player.wait(timeout=60) == 0, process_runner.output('play')
    assert subscriber.wait(timeout=60) == 0
    assert 'received 1001 in_order True' in process_runner.output('subscriber'), process_runner.output('subscriber')


class _Writer:
    """The BagWriter calls the recorder node makes, keeping the written log times."""

    path = Path('memory')

    def __init__(self) -> None:
        self.log_times: list[int] = []

    def flush_if_due(self) -> None:
        pass

    def connection(self, name: str) -> str:
        return name

    def write(self, _connection: str, log_ns: int, _data: bytes) -> None:
        self.log_times.append(log_ns)


def recorder(stop, writer, recorded, tappable=()):
    """The recorder node recording ``recorded`` (its ``topics`` parameter) into ``writer``."""
    from rclpy.parameter import Parameter

    from wallbot_sim.nodes.recorder import Recorder
    return Recorder(stop, tappable, writer, parameter_overrides=[
        Parameter('topics', Parameter.Type.STRING_ARRAY, [topic.name for topic in recorded])])


class _HandlerRunsAtTheCheck:
    """A stop whose signal handler runs right after a callback read ``requested`` (a Python
    handler runs between any two bytecodes): the callback saw no stop, yet it came."""

    signum: int | None = None
    at_ns: int | None = None

    @property
    def requested(self) -> bool:
        seen = self.signum is not None
        if not seen:
            self.signum, self.at_ns = signal.SIGINT, time.time_ns()
        return seen


def test_a_message_written_around_the_signal_is_not_logged_after_it(ros_domain):
    import rclpy

    from wallbot_msgs_py import topics
    rclpy.init()
    node = None
    try:
        writer, stop = _Writer(), _HandlerRunsAtTheCheck()
        node = recorder(stop, writer, [topics.REFERENCE])
        name = node.resolve_topic_name(topics.REFERENCE.name)
        node._on_message(topics.REFERENCE, name, b'')  # the handler runs inside its check
        node._on_message(topics.REFERENCE, name, b'')  # the stop was there before it
        assert stop.requested
        assert writer.log_times[0] <= stop.at_ns, 'logged after the stop it was written before'
        assert writer.log_times[1] == stop.at_ns
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


class _Stop:
    """A stop signal the test gives by hand."""

    signum: int | None = None
    at_ns: int | None = None
    name = 'SIGINT'

    @property
    def requested(self) -> bool:
        return self.signum is not None


class _KeptWriter(_Writer):
    """_Writer that also keeps each message's topic and bytes, and its custom data."""

    def __init__(self) -> None:
        super().__init__()
        self.written: list[tuple[str, int, bytes]] = []
        self.custom: dict[str, str] = {}
        self.closed = False

    def write(self, connection: str, log_ns: int, data: bytes) -> None:
        super().write(connection, log_ns, data)
        self.written.append((connection, log_ns, data))

    def set_custom_data(self, key: str, value: str) -> None:
        self.custom[key] = value

    def close(self) -> None:
        self.closed = True


def test_a_composed_recorder_writes_the_tapped_steps_before_a_dds_message_and_none_after_the_stop(ros_domain):
    """The recorder of dynamics_recorder_node: the steps on its tap are written before a message
    it receives over DDS (log times in order), and at the stop those logged up to it are written,
    later ones counted as left out; the tapped topics have no DDS subscription."""
    import rclpy

    from wallbot_msgs_py import topics
    rclpy.init()
    node = None
    try:
        writer, stop = _KeptWriter(), _Stop()
        node = recorder(stop, writer, [topics.ODOM, topics.CLOCK, topics.REFERENCE],
                        tappable=[topics.ODOM, topics.CLOCK])
        assert node.count_subscribers('/wallbot/odom') == 0 and node.count_subscribers('/wallbot/reference') == 1
        node.tap.put([(topics.ODOM, b'odom 0'), (topics.CLOCK, b'clock 0')], clock=True)
        node.tap.put([(topics.ODOM, b'odom 1'), (topics.CLOCK, b'clock 1')], clock=False)
        node._on_message(topics.REFERENCE, '/wallbot/reference', b'reference')  # a DDS callback
        assert [(name, data) for name, _log, data in writer.written] == [
            ('/wallbot/odom', b'odom 0'), ('/wallbot/clock', b'clock 0'), ('/wallbot/odom', b'odom 1'),
            ('/wallbot/reference', b'reference')]
        assert writer.log_times == sorted(writer.log_times)

        node.tap.put([(topics.ODOM, b'odom 2')], clock=False)
        stop.signum, stop.at_ns = signal.SIGINT, time.time_ns()
        while time.time_ns() <= stop.at_ns:  # the next step is logged after the stop
            pass
        node.tap.put([(topics.ODOM, b'odom 3')], clock=False)
        node.close()
        assert [data for _name, _log, data in writer.written][4:] == [b'odom 2']
        assert writer.log_times[-1] <= stop.at_ns and node.refused == 1
        assert writer.custom['wallbot.recorder.stop_time_ns'] == str(stop.at_ns) and writer.closed
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def test_play_republishes_the_commands_and_latches_the_robot_model(process_runner, tmp_path):
    """A simulate --controller bag played: a subscriber receives every wheel_torque_cmd in order and
    the robot_description, transient-local as constraint_config offers it (its transient-local
    reader would not match a volatile publisher)."""
    import ast
    import re

    from wallbot_msgs_py import topics
    from wallbot_sim.bag.reader import messages

    bag = tmp_path / 'loop'
    assert cli(['simulate', '--controller', '--duration', '0.2', '--bag', str(bag), '--quiet']) == 0
    recorded = {raw.topic: [] for raw in messages(bag)}
    for raw in messages(bag):
        recorded[raw.topic].append(bagio.deserialize(raw.data, raw.type))
    commands = [m.data.tolist() for m in recorded[topics.WHEEL_TORQUE_CMD.resolve()]]
    assert len(commands) == round(0.2 * CONTROL_RATE_HZ) + 1  # every control instant from t = 0
    script = tmp_path / 'latched.py'
    script.write_text(LATCHED_SUBSCRIBER)
    subscriber = process_runner.start([sys.executable, str(script), str(len(commands)), '40'], 'subscriber')
    wait_for(lambda: 'ready' in process_runner.output('subscriber'), 30, 'subscriber')
    player = process_runner.start([sys.executable, '-m', 'wallbot_sim.cli.main', 'play', str(bag), '--topics',
                                   'robot_description', 'wheel_torque_cmd', '--wait-subscribers', '30',
                                   '--delay', '0.5'], 'play')
    assert player.wait(timeout=60) == 0, process_runner.output('play')
    assert subscriber.wait(timeout=60) == 0
    output = process_runner.output('subscriber')
    heard = re.search(r'^descriptions (\d+) commands (.*)$', output, re.M)
    assert heard and heard.group(1) == '1', output
    assert ast.literal_eval(heard.group(2)) == commands
    urdf = ast.literal_eval(re.search(r'^urdf (.*)$', output, re.M).group(1))
    assert urdf == recorded[topics.ROBOT_DESCRIPTION.resolve()][0].data


def test_a_starved_recorder_gets_every_command_of_a_back_pressure_window(process_runner, tmp_path):
    """A recorder process stopped (SIGSTOP: a CPU-starved one) while the graph runs the default
    backpressure_window of steps ahead of it, each step with its per-step messages and a command
    (lockstep_every 1): its transport queue overflows, and what it missed is resent from the
    writers' histories once it runs again, so every command must still be in the command
    publisher's history (topics.WHEEL_TORQUE_CMD's depth; with depth 10, 83 of 200 arrived)."""
    import rclpy
    from rclpy.duration import Duration

    from wallbot_msgs_py import topics
    from wallbot_msgs_py.qos import qos_profile
    from wallbot_sim.settings.dynamics import BACKPRESSURE_WINDOW
    from wallbot_sim.nodes.recorder import message_class

    stepped = (*topics.STEP_STAMPED, topics.CLOCK)
    bag = tmp_path / 'bag'
    names = ','.join(t.name for t in (*stepped, topics.WHEEL_TORQUE_CMD))
    recorder = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args',
                                     '-p', f'output:={bag}', '-p', f'topics:=[{names}]'], 'recorder')
    rclpy.init()
    try:
        node = rclpy.create_node('steps', namespace=topics.NAMESPACE)
        publishers = {t: node.create_publisher(message_class(t.type), t.name, qos_profile(t))
                      for t in (*stepped, topics.WHEEL_TORQUE_CMD)}
        wait_for(lambda: all(p.get_subscription_count() for p in publishers.values()), 30, 'the recorder to match')
        recorder.send_signal(signal.SIGSTOP)
        try:
            for step in range(BACKPRESSURE_WINDOW):
                for topic in stepped:
                    message = message_class(topic.type)()
                    stamp = message.clock if topic is topics.CLOCK else message.header.stamp
                    stamp.sec, stamp.nanosec = 0, step * 1_000_000
                    publishers[topic].publish(message)
                publishers[topics.WHEEL_TORQUE_CMD].publish(message_class(topics.WHEEL_TORQUE_CMD.type)(
                    data=[float(step), 0.0]))
                time.sleep(0.001)
        finally:
            recorder.send_signal(signal.SIGCONT)
        for publisher in publishers.values():  # the recorder acknowledges what its reader holds
            assert publisher.wait_for_all_acked(Duration(seconds=20))
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    recorder.send_signal(signal.SIGINT)
    assert recorder.wait(timeout=20) == 0, process_runner.output('recorder')
    meta = info(bag)
    for topic in stepped:
        assert meta.topic(topic.resolve()).count == BACKPRESSURE_WINDOW, topic.name
    assert meta.topic(topics.WHEEL_TORQUE_CMD.resolve()).count == BACKPRESSURE_WINDOW
