"""``wallbot-sim motors``: motor sizing figures checked against an independent computation; the adhesion force
needed against its definition, solved again here; the turn in place's threshold against the model's simulation."""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest
import yaml

from cli_helpers import WALLBOT, read_csv, simulate, wallbot
from wallbot_sim import paths
from wallbot_sim.bag.headless import HeadlessBagWriter
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.model import Robot, Simulation
from wallbot_sim.rundata.csv_format import CSV_COLUMNS, csv_line
from wallbot_sim.rundata.turning import flat_turn_threshold, turn_thresholds, worst_turn_start


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
    loads = np.column_stack([col[f'N{i}'] for i in range(1, 5)])
    return {'sides': sides, 'applied': robot['adsorption_safety'] * f_min, 'tipping': tipping,
            'run_adhesion': float(np.median(loads.sum(axis=1))), 'samples': len(data),
            'climb': 0.5 * r * (weight + robot['rolling_resistance'] * float(np.median(loads.sum(axis=1))))}


def resplit(loads: np.ndarray, forces: np.ndarray, adhesion: float, held: str, a: float = 0.10,
            b: float = 0.12) -> np.ndarray:
    """The wheels' forces (4, 2) of one sample shared again by the loads of ``adhesion``: the least sum of
    |f_i|^2 / N_i that keeps what ``held`` says as the sample's: 'chassis', the wrench on the chassis (ideal
    contact's split), or 'sides', each side's traction and the lateral force and its moment (coulomb contact's,
    the belt's force free); a KKT solve of the 8 unknowns (fx1..fx4, fy1..fy4)."""
    shifted = loads + (adhesion - loads.sum()) / 4.0
    along, across = np.array([a, -a, a, -a]), np.array([b, b, -b, -b])
    if held == 'chassis':
        rows = np.zeros((3, 8))
        rows[0, 0:4] = rows[1, 4:8] = 1.0
        rows[2] = np.concatenate((-across, along))  # M_Z = sum (x_i f_yi - y_i f_xi)
    else:
        rows = np.zeros((4, 8))
        rows[0, 0:2] = rows[1, 2:4] = rows[2, 4:8] = 1.0
        rows[3, 4:8] = along
    target = rows @ np.concatenate((forces[:, 0], forces[:, 1]))
    weights = np.concatenate((shifted, shifted))
    count = len(rows)
    kkt = np.block([[np.diag(1.0 / weights), rows.T], [rows, np.zeros((count, count))]])
    solution = np.linalg.solve(kkt, np.concatenate((np.zeros(8), target)))
    return np.column_stack((solution[0:4], solution[4:8]))


