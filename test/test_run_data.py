"""The run loader and summary: a bag holding a reset (only the last run is analysed, and that is said),
figures from every step, short runs."""

from __future__ import annotations

import csv
import subprocess
import sys

import numpy as np
import pytest

from cli_helpers import read_csv, simulate
from wallbot_sim import paths
from wallbot_sim.bag.headless import HeadlessBagWriter
from wallbot_sim.rundata import format_summary, summarize
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.rundata import load_run


def test_a_bag_with_a_restart_is_read_as_its_last_run(tmp_path):
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    simulation = Simulation(robot, scenario.reference, ConstraintSelection(), q0, qd0)
    bag = tmp_path / 'bag'
    writer = HeadlessBagWriter.open(bag, simulation)
    simulation.run(0.5, writer.write)
    second_start = q0.copy()
    second_start[0] = 0.5
    simulation.reset(q0=second_start)
    write = writer.writer.write  # a recorder logs receive time, which goes on while sim time restarts
    writer.writer.write = lambda connection, log_ns, data: write(connection, log_ns + 10**9, data)
    simulation.run(0.3, writer.write)
    writer.close()

    run = load_run(bag)
    assert run.restarts == 1
    assert len(run) == 301 and run.t[0] == 0.0 and run.x[0] == 0.5
    assert np.all(np.diff(run.t) > 0)
    summary = summarize(bag)
    assert summary.restarts == 1 and summary.odom_count == 301
    assert 'jumped back 1 time(s)' in format_summary(summary)


def test_summary_figures_come_from_every_step(tmp_path):
    """The residual peak of the circle comes 14 ms into the run, between two diagnostics messages:
    the summary of the bag must still report it, as the CSV's per-step column does."""
    from wallbot_sim.cli.main import main as cli
    bag, table = tmp_path / 'bag', tmp_path / 'run.csv'
    assert cli(['simulate', '--scenario', 'circle', '--constraints', 'belt,non_lateral,nonslip', '--duration', '0.35',
                '--bag', str(bag), '--csv', str(table), '--quiet']) == 0
    with open(table, newline='', encoding='utf-8') as stream:
        rows = list(csv.DictReader(stream))
    residuals = np.array([float(row['residual']) for row in rows])
    peak = residuals.max()
    assert peak > 1.0 and 0.005 < float(rows[int(residuals.argmax())]['t']) < 0.05
    sampled = [residuals[round(t * 1000)] for t in (0.0, 0.1, 0.2, 0.3)]  # what 10 Hz samples would show
    assert max(sampled) < 0.99 * peak
    assert summarize(bag).max_residual == pytest.approx(peak, rel=1e-5)  # diagnostics hold 6 digits
    assert summarize(table).max_residual == peak
    residual_of_bag = load_run(bag).residual
    assert np.nanmax(residual_of_bag) == pytest.approx(peak, rel=1e-5)
    assert np.isfinite(residual_of_bag[-1])  # the steps after the last 10 Hz message are reported too
    times = np.array([float(row['t']) for row in rows])
    settled = residuals[times >= 0.1 - 1e-9].max()  # the start's peak, 14 ms in, left out
    assert settled < 0.9 * peak
    assert summarize(table).max_residual_settled == settled
    assert summarize(bag).max_residual_settled == pytest.approx(settled, rel=1e-5)
    assert np.nanmax(load_run(bag).residual_settled) == pytest.approx(settled, rel=1e-5)
    line = next(line for line in format_summary(summarize(table)).splitlines() if line.startswith('constraint residual'))
    assert f'max {peak:.3e}, after 0.1 s max {settled:.3e} (' in line and 'least-squares misfit' in line


