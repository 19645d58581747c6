"""The run loader on a bag holding a reset: only the last run is analysed, and that is said."""

from __future__ import annotations

import numpy as np

from wallbot_sim.bag.headless import HeadlessBagWriter
from wallbot_sim.bag.summary import format_summary, summarize
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.plots import load_run


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