def wheel_data(csv_path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t (T,), loads (T, 4) and forces (T, 4, 2) of a simulate CSV."""
    header, rows = read_csv(csv_path)
    col = {name: np.array([row[i] for row in rows]) for i, name in enumerate(header)}
    wheels = range(1, 5)
    return (col['t'], np.column_stack([col[f'N{i}'] for i in wheels]),
            np.stack((np.column_stack([col[f'fx{i}'] for i in wheels]),
                      np.column_stack([col[f'fy{i}'] for i in wheels])), axis=2))


def largest_use(loads: np.ndarray, forces: np.ndarray, adhesion: float, held: str) -> float:
    shifted = loads + (adhesion - loads.sum()) / 4.0
    return float(np.max(np.hypot(*resplit(loads, forces, adhesion, held).T) / (0.7 * shifted)))


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
    assert a['applied'] == pytest.approx(expected['applied'], rel=1e-12)
    assert a['tipping_limit'] == pytest.approx(expected['tipping'], rel=1e-12)
    assert a['run_adhesion'] == pytest.approx(expected['run_adhesion'], rel=1e-12)
    assert a['margin'] == pytest.approx(expected['run_adhesion'] / a['needed'], rel=1e-12)
    assert report['turning']['climb_torque'] == pytest.approx(expected['climb'], rel=1e-12)


@pytest.mark.parametrize('contact', ['ideal', 'coulomb'])
def test_the_adhesion_needed_is_the_least_that_keeps_every_wheel_in_its_disc(tracking_run, tmp_path, contact):
    """The figure-8 with ideal contact, and a driven climb turning slowly with coulomb contact: shared again by
    the loads of its own adhesion force as its contact model splits it (ideal: the chassis wrench over the four
    wheels; coulomb: each side's traction between its wheels, the lateral force and moment over all four), every
    sample's forces are the run's; at the force motors reports every wheel of every sample is inside its disc
    and the binding wheel on its edge; a little less, it is outside."""
    if contact == 'ideal':
        csv_path, held = tracking_run[0], 'chassis'
    else:
        csv_path, held = tmp_path / 'climb.csv', 'sides'
        result = simulate('--scenario', 'rest', '--contact', 'coulomb', '--heading', str(math.pi / 2), '--torque',
                          '2.0,1.95', '--csv', csv_path, '--quiet')
        assert result.returncode == 0, result.stderr
    a = motors_json(csv_path)['adsorption']
    t, loads, forces = wheel_data(csv_path)
    for k in range(0, len(t), 50):
        assert resplit(loads[k], forces[k], loads[k].sum(), held) == pytest.approx(forces[k], abs=1e-9)
    needed = a['needed']
    assert 0.5 * a['run_adhesion'] < needed and a['needed_by'].endswith('wheel, friction')
    uses = [largest_use(loads[k], forces[k], needed, held) for k in range(len(t))]
    assert max(uses) <= 1.0 + 1e-9
    binding = int(np.argmin(np.abs(t - a['needed_t'])))
    assert uses[binding] == pytest.approx(1.0, abs=1e-9)
    assert largest_use(loads[binding], forces[binding], needed * (1.0 - 1e-6), held) > 1.0


def test_table_names_every_figure_and_the_robot_file_it_read(tracking_run, tmp_path):
    csv_path, _bag = tracking_run
    result = subprocess.run([*WALLBOT, 'motors', str(csv_path)], capture_output=True, text=True, timeout=180,
                            cwd=tmp_path)  # elsewhere than the source tree: the robot file by its real path
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert any(line.startswith('left ') for line in lines) and any(line.startswith('right ') for line in lines)
    assert f'Robot:  {paths.robot_yaml()} (wheel radius 0.04 m)' in lines
    for words in ('peak |tau|', 'RMS tau', 'peak |w|', 'peak speed', 'peak |P|', 'Turning in place from rest',
                  'worst heading', 'with gravity negligible', 'Climbing straight up', "This run's turns",
                  'Sizing: turning in place governs', 'Adhesion of the run', 'margin', 'Friction use (peak)'):
        assert words in result.stdout, words
    assert result.stdout.count('Adhesion needed') == 1 and 'needed up to' not in result.stdout  # one figure


@pytest.mark.parametrize('which', ['csv', 'bag'])
def test_driven_run_gives_back_the_applied_torques(tmp_path, which):
    """Constant motor torques through the belt/non-lateral/nonslip plant: peak = RMS = applied, from the bag
    (wheel_states' effort) and from the CSV (tau1..tau4), each the total torque on its wheel."""
    robot = Robot(load_robot_parameters())
    plant = Simulation(robot, None, DRIVEN, np.array([0.5, 0.5, math.pi / 2, 0, 0, 0, 0]), np.zeros(7))
    tau_left, tau_right = 2.4, 2.0  # more than gravity needs: climbs and turns
    plant.set_motor_torque(tau_left, tau_right)
    writer = HeadlessBagWriter.open(tmp_path / 'driven', plant)
    rates, lines = [], [','.join(CSV_COLUMNS) + '\r\n']

    def on_step(out):
        writer.write(out)
        lines.append(csv_line(out))
        rates.append(out.qd[3:7].copy())

    try:
        plant.run(1.0, on_step)
    finally:
        writer.close()
    (tmp_path / 'driven.csv').write_text(''.join(lines), newline='')
    report = motors_json(tmp_path / ('driven' if which == 'bag' else 'driven.csv'))
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
    base = motors_json(csv_path)
    result = wallbot('motors', str(csv_path), '--json', '--robot', str(other))
    assert result.returncode == 0, result.stderr
    changed = json.loads(result.stdout)
    assert changed['robot'] == str(other)
    # friction halves: the static minimum doubles, and so does the robot file's adhesion force (k_ad F_min);
    # with the run's adhesion force the turn's threshold with gravity negligible halves
    assert changed['adsorption']['applied'] == pytest.approx(2 * base['adsorption']['applied'], rel=1e-9)
    assert changed['turning']['flat_threshold'] == pytest.approx(0.5 * base['turning']['flat_threshold'], rel=1e-12)


@pytest.mark.parametrize('make, message', [
    (lambda tmp: tmp / 'missing', 'does not exist'),
    (lambda tmp: tmp, 'not a rosbag2 bag'),
    (lambda tmp: (tmp / 'notes.txt').write_text('hello') and tmp / 'notes.txt', 'neither a simulate CSV (.csv) nor'),
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


def test_the_turn_threshold_sticks_below_and_slides_above_in_the_model():
    """turn_thresholds at six headings, turning either way, for a robot whose CoM is off the centre: the model at
    rest under side torques tau_0 -+ 0.98 T* keeps every wheel sticking and the robot where it stands; at
    1.02 T* a wheel slides."""
    params = load_robot_parameters().replace(com_offset=(0.02, -0.01), com_height=0.06, adhesion_force=200.0)
    headings = np.array([0.0, 0.4, math.pi / 2, 2.5, -math.pi / 2, 4.0])
    thresholds = turn_thresholds(params, 200.0, headings)
    assert np.all(thresholds.left > 0.1) and np.all(thresholds.right > 0.1)
    for k, heading in enumerate(headings):
        hold = thresholds.hold_torque[k]
        for turn in (thresholds.left[k], -thresholds.right[k]):
            for scale, slides in ((0.98, False), (1.02, True)):
                start = np.array([0.0, 0.0, heading, 0.0, 0.0, 0.0, 0.0])
                simulation = Simulation(Robot(params), None, DRIVEN, start, np.zeros(7), contact='coulomb')
                simulation.set_motor_torque(hold - scale * turn, hold + scale * turn)
                sliding = []
                simulation.run(0.02, lambda out: sliding.append(any(out.contact.wheel_slipping)))
                assert any(sliding) == slides, (heading, turn, scale)
                if not slides:
                    assert np.abs(simulation.q[:3] - start[:3]).max() < 1e-12


def test_the_worst_heading_takes_the_largest_side_torque_of_every_heading():
    """worst_turn_start against a scan of every hundredth of a degree, both ways: no larger side torque, and what
    it reports is that of its heading and direction. With gravity negligible every
    heading's threshold is docs/model.md 11.4's T* = mu_s F r / (2 sqrt(1 + (b/a)^2)) = 1.696 N m."""
    params = load_robot_parameters()
    adhesion = Robot(params).adsorption.applied_force
    start = worst_turn_start(params, adhesion)
    scan = turn_thresholds(params, adhesion, np.linspace(0.0, 2.0 * math.pi, 36_001))
    largest = max(np.max(np.abs(scan.hold_torque) + scan.left), np.max(np.abs(scan.hold_torque) + scan.right))
    assert largest - 1e-12 <= start.side_torque < largest + 2e-5  # the scan is 1.7e-4 rad coarse
    at = turn_thresholds(params, adhesion, np.array([start.heading]))
    assert abs(at.hold_torque[0]) + getattr(at, start.direction)[0] == pytest.approx(start.side_torque, rel=1e-12)
    assert start.side_torque > 0.5 * params.wheel_radius * Robot(params).total_mass * params.gravity  # > holding
    flat = turn_thresholds(params.replace(gravity=1e-9), 189.19, scan.heading[::100])
    assert flat_turn_threshold(params, 189.19) == pytest.approx(1.696, abs=5e-4)
    for thresholds in (flat.left, flat.right):
        assert thresholds == pytest.approx(np.full(len(thresholds), flat_turn_threshold(params, 189.19)), rel=1e-6)


def test_motors_says_what_the_turn_costs_and_what_governs(tmp_path):
    """A driven climb turning slowly (coulomb contact, every wheel sticking): the turn's figures with the run's
    adhesion force, the differential side torque its wheels' longitudinal forces took (the applied one, its
    wheels spinning up alike), and turning in place governing the straight climb."""
    csv_path = tmp_path / 'climb.csv'
    result = simulate('--scenario', 'rest', '--contact', 'coulomb', '--heading', str(math.pi / 2), '--torque', '2.0,1.95',
                      '--adhesion-force', '170', '--csv', csv_path, '--quiet')
    assert result.returncode == 0, result.stderr
    turning = motors_json(csv_path)['turning']
    params = load_robot_parameters()
    start = worst_turn_start(params, 170.0)
    assert turning['adhesion'] == pytest.approx(170.0, rel=1e-12)
    assert turning['direction'] == start.direction
    assert (turning['heading'], turning['start_torque']) == pytest.approx((start.heading, start.side_torque), rel=1e-12)
    _t, _loads, forces = wheel_data(csv_path)
    differential = 0.02 * np.abs(forces[:, 2, 0] + forces[:, 3, 0] - forces[:, 0, 0] - forces[:, 1, 0])
    assert turning['run_turn_torque'] == np.max(differential) == pytest.approx(0.025, abs=1e-6)
    assert turning['climb_torque'] == pytest.approx(0.02 * (9.0 * 9.81 + 0.03 * 170.0), rel=1e-12)
    assert turning['governs'] == 'turning in place' and turning['governing_torque'] == turning['start_torque']
    assert turning['start_torque'] > turning['climb_torque']
