"""``wallbot-sim run rest --drive cmd_vel``: a user drives the robot from another terminal, and an
aggressive command with coulomb contact slips."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('rclpy')

from cli_helpers import WALLBOT, assert_one_line_error, wait_for_output, wallbot  # noqa: E402
from closed_loop import recorded  # noqa: E402
from wallbot_sim.domain import claim_domain_id  # noqa: E402
from wallbot_sim.rundata import load_run  # noqa: E402


def test_an_aggressive_cmd_vel_slips_with_coulomb_contact(tmp_path, process_runner):
    """The cmd_vel node's acceleration limit raised to 50 m/s^2 (``ros2 param set``) and 0.5 m/s
    asked: the wheel-speed loop saturates at 5 N m per side, 125 N of traction where friction holds
    66 N, so every wheel slides while the wheels spin faster than the robot rolls."""
    with claim_domain_id() as free:
        chosen = free.domain_id
    out = tmp_path / 'run'
    run = process_runner.start([*WALLBOT, 'run', 'rest', '--drive', 'cmd_vel', '--contact', 'coulomb',
                                '--duration', '0', '--domain-id', chosen, '--out', out, '--no-plots'], 'run')
    first = wait_for_output(process_runner, 'run', r'\A.*\n', 60).group(0)
    probe = Path(__file__).with_name('cmd_vel_probe.py')
    driver = process_runner.start(['bash', '-c', f'{first}exec {sys.executable} {probe} 0.5 0.0 1.0 '
                                   'linear.x.max_acceleration:=50.0'], 'driver')
    wait_for_output(process_runner, 'driver', r'^drove [0-9.]+ [0-9.]+$', 120)
    assert driver.wait(timeout=30) == 0
    run.send_signal(signal.SIGINT)
    assert run.wait(timeout=60) == 130
    output = process_runner.output('run')
    assert 'rest, belt+non_lateral+nonslip driven by cmd_vel' in output and 'Traceback' not in output
    assert "first slip at" in output and "tracking error:      none (no reference recorded" in output, output

    data = load_run(out / 'bag')
    slipping = np.nan_to_num(data.slip) > 0.5
    assert slipping.any(axis=0).all()  # every wheel slides
    rolling = 0.04 * data.dphi.mean(axis=1)  # the wheels' rim speed (radius 0.04 m)
    speed = np.cos(data.theta) * data.vx + np.sin(data.theta) * data.vy
    assert (rolling - speed)[slipping.all(axis=1)].max() > 0.05  # wheels spin ahead of the robot
    commands = [list(m.data) for m in recorded(out / 'bag', 'wheel_torque_cmd')]
    assert max(max(c) for c in commands) == pytest.approx(5.0)
    assert recorded(out / 'bag', 'cmd_vel')


def test_drive_and_rest_go_together(tmp_path):
    assert_one_line_error(wallbot('run', 'rest', '--out', tmp_path / 'a'), '--drive and scenario rest go together')
    assert_one_line_error(wallbot('run', 'circle', '--drive', 'cmd_vel', '--out', tmp_path / 'b'),
                          '--drive and scenario rest go together')
    assert_one_line_error(wallbot('run', 'rest', '--drive', 'cmd_vel', '--constraints', 'belt', '--out',
                                  tmp_path / 'c'), '--drive runs the driven robot')
