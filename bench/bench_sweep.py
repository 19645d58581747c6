"""A whole design sweep timed, and some of its robots checked against single ``simulate`` runs.

Runs ``wallbot-sim sweep SPEC --out DIR`` (default: examples/sweep_figure8.yaml, 1,000 robots over
body_mass and com_height on the figure-8) as a user does, prints its wall time, robot-steps per
second, the machine and its load before and after; then runs ``--check`` of its robots, chosen at
random, alone through ``wallbot-sim simulate`` and prints the largest relative difference between
their results.csv rows and what the run summary and the motor analysis give for those CSVs.

    python bench/bench_sweep.py [--spec examples/sweep_figure8.yaml] [--out runs/bench_sweep] [--workers N] [--check 3]
                                [--check-only] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import yaml

from report import Report, add_write_docs_option
from wallbot_sim.rundata import load_run, summarize
from wallbot_sim.rundata.motors import motor_report
from wallbot_sim.sweep import load_spec
from wallbot_sim.sweep.store import read_results

REPO = Path(__file__).resolve().parents[1]
WALLBOT = [sys.executable, '-m', 'wallbot_sim.cli.main']
TINY = 1e-9
"""Outputs this small (a tracking error or residual at round-off) are compared absolutely."""


def checked_outputs(csv_path: Path, params) -> dict[str, float]:
    """The outputs a row holds that come straight from the run summary and the motor analysis."""
    summary, run = summarize(csv_path), load_run(csv_path)
    report = motor_report(run, params)
    return {'final_err': summary.final_tracking_error, 'peak_abs_F_left': summary.peak_drive_force_left,
            'peak_abs_F_right': summary.peak_drive_force_right, 'peak_abs_F_lateral': summary.peak_lateral_force,
            'peak_motor_torque_left': report.left.peak_torque, 'peak_motor_torque_right': report.right.peak_torque,
            'min_normal_load': float(np.min(run.loads)), 'max_residual': summary.max_residual,
            'least_adhesion_force': report.adsorption.needed}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--spec', default=str(REPO / 'examples' / 'sweep_figure8.yaml'))
    parser.add_argument('--out', default=str(REPO / 'runs' / 'bench_sweep'))
    parser.add_argument('--workers', type=int, help='local cluster size (default: one per core)')
    parser.add_argument('--check', type=int, default=3, help='robots to compare with single simulate runs')
    parser.add_argument('--check-only', action='store_true', help='only check the results already in --out')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('sweep')

    spec = load_spec(args.spec)
    if spec.settings.controller or spec.settings.selection.tangent_heading is not None:
        parser.error('the check runs simulate with --constraints only: a spec without controller and tangent_heading')
    if not args.check_only:
        measure(args, spec, report)
    check(args, spec, report)
    report.write(args.write_docs)
    return 0


def measure(args: argparse.Namespace, spec, report: Report) -> None:
    """Run the sweep and print its time."""
    print(f'{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy '
          f'{np.__version__}; {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC; load average before '
          f'{os.getloadavg()[0]:.1f}')
    command = [*WALLBOT, 'sweep', args.spec, '--out', args.out]
    if args.workers:
        command += ['--workers', str(args.workers)]
    started = time.perf_counter()
    subprocess.run(command, check=True)
    seconds = time.perf_counter() - started
    robot_steps = len(spec.robots) * (spec.settings.steps + 1)
    print(f'{len(spec.robots)} robots x {spec.settings.steps + 1} steps in {seconds:.0f} s wall '
          f'({robot_steps / seconds:,.0f} robot-steps/s, start-up and figures included); load average after '
          f'{os.getloadavg()[0]:.1f}')
    report.table(('robots x steps', 'workers', 'wall time', 'robot-steps/s (start-up and figures included)'),
                 [(f'{len(spec.robots):,} x {spec.settings.steps + 1:,}',
                   args.workers or f'{os.cpu_count()} (one per core)', f'{seconds:,.0f} s',
                   f'{robot_steps / seconds:,.0f}')])


def check(args: argparse.Namespace, spec, report: Report) -> None:
    """Compare ``--check`` robots of the results with single simulate runs."""
    names, rows = read_results(Path(args.out) / 'results.csv')
    worst_relative, worst_absolute = 0.0, 0.0
    for index in np.random.default_rng(0).choice(len(rows), size=min(args.check, len(rows)), replace=False):
        params = spec.parameters(int(index))
        row = dict(zip(names, rows[int(index)]))
        with tempfile.TemporaryDirectory() as folder:
            robot_file, csv_path = Path(folder) / 'robot.yaml', Path(folder) / 'run.csv'
            robot_file.write_text(yaml.safe_dump({key: list(value) if isinstance(value, tuple) else value
                                                  for key, value in params.__dict__.items()}), encoding='utf-8')
            settings = spec.settings
            simulate = [*WALLBOT, 'simulate', '--scenario', str(_scenario_argument(args.spec)), '--duration',
                        str(settings.duration), '--dt', str(settings.dt), '--robot', str(robot_file), '--csv',
                        str(csv_path), '--quiet', '--contact', settings.contact,
                        '--constraints', ','.join(n for n in settings.selection.active_names()
                                                  if n not in ('trajectory', 'tangent_heading')) or 'none']
            subprocess.run(simulate, check=True)
            for name, value in checked_outputs(csv_path, params).items():
                difference = abs(row[name] - value)
                if abs(value) > TINY:
                    worst_relative = max(worst_relative, difference / abs(value))
                elif math.isfinite(difference):
                    worst_absolute = max(worst_absolute, difference)
        print(f'robot {index}: checked against simulate')
    print(f'largest relative difference of a checked output: {worst_relative:.2e}; of those at round-off '
          f'(|value| <= {TINY:g}: final error, residual), the largest absolute difference: {worst_absolute:.2e}')
    report.table(('robots checked against single `simulate` runs', 'largest relative difference',
                  f'largest absolute difference of outputs at round-off (<= {TINY:g})'),
                 [(min(args.check, len(rows)), f'{worst_relative:.1e}', f'{worst_absolute:.1e}')])


def _scenario_argument(spec_path: str) -> str:
    """The spec's scenario as simulate's --scenario (a path relative to the spec's folder made absolute)."""
    name = yaml.safe_load(Path(spec_path).read_text(encoding='utf-8')).get('scenario', 'circle')
    candidate = Path(spec_path).parent / name
    return str(candidate) if candidate.is_file() else name


if __name__ == '__main__':
    sys.exit(main())
