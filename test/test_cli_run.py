"""``wallbot-sim run``: the real graph in separate processes, recorded, compared with ``simulate``."""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from cli_helpers import WALLBOT, wait_for_output
from message_fields import planar_state
from wallbot_msgs_py import bagio, codec
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.rundata import summarize
from wallbot_sim.graph import child_processes
from wallbot_sim.plots.figures import FIGURES

mcap_reader = pytest.importorskip('mcap.reader')


def odometry(bag: Path) -> np.ndarray:
    """(stamp ns, x, y, theta, vx, vy, omega) of every odometry message, read with the mcap package."""
    rows = []
    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        for schema, _channel, message in mcap_reader.make_reader(stream).iter_messages(topics=['/wallbot/odom']):
            msg = bagio.deserialize(message.data, schema.name)
            rows.append((*planar_state(msg),))
    return np.array(rows)


def stamped_topics(bag: Path) -> dict[str, tuple[str, list[int | None]]]:
    """Each topic of a bag with messages: its type and the stamps of its messages (a header's or a /clock's, in
    order of their stamps; None for a message without one)."""
    from wallbot_sim.bag.reader import messages
    found: dict[str, tuple[str, list[int | None]]] = {}
    for raw in messages(bag):
        stamped = raw.type not in ('diagnostic_msgs/msg/DiagnosticStatus', 'std_msgs/msg/String')
        found.setdefault(raw.topic, (raw.type, []))[1].append(codec.leading_stamp_ns(raw.data) if stamped else None)
    return {name: (kind, sorted(stamps, key=lambda stamp: stamp or 0)) for name, (kind, stamps) in found.items()}


def urdf_links(urdf: str) -> set[str]:
    """The link names of a URDF document, read by yourdfpy (an independent parser)."""
    import io
    yourdfpy = pytest.importorskip('yourdfpy')
    return {link.name for link in yourdfpy.URDF.load(io.StringIO(urdf), load_meshes=False).robot.links}


