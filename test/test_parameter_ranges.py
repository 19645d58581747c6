"""One rule for a number a parameter accepts: the model, the nodes and the command line agree."""

from __future__ import annotations

import math
import re
import sys

import pytest

from settings_helpers import boundary_values, cli_text
from wallbot_sim.cli.main import build_parser
from wallbot_sim.graph_options import OPTIONS
from wallbot_sim.model import ParameterError, RobotParameters
from wallbot_sim.model.numbers import FINITE, NON_NEGATIVE, POSITIVE, NumberRange
from wallbot_sim.settings.dynamics import REAL_TIME_FACTOR


@pytest.mark.parametrize('allowed, accepted, refused', [
    (FINITE, [-1e300, 0, 2.5], [math.nan, math.inf, -math.inf, '1', None, True]),
    (POSITIVE, [1e-300, 3], [0, -0.0, -1, math.nan, math.inf, False]),
    (NON_NEGATIVE, [0, 0.0, 7], [-1e-300, math.nan, math.inf]),
    (NumberRange(0.0, 0.1, low_open=True), [0.1, 1e-9], [0.0, 0.1000001, math.nan]),
    (NumberRange(1e-3, 1e6, zero='as fast as possible'), [0, -0.0, 1e-3, 1e6], [5e-4, 1e6 + 1, -1, math.inf]),
])
def test_a_range_accepts_exactly_its_numbers(allowed, accepted, refused):
    assert all(allowed.problem(value) is None for value in accepted)
    for value in refused:
        reason = allowed.reason('speed', value)
        assert reason.startswith('speed must be ') and reason.endswith(f'got {value!r}') and '\n' not in reason
        with pytest.raises(ParameterError, match=f'^{re.escape(reason)}$'):
            allowed.check('speed', value)


def test_the_words_say_the_range():
    assert POSITIVE.reason('period', 0.0) == 'period must be > 0, got 0.0'
    assert NON_NEGATIVE.reason('duration', -1) == 'duration must be >= 0, got -1'
    assert FINITE.reason('center_x', math.nan) == 'center_x must be a finite number, got nan'
    assert REAL_TIME_FACTOR.reason('real_time_factor', 5e-4) == (
        'real_time_factor must be 0 (as fast as possible) or in [0.001, 1e+06], got 0.0005')
    assert REAL_TIME_FACTOR.bounds() == (0.0, 1e6)  # what the dynamics' parameter descriptor says
    assert NumberRange(0.0, 0.1, low_open=True).describe() == 'in (0, 0.1]'


def test_the_robot_file_uses_the_same_rule():
    with pytest.raises(ParameterError, match=r'^wheel_radius must be > 0, got 0\.0$'):
        RobotParameters(wheel_radius=0.0)
    with pytest.raises(ParameterError, match=r'^gravity must be a finite number, got inf$'):
        RobotParameters(gravity=math.inf)


