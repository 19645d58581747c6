"""Whole design sweeps timed against a single ``simulate``, and some of their robots checked against it.

For each ``--spec`` (default: examples/sweep_figure8.yaml, 1,000 robots over body_mass and com_height on the
figure-8 with ideal contact, and bench/sweep_coulomb_controller.yaml, the same robots with coulomb contact
under the example controller), ``--samples`` and ``--duration`` overriding the spec's when given: runs one
robot of it alone through ``wallbot-sim simulate`` (the baseline, start-up included, numba's cache warmed
for it and for the sweep by an untimed run first), then ``wallbot-sim sweep SPEC --out DIR`` as a user does, and prints both wall times, the sweep's robot-steps per second and
its ratio to the single run's, with the machine's load (``uptime``) beside each; then runs ``--check`` of
its robots, chosen at random, alone through ``simulate`` and prints the largest relative difference
between their results.csv rows and what the run summary and the motor analysis give for those CSVs.

    python bench/bench_sweep.py [--spec SPEC ...] [--samples N] [--duration S] [--out runs/bench_sweep]
                                [--workers N] [--check 3] [--check-only] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import shutil
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
from wallbot_sim.sweep.compute import load_kernels
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


SPECS = (REPO / 'examples' / 'sweep_figure8.yaml', REPO / 'bench' / 'sweep_coulomb_controller.yaml')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--spec', action='append', help='a sweep spec (repeatable; default: the two of SPECS)')
    parser.add_argument('--samples', type=int, help="robots of each spec (default: the spec's)")
    parser.add_argument('--duration', type=float, help="seconds each robot runs (default: the spec's)")
    parser.add_argument('--out', default=str(REPO / 'runs' / 'bench_sweep'),
                        help="where each spec's sweep is written (its folder emptied before the timed run)")
    parser.add_argument('--workers', type=int, help='local cluster size (default: one per core)')
    parser.add_argument('--check', type=int, default=3, help='robots of each spec to compare with single simulate runs')
    parser.add_argument('--check-only', action='store_true', help='only check the results already in --out')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('sweep')
    print(f'{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy '
          f'{np.__version__}; {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC')
    measured, checked = [], []
    with tempfile.TemporaryDirectory() as folder:
        for number, spec_path in enumerate(args.spec or [str(path) for path in SPECS]):
            (Path(folder) / str(number)).mkdir()
            spec_path = _overridden(Path(spec_path), args, Path(folder) / str(number) / Path(spec_path).name)
            spec = load_spec(spec_path)
            if spec.settings.selection.tangent_heading is not None:
                parser.error(f'{spec_path}: the runs alone take simulate --constraints: a spec without tangent_heading')
            out = Path(args.out) / Path(spec_path).stem
            if not args.check_only:
                measured.append(measure(args, spec_path, spec, out))
            checked.append(check(args, spec_path, spec, out))
    report.table(('spec', 'contact, controller', 'robots x steps', 'workers', 'single `simulate` (load)',
                  'sweep wall time (load)', 'robot-steps/s', 'x a single `simulate`'), measured)
    report.table(('spec', 'robots checked against single `simulate` runs', 'largest relative difference',
                  f'largest absolute difference of outputs at round-off (<= {TINY:g})'), checked)
    report.write(args.write_docs)
    return 0


def _overridden(spec_path: Path, args: argparse.Namespace, copy: Path) -> Path:
    """The spec, or a copy of it with --samples and --duration in place of its own (its scenario path kept)."""
    if args.samples is None and args.duration is None:
        return spec_path
    values = yaml.safe_load(spec_path.read_text(encoding='utf-8'))
    values['scenario'] = _scenario_argument(spec_path)
    values.update({key: value for key, value in (('samples', args.samples), ('duration', args.duration))
                   if value is not None})
    copy.write_text(yaml.safe_dump(values), encoding='utf-8')
    return copy


def uptime_load() -> str:
    """The 1-minute load average as ``uptime`` prints it."""
    text = subprocess.run(['uptime'], capture_output=True, text=True, check=True).stdout
    return text.rsplit('load average:', 1)[1].split(',')[0].strip()


def measure(args: argparse.Namespace, spec_path: Path, spec, out: Path) -> tuple:
    """One robot alone through simulate, then the whole sweep: their times and the ratio of their rates."""
    steps = spec.settings.steps + 1
    with tempfile.TemporaryDirectory() as folder:
        single_run = simulate_command(spec_path, spec.settings, _robot_file(spec.parameters(0), Path(folder)),
                                      Path(folder) / 'run.csv')
        # numba's cache warmed on both sides first: a kernel compiled in the timed run is not its rate
        timed(single_run, allowed=(0, 3))
        load_kernels(spec.settings)
        load_single = uptime_load()
        single = timed(single_run, allowed=(0, 3))
    single_rate = steps / single
    shutil.rmtree(out, ignore_errors=True)  # a sweep resumes into its folder: the timed one starts from nothing
    command = [*WALLBOT, 'sweep', str(spec_path), '--out', str(out)]
    if args.workers:
        command += ['--workers', str(args.workers)]
    load_before = uptime_load()
    seconds = timed(command)
    load_after = uptime_load()
    rate = len(spec.robots) * steps / seconds
    settings = spec.settings
    kind = f'{settings.contact}, {"controller" if settings.controller else "no controller"}'
    print(f'{spec_path.stem} ({kind}): one robot alone {single:.2f} s ({single_rate:,.0f} steps/s, load '
          f'{load_single}); {len(spec.robots)} robots x {steps} steps in {seconds:.1f} s wall ({rate:,.0f} '
          f'robot-steps/s, start-up and figures included, {rate / single_rate:.0f}x), load {load_before} before, '
          f'{load_after} after')
    return (spec_path.stem, kind, f'{len(spec.robots):,} x {steps:,}',
            args.workers or f'{os.cpu_count()} (one per core)', f'{single:.2f} s ({load_single})',
            f'{seconds:,.1f} s ({load_before} / {load_after})', f'{rate:,.0f}', f'{rate / single_rate:.0f}')


def timed(command: list[str], allowed: tuple[int, ...] = (0,)) -> float:
    """Wall seconds of ``command`` (its exit status one of ``allowed``: simulate exits 3 on a lift-off)."""
    started = time.perf_counter()
    result = subprocess.run(command)
    if result.returncode not in allowed:
        raise SystemExit(f'{command[3]} failed (exit status {result.returncode})')
    return time.perf_counter() - started


def _robot_file(params, folder: Path) -> Path:
    path = folder / 'robot.yaml'
    path.write_text(yaml.safe_dump({key: list(value) if isinstance(value, tuple) else value
                                    for key, value in params.__dict__.items()}), encoding='utf-8')
    return path


def simulate_command(spec_path: Path, settings, robot_file: Path, csv_path: Path) -> list[str]:
    """``wallbot-sim simulate`` of one robot of the spec, as the sweep runs it."""
    command = [*WALLBOT, 'simulate', '--scenario', _scenario_argument(spec_path), '--duration',
               str(settings.duration), '--dt', str(settings.dt), '--robot', str(robot_file), '--csv', str(csv_path),
               '--quiet', '--contact', settings.contact]
    if settings.controller:
        return command + ['--controller', '--controller-mass-scale', str(settings.controller_mass_scale)]
    return command + ['--constraints', ','.join(name for name in settings.selection.active_names()
                                                if name not in ('trajectory', 'tangent_heading')) or 'none']


def check(args: argparse.Namespace, spec_path: Path, spec, out: Path) -> tuple:
    """Compare ``--check`` robots of the results with single simulate runs."""
    names, rows = read_results(out / 'results.csv')
    worst_relative, worst_absolute = 0.0, 0.0
    for index in np.random.default_rng(0).choice(len(rows), size=min(args.check, len(rows)), replace=False):
        params = spec.parameters(int(index))
        row = dict(zip(names, rows[int(index)]))
        with tempfile.TemporaryDirectory() as folder:
            csv_path = Path(folder) / 'run.csv'
            timed(simulate_command(spec_path, spec.settings, _robot_file(params, Path(folder)), csv_path),
                  allowed=(0, 3))
            for name, value in checked_outputs(csv_path, params).items():
                if name == 'min_normal_load' and row['detached']:
                    continue  # a lift-off answering a command: its load is in simulate's message, not its CSV
                difference = abs(row[name] - value)
                if abs(value) > TINY:
                    worst_relative = max(worst_relative, difference / abs(value))
                elif math.isfinite(difference):
                    worst_absolute = max(worst_absolute, difference)
        print(f'{spec_path.stem} robot {index}: checked against simulate')
    print(f'largest relative difference of a checked output: {worst_relative:.2e}; of those at round-off '
          f'(|value| <= {TINY:g}: final error, residual), the largest absolute difference: {worst_absolute:.2e}')
    return (spec_path.stem, min(args.check, len(rows)), f'{worst_relative:.1e}', f'{worst_absolute:.1e}')


def _scenario_argument(spec_path: Path) -> str:
    """The spec's scenario as simulate's --scenario (a path relative to the spec's folder made absolute)."""
    name = yaml.safe_load(Path(spec_path).read_text(encoding='utf-8')).get('scenario', 'circle')
    candidate = Path(spec_path).parent / name
    return str(candidate) if candidate.is_file() else name


if __name__ == '__main__':
    sys.exit(main())
