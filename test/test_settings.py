"""Every node's settings table, and the command line's and the launch file's options derived from it: a value one
of them accepts, the others accept (without DDS: the node's check is a function of its table)."""

from __future__ import annotations

import re

import pytest

from settings_helpers import boundary_values, cli_text
from wallbot_sim.cli.main import build_parser
from wallbot_sim.graph_description import GraphDescriptionError, describe_graph
from wallbot_sim.graph_options import OPTIONS, launched_graph
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.settings.config import CONSTRAINT_CONFIG, RECORDER, VIEWER
from wallbot_sim.settings.controller import CONTROLLER
from wallbot_sim.settings.drives import CMD_VEL, JOINT_BRIDGE
from wallbot_sim.settings.dynamics import COMPOSED, DYNAMICS, DynamicsSettings
from wallbot_sim.settings.table import Setting, SettingError, changed, parameters, table_of, text_of, typed
from wallbot_sim.settings.trajectory import TRAJECTORY

TABLES = {'dynamics': DYNAMICS, 'controller': CONTROLLER, 'viewer': VIEWER, 'trajectory': TRAJECTORY,
          'cmd_vel': CMD_VEL, 'joint_bridge': JOINT_BRIDGE, 'constraint_config': CONSTRAINT_CONFIG,
          'recorder': RECORDER}
SIMULATE_OPTIONS = {'--heading': ('dynamics', 'initial_theta'), '--contact': ('dynamics', 'contact_model'),
                    '--engine': ('dynamics', 'engine'), '--adhesion-force': ('dynamics', 'adhesion_force'),
                    '--controller-mass-scale': ('controller', 'mass_scale'), '--world': ('dynamics', 'world_file')}
"""simulate's options that set what a node's parameter sets (its --duration and --dt are its own: a headless run
ends, and steps by a time step, not a rate)."""


def mapped_options() -> list[tuple[str, str, str, str]]:
    """(verb, flag, node, parameter) of every option of run and simulate that sets a node's parameter."""
    return ([('run', option.flag, option.node, option.parameter) for option in OPTIONS if option.node and option.flag]
            + [('simulate', flag, *target) for flag, target in SIMULATE_OPTIONS.items()])


def verb_parser(verb: str):
    parser = build_parser()
    return next(action for action in parser._actions if action.dest == 'verb').choices[verb]


def test_every_option_typed_by_a_setting_is_checked_below():
    """An option whose type is a setting's is one the agreement test covers (so a new one cannot slip by)."""
    covered = {(verb, flag) for verb, flag, _node, _parameter in mapped_options()}
    typed_options = {(verb, action.option_strings[0]) for verb in ('run', 'simulate')
                     for action in verb_parser(verb)._actions
                     if action.option_strings and getattr(action.type, '__qualname__', '').startswith('setting_type')}
    assert typed_options - covered <= {('run', '--constraints'), ('simulate', '--constraints')}  # no node's parameter
    assert len(covered) >= 14


def test_run_and_simulate_start_with_the_same_constraints():
    """Both verbs default to every structural constraint with the trajectory task (the heading task along the
    path, non_lateral being among them)."""
    from wallbot_sim.cli.simulate import build_simulation
    from wallbot_sim.model import STRUCTURAL
    run_args = build_parser().parse_args(['run', 'circle'])
    simulate_args = build_parser().parse_args(['simulate', '--csv', '-'])
    assert run_args.constraints == simulate_args.constraints
    simulation, _ = build_simulation(simulate_args)
    assert simulation.selection.label().split('+') == ['trajectory', 'tangent_heading', *STRUCTURAL]


@pytest.mark.parametrize('verb, flag, node, parameter', mapped_options(), ids=lambda x: str(x))
def test_the_command_line_and_the_node_agree_on_every_boundary_value(verb, flag, node, parameter, capsys):
    """For each value near the ends of the node's range (and NaN, infinities, other types, choices): the command
    line refuses it, with one line naming the option and the node's words, exactly when the node's own check (the
    one its declaration and its parameter callback run) refuses it."""
    setting = TABLES[node][parameter]
    prefix = ['run', 'circle'] if verb == 'run' else ['simulate', '--csv', '-']
    for value in boundary_values(setting):
        node_reason = setting.reason(value)
        try:
            build_parser().parse_args([*prefix, f'{flag}={cli_text(value)}'])
        except SystemExit as refused:
            assert refused.code == 2
            line, = capsys.readouterr().err.strip().splitlines()
            assert line.startswith(f'wallbot-sim {verb}: error: argument {flag}'), line
            assert node_reason is not None, f'{verb} {flag} refuses {value!r}, {node} accepts it: {line}'
            words = node_reason.removeprefix(f'{parameter} ').split(', got ')[0]  # the value as typed or as read
            assert f'argument {flag}: {words}, got ' in line, (line, node_reason)
        else:
            assert node_reason is None, f'{verb} {flag} accepts {value!r}, {node} refuses it: {node_reason}'