@pytest.fixture(scope='module')
def in_process():
    """The dynamics and the tracking controller as objects in this process (no constraints, no odometry: they never
    step); their parameters are set as ``ros2 param set`` sets them, through rclpy and their callbacks."""
    rclpy = pytest.importorskip('rclpy')
    from wallbot_sim.nodes.controller import ControllerNode
    from wallbot_sim.nodes.dynamics import DynamicsNode
    context = rclpy.Context()
    rclpy.init(context=context)
    nodes = {}
    try:
        nodes['dynamics'] = DynamicsNode(context=context)
        nodes['controller'] = ControllerNode(context=context)
        yield nodes
    finally:
        for node in nodes.values():
            close = getattr(node, 'close', None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.shutdown(context=context)


SETTABLE = [option for option in OPTIONS if option.flag and option.node in ('dynamics', 'controller')
            and not option.setting.locked]
"""run's options that set a parameter a running node takes (the read-only ones: test_settings, at start)."""


@pytest.mark.parametrize('option', SETTABLE, ids=lambda option: option.flag)
def test_run_refuses_exactly_the_values_the_running_node_refuses(in_process, option, capsys):
    """Each value near the ends of the node's range, NaN, infinities, other types: ``run`` refuses it exactly when
    the node, given it as ``ros2 param set`` gives it, refuses it (and the node keeps running either way)."""
    from rclpy.parameter import Parameter
    node = in_process[option.node]
    default = node.get_parameter(option.parameter).value
    for value in boundary_values(option.setting):
        result, = node.set_parameters([Parameter(option.parameter, value=value)])
        node.set_parameters([Parameter(option.parameter, value=default)])
        try:
            build_parser().parse_args(['run', 'circle', f'{option.flag}={cli_text(value)}'])
        except SystemExit as refused:
            assert refused.code == 2
            lines = capsys.readouterr().err.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith(f'wallbot-sim run: error: argument {option.flag}: ')
            assert not result.successful, f'the node accepts {value!r}, the command line refuses it: {lines[0]}'
        else:
            assert result.successful, f'the command line accepts {value!r}, the node refuses it: {result.reason}'


def test_the_dynamics_owns_its_clock_and_the_composed_one_keeps_no_snapshots(in_process):
    """use_sim_time is read-only on the dynamics (refused at start with the reason); in the composed process
    snapshot_period and resume_wait are fixed at 0: read-only, a start value other than 0 refused with the
    reason. Both as ``ros2 param describe`` shows them."""
    from rclpy.parameter import Parameter
    from wallbot_sim.nodes.dynamics import DynamicsNode
    from wallbot_sim.settings.dynamics import COMPOSED
    dynamics = in_process['dynamics']
    clock, = dynamics.describe_parameters(['use_sim_time'])
    assert clock.read_only and 'the dynamics owns the simulation clock' in clock.description
    result, = dynamics.set_parameters([Parameter('use_sim_time', value=True)])
    assert not result.successful and dynamics.get_parameter('use_sim_time').value is False
    context = dynamics.context
    with pytest.raises(ValueError, match=r'^use_sim_time is fixed at false here \(the dynamics owns the simulation '
                                         r'clock: it publishes clock, it follows none\), got True$'):
        DynamicsNode(context=context, parameter_overrides=[Parameter('use_sim_time', value=True),
                                                           Parameter('engine', value='python')])
    with pytest.raises(ValueError, match=r'^snapshot_period is fixed at 0.0 here \(no keeper of snapshots in this '
                                         r'process\), got 0.5$'):
        DynamicsNode(context=context, table=COMPOSED, parameter_overrides=[Parameter('snapshot_period', value=0.5),
                                                                           Parameter('engine', value='python')])
    composed = DynamicsNode(context=context, table=COMPOSED, parameter_overrides=[Parameter('engine', value='python')])
    try:
        period, wait = composed.describe_parameters(['snapshot_period', 'resume_wait'])
        assert period.read_only and wait.read_only and 'no keeper of snapshots in this process' in period.description
        assert (period.floating_point_range[0].from_value, period.floating_point_range[0].to_value) == (0.0, 0.0)
        result, = composed.set_parameters([Parameter('snapshot_period', value=0.2)])
        assert not result.successful and composed.settings.snapshot_period == 0.0 == composed.loop.settings.resume_wait
    finally:
        composed.close()
        composed.destroy_node()


# --- every node's parameters, as a ROS user discovers them ----------------------------------------
ENUMERATED = {'shape', 'contact_model', 'engine'}
"""String parameters that take one of a few values (the test checks they list them)."""


def test_an_unknown_engine_is_one_line_and_exit_status_1(process_runner):
    """The dynamics' engine is read-only: a start value not among its choices stops the node at
    start with one line naming it and the choices."""
    dynamics = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.dynamics', '--ros-args',
                                     '-p', 'engine:=fortran'], 'dynamics')
    assert dynamics.wait(timeout=60) == 1
    output = process_runner.output('dynamics')
    errors = [line for line in output.splitlines() if line.startswith('error:')]
    assert errors == ["error: engine must be one of python, numba, got 'fortran'"], output
    assert 'Traceback' not in output


