"""The ``wallbot`` fixture of the pytest plugin (``wallbot_sim.testing``): a test runs the robot and its controller
step by step, injects faults (as ``ros2 param set`` on the dynamics does: refused out of range, the run going on),
and judges it; a test that fails midway leaves no process behind; the example controller's package tests pass."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from wallbot_sim.graph_monitor import ParameterRefused
from wallbot_sim.rundata.faults import fault_events
from wallbot_sim.testing import SpecError

HERE = Path(__file__).parent
EXAMPLE = HERE.parent / 'examples' / 'wallbot_example_controller'
UNDER_TEST = [sys.executable, str(HERE / 'controller_under_test.py')]


def test_the_fixture_runs_injects_and_judges(wallbot):
    wallbot.start(scenario='rest', contact='coulomb', controller=[*UNDER_TEST, 'answer', '0.2', '0.3'])
    state = wallbot.run(0.2)
    assert state.t == pytest.approx(0.2, abs=1e-9)
    assert state.motor_torque == pytest.approx((0.2, 0.3))
    wallbot.inject(motor_left=0.0)
    with pytest.raises(SpecError, match=r'^wallbot.inject: motor_efficiency_left must be .*got 1.5$'):
        wallbot.inject(motor_left=1.5)
    with pytest.raises(ParameterRefused, match='motor_efficiency_right'):  # what ros2 param set meets
        wallbot.session.monitor.set_dynamics_parameters({'motor_efficiency_right': -0.5})
    state = wallbot.run(0.1)
    assert state.t == pytest.approx(0.3, abs=1e-9)
    assert state.motor_torque == pytest.approx((0.0, 0.3))
    with pytest.raises(AssertionError, match=r'^FAIL max_motor_torque: .* on the right side .*\(figure: '):
        wallbot.expect_max_motor_torque(0.25)
    assert (wallbot.out / 'plots' / 'max_motor_torque.png').is_file()
    assert wallbot.expect_no_detachment().passed
    event, = fault_events(wallbot.bag)
    assert (event.stamp_ns, event.changed, event.cause) == (200_000_000, ('motor_efficiency_left',), 'parameter')


FAILS_MIDWAY = '''
import json, sys

def test_fails_midway(wallbot, tmp_path):
    wallbot.start(scenario='rest', contact='coulomb', controller={controller!r})
    wallbot.run(0.1)
    with open({pids!r}, 'w') as stream:
        json.dump(wallbot.processes, stream)
    raise RuntimeError('the test fails here, its robot running')
'''


def inner_pytest(*args: object, timeout: float = 300.0) -> subprocess.CompletedProcess:
    """pytest in a child process with the plugin and the example controller's package importable."""
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(filter(None, (str(EXAMPLE), os.environ.get('PYTHONPATH'))))}
    return subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'wallbot_sim.testing.plugin', '-p',
                           'no:cacheprovider', *map(str, args)], capture_output=True, text=True, timeout=timeout,
                          env=env)


def test_a_test_that_fails_midway_leaves_no_process_behind(tmp_path):
    import json
    pids = tmp_path / 'pids.json'
    (tmp_path / 'test_midway.py').write_text(FAILS_MIDWAY.format(controller=[*UNDER_TEST, 'answer', '0', '0'],
                                                                 pids=str(pids)))
    result = inner_pytest(tmp_path / 'test_midway.py', '--rootdir', tmp_path)
    assert result.returncode == 1 and 'the test fails here' in result.stdout, result.stdout + result.stderr
    started = json.loads(pids.read_text())
    assert 'controller' in started and len(started) >= 3
    for name, pid in started.items():  # each ended and reaped by the fixture before the inner pytest exited
        assert not Path(f'/proc/{pid}').exists(), name


def test_the_example_controller_package_tests_pass(tmp_path):
    result = inner_pytest(EXAMPLE / 'test', '--rootdir', EXAMPLE, '--basetemp', tmp_path / 'basetemp')
    assert result.returncode == 0, result.stdout + result.stderr
