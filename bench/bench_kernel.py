"""The numba engine's coulomb contact against its ideal contact, in the same process, and the kernel's cold compile.

Per contact case (bench_core's: the driven robot from rest, belt, non-lateral and nonslip, no trajectory task),
one ``Simulation(..., engine='numba')`` with ideal contact and one with coulomb contact are stepped in turn, the
outputs computed at every step (as ``simulate`` and the dynamics node do); the best of ``--repeats`` rounds of
each. The ratio is the coulomb step's CPU time over the ideal step's (issue 32 allows at most 1.30). Beside it,
the share of wheel-steps that slid, from the coulomb run's own slip flags: what the case exercises.

The cold compile: a fresh process compiles the kernel (``compile_run``) into an empty numba cache
(``NUMBA_CACHE_DIR`` a new directory) for ideal contact, then what coulomb contact adds; a second process loads
both from that cache. Wall seconds each, numba's import excluded.

    python bench/bench_kernel.py [--seconds 2.0] [--repeats 5] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

from bench_core import CONTACT_CASES, steps_with_outputs_per_second
from report import Report, add_write_docs_option
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import ConstraintSelection, Robot, Simulation
from wallbot_sim.model.robot import DOF

LIMIT = 1.30
"""The largest coulomb / ideal step cost issue 32 allows."""
DRIVEN = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False)
COMPILE = """
import json, time
import numba
from wallbot_sim.model.compiled import compile_run
began = time.perf_counter()
compile_run('ideal')
ideal = time.perf_counter()
compile_run('coulomb')
print(json.dumps([ideal - began, time.perf_counter() - ideal]))
"""
"""A process's compile (or cache load) of the ideal run, then of what coulomb contact adds: seconds each."""


def simulation(case: tuple, contact: str) -> Simulation:
    _, heading, torque, adhesion, _ = case
    robot = Robot(load_robot_parameters().replace(adhesion_force=adhesion))
    made = Simulation(robot, None, DRIVEN, np.array([0.0, 0.0, heading, 0, 0, 0, 0]), np.zeros(DOF), contact=contact,
                      engine='numba')
    made.set_motor_torque(*torque)
    return made


def slid_share(case: tuple, steps: int) -> float:
    """The share of the coulomb run's wheel-steps that slid."""
    sliding = simulation(case, 'coulomb')
    slid = 0
    for _ in range(steps):
        slid += sum(sliding.outputs().contact.wheel_slipping)
        sliding.step()
    return slid / (4 * steps)


def contact_ratios(steps: int, repeats: int, report: Report) -> float:
    """Each case's steps per second with ideal and coulomb contact and their cost ratio; returns the largest."""
    print(f'{"contact case":13s} {"slid":>6s} {"ideal steps/s":>13s} {"coulomb":>8s} {"ratio":>6s}')
    rows, worst = [], 0.0
    for case in CONTACT_CASES:
        rates = [0.0, 0.0]
        for _ in range(repeats):  # alternating, best of all: load from other processes hits both alike
            for k, contact in enumerate(('ideal', 'coulomb')):
                rates[k] = max(rates[k], steps_with_outputs_per_second(simulation(case, contact), steps))
        ratio, share = rates[0] / rates[1], slid_share(case, steps)
        worst = max(worst, ratio)
        print(f'{case[0]:13s} {share:6.0%} {rates[0]:13.0f} {rates[1]:8.0f} {ratio:6.2f}')
        rows.append((case[0], f'{share:.0%}', f'{rates[0]:,.0f}', f'{rates[1]:,.0f}', f'**{ratio:.2f}**'))
    report.table(('contact case', 'wheel-steps sliding', 'ideal steps/s', 'coulomb steps/s', 'coulomb / ideal'), rows,
                 f'The numba engine, one robot with its outputs at every step, {steps} steps of 1 ms, best of '
                 f'{repeats} (CPU time): the coulomb step\'s cost over the ideal step\'s, at most {LIMIT:.2f} allowed; '
                 f'largest {worst:.2f}.')
    return worst


def compile_seconds(cache: str) -> tuple[float, float]:
    """``COMPILE`` in a process of its own with numba's cache in ``cache``."""
    done = subprocess.run([sys.executable, '-c', COMPILE], env={**os.environ, 'NUMBA_CACHE_DIR': cache},
                          capture_output=True, text=True, check=True)
    ideal, coulomb = json.loads(done.stdout.splitlines()[-1])
    return ideal, coulomb


def compile_table(report: Report) -> None:
    with tempfile.TemporaryDirectory() as cache:
        cold, loaded = compile_seconds(cache), compile_seconds(cache)
    print(f'\ncold compile: ideal run {cold[0]:.1f} s, coulomb contact {cold[1]:.1f} s more; '
          f'from the cache: {loaded[0]:.2f} s and {loaded[1]:.2f} s')
    report.table(('kernel', 'cold compile, s', 'load from the cache, s'),
                 [('ideal run (`compile_run("ideal")`)', f'{cold[0]:.1f}', f'{loaded[0]:.2f}'),
                  ('coulomb contact, beyond the ideal run', f'{cold[1]:.1f}', f'{loaded[1]:.2f}')],
                 'Compiling the kernel into an empty numba cache, then loading it from there (a process each, wall '
                 'time, numba imported first):')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=2.0, help='simulated seconds per measurement')
    parser.add_argument('--repeats', type=int, default=5, help='rounds of each measurement; the best counts')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('kernel')
    print(f'load average {" ".join(f"{v:.2f}" for v in os.getloadavg())}')
    compile_table(report)
    worst = contact_ratios(round(args.seconds / 1e-3), args.repeats, report)
    print(f'largest coulomb / ideal ratio {worst:.2f} (at most {LIMIT:.2f} allowed)')
    report.write(args.write_docs)


if __name__ == '__main__':
    main()
