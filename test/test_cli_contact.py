"""``wallbot-sim simulate --scenario rest --contact coulomb``: docs/model.md 11.4's analytic cases through the CLI.

The CSV's slip1..slip4 say which wheels slide, use1..use4 their friction use."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from cli_helpers import WALLBOT, read_csv, simulate, wallbot
from wallbot_sim.config import load_scenario
from wallbot_sim.graph_description import describe_graph
from wallbot_sim.model import ConstraintSelection
from wallbot_sim.paths import robot_yaml


def rest_run(tmp_path, *args: str) -> tuple[object, dict[str, list[float]]]:
    out = tmp_path / 'rest.csv'
    result = simulate('--scenario', 'rest', '--contact', 'coulomb', '--csv', str(out), '--quiet', *args)
    header, rows = read_csv(out) if out.exists() else ([], [])
    return result, {name: [row[i] for row in rows] for i, name in enumerate(header)}


def sliding(run: dict[str, list[float]]) -> list[float]:
    """Every wheel's slip flag at every instant (1 while it slides)."""
    return [flag for i in range(1, 5) for flag in run[f'slip{i}']]


def test_hold(tmp_path):
    """Nothing moves; every wheel uses 2/3 of its disc, so the adhesion force needed is m_t g / mu_s, every disc full
    at once."""
    result, run = rest_run(tmp_path)
    assert result.returncode == 0, result.stderr
    assert len(run['t']) == 1001 and run['t'][-1] == pytest.approx(1.0)  # rest runs 1 s by default
    assert [run[f'use{i}'][0] for i in range(1, 5)] == pytest.approx([0.667] * 4, abs=5e-4)
    assert max(abs(v) for v in run['y']) < 1e-12
    assert not any(sliding(run))
    assert run['N1'][0] == pytest.approx(38.10, abs=0.005) and run['N3'][0] == pytest.approx(56.50, abs=0.005)
    report = wallbot('motors', str(tmp_path / 'rest.csv'), '--json')
    assert report.returncode == 0, report.stderr
    assert json.loads(report.stdout)['adsorption']['needed'] == pytest.approx(9.0 * 9.81 / 0.7, rel=1e-9)  # m_t g / mu


def test_slide(tmp_path):
    result, run = rest_run(tmp_path, '--adhesion-force', '100')
    assert result.returncode == 0, result.stderr
    assert all(sliding(run))  # every wheel slides down
    ydd = (run['vy'][-1] - run['vy'][-101]) / 0.1
    assert ydd == pytest.approx(-2.81, abs=1e-4)
    assert run['y'][-1] == pytest.approx(-1.405, abs=3e-3)
    assert run['N1'][-1] == pytest.approx(18.44, abs=0.005) and run['N2'][-1] == pytest.approx(18.44, abs=0.005)


def test_spinning_climb(tmp_path):
    result, run = rest_run(tmp_path, '--heading', str(math.pi / 2), '--torque', '3,3')
    assert result.returncode == 0, result.stderr
    assert all(sliding(run))
    assert max(abs(v) for v in run['vx']) < 1e-9  # sliding along x_p only: straight up
    ydd = (run['vy'][-1] - run['vy'][-101]) / 0.1
    assert ydd == pytest.approx(2.172, abs=5e-4)


def flat_robot(tmp_path) -> Path:
    """The default robot with in-plane gravity negligible (every wheel carries F_ad / 4)."""
    robot = yaml.safe_load(robot_yaml().read_text())
    robot['gravity'] = 0.01
    robot_file = tmp_path / 'flat.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    return robot_file


def wheel_slip_speeds(run: dict[str, list[float]]) -> np.ndarray:
    """(T, 4): each wheel's contact speed on the wall from the CSV's state (docs/model.md 11.3), written out here."""
    theta, vx, vy, omega = (np.array(run[name]) for name in ('theta', 'vx', 'vy', 'omega'))
    v_long, v_lat = np.cos(theta) * vx + np.sin(theta) * vy, -np.sin(theta) * vx + np.cos(theta) * vy
    speeds = []
    for i, (a, s) in enumerate(((0.10, 0.12), (-0.10, 0.12), (0.10, -0.12), (-0.10, -0.12))):
        along = v_long - s * omega - 0.04 * np.array(run[f'dphi{i + 1}'])
        speeds.append(np.hypot(along, v_lat + a * omega))
    return np.array(speeds).T


