"""``wallbot-sim simulate``: the CSV contract and its error paths."""

from __future__ import annotations

import math
import subprocess

import pytest

from cli_helpers import WALLBOT, read_csv, simulate
from wallbot_sim.rundata import CSV_COLUMNS

HEADER = ('t,x,y,theta,phi1,phi2,phi3,phi4,vx,vy,omega,dphi1,dphi2,dphi3,dphi4,ref_x,ref_y,err,'
          'Fx,Fy,Mz,tau1,tau2,tau3,tau4,F_left,F_right,F_lateral,residual,'
          'N1,N2,N3,N4,use1,use2,use3,use4,slip1,slip2,slip3,slip4,fx1,fx2,fx3,fx4,fy1,fy2,fy3,fy4')


def test_csv_has_the_contract_header_and_one_row_per_step(tmp_path):
    out = tmp_path / 'circle.csv'
    result = simulate('--scenario', 'circle', '--constraints', 'belt,non_lateral,nonslip',
                      '--duration', '0.5', '--csv', str(out))
    assert result.returncode == 0, result.stderr
    assert ','.join(CSV_COLUMNS) == HEADER
    header, rows = read_csv(out)
    assert ','.join(header) == HEADER
    assert len(rows) == 501
    assert [row[0] for row in rows[:3]] == pytest.approx([0.0, 0.001, 0.002])
    col = {name: i for i, name in enumerate(header)}
    for row in rows:
        assert row[col['err']] == pytest.approx(math.hypot(row[col['x']] - row[col['ref_x']],
                                                           row[col['y']] - row[col['ref_y']]), abs=1e-12)
        # drive forces reproduce the chassis wrench through G (docs/model.md section 8)
        th = row[col['theta']]
        fl, fr, flat = row[col['F_left']], row[col['F_right']], row[col['F_lateral']]
        assert math.cos(th) * (fl + fr) - math.sin(th) * flat == pytest.approx(row[col['Fx']], abs=1e-9)
        assert math.sin(th) * (fl + fr) + math.cos(th) * flat == pytest.approx(row[col['Fy']], abs=1e-9)
        assert 0.12 * (fr - fl) == pytest.approx(row[col['Mz']], abs=1e-9)
    assert rows[0][col['x']] == 0.8 and rows[0][col['ref_x']] == 1.0
    assert 'real-time factor' in result.stderr


@pytest.mark.parametrize('scenario', ['circle', 'figure8'])
@pytest.mark.parametrize('constraints, heading', [
    ('none', None), ('belt', None), ('belt,non_lateral', None), ('belt,non_lateral,nonslip', None),
    ('belt,non_lateral', '--no-tangent-heading'), ('belt,non_lateral,nonslip', '--no-tangent-heading')])
def test_every_paper_scenario_runs(tmp_path, scenario, constraints, heading):
    out = tmp_path / 'run.csv'
    args = ['--scenario', scenario, '--constraints', constraints, '--duration', '0.2', '--csv', str(out), '--quiet']
    result = simulate(*args, *([heading] if heading else []))
    assert result.returncode == 0, result.stderr
    _, rows = read_csv(out)
    assert len(rows) == 201 and all(math.isfinite(v) for v in rows[-1])