@pytest.mark.parametrize('value, accepted', [('2e6', False), ('1e6', True), ('1000000.0000001', False),
                                              ('0', True), ('-1', False), ('150', True)])
def test_run_refuses_the_adhesion_forces_the_dynamics_refuses(value, accepted, capsys):
    """The drift that was: run took any positive force, the node refuses more than 1e6 N."""
    try:
        build_parser().parse_args(['run', 'circle', '--adhesion-force', value])
    except SystemExit:
        line = capsys.readouterr().err.strip()
        assert not accepted and line == (f"wallbot-sim run: error: argument --adhesion-force: must be 0 (the robot "
                                         f"file's) or in (0, 1e+06], got {float(value)!r}")
    else:
        assert accepted and DYNAMICS['adhesion_force'].reason(float(value)) is None


def test_every_launch_argument_reads_its_default_and_refuses_what_its_node_refuses():
    defaults = {option.name: text_of(option.setting.default) for option in OPTIONS}
    assert [spec.name for spec in launched_graph(defaults)] == ['constraint_config', 'trajectory', 'dynamics']
    for name, text, words in [('adhesion_force', '2e6', "must be 0 (the robot file's) or in (0, 1e+06]"),
                              ('controller_mass_scale', '0', 'must be in [0.001, 1000]'),
                              ('realtime_priority', '1.5', 'must be an integer'),
                              ('engine', 'fortran', 'must be one of python, numba'),
                              ('viewer', 'yes', 'must be true or false')]:
        with pytest.raises(SettingError, match=f'^{re.escape(f"{name}:={text}: {words}")}, got '):
            launched_graph({**defaults, name: text})


def test_a_graph_description_names_only_parameters_its_nodes_have_with_values_they_take():
    from wallbot_sim.config import load_scenario
    from wallbot_sim.model import ConstraintSelection
    selection = ConstraintSelection.parse('belt')
    with pytest.raises(GraphDescriptionError, match=r"^node dynamics: adhesion_force must be 0 \(the robot file's\) "
                                                    r'or in \(0, 1e\+06\], got 2000000.0$'):
        describe_graph(load_scenario('circle'), selection, adhesion_force=2e6)
    with pytest.raises(GraphDescriptionError, match=r'^node controller: mass_scale must be in \[0.001, 1000\]'):
        describe_graph(load_scenario('circle'), selection, controller_mass_scale=1e4)
    for spec in describe_graph(load_scenario('figure8'), selection, controller_mass_scale=1.2, viewer=True,
                               foxglove_port=8765):
        table = TABLES.get(spec.name)
        assert table is not None and not table.reasons(spec.parameters) and set(spec.parameters) <= set(table.names)


@pytest.mark.parametrize('table', TABLES.values(), ids=TABLES)
def test_every_setting_is_typed_ranged_described_and_keeps_its_default(table):
    for setting in table:
        assert setting.help and setting.reason(setting.default) is None, setting.name
        assert (setting.allowed is not None) == (setting.kind in (int, float)), setting.name
        if setting.kind in (int, float):
            low, high = setting.allowed.bounds()
            assert low <= setting.default <= high, setting.name
        text = text_of(setting.default)
        assert setting.parse(text) == setting.default, setting.name


@pytest.mark.parametrize('kind, text, value', [(bool, 'TRUE', True), (bool, 'false', False), (int, '-3', -3),
                                                (float, '2', 2.0), (float, '1e-3', 1e-3), (str, ' a b ', ' a b '),
                                                (tuple, '[odom, clock]', ('odom', 'clock')), (tuple, '[]', ())])
