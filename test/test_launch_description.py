"""launch/wallbot.launch.py and ``wallbot-sim run`` start the same graph, from one description.

launch and launch_ros are not installable here, so the launch file runs against minimal stand-ins
that record what it asks for; what it asks for must be exactly ``describe_graph``'s nodes.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import types
from pathlib import Path

import pytest

from wallbot_sim.config import load_scenario
from wallbot_sim.graph_description import (CMD_VEL_STEPS, CONTROL_STEPS, EXECUTABLES, describe_driven_graph,
                                           describe_graph, launch_name)
from wallbot_sim.model import ConstraintSelection

LAUNCH_FILE = Path(__file__).resolve().parents[1] / 'launch' / 'wallbot.launch.py'
RUN_DEFAULTS = {'compose': True}
"""What ``wallbot-sim run`` and the launch file start by default beside the graph description's own defaults
(two processes; the engine is numba in all of them)."""


def circle_graph(**options):
    """The circle with every constraint, as run and the launch file start it, with ``options``."""
    return describe_graph(load_scenario('circle'), ConstraintSelection.parse('belt,non_lateral,nonslip'),
                          **{**RUN_DEFAULTS, **options})


def driven_graph(drive: str, **options):
    """``run rest --drive DRIVE``'s graph, as run and the launch file start it, with ``options``."""
    return describe_driven_graph(drive, **{**RUN_DEFAULTS, **options})


class Recorded:
    """Stands in for a launch action: keeps its arguments."""

    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


class LaunchConfiguration:
    def __init__(self, name: str) -> None:
        self.name = name

    def perform(self, context: dict) -> str:
        return context[self.name]


