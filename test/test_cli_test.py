"""``wallbot-sim test`` with real controllers (child processes in a domain of their own, strict lockstep at factor 0):
the example controller passes its spec with a JUnit file the JUnit schema allows; one that publishes nothing, or
stops answering, fails the run with the reason (exit 1); one that will not start is one line and exit 2; a motor
fault makes the tracking fail after it, with the figure of the error and the fault in the bag; a spec run twice
records the same messages."""

from __future__ import annotations

import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import xmlschema
import yaml

from bag_helpers import by_topic, stamp_ns
from cli_helpers import WALLBOT, assert_one_line_error
from wallbot_msgs_py import topics
from wallbot_sim import paths
from wallbot_sim.bag.reader import info, messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.rundata import load_run
from wallbot_sim.rundata.faults import fault_events

HERE = Path(__file__).parent
EXAMPLE = HERE.parent / 'examples' / 'wallbot_example_controller'
EXAMPLE_SPEC = EXAMPLE / 'test' / 'figure8.yaml'
JUNIT_SCHEMA = HERE / 'data' / 'junit-10.xsd'
UNDER_TEST = f'{sys.executable} {HERE / "controller_under_test.py"}'


def run_test(spec: Path, out: Path, *args: object, timeout: float = 300.0):
    """``wallbot-sim test SPEC --out OUT ARGS``, the example controller's package importable."""
    import subprocess
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(filter(None, (str(EXAMPLE), os.environ.get('PYTHONPATH'))))}
    return subprocess.run([*WALLBOT, 'test', str(spec), '--out', str(out), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, env=env)


def write_spec(path: Path, **values) -> Path:
    path.write_text(yaml.safe_dump(values))
    return path


def verdicts(result) -> dict[str, str]:
    """Each verdict line the command printed, by name."""
    lines = [line for line in result.stdout.splitlines() if line.startswith(('PASS ', 'FAIL ', 'SKIP '))]
    return {line.split()[1].rstrip(':'): line for line in lines}


def test_the_example_controller_passes_its_spec_with_a_junit_file_ci_reads(tmp_path):
    result = run_test(EXAMPLE_SPEC, tmp_path / 'out', '--junit', tmp_path / 'results.xml')
    assert result.returncode == 0, result.stdout + result.stderr
    xmlschema.XMLSchema(JUNIT_SCHEMA).validate(tmp_path / 'results.xml')
    suite = ET.parse(tmp_path / 'results.xml').getroot().find('testsuite')
    names = [case.get('name') for case in suite.iter('testcase')]
    assert names == ['run', 'max_tracking_error_after', 'no_slip', 'no_detachment', 'min_adhesion_margin',
                     'max_motor_torque']
    assert suite.get('failures') == '0' and suite.get('skipped') == '0'
    for case in suite.iter('testcase'):
        assert case.find('system-out').text.startswith('measured ')
    assert all(line.startswith('PASS') for line in verdicts(result).values())
    assert '**FAIL**' not in (tmp_path / 'out' / 'report.md').read_text()


def test_a_motor_fault_makes_the_tracking_fail_after_it_with_its_figure_and_the_fault_in_the_bag(tmp_path):
    values = yaml.safe_load(EXAMPLE_SPEC.read_text())
    values['faults'] = [{'at': 0.6, 'motor_left': 0.0}]
    limit = values['expect']['max_tracking_error_after']
    result = run_test(write_spec(tmp_path / 'fault.yaml', **values), tmp_path / 'out')
    assert result.returncode == 1, result.stdout + result.stderr
    assert verdicts(result)['run'].startswith('PASS')
    assert verdicts(result)['max_tracking_error_after'].startswith('FAIL')
    case = next(case for case in ET.parse(tmp_path / 'out' / 'junit.xml').getroot().iter('testcase')
                if case.get('name') == 'max_tracking_error_after')
    worst = float(case.find('failure').text.split('worst at t = ')[1].split(' s')[0])
    run = load_run(tmp_path / 'out' / 'bag')
    before = (run.t >= limit['t']) & (run.t < 0.6)
    assert np.nanmax(run.err[before]) <= limit['m']  # it held until the fault
    assert worst > 0.6 and np.nanmax(run.err[run.t >= 0.6]) > limit['m']
    event, = fault_events(tmp_path / 'out' / 'bag')
    assert (event.stamp_ns, event.changed, event.cause) == (600_000_000, ('motor_efficiency_left',), 'scheduled')
    assert event.values['motor_efficiency_left'] == '0.0'
    assert (tmp_path / 'out' / 'plots' / 'max_tracking_error_after.png').stat().st_size > 0
    assert '![max_tracking_error_after](plots/max_tracking_error_after.png)' in (tmp_path / 'out' /
                                                                                 'report.md').read_text()


def test_a_controller_that_publishes_nothing_fails_the_run_with_the_reason(tmp_path):
    spec = write_spec(tmp_path / 'silent.yaml', scenario='rest', duration=0.2, start_timeout=2.0,
                      controller=f'{UNDER_TEST} silent', expect={'no_slip': True})
    result = run_test(spec, tmp_path / 'out')
    assert result.returncode == 1, result.stdout + result.stderr
    assert 'the controller did not answer' in verdicts(result)['run']
    assert 'start_timeout 2 s' in verdicts(result)['run']
    suite = ET.parse(tmp_path / 'out' / 'junit.xml').getroot().find('testsuite')
    run_case = next(suite.iter('testcase'))
    assert 'the controller did not answer' in run_case.find('failure').get('message')


def test_a_controller_that_stops_answering_fails_at_its_timeout_naming_the_state(tmp_path):
    spec = write_spec(tmp_path / 'mute.yaml', scenario='rest', duration=0.4, controller_timeout=0.5,
                      controller=f'{UNDER_TEST} answer 0.0 0.0 --mute-after 0.2')
    result = run_test(spec, tmp_path / 'out')
    assert result.returncode == 1, result.stdout + result.stderr
    line = verdicts(result)['run']
    assert 'the controller did not answer' in line and 'controller_timeout 0.5 s' in line
    assert 't = 0.200' in line


def test_a_controller_that_will_not_start_is_one_line_and_exit_status_2(tmp_path):
    for command, words in ((f'{UNDER_TEST} exit 3', 'the controller exited with status 3 before the run began'),
                           ('no-such-controller-here', "cannot start the controller 'no-such-controller-here'")):
        spec = write_spec(tmp_path / 'broken.yaml', scenario='rest', duration=0.2, controller=command)
        result = run_test(spec, tmp_path / f'out-{command[-1]}')
        assert result.returncode == 2, result.stdout + result.stderr
        assert_one_line_error(result, 'wallbot-sim test: error:', words)


def test_a_spec_s_world_and_dropped_imu_reach_the_run(tmp_path):
    """On the floor (the spec's world, inclination 0) the IMU at rest reads +g along z (REP 145 specific force; on the
    default vertical wall it would read it along y), and a fault dropping imu for 0.1 s silences exactly the states its steps reach."""
    (tmp_path / 'floor.yaml').write_text('inclination: 0\n')
    (tmp_path / 'robot.yaml').write_text(paths.robot_yaml().read_text() + 'sensors: {imu: {}}\n')
    spec = write_spec(tmp_path / 'floor_spec.yaml', scenario='rest', duration=0.3, robot='robot.yaml',
                      world='floor.yaml', controller=f'{UNDER_TEST} answer 0.0 0.0',
                      faults=[{'at': 0.1, 'for': 0.1, 'drop': 'imu'}])
    result = run_test(spec, tmp_path / 'out')
    assert result.returncode == 0, result.stdout + result.stderr
    imu = by_topic(tmp_path / 'out' / 'bag')[topics.IMU.resolve()]
    gravity = load_robot_parameters(tmp_path / 'robot.yaml').gravity
    assert all(message.linear_acceleration.z == pytest.approx(gravity, rel=1e-9)
               and abs(message.linear_acceleration.y) < 1e-9 for message in imu)
    stamps = [round(stamp_ns(message) / 5e6) * 5 for message in imu]  # ms, on the 200 Hz grid
    assert stamps == [ms for ms in range(0, 301, 5) if not 100 < ms <= 200]  # the states the steps from 0.1 s to 0.2 s reach


def bag_messages(bag: Path) -> dict[str, list[bytes]]:
    """Every message of the bag, by topic, in order."""
    names = [topic.name for topic in info(bag).topics]
    by_topic = {name: [] for name in names}
    for message in messages(bag, names):
        by_topic[message.topic].append(bytes(message.data))
    return by_topic


def test_a_spec_run_twice_records_the_same_messages(tmp_path):
    spec = write_spec(tmp_path / 'twice.yaml', scenario='circle', duration=0.4, contact='coulomb',
                      controller=f'{UNDER_TEST} answer 0.6 0.4',
                      faults=[{'at': 0.2, 'for': 0.1, 'motor_right': 0.5}])
    first, second = (run_test(spec, tmp_path / name) for name in ('one', 'two'))
    assert first.returncode == second.returncode == 0, first.stdout + second.stdout
    one, two = bag_messages(tmp_path / 'one' / 'bag'), bag_messages(tmp_path / 'two' / 'bag')
    assert one.keys() == two.keys()
    for topic in one:
        assert len(one[topic]) == len(two[topic]), topic
        assert one[topic] == two[topic], topic
    assert [event.stamp_ns for event in fault_events(tmp_path / 'one' / 'bag')] == [200_000_000, 300_000_000]
    assert len(one['/wallbot/odom']) > 300  # the run itself, not only its latched topics