def test_a_setting_reads_its_text(kind, text, value):
    examples = {bool: False, int: 0, float: 0.0, str: '', tuple: ()}
    allowed = NumberRange(-10, 10) if kind in (int, float) else None
    setting = Setting('x', examples[kind], 'help', allowed)
    assert setting.parse(text) == value and type(setting.parse(text)) is kind


@pytest.mark.parametrize('setting, value, reason', [
    (Setting('n', 0, 'h', NumberRange(0, 9)), 2.0, 'n must be an integer, got 2.0'),
    (Setting('n', 0, 'h', NumberRange(0, 9)), True, 'n must be an integer, got True'),
    (Setting('x', 0.0, 'h', NumberRange(0, 9)), False, 'x must be a finite number, got False'),
    (Setting('x', 0.0, 'h', NumberRange(0, 9)), '1', "x must be a finite number, got '1'"),
    (Setting('b', False, 'h'), 1, 'b must be true or false, got 1'),
    (Setting('s', 'a', 'h', choices=('a', 'b')), 'c', "s must be one of a, b, got 'c'"),
    (Setting('s', 'a', 'h'), 3, 's must be a string, got 3'),
    (Setting('t', ('a',), 'h'), ['a', 1], "t must be a list of strings, got ['a', 1]"),
])
def test_a_setting_refuses_other_types_in_one_line(setting, value, reason):
    assert setting.reason(value) == reason
    assert setting.reason(setting.default) is None


def test_a_setting_that_cannot_hold_its_default_or_lacks_a_range_is_no_setting():
    with pytest.raises(TypeError, match='its default 20 is refused'):
        Setting('n', 20, 'h', NumberRange(0, 9))
    with pytest.raises(TypeError, match='a range is given for a number, and only for a number'):
        Setting('n', 2, 'h')
    with pytest.raises(TypeError, match='a range needs both ends'):
        Setting('x', 2.0, 'h', NumberRange(0.0))


def test_a_fixed_setting_takes_its_value_only_and_says_why():
    assert COMPOSED['snapshot_period'].reason(0.0) is None and COMPOSED['snapshot_period'].locked
    assert COMPOSED['snapshot_period'].reason(0.5) == ('snapshot_period is fixed at 0.0 here (no keeper of snapshots '
                                                       'in this process), got 0.5')
    assert DYNAMICS['snapshot_period'].reason(0.5) is None and not DYNAMICS['snapshot_period'].locked
    assert DYNAMICS['use_sim_time'].reason(True) == ('use_sim_time is fixed at false here (the dynamics owns the '
                                                     'simulation clock: it publishes clock, it follows none), got True')
    assert 'fixed at false here' in DYNAMICS['use_sim_time'].description()


def test_the_loop_reads_the_table_typed_and_a_change_keeps_the_types():
    settings = typed(DynamicsSettings, DYNAMICS.defaults())
    assert settings == DynamicsSettings() and parameters(settings) == DYNAMICS.defaults()
    assert table_of(DynamicsSettings).names == DYNAMICS.names
    later = changed(settings, {'real_time_factor': 2, 'rate_hz': 500, 'not_a_setting': 1})
    assert later.real_time_factor == 2.0 and type(later.real_time_factor) is float and later.rate_hz == 500


def test_one_default_engine_everywhere():
    """numba: the nodes' own defaults, the graph description, the launch file, and run and simulate for a robot
    without a world file or the robot file's motor and adhesion blocks (``chosen_engine``)."""
    from wallbot_sim.cli.engine import chosen_engine
    from wallbot_sim.graph_options import BY_NAME
    from wallbot_sim.model import Robot, RobotParameters
    assert DYNAMICS['engine'].default == CONTROLLER['engine'].default == BY_NAME['engine'].setting.default == 'numba'
    for command in (['run', 'circle'], ['simulate', '--csv', '-']):
        assert chosen_engine(build_parser().parse_args(command).engine, Robot(RobotParameters()), command[0]) == 'numba'
    from wallbot_sim.config import load_scenario
    from wallbot_sim.model import ConstraintSelection
    specs = describe_graph(load_scenario('circle'), ConstraintSelection.parse('belt'), controller_mass_scale=1.0)
    assert {spec.name: spec.parameters['engine'] for spec in specs if 'engine' in spec.parameters} == {
        'controller': 'numba', 'dynamics': 'numba'}

