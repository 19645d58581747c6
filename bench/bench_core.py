"""Steps per second of the model core, against a straightforward section-6 solver in the same process.

For each scenario and constraint set, the same simulation is stepped with
  * the core (Udwadia-Kalaba form with a factor W of M^-1, one small LAPACK least-squares call),
  * the core's numba engine (``Simulation(..., engine='numba')``: the batch's compiled kernel), and
  * a straightforward Udwadia-Phohomsiri evaluation: two numpy.linalg.pinv per evaluation, no
    structure exploited (wallbot_sim.model.solve),
and the ratios to the last are printed. All must end in the same state (a check that the comparison
is fair). The core and the two-pinv model share the model's evaluation (Q, the constraint rows,
RK4); "solve ratio" compares their solvers alone on the same inputs (A, b, M, Q at the final state).

Then the same with the outputs computed at every step (as ``simulate`` and the dynamics node do), and
whole processes: ``wallbot-sim simulate --duration 20 --csv FILE`` with each engine, and the same
command with the two-pinv model in place of ``Simulation`` (this script's hidden ``--pinv-simulate``:
the command's own code in a process of its own). Each process is timed from start to exit, imports and
numba's loading of its compiled kernel from its cache included; wall time and CPU time (user + system).

Then the wheel-wall contact: the driven robot from rest (docs/model.md 11.4's cases: belt, non-lateral,
nonslip, no trajectory task) stepped with its outputs at every step, as ``simulate`` and the
dynamics node do, with ideal and with coulomb contact, on each engine. "cost" is the coulomb step's
extra time relative to the ideal step of the same engine; in the sticking cases it is the stick/slip
bookkeeping alone.

    python bench/bench_core.py [--seconds 2.0] [--process-seconds 20] [--repeats 3] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from typing import Sequence

import numpy as np

from report import Report, add_write_docs_option
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstrainedMotion, ConstraintSelection, Robot, Simulation, solve
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.solver import constrained_acceleration

SETS = ('none', 'belt', 'belt,non_lateral', 'belt,non_lateral,nonslip')


class StraightforwardSimulation(Simulation):
    """The same model, each RK4 stage and the outputs' solve by the general two-pinv formula."""

    def _derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[:DOF], y[DOF:]
        force, rows, rhs = self._problem(t, q, qd)
        return np.concatenate((qd, solve(self.robot.mass_matrix(q), force, rows, rhs).acceleration))

    def solve(self, t: float, q: np.ndarray, qd: np.ndarray) -> ConstrainedMotion:
        force, rows, rhs = self._problem(t, q, qd)
        return solve(self.robot.mass_matrix(q), force, rows, rhs)


def solves_per_second(simulation: Simulation, count: int = 3000) -> tuple[float, float]:
    """Solves per second at the simulation's state: the core's solver, then the two-pinv formula."""
    q, qd = simulation.q, simulation.qd
    force, rows, rhs = simulation._problem(simulation.t, q, qd)
    mass, factor = simulation.robot.mass_matrix(q), simulation.robot.mass_inverse_factor(q)
    rates = []
    for solve_once in (lambda: constrained_acceleration(factor, force, rows, rhs),
                       lambda: solve(mass, force, rows, rhs)):
        started = time.perf_counter()
        for _ in range(count):
            solve_once()
        rates.append(count / (time.perf_counter() - started))
    return rates[0], rates[1]


def steps_per_second(simulation: Simulation, steps: int) -> float:
    started = time.perf_counter()
    for _ in range(steps):
        simulation.step()
    return steps / (time.perf_counter() - started)


CONTACT_CASES = (  # name, heading, side torques, adhesion force (None: the robot file's), what happens
    ('hold', 0.0, (0.0, 0.0), None, 'sticks'),
    ('climb', math.pi / 2, (2.0, 1.95), None, 'sticks'),
    ('slide', 0.0, (0.0, 0.0), 100.0, 'every wheel slides'),
    ('spin', math.pi / 2, (3.0, 3.0), None, 'every wheel spins'),
    ('turn', math.pi / 2, (3.5, 2.0), None, 'left side spins'),
)


def steps_with_outputs_per_second(simulation: Simulation, steps: int) -> float:
    """Steps per second of CPU time, the outputs computed at every step."""
    started = time.process_time()
    for _ in range(steps):
        simulation.outputs()
        simulation.step()
    return steps / (time.process_time() - started)


