"""``simulate --world``: the surface of a world file through the CLI (docs/model.md 13.1), refused by the numba
engine in one line naming the python engine."""

from __future__ import annotations

import pytest

from bag_helpers import by_topic
from cli_helpers import assert_one_line_error, read_csv, simulate, wallbot
from wallbot_sim import paths
from wallbot_sim.model import RobotParameters

PARAMS = RobotParameters()
WEIGHT = (PARAMS.body_mass + 4 * PARAMS.wheel_mass) * PARAMS.gravity


def ceiling(tmp_path, adhesion: float):
    world = tmp_path / 'ceiling.yaml'
    world.write_text('inclination: 180\n')
    out = tmp_path / 'run.csv'
    result = simulate('--scenario', 'rest', '--contact', 'coulomb', '--engine', 'python', '--world', world,
                      '--adhesion-force', adhesion, '--duration', 0.05, '--csv', out, '--quiet')
    return result, read_csv(out)


def test_on_the_ceiling_too_little_adhesion_detaches_at_once(tmp_path):
    result, (header, rows) = ceiling(tmp_path, 0.9 * WEIGHT)
    assert result.returncode == 3 and 'detached: wheel 1' in result.stderr and 't = 0.000 s' in result.stderr
    assert len(rows) == 1 and rows[0][header.index('N1')] == pytest.approx(-0.025 * WEIGHT, rel=1e-9)


def test_on_the_ceiling_enough_adhesion_holds(tmp_path):
    result, (header, rows) = ceiling(tmp_path, 1.2 * WEIGHT)
    assert result.returncode == 0, result.stderr
    assert [row[header.index('N1')] for row in rows] == pytest.approx([0.05 * WEIGHT] * len(rows), rel=1e-9)
    assert max(abs(row[header.index('y')]) for row in rows) < 1e-9


def test_the_numba_engine_refuses_a_world_in_one_line_naming_the_python_engine(tmp_path):
    result = simulate('--scenario', 'rest', '--world', paths.config_dir() / 'world.yaml', '--engine', 'numba',
                      '--csv', tmp_path / 'run.csv')
    assert_one_line_error(result, '--engine numba: a world file runs on the python engine only', '--engine python')


@pytest.mark.parametrize('files, reason', [
    (('--world', 'world.yaml'), 'a world file runs on the python engine only'),
    (('--robot', 'climber.yaml'), 'a motor block and a vacuum block run on the python engine only'),
    (('--robot', 'climber.yaml', '--world', 'world.yaml'),
     'a world file and a motor block and a vacuum block run on the python engine only'),
], ids=['world', 'climber', 'both'])
def test_without_engine_simulate_computes_the_example_files_on_python_saying_so(tmp_path, files, reason):
    """No --engine: the python engine, one line on stderr saying why, and the CSV --engine python writes, to the
    bit; --engine numba: refused in one line naming why."""
    files = [paths.config_dir() / name if name.endswith('.yaml') else name for name in files]
    common = ('--scenario', 'rest', '--torque', '3,3', '--duration', 0.02, '--quiet', *files)
    chosen, python = tmp_path / 'chosen.csv', tmp_path / 'python.csv'
    result = simulate(*common, '--csv', chosen)
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip().splitlines() == [f'wallbot-sim simulate: engine python ({reason})']
    assert simulate(*common, '--engine', 'python', '--csv', python).returncode == 0
    assert chosen.read_text() == python.read_text()
    assert_one_line_error(simulate(*common, '--engine', 'numba', '--csv', tmp_path / 'numba.csv'),
                          f'--engine numba: {reason} (drop --engine, or --engine python)')
    assert not (tmp_path / 'numba.csv').exists()


def test_run_refuses_an_explicit_numba_engine_for_the_example_files_in_one_line(tmp_path):
    """Before any node starts (no output directory made); run without --engine is test_sensors_graph's run."""
    result = wallbot('run', 'circle', '--robot', paths.config_dir() / 'climber.yaml', '--world',
                     paths.config_dir() / 'world.yaml', '--engine', 'numba', '--out', tmp_path / 'run')
    assert_one_line_error(result, '--engine numba: a world file and a motor block and a vacuum block run on the '
                                  'python engine only (drop --engine, or --engine python)')
    assert not (tmp_path / 'run').exists()


