"""Bags without ROS: headless `simulate --bag`, read back with the `mcap` package's reader (not the
writer's code path) and rosbags' CDR decoder; writer errors; reindex of a cut recording."""

from __future__ import annotations

import csv
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from message_fields import odometry_cdr, planar_state, wrench_values
from wallbot_msgs_py import bagio, codec, topics
from wallbot_sim.bag import BagError
from wallbot_sim.bag.reader import info
from wallbot_sim.bag.reindex import reindex
from wallbot_sim.bag.writer import BagWriter
from wallbot_sim.cli.main import main as cli
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.sampling import CONTROL_RATE_HZ
from wallbot_sim.plots.figures import FIGURES

mcap_reader = pytest.importorskip('mcap.reader')


def _simulate(tmp_path: Path, duration: float = 1.0, constraints: str = 'none') -> tuple[Path, Path]:
    bag, table = tmp_path / 'run', tmp_path / 'run.csv'
    assert cli(['simulate', '--scenario', 'circle', '--constraints', constraints, '--duration', str(duration),
                '--bag', str(bag), '--csv', str(table), '--quiet']) == 0
    return bag, table


def _mcap_messages(bag: Path, topic: str):
    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        reader = mcap_reader.make_reader(stream)
        for schema, _channel, message in reader.iter_messages(topics=[topic]):
            yield message, bagio.deserialize(message.data, schema.name)


def test_headless_bag_reads_back_with_an_independent_mcap_reader(tmp_path):
    bag, table = _simulate(tmp_path, duration=1.0, constraints='belt')
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['version'] == 9 and meta['storage_identifier'] == 'mcap'
    names = {t['topic_metadata']['name']: t for t in meta['topics_with_message_count']}
    assert set(names) == {t.resolve() for t in topics.NOISELESS_RECORDED}
    path_qos = names['/wallbot/reference_path']['topic_metadata']['offered_qos_profiles'][0]
    assert path_qos['durability'] == 'transient_local' and path_qos['reliability'] == 'reliable'

    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        summary = mcap_reader.make_reader(stream).get_summary()
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert schema.encoding == 'ros2msg' and len(schema.data) > 0  # definitions embedded
        assert channel.message_encoding == 'cdr' and 'offered_qos_profiles' in channel.metadata

    odom = [msg for _, msg in _mcap_messages(bag, '/wallbot/odom')]
    assert len(odom) == 1001
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in odom])
    assert np.all(np.diff(stamps) == 1_000_000)
    with open(table, newline='') as stream:
        rows = list(csv.DictReader(stream))
    got = np.array([planar_state(m)[1:4] for m in odom])
    want = np.array([[float(r['x']), float(r['y']), float(r['theta'])] for r in rows])
    assert np.max(np.abs(got - want)) < 1e-12
    wrench = [wrench_values(m) for _, m in _mcap_messages(bag, '/wallbot/constraint_wrench')]
    assert np.max(np.abs(np.array(wrench) - np.array([[float(r['Fx']), float(r['Fy']), float(r['Mz'])]
                                                      for r in rows]))) < 1e-12


def test_headless_clock_goes_at_the_clock_rate_and_with_the_last_state(tmp_path):
    """The robot's clock as the dynamics node publishes it by default: the first state of every 1 / CLOCK_RATE_HZ
    of simulation time and the state the run ends at (0.25 s, off that grid); odometry every step."""
    from wallbot_sim import messages
    bag, _ = _simulate(tmp_path, duration=0.25)
    clock = [m.clock.sec * 10**9 + m.clock.nanosec for _, m in _mcap_messages(bag, '/wallbot/clock')]
    period_ns = round(1e9 / messages.CLOCK_RATE_HZ)
    assert clock == [*range(0, 250_000_000, period_ns), 250_000_000]
    odom = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in _mcap_messages(bag, '/wallbot/odom')]
    assert odom == list(range(0, 250_000_001, 1_000_000))


def test_summary_of_the_headless_circle(tmp_path):
    from wallbot_sim.rundata import format_summary, summarize
    bag, _ = _simulate(tmp_path, duration=1.0)
    summary = summarize(bag)
    assert summary.odom_count == 1001 and summary.duration == pytest.approx(1.0)
    assert summary.peak_tracking_error == pytest.approx(0.2, abs=1e-6)  # starts 0.2 m off the circle
    assert summary.peak_constraint_force_y > 0 and summary.max_residual < 1e-6
    assert 'tracking error' in format_summary(summary)