def test_a_consistent_run_s_residual_is_not_explained_and_simulate_says_it_has_no_reference(tmp_path):
    """A driven run at rest holds every constraint: its residual is rounding, said without the start's
    explanation, and simulate's last line says it has no reference rather than a tracking error of nan."""
    table = tmp_path / 'rest.csv'
    result = subprocess.run([sys.executable, '-m', 'wallbot_sim.cli.main', 'simulate', '--scenario', 'rest',
                             '--duration', '0.2', '--csv', str(table)], capture_output=True, text=True, check=True)
    last = result.stderr.strip().splitlines()[-1]
    assert 'no reference' in last and 'nan' not in last
    line = next(line for line in format_summary(summarize(table)).splitlines() if line.startswith('constraint residual'))
    assert 'after 0.1 s max' in line and '(' not in line


def test_a_run_shorter_than_five_seconds_says_so(tmp_path):
    from wallbot_sim.cli.main import main as cli
    table = tmp_path / 'short.csv'
    assert cli(['simulate', '--scenario', 'circle', '--duration', '0.2', '--csv', str(table), '--quiet']) == 0
    text = format_summary(summarize(table))
    assert 'nan' not in text
    assert 'no peak after 5 s (the run is shorter than 5 s)' in text


def test_another_robot_s_diagnostics_in_the_bag_are_not_this_run_s(tmp_path):
    """A recorder records /diagnostics, where every robot of the domain publishes: the residual of the run
    is its own dynamics' (the one in the odometry's namespace), never a second robot's."""
    from wallbot_msgs_py import codec, topics
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    simulation = Simulation(robot, scenario.reference, ConstraintSelection(), *scenario.initial_state(robot))
    bag = tmp_path / 'bag'
    writer = HeadlessBagWriter.open(bag, simulation)
    simulation.run(0.3, writer.write)
    diagnostics = writer.writer.connection(topics.DIAGNOSTICS.name)
    for t in (0.1, 0.2):  # at the stamps of the run's own diagnostics, with a residual far above its
        other = codec.Status('/robot2/dynamics: simulation', 'ok', 'running', [(topics.DIAGNOSTIC_RESIDUAL_MAX, 99.0)])
        writer.writer.write(diagnostics, round(t * 1e9) + 1, codec.diagnostics(t, [other]))
    writer.close()
    own = summarize(bag).max_residual
    assert own < 1.0 and np.nanmax(load_run(bag).residual) == pytest.approx(own, rel=1e-5)


def test_each_wheel_s_contact_round_trips_through_the_csv_and_the_bag(tmp_path):
    """A coulomb turn in place whose rear wheels slide while the front ones stick, written by simulate to a CSV
    and a bag: either, loaded, gives each wheel's normal load, friction use, slip flag and force in body axes as
    the model's outputs of every step, to the bit."""
    from wallbot_sim.cli.main import build_parser, main as cli
    from wallbot_sim.cli.simulate import build_simulation
    command = ['simulate', '--scenario', 'rest', '--contact', 'coulomb', '--heading', '0.4', '--torque=-0.9,1.2',
               '--duration', '0.3', '--quiet']
    bag, table = tmp_path / 'bag', tmp_path / 'run.csv'
    assert cli([*command, '--csv', str(table), '--bag', str(bag)]) == 0
    simulation, duration = build_simulation(build_parser().parse_args([*command, '--csv', '-']))
    outputs = []
    simulation.run(duration, lambda out: outputs.append(out.contact))
    expected = {'loads': [c.loads for c in outputs], 'use': [c.wheel_use for c in outputs],
                'slip': [c.wheel_slipping for c in outputs], 'wheel_forces': [c.wheel_forces for c in outputs]}
    slides = np.array(expected['slip'])
    assert slides[:, [1, 3]].all() and not slides[:, [0, 2]].any()  # rear wheels slide, front wheels stick
    assert (np.abs(np.array(expected['wheel_forces'])).max(axis=0)[[0, 2]] > 1.0).all()  # front: both axes
    for run in (load_run(table), load_run(bag)):
        assert len(run) == len(outputs) == 301
        for name, values in expected.items():
            assert np.array_equal(getattr(run, name), np.array(values, dtype=float)), name