class ParameterClient:
    """The parameter services of one node, called as ``ros2 param describe`` / ``set`` call them."""

    def __init__(self, graph, node: str) -> None:
        from rcl_interfaces.srv import DescribeParameters, ListParameters, SetParameters
        self.graph, self.node = graph, node
        self.clients = {kind: graph.node.create_client(kind, f'{node}/{service}')
                        for kind, service in ((ListParameters, 'list_parameters'),
                                              (DescribeParameters, 'describe_parameters'),
                                              (SetParameters, 'set_parameters'))}
        for client in self.clients.values():
            assert client.wait_for_service(timeout_sec=20.0), f'{client.srv_name} not available'

    def _call(self, kind, request):
        future = self.clients[kind].call_async(request)
        self.graph.wait_for(future.done, 10.0, f'a response of {self.node}')
        return future.result()

    def descriptors(self) -> list:
        from rcl_interfaces.srv import DescribeParameters, ListParameters
        names = self._call(ListParameters, ListParameters.Request()).result.names
        return list(self._call(DescribeParameters, DescribeParameters.Request(names=names)).descriptors)

    def set(self, name: str, value) -> tuple[bool, str]:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter
        result, = self._call(SetParameters, SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])).results
        return result.successful, result.reason


def _range_of(descriptor):
    """(low, high, is_integer) of a numeric descriptor's range, or None if it has none."""
    for ranges, integer in ((descriptor.floating_point_range, False), (descriptor.integer_range, True)):
        if len(ranges):
            return min(ranges[0].from_value, ranges[0].to_value), max(ranges[0].from_value, ranges[0].to_value), integer
    return None


def node_table(module: str, node: str):
    """The settings table the node ``node`` of ``module`` declares."""
    from wallbot_sim.settings.config import CONSTRAINT_CONFIG, RECORDER, VIEWER
    from wallbot_sim.settings.controller import CONTROLLER
    from wallbot_sim.settings.drives import CMD_VEL, JOINT_BRIDGE
    from wallbot_sim.settings.dynamics import COMPOSED, DYNAMICS
    from wallbot_sim.settings.trajectory import TRAJECTORY
    if node == 'recorder':
        return RECORDER
    tables = {'constraint_config': CONSTRAINT_CONFIG, 'trajectory': TRAJECTORY, 'controller': CONTROLLER,
              'cmd_vel': CMD_VEL, 'joint_bridge': JOINT_BRIDGE, 'viewer': VIEWER, 'dynamics': DYNAMICS,
              'dynamics_recorder': COMPOSED}
    return tables[module.rsplit('.', 1)[-1]]


def described_as_in_table(module: str, table, descriptors) -> list[str]:
    """Where the descriptors ``ros2 param describe`` shows differ from the node's settings table: a setting not
    declared, another description, read-only flag or range."""
    by_name = {descriptor.name: descriptor for descriptor in descriptors}
    problems = []
    for setting in table:
        descriptor = by_name.get(setting.name)
        if descriptor is None:
            problems.append(f'{module} {setting.name}: not declared')
            continue
        span = _range_of(descriptor)
        expected = None if setting.allowed is None else (
            (setting.default, setting.default) if setting.fixed is not None else setting.allowed.bounds())
        if (descriptor.description != setting.description() or descriptor.read_only != setting.locked
                or (span[:2] if span else None) != expected):
            problems.append(f'{module} {setting.name}: described {descriptor.description!r}, read-only '
                            f'{descriptor.read_only}, range {span}; its setting: {setting}')
    return problems