@pytest.mark.parametrize('args, message', [
    (['--scenario', 'square', '--csv', 'x.csv'], "unknown scenario 'square'"),
    (['--constraints', 'belt,sideways', '--csv', 'x.csv'], "unknown constraint 'sideways'"),
    (['--duration', '-1', '--csv', 'x.csv'], 'argument --duration: must be > 0, got -1.0'),
    (['--duration', 'nan', '--csv', 'x.csv'], 'argument --duration: must be a finite number, got nan'),
    (['--dt', '0', '--csv', 'x.csv'], 'argument --dt: must be in (0, 0.1], got 0.0'),
    (['--duration', 'abc', '--csv', 'x.csv'], "argument --duration: must be a finite number, got 'abc'"),
    ([], 'nothing to write'),
    (['--constraints', 'belt', '--tangent-heading', '--bag', 'b', '--duration', '0.01'], 'a bag cannot hold it'),
    (['--csv', '/nonexistent-dir/x.csv', '--duration', '0.01'], 'cannot write /nonexistent-dir/x.csv'),
])
def test_bad_arguments_give_one_line_and_exit_2(tmp_path, args, message):
    result = subprocess.run([*WALLBOT, 'simulate', *args],
                            capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert 'Traceback' not in result.stderr


def test_every_column_group_gives_one_value_per_name():
    from wallbot_sim.config import load_robot_parameters, load_scenario
    from wallbot_sim.model import ConstraintSelection, Robot, Simulation
    from wallbot_sim.rundata.csv_format import COLUMN_GROUPS, csv_row
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    out = Simulation(robot, scenario.reference, ConstraintSelection(), *scenario.initial_state(robot)).outputs()
    for names, values in COLUMN_GROUPS:
        assert len(values(out)) == len(names), names
    assert len(csv_row(out)) == len(CSV_COLUMNS) == len(set(CSV_COLUMNS))


def test_a_line_is_the_text_the_csv_writer_writes():
    """csv_line (simulate's rows) against csv.writer on the same row, with the values a run can hold."""
    import csv
    import io

    import numpy as np

    from wallbot_sim.config import load_robot_parameters, load_scenario
    from wallbot_sim.model import ConstraintSelection, Robot, Simulation
    from wallbot_sim.rundata.csv_format import csv_line, csv_lines, csv_row
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    simulation = Simulation(robot, scenario.reference, ConstraintSelection(), *scenario.initial_state(robot))
    outs = [simulation.outputs()]
    simulation.step()
    outs.append(simulation.outputs())
    # and one with what a diverging or detaching run shows: inf, nan, -0.0, tiny and huge numbers, slip flags
    odd = np.array([np.inf, -np.inf, np.nan, -0.0, 1e-300, 1e300, 5e-324])
    outs.append(outs[-1].__class__(**{**outs[-1].__dict__, 'q': odd, 'residual': np.float64(-0.0)}))
    for out in outs:
        text = io.StringIO(newline='')
        csv.writer(text).writerow(csv_row(out))
        assert csv_line(out) == text.getvalue()
    assert csv_lines(np.array([csv_row(out) for out in outs])) == ''.join(map(csv_line, outs))  # a chunk's lines


@pytest.mark.parametrize('args', [
    ['--scenario', 'circle', '--constraints', 'belt,non_lateral,nonslip'],
    ['--scenario', 'figure8'],
    ['--scenario', 'rest', '--torque', '1.5,-0.5', '--heading', '0.7'],
], ids=['circle-full-set', 'figure8-trajectory', 'rest-driven'])
def test_the_numba_engine_writes_the_python_engines_csv_to_1e9(tmp_path, args):
    """--engine numba: the same header and instants, every column within 1e-9 of its largest magnitude (and of
    1, for the columns that stay at round-off, such as a consistent set's residual), NaN where python has NaN."""
    import numpy as np
    tables = {}
    for engine in ('python', 'numba'):
        out = tmp_path / f'{engine}.csv'
        result = simulate(*args, '--duration', '0.5', '--engine', engine, '--csv', str(out), '--quiet')
        assert result.returncode == 0, result.stderr
        header, rows = read_csv(out)
        assert header == list(CSV_COLUMNS)
        tables[engine] = np.array(rows)
    python, numba = tables['python'], tables['numba']
    assert python.shape == numba.shape == (501, len(CSV_COLUMNS))
    assert np.array_equal(python[:, 0], numba[:, 0])
    assert np.array_equal(np.isnan(python), np.isnan(numba))  # no reference: ref_x, ref_y, err
    python, numba = np.nan_to_num(python), np.nan_to_num(numba)
    scale = np.maximum(np.max(np.abs(python), axis=0), 1.0)
    worst = np.max(np.abs(numba - python) / scale, axis=0)
    assert np.all(worst <= 1e-9), dict(zip(CSV_COLUMNS, worst))
    assert not np.array_equal(python, numba)  # the kernel computed it, not the Python model again


@pytest.mark.parametrize('args', [
    ['--scenario', 'circle'],
    ['--scenario', 'figure8', '--constraints', 'belt,non_lateral,nonslip'],
    ['--scenario', 'rest', '--torque', '1.5,-0.5', '--heading', '0.7'],
], ids=['circle', 'figure8-full-set', 'rest-driven'])
def test_the_numba_engine_writes_its_csv_a_chunk_at_a_time_as_step_by_step(tmp_path, args):
    """With only --csv the numba engine tabulates a chunk of steps per kernel call (Simulation.run_table): the
    file is the bytes the same simulation writes step by step, a csv_line per step's outputs."""
    from wallbot_sim.cli.main import build_parser
    from wallbot_sim.cli.simulate import build_simulation
    from wallbot_sim.rundata.csv_format import csv_line
    command = [*args, '--duration', '2.5', '--engine', 'numba', '--quiet']
    out = tmp_path / 'numba.csv'
    result = simulate(*command, '--csv', str(out))
    assert result.returncode == 0, result.stderr
    simulation, duration = build_simulation(build_parser().parse_args(['simulate', *command, '--csv', '-']))
    lines = [','.join(CSV_COLUMNS) + '\r\n']
    simulation.run(duration, lambda step: lines.append(csv_line(step)))
    assert len(lines) == 2502  # the header and 2,501 instants
    assert out.read_bytes() == ''.join(lines).encode()