# --- the summary read in one pass --------------------------------------------------------------------
def synthetic_bag(path, seconds: float, source: str | None = 'plan', plan_lag: float = 0.0,
                  restart_at: float | None = None, slip_at: float | None = None, seed: int = 3):
    """A bag of a 1 kHz run near the circle with every per-step topic, diagnostics every 0.1 s, and as its
    reference the trajectory node's plans (``source`` 'plan', renewed every 2 s, each logged ``plan_lag``
    seconds after it starts: a recorder whose reader lagged the steps), its 100 Hz poses ('poses') or
    none. ``restart_at``: simulation time goes back to 0 there (a reset); ``slip_at``: from there the
    left front wheel slides, and a wheel lifts off 0.1 s later."""
    from types import SimpleNamespace

    from wallbot_msgs_py import codec, topics
    from wallbot_msgs_py.step_cdr import StepEncoder
    from wallbot_sim import messages
    from wallbot_sim.bag.writer import BagWriter
    from wallbot_sim.model import Circle
    from wallbot_sim.model.trajectories import sample_plan

    rng, circle, encoder = np.random.default_rng(seed), Circle(), StepEncoder()
    writer = BagWriter(path)
    connection = {topic: writer.add_graph_topic(topic) for topic in (
        topics.ODOM, topics.CONSTRAINT_WRENCH, topics.DRIVE_FORCES, topics.WHEEL_CONTACT, topics.REFERENCE_TRAJECTORY,
        topics.REFERENCE, topics.DIAGNOSTICS)}
    queued: list[tuple[int, topics.Topic, bytes]] = []  # (log ns, topic, message): written in log order
    steps = round(seconds * 1000)
    back = round(restart_at * 1000) if restart_at is not None else steps + 1
    for k in range(steps + 1):
        step = k if k < back else k - back
        t, log_ns = step * 1e-3, k * 1_000_000 + 1
        if source == 'plan' and step % 2000 == 0:
            plan = sample_plan(circle, max(t - 0.05, 0.0), t + 4.0, 0.05)
            queued.append((log_ns + round(plan_lag * 1e9), topics.REFERENCE_TRAJECTORY,
                           messages.trajectory_message(plan)))
        if source == 'poses' and step % 10 == 0:
            queued.append((log_ns, topics.REFERENCE, messages.reference_message(circle.sample(t), t)[0]))
        (x, y), slipping = circle.sample(t).position, slip_at is not None and t >= slip_at
        loads = rng.uniform(20.0, 80.0, size=4)
        if slip_at is not None and t >= slip_at + 0.1:
            loads[2] = -1.5
        out = SimpleNamespace(
            t=t, q=np.array([x + rng.normal(0, 1e-3), y + rng.normal(0, 1e-3), 0.3, 0, 0, 0, 0]), qd=rng.normal(size=7),
            wheel_torques=rng.normal(size=4), chassis_wrench=rng.normal(size=3),
            drive=SimpleNamespace(left=rng.normal(), right=rng.normal(), lateral=rng.normal()),
            contact=SimpleNamespace(loads=loads, wheel_use=rng.uniform(size=4),
                                    wheel_slipping=(slipping, False, False, False),
                                    wheel_forces=rng.normal(size=(4, 2)), slip_velocity=rng.normal(size=(4, 2))))
        queued += [(log_ns, topic, data) for topic, data in encoder.encode(out) if topic in connection]
        if step % 100 == 0:
            status = codec.Status(codec.simulation_status_name('/wallbot/dynamics'), 'ok', 'running',
                                  [(topics.DIAGNOSTIC_RESIDUAL_MAX, float(rng.uniform()))])
            queued.append((log_ns + 1, topics.DIAGNOSTICS, codec.diagnostics(t, [status])))
    for log_ns, topic, data in sorted(queued, key=lambda item: item[0]):
        writer.write(connection[topic], log_ns, data)
    writer.close()
    return path


