"""Robot-steps per second of the batched core, both engines, beside the single-robot loop measured in the same run.

The circle with the full constraint set (trajectory, tangent heading, belt, non-lateral, nonslip) and
the ideal contact. The single-robot loop is ``Simulation.step`` on one robot; the batch is
``BatchSimulation.run`` on N robots with slightly different body masses, with the NumPy engine
(whole-batch array passes) and the compiled one (numba, when installed: each robot's steps fused,
the robots split over the cores). Timings are wall clock, the best of ``--repeats`` rounds; each
round measures the single loop and every batch in turn, so load from other processes on the
machine hits them alike. Beside each wall-clock rate is the rate per CPU-second the process got
(its threads' CPU time): on a machine others load, that says what the code would do with the
cores to itself.

What limits the NumPy engine: a batch step costs t(N) = t0 + N c(N). t0, measured at N = 1, is the
cost that does not grow with N (Python and NumPy call overhead of ~200 array operations per step);
c(N) is the per-robot cost of the array work, printed for every size (it grows once the working
set, a few kB per robot, leaves the cache). The per-stage split at its fastest size says where c
goes. The compiled engine is bound by arithmetic: its cost per robot-step on one core is printed,
and its limit is the cores over that.

    python bench/bench_batch.py [--sizes 1,100,1000,4000,16000] [--robot-steps 40000] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from typing import Callable

import numpy as np

from report import Report, add_write_docs_option
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.control import ControllerGains, TrackingController
from wallbot_sim.control.sampling import (
    CONTROL_RATE_HZ, MAX_WHEEL_TORQUE, SampledController, close_loop, controller_robot)
from wallbot_sim.model.batch import BatchSimulation, BatchTrackingController, batch_constrained_acceleration, kernel
from wallbot_sim.model.batch import solver

SELECTION = 'belt,non_lateral,nonslip'
MAX_BATCH_STEPS = 400
"""Steps per measurement at most (the small batches' per-step overhead would make --robot-steps long)."""


def best_seconds(action: Callable[[], None], repeats: int) -> float:
    """The shortest wall time of ``repeats`` runs of ``action``."""
    return best_times(action, repeats)[0]


def best_times(action: Callable[[], None], repeats: int) -> tuple[float, float]:
    """The shortest wall time and the shortest CPU time (all threads) of ``repeats`` runs of ``action``."""
    wall = cpu = float('inf')
    for _ in range(repeats):
        started, started_cpu = time.perf_counter(), time.process_time()
        action()
        wall, cpu = min(wall, time.perf_counter() - started), min(cpu, time.process_time() - started_cpu)
    return wall, cpu


def batch_of(size: int, selection: ConstraintSelection | None = None, engine: str = 'numpy') -> BatchSimulation:
    params = load_robot_parameters()
    robots = [Robot(params.replace(body_mass=params.body_mass * (1.0 + 0.2 * i / size))) for i in range(size)]
    return BatchSimulation.from_scenario(robots, load_scenario('circle'),
                                         selection or ConstraintSelection.parse(SELECTION), engine=engine)


def single_run_seconds(steps: int) -> float:
    """Seconds per step of the single-robot loop over ``steps`` steps."""
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    simulation = Simulation(robot, scenario.reference, ConstraintSelection.parse(SELECTION), q0, qd0)

    def run() -> None:
        for _ in range(steps):
            simulation.step()
    return best_seconds(run, 1) / steps


def closed_loop_rates(size: int, steps: int, repeats: int, engines: list[str]) -> tuple[float, dict[str, float]]:
    """Robot-steps/s of the single robot and of a batch of ``size`` (each engine) under the example controller with
    coulomb contact.

    The figure-8, the driven set, controller mass scales 0.8-1.2: ``simulate --controller --contact coulomb``.
    """
    params, scenario = load_robot_parameters(), load_scenario('figure8')
    selection = ConstraintSelection.structural(trajectory=False)
    robot = Robot(params)

    def single_loop() -> None:
        q0, qd0 = scenario.initial_state(robot)
        simulation = Simulation(robot, scenario.reference, selection, q0, qd0, contact='coulomb')
        simulation.run(steps * simulation.dt,
                       close_loop(simulation, SampledController(TrackingController(robot, scenario.reference))))

    def batch_loop(engine: str) -> None:
        batch = BatchSimulation.from_scenario([robot] * size, scenario, selection, contact='coulomb', engine=engine)
        scales = np.linspace(0.8, 1.2, size)
        loop = BatchTrackingController([controller_robot(params, scale) for scale in scales], scenario.reference,
                                       ControllerGains(), CONTROL_RATE_HZ, MAX_WHEEL_TORQUE)
        batch.run(steps, loop.hook(batch))
    return steps / best_seconds(single_loop, repeats), {
        engine: size * steps / best_seconds(lambda: batch_loop(engine), repeats) for engine in engines}


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
    times = {name: best_seconds(part, repeats) for name, part in parts.items()}
    matrix = rows @ factor
    gram = np.swapaxes(matrix, 1, 2) @ matrix
    times['  of which B^T B'] = best_seconds(lambda: np.swapaxes(matrix, 1, 2) @ matrix, repeats)
    times['  of which its Cholesky'] = best_seconds(lambda: solver._cholesky(gram), repeats)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', default='1,100,1000,4000,16000', help='comma list of batch sizes')
    parser.add_argument('--robot-steps', type=int, default=40000, help='robot-steps per batch measurement')
    parser.add_argument('--single-steps', type=int, default=2000, help='single-robot steps per measurement')
    parser.add_argument('--repeats', type=int, default=7, help='measurements per figure (the best is kept)')
    parser.add_argument('--closed-loop-size', type=int, default=1000,
                        help='batch size under the controller with coulomb contact (default 1000)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('batch')
    figures: list[tuple[str, str]] = []
    sizes = [int(size) for size in args.sizes.split(',')]
    engines = ['numpy'] + (['numba'] if kernel.available() else [])
    print(f'# {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}'
          f'{", numba " + kernel.numba.__version__ if kernel.available() else ", no numba"}; load average '
          f'{os.getloadavg()[0]:.1f} at start; circle, {SELECTION} + trajectory, ideal contact')
    batches = {(engine, size): batch_of(size, engine=engine) for engine in engines for size in sizes}
    for batch in batches.values():
        batch.step()  # first step: allocations, caches warm, the kernel compiled (or loaded from its cache)
    single_seconds = float('inf')
    wall, cpu = dict.fromkeys(batches, float('inf')), dict.fromkeys(batches, float('inf'))
    for _ in range(args.repeats):  # round robin, best of each: load from other processes hits all alike
        single_seconds = min(single_seconds, single_run_seconds(args.single_steps))
        for key, batch in batches.items():
            size = key[1]
            limit = MAX_BATCH_STEPS if key[0] == 'numpy' else 10 * MAX_BATCH_STEPS
            steps = max(2, min(round(args.robot_steps / size), limit))
            seconds, cpu_seconds = best_times(lambda: batch.run(steps), 1)
            wall[key], cpu[key] = min(wall[key], seconds / steps), min(cpu[key], cpu_seconds / steps)
    single = 1.0 / single_seconds
    print(f'single-robot loop: {single:10.0f} robot-steps/s')
    print(f'{"engine":>6s} {"batch size":>10s} {"robot-steps/s":>14s} {"x single":>9s} {"per CPU-s":>10s} '
          f'{"ms/step":>8s} {"ns/robot-step beyond t(1)":>26s}')
    rates = {key: key[1] / seconds for key, seconds in wall.items()}
    rows = []
    for (engine, size), seconds in wall.items():
        overhead = wall.get((engine, 1))
        beyond = '' if overhead is None or size == 1 else f'{(seconds - overhead) / size * 1e9:26.0f}'
        print(f'{engine:>6s} {size:10d} {rates[engine, size]:14.0f} {rates[engine, size] / single:9.1f} '
              f'{size / cpu[engine, size]:10.0f} {seconds * 1e3:8.2f} {beyond}')
        rows.append((engine, f'{size:,}', f'{rates[engine, size]:,.0f}', f'**{rates[engine, size] / single:.1f}**',
                     f'{size / cpu[engine, size]:,.0f}', f'{seconds * 1e3:.2f}'))
    report.table(('engine', 'batch size N', 'robot-steps/s', 'x the single-robot loop', 'robot-steps per CPU-second',
                  'ms per batch step'), rows,
                 f'Circle, full set, ideal contact; the single-robot loop in the same rounds: {single:,.0f} steps/s '
                 f'(wall clock, best of {args.repeats}):')
    for engine in engines:
        check_agreement(batches[engine, sizes[-1]])
        fastest = max((size for size in sizes), key=lambda size: rates[engine, size])
        rate = rates[engine, fastest]
        print(f'{engine}: fastest N = {fastest}, {rate:.0f} robot-steps/s = {rate / single:.1f} x the single loop')
        figures.append((f'{engine}: fastest batch', f'N = {fastest:,}: {rate:,.0f} robot-steps/s, '
                                                    f'{rate / single:.1f} x the single loop'))
        driven = batch_of(fastest, ConstraintSelection.structural(trajectory=False), engine)
        driven.set_motor_torque((0.5, 0.4))
        driven.step()
        steps = max(2, round(args.robot_steps / fastest))
        seconds = best_seconds(lambda: driven.run(steps), args.repeats) / steps
        print(f'  driven set without the trajectory task (B of rank 5: the rank-revealing path), N = {fastest}: '
              f'{fastest / seconds:.0f} robot-steps/s')
        figures.append((f'{engine}: driven set without the trajectory task (the rank-revealing path)',
                        f'N = {fastest:,}: {fastest / seconds:,.0f} robot-steps/s'))
    fastest = max((size for size in sizes), key=lambda size: rates['numpy', size])
    batch = batch_of(fastest)
    batch.run(3)
    split = stage_split(batch, args.repeats)
    stage = sum(seconds for name, seconds in split.items() if not name.startswith(' '))
    print(f'numpy: one RK4 stage at N = {fastest} ({stage / fastest * 1e9:.0f} ns per robot; a step is 4 stages and '
          f'the RK4 sums):')
    for name, seconds in split.items():
        print(f'  {name:26s} {seconds / fastest * 1e9:6.0f} ns per robot  {seconds / stage:5.1%}')
    shares = ', '.join(f'{name.strip()} {seconds / stage:.0%}' for name, seconds in split.items())
    figures.append((f'numpy: one RK4 stage at N = {fastest:,}', f'{stage / fastest * 1e9:,.0f} ns per robot: {shares}'))
    if kernel.available():
        size = max(sizes)
        batch = batches['numba', size]
        threads = kernel.numba.get_num_threads()
        steps = max(2, min(round(args.robot_steps / size), 10 * MAX_BATCH_STEPS))
        timings = {}
        for count in sorted({1, threads}):  # one thread, then all: how far the second core was there to take
            kernel.numba.set_num_threads(count)
            timings[count] = best_times(lambda: batch.run(steps), args.repeats)
        kernel.numba.set_num_threads(threads)
        per_robot = timings[1][1] / steps / size
        print(f'numba at N = {size}: one thread {size * steps / timings[1][0]:.0f} robot-steps/s, {threads} threads '
              f'{size * steps / timings[threads][0]:.0f} ({timings[1][0] / timings[threads][0]:.2f}x); '
              f'one robot-step costs {per_robot * 1e9:.0f} ns of one core: with the {os.cpu_count()} cores to itself '
              f'at most {os.cpu_count() / per_robot:.0f} robot-steps/s')
        figures.append((f'numba at N = {size:,}: one thread, {threads} threads',
                        f'{size * steps / timings[1][0]:,.0f} and {size * steps / timings[threads][0]:,.0f} '
                        f'robot-steps/s ({timings[1][0] / timings[threads][0]:.2f}x); {per_robot * 1e9:,.0f} ns of one '
                        f'core a robot-step, so at most {os.cpu_count() / per_robot:,.0f} robot-steps/s on '
                        f'{os.cpu_count()} cores'))
    size = args.closed_loop_size
    single_rate, batch_rates = closed_loop_rates(size, 200, min(args.repeats, 3), engines)
    print(f'under the controller with coulomb contact (figure-8, driven set): single robot {single_rate:.0f} '
          f'robot-steps/s; N = {size}: ' + ', '.join(f'{engine} {rate:.0f} ({rate / single_rate:.1f}x)'
                                                    for engine, rate in batch_rates.items()))
    batches = ', '.join(f'{engine} {rate:,.0f} (**{rate / single_rate:.1f}x**)' for engine, rate in batch_rates.items())
    figures.append(('under the controller with coulomb contact (figure-8, driven set)',
                    f'single robot {single_rate:,.0f} robot-steps/s; N = {size:,}: {batches}'))
    print(f'load average {os.getloadavg()[0]:.1f} at end')
    report.table(('measure', 'figure'), figures)
    report.write(args.write_docs)


if __name__ == '__main__':
    main()
