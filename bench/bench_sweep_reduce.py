"""The sweep's reduce of its robots' rows (``sweep.reduce.DecidingRows``): the compiled screen against the NumPy reduce.

A chunk of ``--robots`` robots of ``--spec`` (default examples/sweep_figure8.yaml: ideal contact, the rows
``wallbot-sim sweep`` computes by ``Simulation.compute_block``) is run for ``--duration`` seconds and its CSV rows
kept, a block of ``--block`` instants per robot at a time (as the sweep reduces them); then both reducers take the
same blocks, the best of ``--repeats`` rounds each, and the CPU time per robot-step of each and their ratio are
printed, with the machine's load. Both must keep the same rows; the bench says so or stops.

    python bench/bench_sweep_reduce.py [--spec SPEC] [--robots 20] [--duration 5] [--block 2048] [--repeats 3]
                                       [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np

from report import Report, add_write_docs_option
from wallbot_sim.model import Robot, Simulation
from wallbot_sim.rundata.csv_format import CSV_COLUMNS, csv_row, fill_rows
from wallbot_sim.sweep import load_spec
from wallbot_sim.sweep.compute import BLOCK
from wallbot_sim.sweep.reduce import DecidingRows
from wallbot_sim.sweep.screen import compile_screen


def blocks(spec_path: str, robots: int, duration: float, block: int) -> tuple[list, list[np.ndarray]]:
    """The robots' parameters and their CSV rows, each robot's block (1, instants, columns) in the sweep's order."""
    spec = load_spec(spec_path)
    settings = dataclasses.replace(spec.settings, duration=duration)
    params = [spec.parameters(i) for i in range(robots)]
    simulations = []
    for robot_params in params:
        robot = Robot(robot_params)
        q0, qd0 = settings.scenario.initial_state(robot)
        simulations.append(Simulation(robot, settings.scenario.reference, settings.selection, q0, qd0, dt=settings.dt,
                                      contact=settings.contact, engine='numba'))
    found = [np.array([[csv_row(simulation.outputs())] for simulation in simulations])]
    done = 0
    while done < settings.steps:
        count = min(block, settings.steps - done)
        sampled = simulations[0].sample_reference(count)
        for simulation in simulations:
            steps = simulation.compute_block(count, sampled)
            if steps is None:
                raise SystemExit('a robot diverged: choose other robots')
            simulation.take(steps)
            rows = np.empty((1, count, len(CSV_COLUMNS)))
            fill_rows(steps.table, rows[0], simulation.motor_torque)
            found.append(rows)
        done += count
    return params, found


def reduced(params: list, found: list[np.ndarray], compiled: bool) -> DecidingRows:
    """Every block reduced: the first rows of all robots, then the compiled screen one robot's block at a time (as the
    sweep does), the NumPy reduce every robot's block of the same instants at once (vectorized over the robots)."""
    rows = DecidingRows(params, len(CSV_COLUMNS), compiled)
    rows.add(found[0], np.ones(found[0].shape[:2], dtype=bool))
    if compiled:
        for number, block in enumerate(found[1:]):
            robot = number % len(params)
            rows.add(block, np.ones(block.shape[:2], dtype=bool), slice(robot, robot + 1))
    else:
        for start in range(1, len(found), len(params)):
            block = np.concatenate(found[start:start + len(params)])
            rows.add(block, np.ones(block.shape[:2], dtype=bool))
    return rows


def cpu_seconds(action, repeats: int) -> float:
    best = float('inf')
    for _ in range(repeats):
        started = time.process_time()
        action()
        best = min(best, time.process_time() - started)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--spec', default='examples/sweep_figure8.yaml')
    parser.add_argument('--robots', type=int, default=20)
    parser.add_argument('--duration', type=float, default=5.0)
    parser.add_argument('--block', type=int, default=BLOCK)
    parser.add_argument('--repeats', type=int, default=3)
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('sweep-reduce')
    load_before = os.getloadavg()[0]
    compile_screen()
    params, found = blocks(args.spec, args.robots, args.duration, args.block)
    screened, numpy_reduced = reduced(params, found, True), reduced(params, found, False)
    if not (np.array_equal(screened.valid, numpy_reduced.valid)
            and np.array_equal(screened.rows[screened.valid], numpy_reduced.rows[numpy_reduced.valid])):
        raise SystemExit('the compiled screen and the NumPy reduce kept other rows')
    robot_steps = sum(block.shape[1] for block in found[1:])
    compiled_time = cpu_seconds(lambda: reduced(params, found, True), args.repeats)
    numpy_time = cpu_seconds(lambda: reduced(params, found, False), args.repeats)
    load = f'{load_before:.2f} / {os.getloadavg()[0]:.2f}'
    print(f'{args.spec}: {args.robots} robots x {robot_steps // args.robots} instants, blocks of {args.block}; '
          f'load {load}')
    print(f'NumPy reduce     {numpy_time / robot_steps * 1e6:7.3f} us CPU per robot-step')
    print(f'compiled screen  {compiled_time / robot_steps * 1e6:7.3f} us CPU per robot-step '
          f'({numpy_time / compiled_time:.1f}x faster, the same rows)')
    report.table(('blocks', 'NumPy reduce: us CPU a robot-step',
                  'compiled screen: us CPU a robot-step', 'screen / NumPy', 'rows kept'),
                 [(f'{args.robots} robots x {robot_steps // args.robots:,} instants of {args.spec}, {args.block} '
                   f'at a time', f'{numpy_time / robot_steps * 1e6:.3f}',
                   f'{compiled_time / robot_steps * 1e6:.3f}', f'{numpy_time / compiled_time:.1f}x faster',
                   'the same')])
    report.write(args.write_docs)


if __name__ == '__main__':
    main()
