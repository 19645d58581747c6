"""The example controller against the simulated robot: its spec, and a run driven step by step (the ``wallbot``
fixture of wallbot_sim's pytest plugin)."""

import sys
from pathlib import Path

import pytest

SPEC = Path(__file__).with_name('figure8.yaml')
CONTROLLER = [sys.executable, '-m', 'wallbot_example_controller.node']


def test_the_spec_holds(wallbot):
    outcome = wallbot.run_spec(SPEC)
    assert outcome.passed, outcome.summary()


def test_it_keeps_to_the_path_through_a_tenth_of_a_second_without_odometry(wallbot):
    wallbot.start(scenario='figure8', contact='coulomb', adhesion_force=250.0, controller=CONTROLLER)
    state = wallbot.run(0.6)
    assert state.t == pytest.approx(0.6)
    wallbot.inject({'at': 0.8, 'for': 0.1, 'drop': 'odom'})  # it holds its last command meanwhile
    wallbot.run(0.6)
    wallbot.expect_max_tracking_error_after(t=0.5, m=0.02)
    wallbot.expect_no_slip()
    wallbot.expect_no_detachment()