@pytest.fixture
def launch_file(monkeypatch):
    stand_ins = {
        'launch': {'LaunchDescription': Recorded},
        'launch.actions': {'DeclareLaunchArgument': Recorded, 'OpaqueFunction': Recorded},
        'launch.substitutions': {'LaunchConfiguration': LaunchConfiguration},
        'launch_ros': {},
        'launch_ros.actions': {'Node': Recorded},
    }
    for name, attributes in stand_ins.items():
        module = types.ModuleType(name)
        module.__dict__.update(attributes)
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location('wallbot_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def launched_nodes(launch_file, **arguments: str) -> list[dict]:
    """The Node actions the launch file creates for ``arguments`` (the rest at their defaults)."""
    actions = launch_file.generate_launch_description().args[0]
    context = {a.args[0]: a.kwargs['default_value'] for a in actions if 'default_value' in a.kwargs}
    unknown = set(arguments) - set(context)
    assert not unknown, f'not launch arguments: {unknown}'
    context.update(arguments)
    opaque = [a for a in actions if 'function' in a.kwargs]
    assert len(opaque) == 1
    return [node.kwargs for node in opaque[0].kwargs['function'](context)]


def as_launched(specs, namespace: str = '/wallbot') -> list[dict]:
    return [{'package': 'wallbot_sim', 'executable': EXECUTABLES[s.module], **launch_name(s),
             'namespace': namespace, 'output': 'screen', 'parameters': [dict(s.parameters)],
             'remappings': [tuple(remap.split(':=')) for remap in s.remaps]} for s in specs]


def test_defaults_are_the_circle_with_every_constraint_as_run_starts_it(launch_file):
    nodes = launched_nodes(launch_file)
    assert nodes == as_launched(circle_graph())
    assert [n['executable'] for n in nodes] == ['constraint_config_node', 'trajectory_node', 'dynamics_node']


def test_figure8_starts_from_the_figure8_state(launch_file):
    """scenario:=figure8 once changed only the shape and kept the circle's start."""
    dynamics = launched_nodes(launch_file, scenario='figure8')[-1]['parameters'][0]
    figure8 = load_scenario('figure8').initial
    assert (dynamics['initial_x'], dynamics['initial_y'], dynamics['initial_theta'], dynamics['initial_at_rest']) == (
        figure8.x, figure8.y, figure8.theta, figure8.at_rest)
    assert dynamics['initial_theta'] == pytest.approx(math.pi / 4) and dynamics['initial_at_rest'] is False


def test_recorded_closed_loop_is_the_graph_of_run_controller(launch_file, tmp_path):
    nodes = launched_nodes(launch_file, record=str(tmp_path / 'bag'), controller='true', controller_mass_scale='1.2',
                           duration='20', real_time_factor='0', compose='false')
    expected = circle_graph(duration=20.0, real_time_factor=0.0, bag=tmp_path / 'bag', controller_mass_scale=1.2,
                            compose=False)
    assert nodes == as_launched(expected)
    assert [n['name'] for n in nodes] == ['recorder', 'constraint_config', 'trajectory', 'controller', 'dynamics']
    dynamics = nodes[-1]['parameters'][0]
    assert dynamics['wait_for_recorder'] and dynamics['wait_for_command'] and dynamics['stop_at'] == 20.0
    assert nodes[0]['parameters'][0]['output'] == str(tmp_path / 'bag')
    # the controller reads the odometry of its control instants only: those the dynamics waits on
    assert nodes[3]['remappings'] == [('odom', 'control_odom')]
    assert dynamics['control_odom_every'] == dynamics['lockstep_every'] == CONTROL_STEPS
    assert all(not n['remappings'] for n in nodes if n['name'] != 'controller')


def test_a_recorded_graph_runs_the_dynamics_and_the_recorder_in_one_process_as_run_does(launch_file, tmp_path):
    nodes = launched_nodes(launch_file, record=str(tmp_path / 'bag'), duration='20')
    expected = circle_graph(duration=20.0, bag=tmp_path / 'bag')
    assert nodes == as_launched(expected)
    assert [n['executable'] for n in nodes] == ['dynamics_recorder_node', 'constraint_config_node', 'trajectory_node']
    assert 'name' not in nodes[0]  # its two nodes keep their names
    composed = nodes[0]['parameters'][0]
    assert composed['output'] == str(tmp_path / 'bag') and composed['stop_at'] == 20.0 and composed['wait_for_recorder']
    separate = launched_nodes(launch_file, record=str(tmp_path / 'bag'), duration='20', compose='false')
    assert separate == as_launched(circle_graph(duration=20.0, bag=tmp_path / 'bag', compose=False))
    assert [n['executable'] for n in separate] == ['recorder_node', 'constraint_config_node', 'trajectory_node',
                                                   'dynamics_node']
    # without a bag there is nothing to compose: the dynamics alone
    assert [n['executable'] for n in launched_nodes(launch_file, compose='true')][-1] == 'dynamics_node'
    driven = describe_driven_graph('cmd_vel', bag=tmp_path / 'bag', compose=True)
    assert [s.name for s in driven] == ['dynamics_recorder', 'constraint_config', 'cmd_vel_controller']
    assert driven[0].parameters['topics'] == describe_driven_graph('cmd_vel', bag=tmp_path / 'bag')[0].parameters['topics']


def test_viewer_true_adds_the_viewer_before_the_dynamics_as_run_markers_does(launch_file):
    nodes = launched_nodes(launch_file, viewer='true')
    expected = circle_graph(viewer=True)
    assert nodes == as_launched(expected)
    assert [n['executable'] for n in nodes] == ['constraint_config_node', 'trajectory_node', 'viewer_node',
                                                'dynamics_node']


@pytest.mark.parametrize('drive', ['', 'joint_commands'])
def test_a_second_robot_has_its_namespace_and_its_frame_prefix_on_every_node_naming_its_frames(launch_file, drive):
    """namespace:= and frame_prefix:= (a second robot): every node in that namespace, and the
    prefix on the nodes that name the robot's frames (the dynamics' odometry, constraint_config's
    robot_description, the viewer's tf), nowhere else; by default no node has a frame parameter."""
    nodes = launched_nodes(launch_file, namespace='/robot2', frame_prefix='robot2/', viewer='true', drive=drive,
                           domain_clock='false')
    if drive:
        expected = driven_graph(drive, viewer=True, frame_prefix='robot2/', domain_clock=False)
    else:
        expected = circle_graph(viewer=True, frame_prefix='robot2/', domain_clock=False)
    assert nodes == as_launched(expected, '/robot2')
    prefixed = {n['executable'] for n in nodes if n['parameters'][0].get('frame_prefix') == 'robot2/'}
    assert prefixed == {'constraint_config_node', 'viewer_node', 'dynamics_node'}
    # domain_clock:=false: the second robot's dynamics leaves the domain's /clock to the first's
    assert [n['executable'] for n in nodes if n['parameters'][0].get('domain_clock') is False] == ['dynamics_node']
    default = launched_nodes(launch_file, viewer='true', drive=drive)
    assert not any('frame_prefix' in n['parameters'][0] or 'domain_clock' in n['parameters'][0] for n in default)


def test_engine_numba_is_the_dynamics_and_controller_engine_as_run_engine_gives_it(launch_file):
    nodes = launched_nodes(launch_file, engine='numba')
    expected = circle_graph(engine='numba')
    assert nodes == as_launched(expected) and nodes[-1]['parameters'][0]['engine'] == 'numba'
    assert launched_nodes(launch_file)[-1]['parameters'][0]['engine'] == 'numba'  # run's default
    assert launched_nodes(launch_file, engine='python')[-1]['parameters'][0]['engine'] == 'python'
    assert describe_driven_graph('joint_commands', engine='numba')[-1].parameters['engine'] == 'numba'
    # and the tracking controller's law, as run --controller --engine numba gives it
    closed = {n['name']: n['parameters'][0] for n in launched_nodes(launch_file, controller='true', engine='numba')}
    assert closed['controller']['engine'] == closed['dynamics']['engine'] == 'numba'


@pytest.mark.parametrize('drive, executable', [('cmd_vel', 'cmd_vel_node'), ('joint_commands', 'joint_bridge_node')])
def test_drive_starts_the_graph_of_run_rest_drive(launch_file, tmp_path, drive, executable):
    nodes = launched_nodes(launch_file, drive=drive)
    assert nodes == as_launched(driven_graph(drive))
    assert [n['executable'] for n in nodes] == ['constraint_config_node', executable, 'dynamics_node']
    dynamics = nodes[-1]['parameters'][0]
    assert (dynamics['initial_x'], dynamics['initial_y'], dynamics['initial_theta']) == (0.0, 0.0, 0.0)
    assert nodes[0]['parameters'][0]['trajectory_task'] is False
    # recorded, with the other arguments run rest --drive takes
    arguments = dict(record=str(tmp_path / 'bag'), duration='5', real_time_factor='0', realtime_priority='10',
                     contact='coulomb', adhesion_force='150', engine='python', viewer='true', compose='false')
    nodes = launched_nodes(launch_file, drive=drive, **arguments)
    expected = describe_driven_graph(drive, bag=tmp_path / 'bag', duration=5.0, real_time_factor=0.0,
                                     realtime_priority=10, contact_model='coulomb', adhesion_force=150.0,
                                     engine='python', viewer=True)
    assert nodes == as_launched(expected)
    assert [n['name'] for n in nodes] == ['recorder', 'constraint_config', nodes[2]['name'], 'viewer', 'dynamics']
    assert nodes[2]['parameters'][0]['wait_for_recorder'] is True  # forwards nothing the recorder does not hear
    # cmd_vel_node reads the odometry of its lockstep instants only; joint_bridge_node reads wheel_states
    assert nodes[2]['remappings'] == ([('odom', 'control_odom')] if drive == 'cmd_vel' else [])
    assert nodes[-1]['parameters'][0].get('control_odom_every') == (CMD_VEL_STEPS if drive == 'cmd_vel' else None)
    assert nodes[0]['parameters'][0]['topics'] == expected[0].parameters['topics']
    composed = launched_nodes(launch_file, drive=drive, record=str(tmp_path / 'bag'))
    assert composed == as_launched(driven_graph(drive, bag=tmp_path / 'bag'))
    assert composed[0]['executable'] == 'dynamics_recorder_node'


@pytest.mark.parametrize('argument, value', [('scenario', 'figure8'), ('constraints', 'belt'), ('controller', 'true'),
                                             ('controller_mass_scale', '1.2')])
def test_drive_refuses_the_arguments_of_a_scenario_run(launch_file, argument, value):
    with pytest.raises(ValueError, match=f'drive:= runs the driven robot .*: drop {argument}$'):
        launched_nodes(launch_file, drive='cmd_vel', **{argument: value})


def test_an_unknown_drive_is_refused_with_the_drives_named(launch_file):
    with pytest.raises(ValueError, match="unknown drive 'teleop': use cmd_vel or joint_commands"):
        launched_nodes(launch_file, drive='teleop')


def test_a_driven_run_starts_the_viewer_before_the_dynamics_too():
    specs = describe_driven_graph('cmd_vel', foxglove_port=8765)
    assert [s.name for s in specs] == ['constraint_config', 'cmd_vel_controller', 'viewer', 'dynamics']
    assert specs[2].parameters == {'foxglove_port': 8765, 'foxglove_host': '127.0.0.1', 'use_sim_time': True}
    assert 'viewer' not in [s.name for s in describe_driven_graph('cmd_vel')]


def test_every_node_module_has_its_console_script():
    setup = (LAUNCH_FILE.parents[1] / 'setup.py').read_text()
    for module, executable in EXECUTABLES.items():
        assert f"'{executable} = {module}:main'" in setup


def test_a_world_file_reaches_the_viewer_as_it_reaches_the_dynamics():
    world, selection = Path('/walls/wet.yaml'), ConstraintSelection.parse('belt')
    specs = {s.name: s for s in describe_graph(load_scenario('circle'), selection, viewer=True, world_file=world)}
    assert specs['viewer'].parameters['world_file'] == specs['dynamics'].parameters['world_file'] == str(world)
    plain = {s.name: s for s in describe_graph(load_scenario('circle'), selection, viewer=True)}
    assert 'world_file' not in plain['viewer'].parameters