def test_a_misspelt_world_key_is_one_line_naming_the_closest(tmp_path):
    world = tmp_path / 'world.yaml'
    world.write_text('inclination: 45\npatchs: []\n')
    result = simulate('--scenario', 'rest', '--world', world, '--engine', 'python', '--csv', tmp_path / 'run.csv')
    assert_one_line_error(result, str(world), "unknown world key 'patchs' (did you mean 'patches'?)")


def test_a_motor_block_appends_the_applied_torques_to_the_csv(tmp_path):
    """Facing up, commanding 50 N m per side against a 4 N m stall torque: the CSV's tau_L_applied, tau_R_applied
    start at the stall torque (at rest) and fall along the torque-speed line with the wheels' speed."""
    robot = tmp_path / 'robot.yaml'
    robot.write_text(paths.robot_yaml().read_text() + 'motor: {stall_torque: 4.0, no_load_speed: 20.0}\n')
    out = tmp_path / 'run.csv'
    result = simulate('--scenario', 'rest', '--heading', 1.5707963267948966, '--torque', '50,50', '--robot', robot,
                      '--engine', 'python', '--duration', 0.1, '--csv', out, '--quiet')
    assert result.returncode == 0, result.stderr
    header, rows = read_csv(out)
    assert header[-4:] == ['tau_L_applied', 'tau_R_applied', 'tau_L_cmd', 'tau_R_cmd']
    left, right = header.index('tau_L_applied'), header.index('tau_R_applied')
    assert rows[0][left] == rows[0][right] == 4.0
    for row in rows:
        speed = 0.5 * (row[header.index('dphi1')] + row[header.index('dphi2')])
        assert row[left] == pytest.approx(4.0 * (1 - speed / 20.0), rel=1e-12)


def test_a_headless_bag_s_diagnostics_name_the_saturated_side_since_its_first_step(tmp_path):
    """simulate --bag writes the dynamics' motor entries: 50 N m on the left against 4 N m saturates it from t = 0,
    the right's 1 N m stays inside its envelope (at 1 kHz over 0.1 s the wheels stay far below 20 rad/s)."""
    robot = tmp_path / 'robot.yaml'
    robot.write_text(paths.robot_yaml().read_text() + 'motor: {stall_torque: 4.0, no_load_speed: 20.0}\n')
    bag = tmp_path / 'bag'
    result = simulate('--scenario', 'rest', '--torque', '50,1', '--robot', robot, '--engine', 'python',
                      '--duration', 0.1, '--bag', bag, '--quiet')
    assert result.returncode == 0, result.stderr
    [last] = by_topic(bag)['/diagnostics'][-1].status
    values = {value.key: value.value for value in last.values}
    assert last.level == last.WARN and 'motor saturated: left since t = 0.000 s' in last.message
    assert float(values['left motor commanded (N m)']) == 50.0 and 0.0 < float(values['left motor applied (N m)']) < 4.0
    assert float(values['left motor saturated since (s)']) == 0.0
    assert values['right motor saturated since (s)'] == 'not saturated'
    assert float(values['right motor applied (N m)']) == float(values['right motor commanded (N m)']) == 1.0


def test_a_vacuum_block_appends_dp_and_f_ad_and_the_pump_command_lowers_them(tmp_path):
    robot = tmp_path / 'robot.yaml'
    robot.write_text(paths.robot_yaml().read_text() + 'adhesion: {chamber_area: 0.02, chamber_volume: 0.002, '
                     'pump_max_pressure: 12000.0, pump_max_flow: 0.01, leak_area: 2.0e-5}\n')
    out = tmp_path / 'run.csv'
    result = simulate('--scenario', 'rest', '--robot', robot, '--engine', 'python', '--pump-command', 0.9,
                      '--duration', 0.2, '--csv', out, '--quiet')
    assert result.returncode == 0, result.stderr
    header, rows = read_csv(out)
    assert header[-2:] == ['dp', 'F_ad']
    dp, force = header.index('dp'), header.index('F_ad')
    assert all(row[force] == pytest.approx(0.02 * row[dp], rel=1e-12) for row in rows)
    assert rows[-1][dp] < rows[0][dp]  # from the balance at full command towards the lower one at 0.9


def test_the_pump_command_needs_a_vacuum_block(tmp_path):
    result = simulate('--scenario', 'rest', '--engine', 'python', '--pump-command', 0.5, '--csv', tmp_path / 'r.csv')
    assert_one_line_error(result, '--pump-command', 'adhesion block')