@pytest.mark.parametrize('scenario, factor, duration', [('circle', 1.0, 2.0), ('figure8', 0.0, 1.5)])
def test_run_records_what_simulate_computes(tmp_path, scenario, factor, duration):
    out = tmp_path / 'run'
    result = subprocess.run([*WALLBOT, 'run', scenario, '--duration', str(duration), '--real-time-factor', str(factor),
                             '--out', str(out)], capture_output=True, text=True, timeout=180)
    assert result.returncode == 0, result.stderr + result.stdout
    assert 'real-time factor' in result.stderr
    for line in ('tracking error:', 'constraint wrench:', 'drive forces:', 'constraint residual:', 'adsorption force:',
                 f'bag:                 {out / "bag"}'):
        assert line in result.stdout
    meta = yaml.safe_load((out / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['storage_identifier'] == 'mcap'
    recorded = odometry(out / 'bag')
    steps = round(duration * 1000)
    assert len(recorded) == steps + 1
    assert np.all(np.diff(recorded[:, 0]) == 1_000_000) and recorded[0, 0] == 0

    headless = tmp_path / 'headless'
    assert subprocess.run([*WALLBOT, 'simulate', '--scenario', scenario, '--constraints', 'belt,non_lateral,nonslip',
                           '--duration', str(duration), '--bag', str(headless), '--quiet'],
                          capture_output=True, timeout=120).returncode == 0
    expected = odometry(headless)
    assert np.array_equal(recorded[:, 0], expected[:, 0])
    assert np.max(np.abs(recorded[:, 1:] - expected[:, 1:])) < 1e-9
    # the headless bag is the graph's, topic for topic: the same topics of the same types, and every message
    # stamped in simulation time at the same stamps (so the same counts and rates: reference at 100 Hz, /clock
    # at 10 Hz and with the last state); /diagnostics, once a wall second in the graph, is there in both
    graph_topics, headless_topics = stamped_topics(out / 'bag'), stamped_topics(headless)
    assert {name: kind for name, (kind, _stamps) in graph_topics.items()} == {
        name: kind for name, (kind, _stamps) in headless_topics.items()}
    for name, (_kind, stamps) in graph_topics.items():
        if name != '/diagnostics':
            assert stamps == headless_topics[name][1], name
    assert len(graph_topics['/wallbot/reference'][1]) == round(100 * duration) + 1
    assert len(graph_topics['/diagnostics'][1]) >= 1 <= len(headless_topics['/diagnostics'][1])
    # the residual peak comes from every step (the diagnostics carry each window's maximum), not
    # from 1 Hz samples: the same as the headless run's, to the diagnostics' 6 digits
    assert summarize(out / 'bag').max_residual == pytest.approx(summarize(headless).max_residual, rel=1e-5)

    plots = sorted((out / 'plots').glob('*.png'))
    assert sorted(p.stem for p in plots) == sorted(set(FIGURES) - {'machine'})  # no motor or vacuum block
    assert all(p.stat().st_size > 10_000 for p in plots)


def test_a_graph_on_the_numba_engine_records_what_simulate_on_it_computes(tmp_path):
    """run on its default engine, numba (factor 0): the odometry is simulate --engine numba's exactly
    (the same compiled steps on the same plans) and the Python model's to 1e-9 relative. The run
    compiles the kernel, or loads it from numba's cache, before its nodes start."""
    from wallbot_sim.model.batch import kernel
    if not kernel.available():
        pytest.skip('numba is not installed')
    out = tmp_path / 'run'
    result = subprocess.run([*WALLBOT, 'run', 'circle', '--duration', '1', '--real-time-factor', '0',
                             '--realtime-priority', '50', '--no-plots', '--out', str(out)], capture_output=True, text=True,
                            timeout=240)
    assert result.returncode == 0, result.stderr + result.stdout
    from wallbot_msgs_py import bagio
    from wallbot_sim.bag.reader import messages
    policies = {item.value for raw in messages(out / 'bag', ['/diagnostics'])
                for status in bagio.deserialize(raw.data, raw.type).status if 'simulation' in status.name
                for item in status.values if item.key == 'loop priority'}
    assert policies == {'SCHED_FIFO 50 while paced'}  # --realtime-priority reached the node (factor 0: no sleep)
    recorded = odometry(out / 'bag')
    bags = {}
    for engine in ('numba', 'python'):
        bags[engine] = tmp_path / engine
        simulated = subprocess.run([*WALLBOT, 'simulate', '--scenario', 'circle', '--constraints',
                                    'belt,non_lateral,nonslip', '--duration', '1', '--engine', engine, '--bag',
                                    str(bags[engine]), '--quiet'], capture_output=True, text=True, timeout=240)
        assert simulated.returncode == 0, simulated.stderr
    assert len(recorded) == 1001 and np.array_equal(recorded, odometry(bags['numba']))
    python = odometry(bags['python'])
    assert np.array_equal(recorded[:, 0], python[:, 0])
    scale = np.max(np.abs(python[:, 1:]), axis=0)
    assert np.all(np.abs(recorded[:, 1:] - python[:, 1:]) <= 1e-9 * scale)


def start_run(process_runner, out: Path, *extra: str) -> subprocess.Popen:
    """A long circle run, returned once its progress line shows more than a second simulated."""
    process = process_runner.start([*WALLBOT, 'run', 'circle', '--duration', '60', '--out', str(out), '--no-plots',
                                    *extra], 'run')
    deadline = time.monotonic() + 90
    while True:
        assert process.poll() is None, process_runner.output('run')
        assert time.monotonic() < deadline, 'the graph did not come up: ' + process_runner.output('run')
        shown = re.findall(r't = +([0-9.]+) /', process_runner.output('run'))
        if shown and float(shown[-1]) > 1.0:
            return process
        time.sleep(0.2)


@pytest.mark.parametrize('compose, node', [('--compose', 'dynamics_recorder'), ('--no-compose', 'dynamics')])
def test_a_node_that_dies_ends_the_run_with_its_status_and_log(tmp_path, process_runner, compose, node):
    out = tmp_path / 'run'
    process = start_run(process_runner, out, compose)
    dynamics = [pid for pid, cmd in child_processes(process.pid).items()
                if re.search(rf'wallbot_sim\.nodes\.{node}\b', cmd)]
    assert len(dynamics) == 1
    os.kill(dynamics[0], signal.SIGKILL)
    assert process.wait(timeout=60) == 1
    error = process_runner.output('run').strip().splitlines()[-1]
    assert f'node {node} exited with status -9' in error and str(out / 'logs' / f'{node}.log') in error
    assert 'partial bag kept' in error
    # composed, the recorder died with the dynamics, its bag unclosed: run rebuilt its index and metadata
    assert ('its recorder did not close it; reindexed' in error) == (node == 'dynamics_recorder')
    assert (out / 'bag' / 'metadata.yaml').is_file() and len(odometry(out / 'bag')) > 500
    assert child_processes(process.pid) == {}


@pytest.mark.parametrize('sig, status', [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_stopping_the_run_stops_the_graph_and_keeps_a_readable_bag(tmp_path, process_runner, sig, status):
    out = tmp_path / 'run'
    process = start_run(process_runner, out)
    nodes = list(child_processes(process.pid))
    os.kill(process.pid, sig)
    assert process.wait(timeout=60) == status
    assert 'Traceback' not in process_runner.output('run')
    for pid in nodes:
        assert not Path(f'/proc/{pid}').exists() or 'zombie' in Path(f'/proc/{pid}/status').read_text()
    recorded = odometry(out / 'bag')
    assert len(recorded) > 500 and np.all(np.diff(recorded[:, 0]) == 1_000_000)


@pytest.mark.parametrize('args, message', [
    (['square'], "unknown scenario 'square'"),
    (['circle', '--real-time-factor', '-1'], 'argument --real-time-factor: must be 0 (as fast as possible) or in'),
    (['circle', '--real-time-factor', '0.0005'], 'argument --real-time-factor: must be 0'),
    (['circle', '--duration', '-1'], 'argument --duration: must be 0 (never) or in (0, 1e+09], got -1.0'),
    (['circle', '--domain-id', '0'], "argument --domain-id: must be an integer in 1..101 (0 is the domain"),
    (['circle', '--domain-id', '102'], "argument --domain-id: must be an integer in 1..101"),
    (['circle', '--domain-id', 'seven'], "got 'seven'"),
    (['circle', '--constraints', 'glue'], "unknown constraint 'glue'"),
    (['circle', '--out', '/proc/wallbot'], 'cannot write to output directory /proc/wallbot'),
    (['circle', '--constraints', 'belt', '--tangent-heading'], '--tangent-heading acts with non_lateral'),
    (['circle', '--foxglove', '70000'], 'argument --foxglove: must be in [0, 65535], got 70000'),
    (['circle', '--foxglove-host', '0.0.0.0'], '--foxglove-host needs --foxglove'),
    (['circle', '--engine', 'fortran'], "argument --engine: must be one of python, numba, got 'fortran'"),
    (['circle', '--realtime-priority', '100'], 'argument --realtime-priority: must be in [0, 99], got 100'),
    (['circle', '--adhesion-force', '2e6'], "argument --adhesion-force: must be 0 (the robot file's) or in (0, 1e+06]"),
])
def test_bad_arguments_give_one_line(args, message):
    result = subprocess.run([*WALLBOT, 'run', *args], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr


def test_the_default_engine_without_numba_names_the_package_and_the_other_engine(monkeypatch):
    from wallbot_sim.cli import engine
    from wallbot_sim.cli.errors import CliError
    monkeypatch.setattr(engine, 'find_spec', lambda name: None if name == 'numba' else object())
    with pytest.raises(CliError, match=r"^engine 'numba' needs the numba package \(pip install numba\), or --engine "
                                       r'python$'):
        engine.require_compiled_engine()


def test_the_start_clock_leaves_the_kernels_load_out_and_says_once_when_it_takes_long():
    """run's start timeouts do not count the time the dynamics says it loads its compiled kernel (a machine's
    first run compiles it for about a minute), up to COMPILE_LIMIT; past COMPILE_NOTICE of it, the terminal is
    told once why the start takes long. A load from numba's cache, shorter, says nothing."""
    from wallbot_sim.cli.engine import COMPILE_LIMIT, COMPILE_NOTICE, StartClock
    clock = StartClock(100.0)
    assert not clock.tick(101.0, loading=False) and clock.waited() == pytest.approx(1.0)
    assert not clock.tick(101.0 + COMPILE_NOTICE / 2, loading=True)  # a load from the cache: nothing said
    assert clock.waited() == pytest.approx(1.0)
    said = [clock.tick(101.0 + COMPILE_NOTICE / 2 + seconds, loading=True) for seconds in range(1, 60)]
    assert said.count(True) == 1 and said.index(True) == math.ceil(COMPILE_NOTICE / 2) - 1
    assert not clock.tick(170.0, loading=False)
    assert clock.waited() == pytest.approx(1.0 + 170.0 - (101.0 + COMPILE_NOTICE / 2 + 59))
    endless = StartClock(0.0)
    endless.tick(COMPILE_LIMIT + 50.0, loading=True)
    assert endless.waited() == pytest.approx(50.0)  # a load that never ends is not waited for for ever


def test_an_existing_bag_is_never_overwritten(tmp_path):
    (tmp_path / 'bag').mkdir()
    result = subprocess.run([*WALLBOT, 'run', 'circle', '--out', str(tmp_path)], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2 and 'exists already' in result.stderr


def test_a_headless_bag_holds_the_messages_of_a_graph_run(tmp_path):
    """simulate --bag and run (factor 0) of the same scenario and duration: every topic both write
    carries the same messages, field for field; diagnostics apart from their wall-clock figures
    and the moments they were sent at. The robot model is in both, once: a URDF an independent
    parser reads, naming the robot's links."""
    from bag_helpers import by_topic, diagnostics_without_wall_clock, fields, stamp_ns
    from wallbot_msgs_py import topics
    from wallbot_sim import messages
    from wallbot_sim.urdf import wheel_link

    graph_out, headless = tmp_path / 'run', tmp_path / 'headless'
    result = subprocess.run([*WALLBOT, 'run', 'circle', '--duration', '1', '--real-time-factor', '0', '--no-plots',
                             '--engine', 'python', '--out', str(graph_out)], capture_output=True, text=True,
                            timeout=180)
    assert result.returncode == 0, result.stderr
    result = subprocess.run([*WALLBOT, 'simulate', '--scenario', 'circle', '--constraints', 'belt,non_lateral,nonslip',
                             '--duration', '1', '--engine', 'python', '--bag', str(headless), '--quiet'],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    graph, alone = by_topic(graph_out / 'bag'), by_topic(headless)
    assert set(graph) == set(alone) == {t.resolve() for t in topics.NOISELESS_RECORDED}

    clocks = round(1.0 * messages.CLOCK_RATE_HZ) + 1  # every period of 1 s from t = 0, and t = 1 s
    for topic, count in ((topics.ODOM, 1001), (topics.WHEEL_STATES, 1001), (topics.CONSTRAINT_WRENCH, 1001),
                         (topics.DRIVE_FORCES, 1001), (topics.CLOCK, clocks)):
        name = topic.resolve()
        assert len(graph[name]) == count, name
        assert [fields(m) for m in graph[name]] == [fields(m) for m in alone[name]], name
    # the reference pose at the trajectory node's rate, on its grid of 1 / publish_rate_hz from t = 0 to the last
    # state, none missing (the node publishes every grid point each /clock has passed, however rarely /clock
    # comes): the same poses as the headless bag's, at the same rate
    references = graph[topics.REFERENCE.resolve()]
    period_ns = round(1e9 / messages.PUBLISH_RATE_HZ)
    assert [stamp_ns(m) for m in references] == [k * period_ns for k in range(round(1e9 / period_ns) + 1)]
    assert [fields(m) for m in references] == [fields(m) for m in alone[topics.REFERENCE.resolve()]]
    for topic in (topics.REFERENCE_TRAJECTORY, topics.REFERENCE_PATH, topics.CONSTRAINTS):
        name = topic.resolve()
        # latched (transient-local): DDS may deliver the sample again when a match is re-established
        # on a loaded machine (seen: the constraints twice, 2 s apart); the same message either way
        distinct = []
        for m in graph[name]:
            if fields(m) not in distinct:
                distinct.append(fields(m))
        assert distinct == [fields(m) for m in alone[name]], name
    description = [m.data for m in graph[topics.ROBOT_DESCRIPTION.resolve()]]
    # latched: DDS may deliver it again to a recorder (seen with constraints); never a different document
    assert description and set(description) == {description[0]}
    assert [m.data for m in alone[topics.ROBOT_DESCRIPTION.resolve()]] == description[:1]
    assert urdf_links(description[0]) == {topics.WALL_FRAME, topics.BASE_FRAME,
                                          *(wheel_link(joint) for joint in topics.WHEEL_JOINTS)}

    def running(messages):
        return {diagnostics_without_wall_clock(m, same_moments=False) for m in messages
                if m.status[0].values[0].value == 'running' or m.status[0].values[0].value.startswith('stopped')}

    graph_diagnostics = running(graph['/diagnostics'])
    assert graph_diagnostics and graph_diagnostics == running(alone['/diagnostics'])


def test_a_domain_another_run_holds_is_refused(tmp_path, ros_domain):
    result = subprocess.run([*WALLBOT, 'run', 'circle', '--domain-id', str(ros_domain.domain_id),
                             '--out', str(tmp_path / 'run')], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f'ROS_DOMAIN_ID {ros_domain.domain_id} is in use by another run' in lines[0], \
        result.stderr
    assert result.stdout == '' and not (tmp_path / 'run').exists()


def test_another_terminal_attaches_with_the_printed_export_until_ctrl_c(tmp_path, process_runner):
    """A run until stopped (--duration 0) in a chosen domain: a separate process given nothing but
    the printed first line (on top of this session's own domain, which cannot see the run) receives
    its odometry; Ctrl-C then ends the run with status 130, the summary and a closed bag."""
    with claim_domain_id() as free:  # a domain no other claim holds; the run claims it again
        chosen = free.domain_id
    out = tmp_path / 'run'
    run = process_runner.start([*WALLBOT, 'run', 'circle', '--duration', '0', '--domain-id', chosen,
                                '--out', out, '--no-plots'], 'run')
    first = wait_for_output(process_runner, 'run', r'\A.*\n', 60).group(0)
    assert first.startswith(f'export ROS_DOMAIN_ID={chosen} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST  # ')
    assert os.environ['ROS_DOMAIN_ID'] != str(chosen)

    probe = Path(__file__).with_name('odom_probe.py')
    attached = process_runner.start(['bash', '-c', f'{first}exec {sys.executable} {probe}'], 'attached')
    assert wait_for_output(process_runner, 'attached', r'^domain (\d+)$', 30).group(1) == str(chosen)
    # the probe exits once it has odometry; a stall of the run shows as its progress not moving
    wait_for_output(process_runner, 'attached', r'^odom [0-9.]+$', 120)
    assert attached.wait(timeout=30) == 0

    wait_for_output(process_runner, 'run', r't = +[0-9.]+ s \(until stopped\)', 60)
    os.kill(run.pid, signal.SIGINT)
    assert run.wait(timeout=60) == 130
    output = process_runner.output('run')
    assert 'Traceback' not in output and 'until Ctrl-C at real-time factor 1' in output
    assert 'wallbot-sim run: stopped by Ctrl-C' in output and 'interrupted' not in output
    assert 'tracking error:' in output and f'bag:                 {out / "bag"}' in output
    meta = yaml.safe_load((out / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['custom_data']['wallbot.recorder.stop_signal'] == 'SIGINT'
    recorded = odometry(out / 'bag')
    assert len(recorded) > 0 and recorded[0, 0] == 0 and np.all(np.diff(recorded[:, 0]) == 1_000_000)


STEP_TOPICS = ('/wallbot/odom', '/wallbot/wheel_states', '/wallbot/constraint_wrench', '/wallbot/drive_forces',
               '/wallbot/wheel_contact', '/wallbot/clock')
"""The dynamics' per-step topics: what a composed run (--compose) records in process."""


def step_messages(bag: Path) -> tuple[dict[str, dict[int, bytes]], list[int]]:
    """{topic: {stamp ns: CDR bytes}} of the per-step topics, and every log time in file order."""
    by_topic: dict[str, dict[int, bytes]] = {name: {} for name in STEP_TOPICS}
    log_times = []
    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        for _schema, channel, message in mcap_reader.make_reader(stream).iter_messages(log_time_order=False):
            log_times.append(message.log_time)
            if channel.topic in by_topic:
                stamp = codec.leading_stamp_ns(message.data)
                assert stamp not in by_topic[channel.topic], f'{channel.topic} at {stamp} twice'
                by_topic[channel.topic][stamp] = message.data
    return by_topic, log_times


@pytest.mark.parametrize('engine', ['python', 'numba'])
def test_a_composed_run_records_the_bytes_a_separate_recorder_does(tmp_path, engine):
    """run --compose (the per-step topics through the in-process tap) and --no-compose (all over DDS) of the
    same scenario at factor 0: the same per-step messages byte for byte, a step every 1 ms, the
    log times never going back in the file; the robot model recorded by each. On the numba engine
    the dynamics takes its steps in blocks at factor 0, encoded at once. And composed at factor 2:
    the same bytes again (on the numba engine its blocks go to the tap ahead of their due times,
    nobody outside hearing them), its log times never going back either."""
    from bag_helpers import by_topic
    from wallbot_sim.config import load_robot_parameters
    from wallbot_sim.urdf import robot_urdf
    if engine == 'numba':
        from wallbot_sim.model.batch import kernel
        if not kernel.available():
            pytest.skip('numba is not installed')

    bags = {}
    for label, extra in (('composed', ['--compose', '--real-time-factor', '0']),
                         ('separate', ['--no-compose', '--real-time-factor', '0']),
                         ('paced', ['--compose', '--real-time-factor', '2'])):
        out = tmp_path / label
        result = subprocess.run([*WALLBOT, 'run', 'circle', '--duration', '1.5',
                                 '--engine', engine, '--no-plots', '--out', str(out), *extra],
                                capture_output=True, text=True, timeout=180)
        assert result.returncode == 0, result.stderr + result.stdout
        bags[label] = out / 'bag'
    meta = yaml.safe_load((bags['composed'] / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['custom_data']['wallbot.recorder'] == 'dynamics_recorder_node'
    composed, log_times = step_messages(bags['composed'])
    separate, _ = step_messages(bags['separate'])
    paced, paced_log_times = step_messages(bags['paced'])
    assert log_times == sorted(log_times) and paced_log_times == sorted(paced_log_times)
    steps = list(range(0, 1_500_000_001, 1_000_000))
    for name in STEP_TOPICS[:-1]:
        assert sorted(composed[name]) == steps, name
    assert len(composed['/wallbot/clock']) > 10
    assert composed == separate
    assert paced == separate
    for bag in bags.values():  # the robot model, subscribed over DDS by both recorders
        recorded = [m.data for m in by_topic(bag)['/wallbot/robot_description']]
        assert recorded and set(recorded) == {robot_urdf(load_robot_parameters())}


def test_a_composed_run_stopped_by_ctrl_c_logs_nothing_after_the_signal(tmp_path, process_runner):
    """Ctrl-C mid-run with --compose: the composed process ends the recording at its signal; the
    bag is readable, nothing in it is logged after stop_time_ns, and every step in it is whole
    (the tap writes a step's messages together) and consecutive from t = 0."""
    out = tmp_path / 'run'
    process = start_run(process_runner, out, '--compose')
    nodes = child_processes(process.pid)
    assert [cmd for cmd in nodes.values() if 'wallbot_sim.nodes.dynamics_recorder' in cmd]
    assert not [cmd for cmd in nodes.values() if 'wallbot_sim.nodes.recorder' in cmd
                or re.search(r'wallbot_sim\.nodes\.dynamics\b(?!_)', cmd)]
    os.kill(process.pid, signal.SIGINT)
    assert process.wait(timeout=60) == 130
    log = (out / 'logs' / 'dynamics_recorder.log').read_text()
    assert 'stopped by SIGINT' in log and 'Traceback' not in log + process_runner.output('run')
    from wallbot_msgs_py import topics
    from wallbot_sim.nodes.state_publisher import STEP_TOPICS as TAPPABLE
    in_process = sum(topic in TAPPABLE for topic in topics.RECORDED)  # the dynamics' per-step topics, through the tap
    assert f'recording {len(topics.RECORDED)} topics ({in_process} of them in process)' in log, log
    for pid in nodes:
        assert not Path(f'/proc/{pid}').exists() or 'zombie' in Path(f'/proc/{pid}/status').read_text()
    meta = yaml.safe_load((out / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['custom_data']['wallbot.recorder.stop_signal'] == 'SIGINT'
    stop_ns = int(meta['custom_data']['wallbot.recorder.stop_time_ns'])
    by_topic, log_times = step_messages(out / 'bag')
    assert log_times == sorted(log_times) and log_times[-1] <= stop_ns
    odom = sorted(by_topic['/wallbot/odom'])
    assert len(odom) > 500 and odom == list(range(0, odom[-1] + 1, 1_000_000))
    for name in STEP_TOPICS[1:-1]:
        assert sorted(by_topic[name]) == odom, name


def test_the_monitor_hears_the_stop_its_dynamics_reported_before_it_joined(ros_domain):
    """The end of a run waits for the status the dynamics publishes once it stops. A monitor whose discovery of the
    dynamics came after that status (the dynamics publishes the next one a second later) still gets it with the
    match: published once, before the monitor joins, never again, it must arrive."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from wallbot_msgs_py import topics
    from wallbot_msgs_py.qos import offered_qos_profile
    from wallbot_sim.graph_monitor import Monitor

    context = rclpy.Context()
    rclpy.init(context=context)
    monitor = None
    try:
        node = rclpy.create_node('dynamics', namespace=topics.NAMESPACE, context=context)
        diagnostics = node.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name,
                                            offered_qos_profile(topics.DIAGNOSTICS))  # as the dynamics offers it
        diagnostics.publish(DiagnosticArray(status=[DiagnosticStatus(
            name='/wallbot/dynamics: simulation', values=[KeyValue(key='status', value='running')])]))
        diagnostics.publish(DiagnosticArray(status=[DiagnosticStatus(
            name='/wallbot/dynamics: simulation',
            values=[KeyValue(key='status', value='stopped at t = 1.000 s (stop_at)')])]))
        monitor = Monitor()
        deadline = time.monotonic() + 30
        while not monitor.dynamics_stopped():
            assert time.monotonic() < deadline, f'the stop not heard; the status heard: {monitor.status!r}'
            monitor.spin(0.05)
        node.destroy_node()
    finally:
        if monitor is not None:
            monitor.close()
        rclpy.try_shutdown(context=context)


FOREIGN_STATUS_PUBLISHER = """
import time, rclpy
from diagnostic_msgs.msg import DiagnosticArray
from wallbot_msgs_py import topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.graph_monitor import Monitor
context = rclpy.Context()
rclpy.init(context=context)
node = rclpy.create_node('diagnostic_updater', context=context)
node.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name, qos_profile(topics.DIAGNOSTICS))  # volatile
monitor = Monitor()
deadline = time.monotonic() + 30
while not monitor.unheard_status_publishers:
    assert time.monotonic() < deadline, 'the volatile publisher not discovered: a stall'
    monitor.spin(0.05)
print('unheard', monitor.unheard_status_publishers, flush=True)
monitor.close()
node.destroy_node()
rclpy.try_shutdown(context=context)
"""
"""Another program's volatile /diagnostics publisher beside a monitor, until the monitor has counted it."""


def test_the_monitor_passes_over_another_programs_status_publisher_without_a_warning(ros_domain):
    """A volatile /diagnostics publisher (another program's, as a diagnostic_updater's) does not match the monitor's
    transient-local reader: it is counted, and not warned about on run's terminal as rclpy would by default."""
    result = subprocess.run([sys.executable, '-c', FOREIGN_STATUS_PUBLISHER], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ['unheard', '1']
    assert 'incompatible' not in result.stderr.lower(), result.stderr


def test_the_dynamics_diagnostics_reach_a_subscriber_with_ros_default_qos(ros_domain):
    """/diagnostics stays a topic for the ROS tools: a subscriber with rclpy's default QoS (reliable, volatile, depth
    10), as a diagnostics aggregator has, matches the dynamics' transient-local publisher and gets its statuses."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from rclpy.executors import SingleThreadedExecutor

    from wallbot_msgs_py import topics
    from wallbot_msgs_py.qos import offered_qos_profile

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('tools', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        heard: list[DiagnosticArray] = []
        subscription = node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS.name, heard.append, 10)
        publisher = node.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name,
                                          offered_qos_profile(topics.DIAGNOSTICS))
        deadline = time.monotonic() + 30
        while not heard:
            assert time.monotonic() < deadline, (f'nothing heard (matched: {publisher.get_subscription_count()} '
                                                 f'subscriber, {subscription.get_publisher_count()} publisher)')
            if publisher.get_subscription_count():
                publisher.publish(DiagnosticArray(status=[DiagnosticStatus(name='/wallbot/dynamics: simulation')]))
            executor.spin_once(timeout_sec=0.05)
        assert heard[0].status[0].name == '/wallbot/dynamics: simulation'
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_the_monitor_follows_its_robot_through_a_reset_and_reads_only_its_diagnostics(ros_domain):
    """run's view of the graph: the recorder's progress as it is now (after a ~/reset of the dynamics it is
    back near 0, and the progress line follows), and the status of its own robot's dynamics among every
    robot's on /diagnostics."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rosgraph_msgs.msg import Clock

    from wallbot_msgs_py import topics
    from wallbot_msgs_py.qos import offered_qos_profile, qos_profile
    from wallbot_sim.graph_monitor import Monitor

    monitor = Monitor()
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node('robots', context=context)
        progress = node.create_publisher(Clock, topics.RECORD_PROGRESS.resolve(), qos_profile(topics.RECORD_PROGRESS))
        diagnostics = node.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name,
                                            offered_qos_profile(topics.DIAGNOSTICS))  # as the dynamics offers it

        def spin_until(condition, what: str) -> None:
            deadline = time.monotonic() + 30
            while not condition():
                assert time.monotonic() < deadline, what
                monitor.spin(0.05)

        spin_until(lambda: progress.get_subscription_count() and diagnostics.get_subscription_count(), 'matched')
        for seconds in (5.0, 0.25):  # the run, then its reset
            message = Clock()
            message.clock.sec, message.clock.nanosec = int(seconds), round(seconds % 1 * 1e9)
            progress.publish(message)
            spin_until(lambda: monitor.recorded == seconds, f'recorded {seconds} s')

        def status(node_name: str, state: str) -> DiagnosticStatus:
            return DiagnosticStatus(name=f'{node_name}: simulation', values=[KeyValue(key='status', value=state)])
        diagnostics.publish(DiagnosticArray(status=[status('/wallbot/dynamics', 'running'),
                                                    status('/robot2/dynamics', 'stopped at t = 3.000 s (stop_at)')]))
        spin_until(lambda: monitor.diagnostics, 'diagnostics')
        assert monitor.diagnostics['status'] == 'running' and not monitor.dynamics_stopped()
        diagnostics.publish(DiagnosticArray(status=[status('/robot2/dynamics', 'stopped at t = 3.000 s (stop_at)')]))
        diagnostics.publish(DiagnosticArray(status=[status('/wallbot/dynamics', 'paused')]))
        spin_until(lambda: monitor.diagnostics['status'] == 'paused', 'the next status of /wallbot/dynamics')
        node.destroy_node()
    finally:
        monitor.close()
        rclpy.try_shutdown(context=context)