def contact_table(steps: int, report: Report) -> None:
    """Steps per second with the outputs of every step, ideal and coulomb contact, on each engine (alternating,
    best of five); "cost" is the coulomb step's extra time over the ideal step of the same engine."""
    print(f'\n{"contact case":13s} {"":17s} {"python: ideal":>13s} {"coulomb":>8s} {"cost":>7s} '
          f'{"numba: ideal":>13s} {"coulomb":>8s} {"cost":>7s}')
    driven = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False)
    rows = []
    for name, heading, torque, adhesion, what in CONTACT_CASES:
        robot = Robot(load_robot_parameters().replace(adhesion_force=adhesion))
        columns, cells = [], [name, what]
        for engine in ('python', 'numba'):
            rates = [0.0, 0.0]
            for _ in range(5):  # alternating, best of five: load from other processes hits both alike
                for k, contact in enumerate(('ideal', 'coulomb')):
                    simulation = Simulation(robot, None, driven, np.array([0.0, 0.0, heading, 0, 0, 0, 0]),
                                            np.zeros(DOF), contact=contact, engine=engine)
                    simulation.set_motor_torque(*torque)
                    rates[k] = max(rates[k], steps_with_outputs_per_second(simulation, steps))
            columns.append(f'{rates[0]:13.0f} {rates[1]:8.0f} {rates[0] / rates[1] - 1:7.1%}')
            cells += [f'{rates[0]:,.0f}', f'{rates[1]:,.0f}', f'{rates[0] / rates[1] - 1:.1%}']
        print(f'{name:13s} {what:17s} {" ".join(columns)}')
        rows.append(cells)
    report.table(('contact case', 'what happens', 'python ideal, steps/s', 'python coulomb', 'coulomb cost',
                  'numba ideal', 'numba coulomb', 'coulomb cost'), rows,
                 'Wheel-wall contact: the driven robot with its outputs at every step, ideal against coulomb contact '
                 "on each engine (the cost is the coulomb step's extra time):")


def outputs_table(robot: Robot, steps: int, report: Report) -> None:
    """Steps per second with the outputs of every step, the circle's default and full sets, each engine and the
    two-pinv model (best of three, alternating)."""
    print(f'\n{"outputs at every step, CPU time":58s} {"core steps/s":>12s} {"numba steps/s":>13s} '
          f'{"pinv steps/s":>12s} {"ratio":>6s} {"numba ratio":>11s}')
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    rows = []
    for constraints in ('none', SETS[-1]):
        selection = ConstraintSelection.parse(constraints)
        rates = [0.0, 0.0, 0.0]
        for _ in range(3):
            for k, (kind, engine) in enumerate(((Simulation, 'python'), (Simulation, 'numba'),
                                                (StraightforwardSimulation, 'python'))):
                simulation = kind(robot, scenario.reference, selection, q0, qd0, engine=engine)
                simulation.step()
                simulation.reset()
                rates[k] = max(rates[k], steps_with_outputs_per_second(simulation, steps))
        core, compiled, plain = rates
        print(f'{"circle":9s} {selection.label():48s} {core:12.0f} {compiled:13.0f} {plain:12.0f} {core / plain:6.2f} '
              f'{compiled / plain:11.2f}')
        rows.append(('circle', selection.label(), f'{core:,.0f}', f'{compiled:,.0f}', f'{plain:,.0f}',
                     f'**{core / plain:.2f}**', f'**{compiled / plain:.2f}**'))
    report.table(('scenario', 'constraint set', 'core steps/s', 'numba steps/s', 'two-pinv steps/s',
                  'core / two-pinv', 'numba / two-pinv'), rows,
                 'With the outputs computed at every step (as `simulate` and the dynamics node do), CPU time:')


def simulate_with_pinv(argv: Sequence[str]) -> int:
    """``wallbot-sim simulate ARGV`` in this process, with the two-pinv model in place of ``Simulation``."""
    from wallbot_sim.cli import main as cli
    from wallbot_sim.cli import simulate
    simulate.Simulation = StraightforwardSimulation
    return cli.main(['simulate', *argv])


