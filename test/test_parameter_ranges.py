"""One rule for a number a parameter accepts: the model, the nodes and the command line agree."""

from __future__ import annotations

import math
import re

import pytest

from wallbot_sim.cli.main import build_parser
from wallbot_sim.model import ParameterError, RobotParameters
from wallbot_sim.model.numbers import FINITE, NON_NEGATIVE, POSITIVE, NumberRange
from wallbot_sim.nodes.pacing import REAL_TIME_FACTOR


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


FACTORS = [0.0, 5e-4, 9.99e-4, 1e-3, 0.5, 1.0, 1e6, 1e6 + 1.0, 2e6, -1.0, math.nan, math.inf]


@pytest.fixture(scope='module')
def dynamics_node():
    rclpy = pytest.importorskip('rclpy')
    from wallbot_sim.nodes.dynamics import DynamicsNode
    context = rclpy.Context()
    rclpy.init(context=context)
    node = None
    try:
        node = DynamicsNode(context=context)  # no constraints arrive: it never steps
        yield node
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.shutdown(context=context)


@pytest.mark.parametrize('factor', FACTORS, ids=repr)
def test_run_refuses_exactly_the_real_time_factors_the_dynamics_node_refuses(dynamics_node, factor, capsys):
    from rclpy.parameter import Parameter
    result, = dynamics_node.set_parameters([Parameter('real_time_factor', Parameter.Type.DOUBLE, factor)])
    try:
        build_parser().parse_args(['run', 'circle', '--real-time-factor', repr(factor)])
    except SystemExit as refused:
        assert refused.code == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith('wallbot-sim run: error: argument --real-time-factor: must be ')
        assert not result.successful, f'the node accepts {factor!r}, the command line refuses it: {lines[0]}'
        assert 'real_time_factor' in result.reason
    else:
        assert result.successful, f'the command line accepts {factor!r}, the node refuses it: {result.reason}'