def test_writer_refuses_existing_or_unwritable_targets(tmp_path):
    (tmp_path / 'full').mkdir()
    (tmp_path / 'full' / 'x').write_text('x')
    with pytest.raises(BagError, match='exists already'):
        BagWriter(tmp_path / 'full')
    blocker = tmp_path / 'file'
    blocker.write_text('x')
    with pytest.raises(BagError, match='not a directory'):
        BagWriter(blocker / 'bag')
    (tmp_path / 'empty').mkdir()
    with BagWriter(tmp_path / 'empty') as writer:  # an empty directory is fine
        writer.add_graph_topic(topics.CLOCK)
    assert info(tmp_path / 'empty').message_count == 0


def test_reindex_recovers_a_recording_cut_mid_chunk(tmp_path):
    bag = tmp_path / 'cut'
    writer = BagWriter(bag, flush_period=1e9)
    odom = writer.add_graph_topic(topics.ODOM)
    for i in range(3000):
        writer.write(odom, i * 1_000_000, odometry_cdr(i * 1e-3, float(i), 0.0, 0.0, 0.0, 0.0, 0.0))
        if i in (999, 1999):
            writer.flush()
    writer._writer.storage.bio.flush()
    # what a SIGKILL leaves: the file as flushed so far, cut inside the record after the 2nd flush
    data = next(bag.glob('*.mcap')).read_bytes()
    writer._writer.abort()
    shutil.rmtree(bag)
    bag.mkdir()
    (bag / 'cut.mcap').write_bytes(data + b'\x06\xff\xff\x00\x00\x00\x00\x00\x00partial')
    with pytest.raises(BagError, match='reindex'):
        info(bag)
    report = reindex(bag)
    assert report.messages == 2000 and report.truncated
    assert info(bag).topic('/wallbot/odom').count == 2000
    xs = [m.pose.pose.position.x for _, m in _mcap_messages(bag, '/wallbot/odom')]
    assert xs == [float(i) for i in range(2000)]


def test_reindex_rebuilds_missing_metadata_of_a_complete_bag(tmp_path):
    bag, _ = _simulate(tmp_path, duration=0.2)
    before = info(bag)
    (bag / 'metadata.yaml').unlink()
    report = reindex(bag)
    after = info(bag)
    assert not report.truncated and after.message_count == before.message_count
    assert [(t.name, t.count) for t in sorted(after.topics, key=lambda t: t.name)] == \
        [(t.name, t.count) for t in sorted(before.topics, key=lambda t: t.name)]