def test_every_numeric_parameter_of_every_node_has_a_range_that_its_node_keeps(process_runner, tmp_path):
    """Each node of the graph (graph_description.EXECUTABLES) alone in a namespace of its own, so
    none of them runs; through its parameter services (as ``ros2 param describe`` and ``set`` call
    them): every setting of its table is described as the table says (description, read-only,
    range); every integer and double parameter has a range, each end is accepted and the nearest
    number outside is refused (rclpy lets numbers within 1e-6 of an end through: the node's own
    check must refuse them); every enumerated parameter lists its values and accepts exactly those."""
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    from graph_helpers import Graph
    from wallbot_sim.graph_description import EXECUTABLES

    graph = Graph(process_runner)
    try:
        namespaces = {}
        for index, module in enumerate(EXECUTABLES):
            namespace = f'/ranges_{index}'
            extra = ['-p', f'output:={tmp_path / f"bag{index}"}'] if module.endswith('recorder') else []
            graph.procs[module] = process_runner.start(
                [sys.executable, '-m', module, '--ros-args', '-r', f'__ns:={namespace}', *extra], module)
            namespaces[namespace] = module

        def started():
            found = {(ns, name) for name, ns in graph.node.get_node_names_and_namespaces() if ns in namespaces
                     and not name.startswith('_')}
            return found if {ns for ns, _ in found} == set(namespaces) else None
        nodes = graph.wait_for(started, 30.0, 'every node')
        problems, checked, enumerated = [], 0, set()
        for namespace, name in sorted(nodes):
            client = ParameterClient(graph, f'{namespace}/{name}')
            descriptors = client.descriptors()
            names = [d.name for d in descriptors]
            values = dict(zip(names, graph.call(GetParameters, f'{namespace}/{name}/get_parameters',
                                                GetParameters.Request(names=names)).values))
            problems += described_as_in_table(namespaces[namespace], node_table(namespaces[namespace], name),
                                              descriptors)
            for descriptor in descriptors:
                where = f'{namespaces[namespace]} {descriptor.name}'
                default = parameter_value_to_python(values[descriptor.name])
                if descriptor.type == ParameterType.PARAMETER_STRING and (
                        descriptor.name in ENUMERATED or descriptor.additional_constraints.startswith('one of: ')):
                    enumerated.add(descriptor.name)
                    choices = descriptor.additional_constraints.removeprefix('one of: ').split(', ')
                    if not descriptor.additional_constraints.startswith('one of: ') or default not in choices:
                        problems.append(f'{where}: lists no choices ({descriptor.additional_constraints!r})')
                        continue
                    if descriptor.additional_constraints not in descriptor.description:
                        problems.append(f'{where}: the description does not list the choices')
                    if descriptor.read_only:  # its start value is checked (test_an_unknown_engine_...)
                        continue
                    for choice in choices:
                        if not client.set(descriptor.name, choice)[0]:
                            problems.append(f'{where}: its choice {choice!r} is refused')
                    if client.set(descriptor.name, 'no_such_choice')[0]:
                        problems.append(f'{where}: accepts a value not among its choices')
                    client.set(descriptor.name, default)
                    continue
                if descriptor.type not in (ParameterType.PARAMETER_INTEGER, ParameterType.PARAMETER_DOUBLE):
                    continue
                checked += 1
                span = _range_of(descriptor)
                if span is None:
                    problems.append(f'{where}: no range')
                    continue
                low, high, integer = span
                if not low <= default <= high:
                    problems.append(f'{where}: default {default!r} outside [{low!r}, {high!r}]')
                if descriptor.read_only:
                    continue
                outside = (low - 1, high + 1) if integer else (math.nextafter(low, -math.inf),
                                                               math.nextafter(high, math.inf))
                for value in (low, high):
                    accepted, reason = client.set(descriptor.name, value)
                    if not accepted:
                        problems.append(f'{where}: refuses {value!r}, an end of its range: {reason}')
                    client.set(descriptor.name, default)
                for value in outside:
                    accepted, _reason = client.set(descriptor.name, value)
                    if accepted:
                        problems.append(f'{where}: accepts {value!r}, outside its range [{low!r}, {high!r}]')
                        client.set(descriptor.name, default)
        assert checked >= 40 and ENUMERATED <= enumerated, (checked, enumerated)
        assert not problems, '\n'.join(problems)
        for module, proc in graph.procs.items():
            assert proc.poll() is None, f'{module} exited:\n{process_runner.output(module)}'
    finally:
        graph.close()