@pytest.mark.parametrize('torque', [1.54, 1.85])
def test_turning_in_place_with_gravity_negligible(tmp_path, torque):
    """-T, +T facing +X: at 1.54 N m (91 % of the threshold 1.696 N m) nothing moves; at 1.85 N m the robot turns,
    all four wheels sliding."""
    result, run = rest_run(tmp_path, '--heading', '0', f'--torque=-{torque},{torque}', '--adhesion-force', '189.19',
                           '--robot', str(flat_robot(tmp_path)))
    assert result.returncode == 0, result.stderr
    slides = wheel_slip_speeds(run)[1:] > 1e-3  # v_st
    if torque < 1.696:
        assert max(abs(v) for v in run['theta'] + run['x'] + run['y']) < 1e-9
        assert not slides.any() and not any(sliding(run))
    else:
        assert run['theta'][-1] > 0.5 and run['omega'][-1] > 1.0
        assert slides.all()


def test_spinning_wheels_facing_x_slide_down(tmp_path):
    """3 N m per side facing +X: the wheels spin, lose their lateral grip, and the robot slides down more than 3 m
    within 1 s (where it peels off, the run ends with status 3 and the rows up to there)."""
    result, run = rest_run(tmp_path, '--heading', '0', '--torque', '3,3')
    assert result.returncode in (0, 3), result.stderr
    assert run['t'][-1] <= 1.0 and min(run['y']) < -3.0


def test_detachment_ends_the_run_with_status_3(tmp_path):
    robot = yaml.safe_load(robot_yaml().read_text())
    robot['com_height'] = 0.25
    robot_file = tmp_path / 'tall.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    result, run = rest_run(tmp_path, '--robot', str(robot_file), '--adhesion-force', '130')
    assert result.returncode == 3
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('detached: wheel ')
    assert '-13.48 N' in lines[0] and 't = 0.000 s' in lines[0]
    assert run['t'] == [0.0]  # the rows up to the detachment
    assert run['N1'][0] == pytest.approx(-13.48, abs=0.005)


def test_ideal_contact_reports_zero_slip_and_the_loads(tmp_path):
    out = tmp_path / 'ideal.csv'
    result = simulate('--scenario', 'rest', '--adhesion-force', '100', '--duration', '0.2', '--csv', str(out),
                      '--quiet')
    assert result.returncode == 0, result.stderr
    header, rows = read_csv(out)
    col = {name: i for i, name in enumerate(header)}
    assert all(row[col[f'slip{i}']] == 0 for row in rows for i in range(1, 5))
    assert [rows[-1][col[f'use{i}']] for i in range(1, 5)] == pytest.approx([9.0 * 9.81 / 70.0] * 4, rel=1e-6)
    assert rows[-1][col['y']] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize('args, words', [
    (('--scenario', 'circle', '--contact', 'coulomb'), '--contact coulomb with the trajectory task'),
    (('--scenario', 'rest', '--adhesion-force', '-5'), "argument --adhesion-force: must be 0 (the robot file's) or in (0, "
                                                       "1e+06], got -5.0"),
    (('--scenario', 'rest', '--torque', '3'), '--torque must be two numbers'),
    (('--scenario', 'circle', '--torque', '1,1'), '--heading and --torque set up --scenario rest'),
    (('--scenario', 'rest', '--contact', 'sticky'), "argument --contact: must be one of ideal, coulomb, got 'sticky'"),
])
def test_bad_values_are_one_line_errors(tmp_path, args, words):
    result = simulate(*args, '--csv', str(tmp_path / 'x.csv'))
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and words in result.stderr