def test_without_ros_the_headless_bag_holds_the_same_messages(tmp_path):
    """Whether rclpy is installed does not change what simulate --bag writes: every message is the
    same, field for field (diagnostics apart from their wall-clock figures)."""
    import subprocess
    import sys

    from bag_helpers import by_topic, diagnostics_without_wall_clock, fields
    with_ros, without_ros = tmp_path / 'with', tmp_path / 'without'
    args = ['simulate', '--scenario', 'figure8', '--constraints', 'belt,non_lateral', '--duration', '0.3', '--quiet']
    assert cli([*args, '--bag', str(with_ros)]) == 0
    blocked = ('rclpy', 'rosidl_runtime_py', 'nav_msgs', 'geometry_msgs', 'diagnostic_msgs', 'trajectory_msgs',
               'sensor_msgs', 'std_msgs', 'rosgraph_msgs', 'builtin_interfaces')
    script = (f'import sys\nfor name in {blocked!r}:\n    sys.modules[name] = None\n'
              'from wallbot_sim.cli.main import main\nmain(sys.argv[1:])\n')
    result = subprocess.run([sys.executable, '-c', script, *args, '--bag', str(without_ros)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    a, b = by_topic(with_ros), by_topic(without_ros)
    assert sorted(a) == sorted(b) == sorted(t.resolve() for t in topics.NOISELESS_RECORDED)
    for topic in a:
        if topic == '/diagnostics':
            assert [diagnostics_without_wall_clock(m, same_moments=True) for m in a[topic]] == \
                [diagnostics_without_wall_clock(m, same_moments=True) for m in b[topic]]
        else:
            assert [fields(m) for m in a[topic]] == [fields(m) for m in b[topic]], topic


def test_a_closed_loop_bag_holds_every_command_the_controller_sent(tmp_path):
    """simulate --controller --bag: one wheel_torque_cmd per controller update, the payload that
    update produced (the loop run again here on the model, bit for bit, and the controller acting
    on the bag's own odometry, as the graph's controller node would), logged at the stamp of the
    state it answers, after that state's messages; the controller's QoS (reliable, volatile, topics.py's depth)."""
    from wallbot_sim.bag.reader import messages
    from wallbot_sim.config import load_scenario
    from wallbot_sim.control import TrackingController
    from wallbot_sim.control.sampling import SampledController, controller_robot, odometry_state
    from wallbot_sim.control.tracking import DRIVEN
    from wallbot_sim.model import Robot, Simulation

    bag = tmp_path / 'loop'
    assert cli(['simulate', '--controller', '--duration', '0.3', '--engine', 'python', '--bag', str(bag), '--quiet']) == 0

    params, scenario = load_robot_parameters(), load_scenario('circle')
    plant = Robot(params)
    simulation = Simulation(plant, scenario.reference, DRIVEN, *scenario.initial_state(plant))
    loop = SampledController(TrackingController(controller_robot(params, 1.0), scenario.reference))
    sent = []

    def control(out):
        stamp_ns = codec.to_nanoseconds(out.t)
        loop.observe(stamp_ns)
        if loop.due(stamp_ns):
            command = loop.command(odometry_state(out))
            simulation.set_motor_torque(command.tau_left, command.tau_right)
            sent.append((stamp_ns, command.tau_left, command.tau_right))
    simulation.run(0.3, control)
    assert [ns for ns, _, _ in sent] == list(range(0, 300_000_001, 10**9 // CONTROL_RATE_HZ))  # in simulation time

    name, odom_name = topics.WHEEL_TORQUE_CMD.resolve(), topics.ODOM.resolve()
    recorded, previous_odom = [], None
    for raw in messages(bag):
        if raw.topic == odom_name:
            previous_odom = codec.leading_stamp_ns(raw.data)
        elif raw.topic == name:
            assert raw.type == topics.WHEEL_TORQUE_CMD.type and previous_odom == raw.timestamp
            recorded.append((raw.timestamp, *bagio.deserialize(raw.data, raw.type).data.tolist()))
    assert recorded == sent

    # what a controller node subscribed to the bag's odometry sends: the same commands
    again = SampledController(TrackingController(controller_robot(params, 1.0), scenario.reference))
    answers = []
    for _, state in _mcap_messages(bag, odom_name):
        planar = planar_state(state)
        again.observe(planar.stamp_ns)
        if again.due(planar.stamp_ns):
            command = again.command(planar)
            answers.append((planar.stamp_ns, command.tau_left, command.tau_right))
    assert [a[0] for a in answers] == [s[0] for s in sent]
    assert np.max(np.abs(np.array(answers)[:, 1:] - np.array(sent)[:, 1:])) < 1e-9

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    described = {t['topic_metadata']['name']: t['topic_metadata'] for t in meta['topics_with_message_count']}
    assert set(described) == {t.resolve() for t in (*topics.NOISELESS_RECORDED, topics.WHEEL_TORQUE_CMD)}
    qos = described[name]['offered_qos_profiles'][0]
    assert (qos['reliability'], qos['durability'], qos['history'], qos['depth']) == \
        ('reliable', 'volatile', 'keep_last', topics.WHEEL_TORQUE_CMD.depth)


def test_the_tools_read_a_closed_loop_bag(tmp_path, capsys):
    """info, plot, compare and motors on a simulate --controller --bag bag (its wheel_torque_cmd
    and robot_description beside the step topics): motors gives back the largest torque the
    bag's commands held."""
    import json

    bag, table = tmp_path / 'loop', tmp_path / 'loop.csv'
    assert cli(['simulate', '--controller', '--duration', '0.3', '--bag', str(bag), '--csv', str(table),
                '--quiet']) == 0
    capsys.readouterr()
    assert cli(['info', str(bag)]) == 0
    listed = capsys.readouterr().out
    commands = math.floor(0.3 * CONTROL_RATE_HZ + 1e-9) + 1  # every control instant from t = 0 to 0.3 s
    assert '/wallbot/wheel_torque_cmd' in listed and f'{commands} msgs' in listed
    assert '/wallbot/robot_description' in listed
    assert cli(['plot', str(bag), '--out', str(tmp_path / 'plots')]) == 0
    assert sorted(f.stem for f in (tmp_path / 'plots').glob('*.png')) == sorted(set(FIGURES) - {'machine'})  # no motor or vacuum block
    assert cli(['compare', str(bag), str(table), '--out', str(tmp_path / 'compare')]) == 0
    assert sorted(f.stem for f in (tmp_path / 'compare').glob('*.png')) == sorted(set(FIGURES) - {'machine'})  # no motor or vacuum block
    capsys.readouterr()
    assert cli(['motors', str(bag), '--json']) == 0
    figures = json.loads(capsys.readouterr().out)
    commands = np.array([list(bagio.deserialize(raw.data, raw.type).data) for raw in _raw(bag, 'wheel_torque_cmd')])
    held = commands[:-1]  # the last answers the last state: no step of the run applied it
    for side, column in (('left', 0), ('right', 1)):
        assert figures[side]['peak_torque'] == pytest.approx(np.max(np.abs(held[:, column])), rel=1e-9), side


def _raw(bag: Path, leaf: str):
    from wallbot_sim.bag.reader import messages
    return [raw for raw in messages(bag) if raw.topic.rsplit('/', 1)[-1] == leaf]


def test_the_headless_bag_holds_the_robot_model_of_its_robot_file(tmp_path):
    """simulate --robot FILE --bag writes robot_description once, at the start (transient-local, as
    constraint_config publishes it): the URDF of that file, which an independent parser reads,
    with the chassis and the four wheel links at that file's wheel radius."""
    import io

    from wallbot_sim import paths
    from wallbot_sim.urdf import ROBOT_NAME, robot_urdf, wheel_link
    yourdfpy = pytest.importorskip('yourdfpy')

    robot = yaml.safe_load(paths.robot_yaml().read_text())
    robot['wheel_radius'], robot['half_track'] = 0.05, 0.14
    robot_file = tmp_path / 'robot.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    bag = tmp_path / 'run'
    assert cli(['simulate', '--scenario', 'circle', '--constraints', 'belt', '--duration', '0.05', '--robot',
                str(robot_file), '--bag', str(bag), '--quiet']) == 0

    name = topics.ROBOT_DESCRIPTION.resolve()
    described = list(_mcap_messages(bag, name))
    assert [record.log_time for record, _ in described] == [0]
    urdf = described[0][1].data
    assert urdf == robot_urdf(load_robot_parameters(robot_file))
    model = yourdfpy.URDF.load(io.StringIO(urdf), build_scene_graph=True, load_meshes=False)
    assert model.robot.name == ROBOT_NAME
    assert {link.name for link in model.robot.links} == {topics.WALL_FRAME, topics.BASE_FRAME,
                                                         *(wheel_link(joint) for joint in topics.WHEEL_JOINTS)}
    wheel = model.link_map[wheel_link(topics.WHEEL_JOINTS[0])]
    assert wheel.visuals[0].geometry.cylinder.radius == pytest.approx(0.05)
    assert model.get_transform(wheel.name, topics.BASE_FRAME)[1, 3] == pytest.approx(0.14)
    qos = info(bag).topic(name).offered_qos[0]
    assert qos.durability.name == 'TRANSIENT_LOCAL' and qos.depth == 1


def test_the_writer_writes_the_bytes_rosbags_writes(tmp_path):
    """BagWriter appends messages itself (``_append_message``); the bag must be rosbags' own, byte for byte:
    several topics, sizes from empty to past a chunk, log times out of order, flushes between."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ours = BagWriter(tmp_path / 'ours' / 'bag', flush_period=3600.0)  # one name: the bag names its file
    theirs = Writer(tmp_path / 'theirs' / 'bag', version=9, storage_plugin=StoragePlugin.MCAP)
    theirs.open()
    graph_topics = [topics.ODOM, topics.WHEEL_STATES, topics.CLOCK, topics.DIAGNOSTICS]
    ours_by_topic = {t: ours.add_graph_topic(t) for t in graph_topics}
    theirs_by_topic = {t: theirs.add_connection(t.resolve(topics.NAMESPACE), t.type, typestore=bagio.typestore(),
                                                serialization_format='cdr',
                                                offered_qos_profiles=bagio.offered_qos(t))
                       for t in graph_topics}
    rng = np.random.default_rng(7)
    sizes = [0, 1, 7, 700, 2**20 + 5, 40, 3000]
    for k in range(3000):
        topic = graph_topics[int(rng.integers(len(graph_topics)))]
        data = rng.bytes(sizes[k % len(sizes)] if k % 500 == 4 else int(rng.integers(0, 900)))
        log_ns = 10**9 + 1_000_000 * k + int(rng.integers(-3_000_000, 3_000_000))
        ours.write(ours_by_topic[topic], log_ns, data if k % 2 else memoryview(data))
        theirs.write(theirs_by_topic[topic], log_ns, data)
        if k % 701 == 700:
            ours.flush()
            theirs.storage.close_chunk()
    ours.close()
    theirs.close()
    assert ours.count == 3000
    for name in ('bag.mcap', 'metadata.yaml'):
        assert (tmp_path / 'ours/bag' / name).read_bytes() == (tmp_path / 'theirs/bag' / name).read_bytes()


def test_the_writer_refuses_a_connection_of_another_bag(tmp_path):
    from rosbags.rosbag2.errors import WriterError

    one, other = BagWriter(tmp_path / 'one'), BagWriter(tmp_path / 'other')
    own = [one.add_graph_topic(topics.CLOCK), one.add_graph_topic(topics.DIAGNOSTICS)]
    other.add_graph_topic(topics.CLOCK)
    stranger = other.add_graph_topic(topics.ODOM)
    assert stranger.id == own[1].id  # the channel id alone does not make it this bag's
    with pytest.raises(WriterError):
        one.write(stranger, 1, b'')
    one.close()
    other.close()
    with pytest.raises(WriterError):
        one.write(own[0], 2, b'')  # closed