@pytest.mark.parametrize('case', [
    dict(seconds=6.0), dict(seconds=3.0, plan_lag=0.5), dict(seconds=3.0, source='poses'),
    dict(seconds=2.0, source=None),
    dict(seconds=3.0, restart_at=1.7), dict(seconds=2.0, slip_at=0.85)],
    ids=['plans', 'plans_logged_late', 'poses', 'driven', 'reset', 'slip'])
def test_the_summary_read_in_one_pass_is_the_loaded_run_s(tmp_path, case):
    """summarize reads a bag once, message by message; its figures are those of the whole run loaded
    (load_run) and summarized: with the plans logged before the states they cover or after them, with
    reference poses only, without a reference, across a reset, through a slip and a lift-off."""
    from dataclasses import fields

    from wallbot_sim.rundata.summary import summarize_run
    bag = synthetic_bag(tmp_path / 'bag', **case)
    streamed, loaded = summarize(bag), summarize_run(load_run(bag), bag)
    for field in fields(streamed):
        mine, theirs = getattr(streamed, field.name), getattr(loaded, field.name)
        assert mine == (pytest.approx(theirs, rel=1e-12, abs=1e-15, nan_ok=True) if isinstance(theirs, float) else
                        theirs), field.name
    assert np.isfinite(streamed.peak_tracking_error) == (case.get('source', 'plan') is not None)
    assert (streamed.first_slip is not None, streamed.restarts) == ('slip_at' in case, 'restart_at' in case)


def test_the_summary_holds_as_much_for_a_long_bag_as_for_a_short_one(tmp_path):
    """The memory summarize takes does not grow with the bag: 8 s more of a 1 kHz run are 11 MB more when every
    series is loaded (about 1.4 kB a step), and here at most one more of the bag reader's chunks in memory
    (it holds one or two of their messages at a time, up to 1 MiB of bytes each)."""
    import tracemalloc
    peaks = []
    bags = [synthetic_bag(tmp_path / f'{seconds:g}', seconds) for seconds in (2.0, 10.0)]
    summarize(bags[0])  # what the first call imports is not the summary's
    for bag in bags:
        tracemalloc.start()
        summarize(bag)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] - peaks[0] < 3 * 2**20, peaks


def test_a_csv_s_block_columns_are_the_run_s_machine_series(tmp_path):
    """The example robot file's motor and vacuum blocks: load_run reads their columns as the machine series (what
    plot draws), each against the CSV's own column, F_ad the chamber area times dp."""
    out = tmp_path / 'climb.csv'
    result = simulate('--scenario', 'rest', '--heading', 1.5707963267948966, '--torque', '3,3', '--robot',
                      paths.config_dir() / 'climber.yaml', '--engine', 'python', '--duration', 0.05, '--csv', out,
                      '--quiet')
    assert result.returncode == 0, result.stderr
    header, rows = read_csv(out)
    run = load_run(out)
    assert list(run.machine) == ['tau_L_applied', 'tau_R_applied', 'tau_L_cmd', 'tau_R_cmd', 'dp', 'F_ad']
    for name, (t, values) in run.machine.items():
        assert t.tolist() == [row[0] for row in rows]
        assert values.tolist() == [row[header.index(name)] for row in rows]
    assert run.machine['F_ad'][1] == pytest.approx(0.02 * run.machine['dp'][1], rel=1e-12)
    assert run.machine['tau_L_applied'][1][0] == 3.0  # at rest the 4 N m envelope holds the command
    assert run.machine['tau_L_cmd'][1].tolist() == [3.0] * len(rows)


def machine_lines(run) -> dict[str, dict[str, tuple[list, list]]]:
    """The lines of ``run``'s machine figure: each panel's (by its y axis) lines by legend entry, (x, y)."""
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    from wallbot_sim.plots.figures import run_figures
    figure = dict(run_figures(plt, [run], 0.1, 0.12))['machine']
    try:
        return {ax.get_ylabel(): {line.get_label(): (list(line.get_xdata()), list(line.get_ydata()))
                                  for line in ax.get_lines()} for ax in figure.axes}
    finally:
        plt.close('all')