def test_kinetic_above_static_friction_in_the_robot_file(tmp_path):
    robot = yaml.safe_load(robot_yaml().read_text())
    robot['kinetic_friction'] = 0.9
    robot_file = tmp_path / 'bad.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    result = simulate('--scenario', 'rest', '--robot', str(robot_file), '--csv', str(tmp_path / 'x.csv'))
    assert result.returncode == 2 and 'kinetic_friction must be <= wall_friction' in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_run_takes_a_robot_file_and_refuses_a_bad_one_before_starting(tmp_path):
    specs = describe_graph(load_scenario('circle'), ConstraintSelection.parse('belt'), duration=1.0,
                           real_time_factor=0.0, bag=tmp_path / 'bag', robot_file=Path('/robots/tall.yaml'))
    assert {spec.name: spec.parameters for spec in specs}['dynamics']['robot_file'] == '/robots/tall.yaml'
    specs = describe_graph(load_scenario('circle'), ConstraintSelection.parse('belt'), duration=1.0,
                           real_time_factor=0.0, bag=tmp_path / 'bag', controller_mass_scale=1.0,
                           contact_model='coulomb', adhesion_force=150.0)
    dynamics = {spec.name: spec.parameters for spec in specs}['dynamics']
    assert dynamics['contact_model'] == 'coulomb' and dynamics['adhesion_force'] == 150.0
    refused = wallbot('run', 'circle', '--contact', 'coulomb', '--out', str(tmp_path / 'refused'))
    assert refused.returncode == 2 and '--contact coulomb needs --controller' in refused.stderr
    robot = yaml.safe_load(robot_yaml().read_text())
    robot['adhesion_force'] = -1.0
    robot_file = tmp_path / 'bad.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    result = subprocess.run([*WALLBOT, 'run', 'circle', '--robot', str(robot_file),
                             '--out', str(tmp_path / 'run')], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and 'adhesion_force must be > 0' in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / 'run').exists()


CLIMB = ('--heading', str(math.pi / 2), '--torque', '2.0,1.95')
"""Climbing while turning slowly: every wheel sticks, the left ones near their discs' edges."""


def slip_count(path: Path) -> float:
    header, run = read_csv(path)
    return sum(row[header.index(f'slip{i}')] for row in run for i in range(1, 5))


def test_motors_adhesion_needed_is_what_keeps_the_run_sticking(tmp_path):
    """The adhesion force motors says the climb needed: 2 % less and a wheel slides, 2 % more and none does."""
    result, run = rest_run(tmp_path, *CLIMB)
    assert result.returncode == 0 and not any(sliding(run))
    report = wallbot('motors', str(tmp_path / 'rest.csv'), '--json')
    assert report.returncode == 0, report.stderr
    figures = json.loads(report.stdout)
    assert figures['contact']['peak_use'] == pytest.approx([max(run[f'use{i}']) for i in range(1, 5)])
    adsorption = figures['adsorption']
    least = adsorption['needed']
    assert adsorption['needed_by'] == 'left front wheel, friction' and 100.0 < least < 189.0
    for scale, slips in ((0.98, True), (1.02, False)):
        out = tmp_path / f'at{scale}.csv'
        again = simulate('--scenario', 'rest', '--contact', 'coulomb', *CLIMB, '--adhesion-force', str(scale * least),
                         '--csv', str(out), '--quiet')
        assert again.returncode == 0, again.stderr
        assert (slip_count(out) > 0) == slips, f'at {scale} x the adhesion force needed'
    assert 'Adhesion needed' in wallbot('motors', str(tmp_path / 'rest.csv')).stdout


def test_summary_plot_and_bag_show_slip_and_lift_off(tmp_path):
    from wallbot_sim.rundata import format_summary, summarize
    from wallbot_sim.rundata import load_run
    result, _ = rest_run(tmp_path, '--adhesion-force', '100', '--duration', '0.3', '--bag', str(tmp_path / 'bag'))
    assert result.returncode == 0, result.stderr
    text = format_summary(summarize(tmp_path / 'rest.csv'))
    assert 'first slip at t = 0.000 s (left front, left rear, right front, right rear)' in text
    assert 'lifts off' not in text
    csv_run, bag_run = load_run(tmp_path / 'rest.csv'), load_run(tmp_path / 'bag')
    assert np.array_equal(csv_run.loads, bag_run.loads) and np.array_equal(csv_run.use, bag_run.use)
    assert np.array_equal(csv_run.slip, bag_run.slip) and bag_run.slip[:, 2].all()
    plotted = wallbot('plot', str(tmp_path / 'bag'), '--out', str(tmp_path / 'plots'))
    assert plotted.returncode == 0, plotted.stderr
    assert (tmp_path / 'plots' / 'friction_use.png').stat().st_size > 10_000
    assert (tmp_path / 'plots' / 'normal_loads.png').stat().st_size > 10_000

    ideal = tmp_path / 'tall_ideal.csv'
    robot = yaml.safe_load(robot_yaml().read_text())
    robot['com_height'] = 0.25
    robot_file = tmp_path / 'tall.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    assert simulate('--scenario', 'rest', '--robot', str(robot_file), '--adhesion-force', '130', '--duration', '0.1',
                    '--csv', str(ideal), '--quiet').returncode == 0
    text = format_summary(summarize(ideal))
    assert 'no slip' in text and 'lifts off at t = 0.000 s (normal load -13.48 N)' in text
