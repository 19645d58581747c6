"""``wallbot-sim motors``: motor sizing figures checked against an independent computation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from cli_helpers import wallbot
from wallbot_sim import paths
from wallbot_sim.bag.headless import HeadlessBagWriter
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.model import Robot, Simulation


def motors_json(path) -> dict:
    result = wallbot('motors', str(path), '--json')
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.fixture(scope='module')
def tracking_run(tmp_path_factory):
    """A figure-8 tracking run with all constraints, as a CSV and a bag from the same simulate."""
    out = tmp_path_factory.mktemp('motors')
    result = wallbot('simulate', '--scenario', 'figure8', '--constraints', 'belt,non_lateral,nonslip',
                 '--duration', '2.0', '--csv', str(out / 'run.csv'), '--bag', str(out / 'bag'), '--quiet')
    assert result.returncode == 0, result.stderr
    return out / 'run.csv', out / 'bag'


def expected_from_csv(csv_path) -> dict:
    """The figures recomputed from the CSV columns and the raw robot YAML, with numpy only."""
    with open(csv_path) as stream:
        header = stream.readline().strip().split(',')
    data = np.loadtxt(csv_path, delimiter=',', skiprows=1)
    col = {name: data[:, i] for i, name in enumerate(header)}
    robot = yaml.safe_load(open(paths.robot_yaml()))
    r = robot['wheel_radius']
    sides = {}
    for side, force, (i, j) in (('left', 'F_left', (1, 2)), ('right', 'F_right', (3, 4))):
        tau = r * col[force] + col[f'tau{i}'] + col[f'tau{j}']
        rate = 0.5 * (col[f'dphi{i}'] + col[f'dphi{j}'])
        sides[side] = {'peak_torque': np.abs(tau).max(), 'rms_torque': math.sqrt(np.mean(tau ** 2)),
                       'peak_spin_rate': np.abs(rate).max(), 'peak_ground_speed': r * np.abs(rate).max(),
                       'peak_power': np.abs(tau * rate).max(), 'peak_drive_power': max((tau * rate).max(), 0.0)}
    m_t = robot['body_mass'] + 4 * robot['wheel_mass']
    weight = m_t * robot['gravity']
    tipping = weight * robot['com_height'] / min(robot['half_wheelbase'], robot['half_track'])
    f_min = max(weight / robot['wall_friction'], tipping)
    friction = np.hypot(col['F_left'] + col['F_right'], col['F_lateral']) / robot['wall_friction']
    needed = np.maximum(tipping, friction).max()
    applied = robot['adsorption_safety'] * f_min
    return {'sides': sides, 'needed': needed, 'applied': applied, 'margin': applied / needed,
            'tipping': tipping, 'samples': len(data)}


@pytest.mark.parametrize('which', ['csv', 'bag'])
def test_tracking_run_figures_match_an_independent_computation(tracking_run, which):
    csv_path, bag = tracking_run
    expected = expected_from_csv(csv_path)
    report = motors_json(csv_path if which == 'csv' else bag)
    assert report['samples'] == expected['samples']
    for side in ('left', 'right'):
        for key, value in expected['sides'][side].items():
            assert report[side][key] == pytest.approx(value, rel=1e-9, abs=1e-12), (side, key)
        assert report[side]['peak_torque'] > 0.1  # the figure-8 needs real torque
    a = report['adsorption']
    assert a['peak_needed'] == pytest.approx(expected['needed'], rel=1e-9)
    assert a['applied'] == pytest.approx(expected['applied'], rel=1e-12)
    assert a['margin'] == pytest.approx(expected['margin'], rel=1e-9)
    assert a['tipping_limit'] == pytest.approx(expected['tipping'], rel=1e-12)


def test_table_names_every_figure(tracking_run):
    csv_path, _bag = tracking_run
    result = wallbot('motors', str(csv_path))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert any(line.startswith('left ') for line in lines) and any(line.startswith('right ') for line in lines)
    for words in ('peak |tau|', 'RMS tau', 'peak |w|', 'peak speed', 'peak |P|', 'Adsorption needed',
                  'Adsorption applied', 'margin'):
        assert words in result.stdout


def test_driven_run_gives_back_the_applied_torques(tmp_path):
    """Constant motor torques through the belt/non-lateral/nonslip plant: peak = RMS = applied."""
    robot = Robot(load_robot_parameters())
    plant = Simulation(robot, None, DRIVEN, np.array([0.5, 0.5, math.pi / 2, 0, 0, 0, 0]), np.zeros(7))
    tau_left, tau_right = 2.4, 2.0  # more than gravity needs: climbs and turns
    plant.set_motor_torque(tau_left, tau_right)
    writer = HeadlessBagWriter.open(tmp_path / 'driven', plant)
    rates = []

    def on_step(out):
        writer.write(out)
        rates.append(out.qd[3:7].copy())

    try:
        plant.run(1.0, on_step)
    finally:
        writer.close()
    report = motors_json(tmp_path / 'driven')
    rates = np.array(rates)
    for side, tau, cols in (('left', tau_left, [0, 1]), ('right', tau_right, [2, 3])):
        figures = report[side]
        assert figures['peak_torque'] == pytest.approx(tau, abs=1e-6)
        assert figures['rms_torque'] == pytest.approx(tau, abs=1e-6)
        peak_rate = np.abs(rates[:, cols].mean(axis=1)).max()
        assert figures['peak_spin_rate'] == pytest.approx(peak_rate, rel=1e-9)
        assert figures['peak_power'] == pytest.approx(tau * peak_rate, rel=1e-6)
        assert figures['peak_spin_rate'] > 1.0  # it did move


def test_robot_file_changes_the_adsorption_figures(tracking_run, tmp_path):
    csv_path, _bag = tracking_run
    robot = yaml.safe_load(open(paths.robot_yaml()))
    robot['wall_friction'] = 0.35
    robot['kinetic_friction'] = 0.3
    other = tmp_path / 'robot.yaml'
    other.write_text(yaml.safe_dump(robot))
    base = motors_json(csv_path)['adsorption']
    result = wallbot('motors', str(csv_path), '--json', '--robot', str(other))
    assert result.returncode == 0, result.stderr
    changed = json.loads(result.stdout)['adsorption']
    # friction halves: the friction requirement and the static minimum double
    assert changed['peak_friction_needed'] == pytest.approx(2 * base['peak_friction_needed'], rel=1e-9)
    assert changed['applied'] == pytest.approx(2 * base['applied'], rel=1e-9)


@pytest.mark.parametrize('make, message', [
    (lambda tmp: tmp / 'missing', 'does not exist'),
    (lambda tmp: tmp, 'not a rosbag2 bag'),
    (lambda tmp: (tmp / 'notes.txt').write_text('hello') and tmp / 'notes.txt', 'not a rosbag2 bag'),
    (lambda tmp: (tmp / 'bad.csv').write_text('a,b\n1,2\n') and tmp / 'bad.csv', 'not a wallbot-sim simulate CSV'),
])
def test_bad_input_is_one_line(tmp_path, make, message):
    result = wallbot('motors', str(make(tmp_path)))
    assert result.returncode == 2
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert result.stdout == ''


def test_bad_robot_file_is_one_line(tracking_run, tmp_path):
    csv_path, _bag = tracking_run
    result = wallbot('motors', str(csv_path), '--robot', str(tmp_path / 'nope.yaml'))
    assert result.returncode == 2
    assert 'cannot read' in result.stderr and len(result.stderr.strip().splitlines()) == 1
