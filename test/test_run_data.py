"""The run loader and summary: a bag holding a reset (only the last run is analysed, and that is said),
figures from every step, short runs."""

from __future__ import annotations

import csv

import numpy as np
import pytest

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