def test_plot_draws_a_csv_s_applied_torque_against_its_command(tmp_path):
    """The example robot file commanded 50 N m per side against its 4 N m motors: each side's panel holds the CSV's
    applied column (at rest the stall torque, then the torque-speed line) and the command, in N m."""
    out = tmp_path / 'climb.csv'
    result = simulate('--scenario', 'rest', '--heading', 1.5707963267948966, '--torque', '50,50', '--robot',
                      paths.config_dir() / 'climber.yaml', '--duration', 0.05, '--csv', out, '--quiet')
    assert result.returncode == 0, result.stderr
    header, rows = read_csv(out)
    lines = machine_lines(load_run(out))
    for side, panel in (('L', 'left side torque (N m)'), ('R', 'right side torque (N m)')):
        times = [row[0] for row in rows]
        assert lines[panel]['applied'] == (times, [row[header.index(f'tau_{side}_applied')] for row in rows])
        assert lines[panel]['commanded'] == (times, [50.0] * len(rows))
        assert lines[panel]['applied'][1][0] == 4.0 and max(lines[panel]['applied'][1]) <= 4.0


def test_a_bag_s_applied_and_commanded_side_torques_are_the_simulation_s_at_its_simulation_times(tmp_path):
    """The closed loop on the example robot file, its bag logged as a recorder logs it, at wall-clock receive times
    (a command 0.4 ms after the state it answers): the applied torques read back from wheel_states, drive_forces and
    robot_description are the simulation's at every state, and each command is placed at the simulation time of the
    state it answers; the machine figure draws exactly these."""
    from wallbot_sim.cli.main import build_parser
    from wallbot_sim.cli.simulate import build_controller, build_simulation
    args = build_parser().parse_args(['simulate', '--robot', str(paths.config_dir() / 'climber.yaml'), '--controller',
                                      '--duration', '0.3', '--csv', '-'])
    simulation, duration = build_simulation(args)
    bag = tmp_path / 'bag'
    writer = HeadlessBagWriter.open(bag, simulation)
    wall, delay = 1_733_000_000 * 10**9, 400_000
    write = writer.writer.write
    writer.writer.write = lambda connection, log_ns, data: write(
        connection, log_ns + wall + (delay if connection.topic.endswith('wheel_torque_cmd') else 0), data)
    applied, commands = [], []

    def on_command(t, command):
        commands.append((t, command.tau_left, command.tau_right))
        writer.write_command(t, command.tau_left, command.tau_right)
    controller = build_controller(args, simulation, on_command)

    def on_step(out):
        writer.write(out)
        applied.append((out.t, *out.motor_torque))
        controller(out)
    simulation.run(duration, on_step)
    writer.close()

    run = load_run(bag)
    t, left, right = (np.array(column) for column in zip(*applied))
    assert run.t == pytest.approx(t, abs=1e-12)  # the bag's stamps in whole nanoseconds
    assert np.abs(run.machine['tau_L_applied'][1] - left).max() < 1e-9
    assert np.abs(run.machine['tau_R_applied'][1] - right).max() < 1e-9
    assert np.abs(left).max() > 1.0  # the loop drives the motors
    lines = machine_lines(run)
    assert len(commands) == int(duration * 25 + 1e-9) + 1 and len({c[1] for c in commands}) > 3  # at 25 Hz
    for side, panel, column in (('L', 'left side torque (N m)', 1), ('R', 'right side torque (N m)', 2)):
        times, values = lines[panel]['commanded']
        assert times == pytest.approx([c[0] for c in commands], abs=1e-12) and values == [c[column] for c in commands]
        assert lines[panel]['applied'] == (run.t.tolist(), run.machine[f'tau_{side}_applied'][1].tolist())
