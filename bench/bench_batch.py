"""Robot-steps per second of the batched core, beside the single-robot loop measured in the same run.

The circle with the full constraint set (trajectory, tangent heading, belt, non-lateral, nonslip) and
the ideal contact. The single-robot loop is ``Simulation.step`` on one robot; the batch is
``BatchSimulation.step`` on N robots with slightly different body masses. Timings are best of
``--repeats`` (wall clock; other processes on the machine slow both alike), interleaved.

What limits the batch: the time of one batch step is fitted as t(N) = t0 + c N over the batch sizes.
t0 is the per-step cost that does not grow with N (Python and NumPy call overhead, ~100 array
operations per RK4 stage); c is the per-robot cost of the array work, and 1/c the rate no batch size
can exceed. The per-stage split says where c goes, at the largest batch.

    python bench/bench_batch.py [--sizes 100,1000,4000,16000] [--steps 40]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from typing import Callable

import numpy as np

from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.model.batch import BatchSimulation, batch_constrained_acceleration

SELECTION = 'belt,non_lateral,nonslip'


def best_seconds(action: Callable[[], None], repeats: int) -> float:
    """The shortest wall time of ``repeats`` runs of ``action``."""
    best = float('inf')
    for _ in range(repeats):
        started = time.perf_counter()
        action()
        best = min(best, time.perf_counter() - started)
    return best


def batch_of(size: int) -> BatchSimulation:
    params = load_robot_parameters()
    robots = [Robot(params.replace(body_mass=params.body_mass * (1.0 + 0.2 * i / size))) for i in range(size)]
    return BatchSimulation.from_scenario(robots, load_scenario('circle'), ConstraintSelection.parse(SELECTION))


def single_rate(steps: int, repeats: int) -> float:
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    simulation = Simulation(robot, scenario.reference, ConstraintSelection.parse(SELECTION), q0, qd0)

    def run() -> None:
        for _ in range(steps):
            simulation.step()
    return steps / best_seconds(run, repeats)


def check_agreement(batch: BatchSimulation) -> None:
    """The batch's last robot against the single-robot Simulation after the same steps (a fair comparison)."""
    robot = batch.robots.robots[-1]
    q0, qd0 = load_scenario('circle').initial_state(robot)
    single = Simulation(robot, load_scenario('circle').reference, batch.selection, q0, qd0)
    for _ in range(batch.steps):
        single.step()
    if not np.allclose(batch.q[-1], single.q, rtol=1e-9, atol=1e-12):
        raise SystemExit(f'batch and single robot disagree: {batch.q[-1]} vs {single.q}')


def stage_split(batch: BatchSimulation, repeats: int) -> dict[str, float]:
    """Seconds per RK4 stage of each part of the derivative, at the batch's state."""
    q, qd, t = batch.q, batch.qd, batch.t
    force, rows, rhs = batch._problem(t, q, qd)
    factor = batch.robots.mass_inverse_factor(q)
    parts = {
        'applied force Q': lambda: batch.robots.applied_force(q, qd, batch.motor_torque),
        'constraint rows A, b': lambda: [module.rows(t, q, qd) for module in batch.modules],
        'mass factor W': lambda: batch.robots.mass_inverse_factor(q),
        'solve (W, Q, A, b -> qdd)': lambda: batch_constrained_acceleration(factor, force, rows, rhs),
    }
    return {name: best_seconds(part, repeats) for name, part in parts.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', default='100,1000,4000,16000', help='comma list of batch sizes')
    parser.add_argument('--steps', type=int, default=40, help='batch steps per measurement')
    parser.add_argument('--single-steps', type=int, default=2000, help='single-robot steps per measurement')
    parser.add_argument('--repeats', type=int, default=5, help='measurements per figure (the best is kept)')
    args = parser.parse_args()
    sizes = [int(size) for size in args.sizes.split(',')]
    print(f'# {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; '
          f'load average {os.getloadavg()[0]:.1f} at start; circle, {SELECTION} + trajectory, ideal contact')
    single = single_rate(args.single_steps, args.repeats)
    print(f'single-robot loop: {single:10.0f} robot-steps/s')
    print(f'{"batch size":>10s} {"robot-steps/s":>14s} {"x single":>9s} {"ms/step":>8s}')
    step_times = []
    batch = None
    for size in sizes:
        batch = batch_of(size)
        batch.step()  # first step: allocations and caches warm
        seconds = best_seconds(lambda: batch.run(args.steps), args.repeats) / args.steps
        step_times.append(seconds)
        rate = size / seconds
        print(f'{size:10d} {rate:14.0f} {rate / single:9.1f} {seconds * 1e3:8.2f}')
    check_agreement(batch)
    if len(sizes) > 1:
        per_robot, overhead = np.polyfit(sizes, step_times, 1)
        print(f'fit t(N) = t0 + c N: t0 = {overhead * 1e6:.0f} us per step (not growing with N), '
              f'c = {per_robot * 1e9:.0f} ns per robot-step -> at most {1.0 / per_robot:.0f} robot-steps/s')
    split = stage_split(batch, args.repeats)
    stage = sum(split.values())
    print(f'one RK4 stage at N = {batch.size} ({stage / batch.size * 1e9:.0f} ns per robot):')
    for name, seconds in split.items():
        print(f'  {name:26s} {seconds / batch.size * 1e9:6.0f} ns per robot  {seconds / stage:5.1%}')
    print(f'load average {os.getloadavg()[0]:.1f} at end')


if __name__ == '__main__':
    main()
