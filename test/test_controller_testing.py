"""``wallbot-sim test`` without a graph: a spec is checked as the other input files are (one line naming what is
wrong, exit status 2), its faults become dynamics settings at simulation times, the JUnit file is what the JUnit
schema CI systems read allows, and the adhesion a wheel set needs is what the friction disc gives by hand."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import xmlschema
import yaml

from cli_helpers import assert_one_line_error, wallbot
from wallbot_msgs_py.codec import FaultEvent
from wallbot_sim import paths
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.graph_description import describe_tested_graph
from wallbot_sim.model import Robot
from wallbot_sim.model.simulation import NUMBA, PYTHON
from wallbot_sim.rundata.least_adhesion import least_adhesion, needed_adhesion
from wallbot_sim.testing import Outcome, SpecError, load_spec, make_spec
from wallbot_sim.testing.expectations import Ending, Verdict
from wallbot_sim.testing.junit import write_junit
from wallbot_sim.testing.spec import fault_schedule

JUNIT_SCHEMA = Path(__file__).with_name('data') / 'junit-10.xsd'
GOOD = {'scenario': 'rest', 'duration': 1.0, 'controller': 'python3 my_controller.py --ros-args -p gain:=2.0',
        'expect': {'no_slip': True}}


def spec_file(tmp_path: Path, **changes) -> Path:
    values = {**GOOD, **changes}
    path = tmp_path / 'spec.yaml'
    path.write_text(yaml.safe_dump({key: value for key, value in values.items() if value is not None}))
    return path


@pytest.mark.parametrize('changes, words', [
    ({'world': 'my_wall.yaml'}, 'world: '),
    ({'world': 7}, 'world must be a world file path, got 7'),
    ({'scenaro': 'circle'}, "unknown test spec key 'scenaro' (did you mean 'scenario'?)"),
    ({'controller': None}, 'controller is missing'),
    ({'controller': ''}, 'controller must be a command line or a list of its words'),
    ({'drive': 'torque'}, 'drive must be one of wheel_torque_cmd, cmd_vel, joint_commands'),
    ({'duration': None}, 'duration is missing: scenario rest has none of its own'),
    ({'control_rate': 30}, 'control_rate must be a whole number of Hz dividing 1000'),
    ({'faults': [{'at': 0.5, 'motor_left': 1.5}]}, 'faults[0]: motor_efficiency_left must be'),
    ({'faults': [{'at': 0.5, 'drop': 'gps'}]}, "faults[0]: drop must name a sensor topic (odom, wheel_states, imu), "
                                                "got 'gps'"),
    ({'faults': [{'at': 2.0, 'motor_left': 0.0}]}, 'a fault at 2 s comes after the run ends (1 s)'),
    ({'faults': [{'at': 0.2, 'for': 0.5, 'adhesion_scale': 0.6}, {'at': 0.5, 'adhesion_scale': 0.8}]},
     'faults[1]: adhesion_scale at 0.5 s overlaps faults[0]'),
    ({'expect': {'no_slp': True}}, "unknown expectation 'no_slp' (did you mean 'no_slip'?)"),
    ({'expect': {'max_tracking_error_after': {'t': 1.0, 'm': 0.01}}}, 'needs a reference to track'),
    ({'expect': {'max_motor_torque': -1}}, 'max_motor_torque must be'),
])
def test_a_bad_spec_is_one_line_naming_the_file_and_what_is_wrong(tmp_path, changes, words):
    path = spec_file(tmp_path, **changes)
    with pytest.raises(SpecError) as caught:
        load_spec(path)
    message = str(caught.value)
    assert message.startswith(f'{path}: ') and words in message and '\n' not in message


def test_the_command_line_refuses_a_bad_spec_with_exit_status_2_and_one_line(tmp_path):
    result = wallbot('test', spec_file(tmp_path, world='my_wall.yaml'), '--out', tmp_path / 'out')
    assert result.returncode == 2
    assert_one_line_error(result, 'wallbot-sim test: error:', 'world: ', 'my_wall.yaml')
    assert not (tmp_path / 'out').exists()  # refused before anything ran


def test_a_spec_reads_its_files_from_its_folder_and_its_controller_as_words(tmp_path):
    spec = load_spec(spec_file(tmp_path, scenario='circle', duration=None))
    assert spec.controller == ('python3', 'my_controller.py', '--ros-args', '-p', 'gain:=2.0')
    assert spec.run_duration() == spec.loaded_scenario().duration
    with pytest.raises(SpecError, match=r"scenario: .*my_circle\.yaml"):
        load_spec(spec_file(tmp_path, scenario='my_circle.yaml'))


def test_a_world_runs_the_tested_graph_on_the_python_engine_with_the_dynamics_world_file(tmp_path):
    """The spec's world (relative to its folder) reaches the dynamics as run's --world does, and needs the python
    engine (as a robot file's motor block does); without either the dynamics runs on numba."""
    (tmp_path / 'floor.yaml').write_text('inclination: 0\n')
    (tmp_path / 'motor.yaml').write_text(paths.robot_yaml().read_text() + 'motor: {stall_torque: 4.0, '
                                                                          'no_load_speed: 20.0}\n')
    plain, floor, motor = (load_spec(spec_file(tmp_path, **changes)) for changes in
                           ({}, {'world': 'floor.yaml'}, {'robot': 'motor.yaml'}))
    assert floor.world == tmp_path / 'floor.yaml' and plain.world is None
    assert (plain.engine, floor.engine, motor.engine) == (NUMBA, PYTHON, PYTHON)
    for spec in (plain, floor):
        dynamics, *_others = describe_tested_graph(None, spec.drive, spec.control_steps, stop_at=1.0,
                                                   bag=tmp_path / 'bag', world_file=spec.world, engine=spec.engine)
        assert dynamics.parameters.get('world_file') == (str(spec.world) if spec.world else None)
        assert dynamics.parameters['engine'] == spec.engine


def test_a_dropped_imu_is_the_dynamics_drop_imu_setting_for_its_span():
    assert [(fault.at, dict(fault.changes)) for fault in fault_schedule([{'at': 0.2, 'for': 0.1, 'drop': 'imu'}])] == [
        (0.2, {'drop_imu': True}), (pytest.approx(0.3), {'drop_imu': False})]


def test_a_fault_for_a_while_ends_with_its_settings_back_at_no_fault():
    schedule = fault_schedule([{'at': 0.5, 'for': 0.25, 'adhesion_scale': 0.6, 'motor_right': 0.0},
                               {'at': 0.1, 'drop': 'odom'}])
    assert [(fault.at, dict(fault.changes)) for fault in schedule] == [
        (0.1, {'drop_odom': True}),
        (0.5, {'motor_efficiency_right': 0.0, 'adhesion_scale': 0.6}),
        (0.75, {'motor_efficiency_right': 1.0, 'adhesion_scale': 1.0})]


def outcome_with_every_verdict(tmp_path: Path) -> Outcome:
    spec = make_spec(controller='python3 my_controller.py', scenario='rest', duration=1.0,
                     expect={'no_slip': True, 'max_motor_torque': 2.5, 'min_adhesion_margin': 1.1})
    verdicts = (Verdict('no_slip', True, 0.5, 1.0, '', 0.25, 'friction use at most 0.5'),
                Verdict('max_motor_torque', False, 3.25, 2.5, 'N m', 0.75, 'motor torque at most 3.25 N m'),
                Verdict('min_adhesion_margin', None, math.nan, 1.1, '', math.nan, 'not judged: no wheel contact'))
    faults = (FaultEvent(500_000_000, 'dynamics', ('motor_efficiency_left',), 'scheduled',
                         {'motor_efficiency_left': '0.0'}),)
    return Outcome(spec, tmp_path / 'bag', 1.0, 0.6, Ending(0.6, 'the controller did not answer'), verdicts, faults,
                   2.5)


def test_the_junit_file_is_what_the_junit_schema_allows_a_testcase_an_expectation(tmp_path):
    path = write_junit(outcome_with_every_verdict(tmp_path), tmp_path / 'reports' / 'junit.xml')
    xmlschema.XMLSchema(JUNIT_SCHEMA).validate(path)
    suite = ET.parse(path).getroot().find('testsuite')
    assert (suite.get('tests'), suite.get('failures'), suite.get('skipped')) == ('4', '2', '1')
    cases = {case.get('name'): case for case in suite.iter('testcase')}
    assert list(cases) == ['run', 'no_slip', 'max_motor_torque', 'min_adhesion_margin']
    assert cases['run'].find('failure').get('message') == 'the controller did not answer'
    assert cases['no_slip'].find('failure') is None and cases['no_slip'].find('skipped') is None
    failure = cases['max_motor_torque'].find('failure')
    assert failure.get('message') == 'motor torque at most 3.25 N m'
    assert failure.text.startswith('measured 3.25 N m, limit 2.5 N m, worst at t = 0.750 s')
    assert cases['min_adhesion_margin'].find('skipped').get('message') == 'not judged: no wheel contact'
    properties = {p.get('name'): p.get('value') for p in suite.find('properties')}
    assert properties['fault at 0.500 s'] == 'motor_efficiency_left (scheduled)'


def test_the_adhesion_a_wheel_set_at_rest_needs_is_its_weight_over_the_wall_friction():
    params = load_robot_parameters()
    robot = Robot(params)
    weight = np.array([40.0, 60.0, 90.0])  # N, carried sideways in equal shares: the split equal loads give
    loads = np.tile([[50.0, 50.0, 50.0, 50.0]], (3, 1))
    forces = np.zeros((3, 4, 2))
    forces[:, :, 1] = weight[:, None] / 4
    needed = needed_adhesion(loads, forces, robot)
    # each wheel holds while weight / 4 <= mu_s F / 4
    np.testing.assert_allclose(needed, weight / params.wall_friction, rtol=1e-9)
    assert least_adhesion(loads, forces, robot)[:2] == (pytest.approx(needed.max(), rel=1e-12), 2)