def timed_process(command: Sequence[str]) -> tuple[float, float]:
    """Wall and CPU seconds (user + system) of ``command`` from its start to its exit."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        raise SystemExit(f'{" ".join(command)} failed: {result.stderr[-2000:]}')
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def process_table(seconds: float, repeats: int, report: Report) -> None:
    """Whole ``simulate --csv`` processes: each engine and the two-pinv model, alternating, best of ``repeats``."""
    wallbot = [sys.executable, '-m', 'wallbot_sim.cli.main', 'simulate']
    print(f'\nwhole processes: simulate --scenario circle --duration {seconds:g} --csv FILE, best of {repeats} '
          f'(load average {" ".join(f"{v:.2f}" for v in os.getloadavg())} before)')
    print(f'{"constraint set":25s} {"model":7s} {"wall s":>7s} {"CPU s":>7s} {"pinv/this wall":>14s} '
          f'{"pinv/this CPU":>13s}  (model: pinv = two-pinv Simulation, python and numba = --engine)')
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        timed_process([*wallbot, '--duration', '0.01', '--csv', os.devnull, '--quiet', '--engine', 'numba'])  # cache
        for constraints in ('none', SETS[-1]):
            common = ['--scenario', 'circle', '--constraints', constraints, '--duration', f'{seconds:g}', '--quiet']
            commands = {
                'pinv': [sys.executable, os.path.abspath(__file__), '--pinv-simulate', *common,
                         '--csv', f'{folder}/pinv.csv'],
                'python': [*wallbot, *common, '--engine', 'python', '--csv', f'{folder}/python.csv'],
                'numba': [*wallbot, *common, '--engine', 'numba', '--csv', f'{folder}/numba.csv'],
            }
            best = {name: (math.inf, math.inf) for name in commands}
            for _ in range(repeats):
                for name, command in commands.items():
                    wall, cpu = timed_process(command)
                    best[name] = (min(best[name][0], wall), min(best[name][1], cpu))
            tables = {name: np.loadtxt(f'{folder}/{name}.csv', delimiter=',', skiprows=1) for name in commands}
            scale = np.maximum(np.max(np.abs(tables['python']), axis=0), 1.0)  # round-off columns stay near 0
            for name in ('pinv', 'numba'):
                difference = np.max(np.abs(tables[name] - tables['python']) / scale)
                if not difference < 1e-6:
                    raise SystemExit(f'{constraints}: the {name} CSV differs from the python one by {difference:.1e} '
                                     "of a column's largest value")
            plain_wall, plain_cpu = best['pinv']
            for name, (wall, cpu) in best.items():
                print(f'{constraints:25s} {name:7s} {wall:7.2f} {cpu:7.2f} {plain_wall / wall:14.2f} '
                      f'{plain_cpu / cpu:13.2f}')
                rows.append((constraints, name, f'{wall:.2f}', f'{cpu:.2f}', f'**{plain_wall / wall:.2f}**',
                             f'**{plain_cpu / cpu:.2f}**'))
    report.table(('constraint set', 'model', 'wall s', 'CPU s', 'two-pinv / this, wall', 'two-pinv / this, CPU'), rows,
                 f'Whole processes, `simulate --scenario circle --duration {seconds:g} --csv FILE` from start to exit '
                 f'(imports and the kernel loaded from its cache included), best of {repeats}; `pinv` is the same '
                 'command on the two-pinv model:')
    print(f'load average after: {" ".join(f"{v:.2f}" for v in os.getloadavg())}')


def numba_version() -> str:
    try:
        import numba
    except ImportError:
        return 'not installed'
    return numba.__version__


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=2.0, help='simulated seconds per measurement')
    parser.add_argument('--process-seconds', type=float, default=20.0,
                        help='simulated seconds of each whole simulate process (0: none)')
    parser.add_argument('--repeats', type=int, default=3, help='processes of each kind, alternating; the best counts')
    parser.add_argument('--pinv-simulate', nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    add_write_docs_option(parser)
    args = parser.parse_args()
    if args.pinv_simulate is not None:
        sys.exit(simulate_with_pinv(args.pinv_simulate))
    report = Report('core')
    steps = round(args.seconds / 1e-3)
    robot = Robot(load_robot_parameters())
    print(f'# {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, '
          f'numpy {np.__version__}, numba {numba_version()}; {steps} steps of 1 ms per measurement, single thread; '
          f'load average {" ".join(f"{v:.2f}" for v in os.getloadavg())}')
    print(f'{"scenario":9s} {"constraint set":48s} {"core steps/s":>12s} {"numba steps/s":>13s} '
          f'{"pinv steps/s":>12s} {"ratio":>6s} {"numba ratio":>11s} {"x real time":>11s} {"solve ratio":>11s}')
    rows = []
    for name in ('circle', 'figure8'):
        scenario = load_scenario(name)
        q0, qd0 = scenario.initial_state(robot)
        for constraints in SETS:
            selection = ConstraintSelection.parse(constraints)
            core = Simulation(robot, scenario.reference, selection, q0, qd0)
            compiled = Simulation(robot, scenario.reference, selection, q0, qd0, engine='numba')
            compiled.step()  # numba loads (or compiles) its kernel at the first call: not part of the rate
            compiled.reset()
            plain = StraightforwardSimulation(robot, scenario.reference, selection, q0, qd0)
            fast, faster, slow = (steps_per_second(simulation, steps) for simulation in (core, compiled, plain))
            for other in (plain, compiled):
                if not np.allclose(core.q, other.q, rtol=1e-9, atol=1e-9):
                    raise SystemExit(f'{name} {constraints}: {type(other).__name__} {other.engine} disagrees with '
                                     f'the core: {other.q} vs {core.q}')
            fast_solve, slow_solve = solves_per_second(core)
            print(f'{name:9s} {selection.label():48s} {fast:12.0f} {faster:13.0f} {slow:12.0f} {fast / slow:6.2f} '
                  f'{faster / slow:11.2f} {fast / 1000:11.1f} {fast_solve / slow_solve:11.2f}')
            rows.append((name, selection.label(), f'{fast:,.0f}', f'{faster:,.0f}', f'{slow:,.0f}',
                         f'**{fast / slow:.2f}**', f'**{faster / slow:.2f}**', f'{fast / 1000:.1f}',
                         f'{fast_solve / slow_solve:.2f}'))
    report.table(('scenario', 'constraint set', 'core steps/s', 'numba steps/s', 'two-pinv steps/s', 'core / two-pinv',
                  'numba / two-pinv', 'core x real time', 'solve: core / two-pinv'), rows,
                 f'Steps per second of one simulation, single thread, {steps} steps of 1 ms each:')
    outputs_table(robot, steps, report)
    contact_table(steps, report)
    if args.process_seconds > 0:
        process_table(args.process_seconds, args.repeats, report)
    report.write(args.write_docs)


if __name__ == '__main__':
    main()
