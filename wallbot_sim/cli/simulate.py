"""``wallbot-sim simulate``: run a scenario headless, straight from the model, and write a CSV."""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path
from typing import TextIO

from wallbot_sim.cli import signals
from wallbot_sim.cli.errors import CliError
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation, StepOutputs

HELP = 'run a scenario headless (no ROS) and write a CSV of every step'

CSV_COLUMNS = (
    't', 'x', 'y', 'theta', 'phi1', 'phi2', 'phi3', 'phi4', 'vx', 'vy', 'omega',
    'dphi1', 'dphi2', 'dphi3', 'dphi4', 'ref_x', 'ref_y', 'err', 'Fx', 'Fy', 'Mz',
    'tau1', 'tau2', 'tau3', 'tau4', 'F_left', 'F_right', 'F_lateral', 'residual')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--scenario', default='circle', help='circle, figure8, or a scenario YAML path')
    parser.add_argument('--constraints', default='none',
                        help='comma list of belt, non_lateral, nonslip, or none (trajectory task only)')
    parser.add_argument('--tangent-heading', action=argparse.BooleanOptionalAction, default=None,
                        help='heading task along the path (default: on when non_lateral is active)')
    parser.add_argument('--duration', type=float, help='seconds to simulate (default: the scenario\'s)')
    parser.add_argument('--dt', type=float, default=1e-3, help='RK4 step in seconds (default 0.001)')
    parser.add_argument('--robot', help='robot parameter YAML (default: config/robot.yaml)')
    parser.add_argument('--csv', help='CSV output path (- for stdout)')
    parser.add_argument('--bag', help='also write the graph\'s topics to this rosbag2 directory (MCAP)')
    parser.add_argument('--quiet', action='store_true', help='no progress on stderr')


def csv_row(out: StepOutputs) -> list[float]:
    """One CSV row in the order of CSV_COLUMNS."""
    ref = out.reference.position if out.reference is not None else (math.nan, math.nan)
    return [out.t, *out.q, *out.qd, *ref, out.tracking_error, *out.constraint_force,
            out.drive.left, out.drive.right, out.drive.lateral, out.residual]


def build_simulation(args: argparse.Namespace) -> tuple[Simulation, float]:
    """The simulation and duration the arguments ask for (shared with the bag writer)."""
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise CliError(f'--duration must be a positive number of seconds, got {args.duration}')
    if not (math.isfinite(args.dt) and 0 < args.dt <= 0.1):
        raise CliError(f'--dt must be in (0, 0.1] seconds, got {args.dt}')
    scenario = load_scenario(args.scenario)
    selection = ConstraintSelection.parse(args.constraints, tangent_heading=args.tangent_heading)
    robot = Robot(load_robot_parameters(args.robot))
    q0, qd0 = scenario.initial_state(robot)
    duration = args.duration if args.duration is not None else scenario.duration
    return Simulation(robot, scenario.reference, selection, q0, qd0, dt=args.dt), duration


class Progress:
    """Simulation time and real-time factor on one refreshed stderr line, a few times a second.

    The factor is measured from the first time simulation time moved, so start-up is not in it.
    """

    def __init__(self, duration: float, stream: TextIO | None) -> None:
        self.duration, self.stream = duration, stream
        self.last = time.monotonic()
        self.anchor: tuple[float, float] | None = None

    def update(self, t: float, force: bool = False) -> None:
        now = time.monotonic()
        if self.anchor is None:
            self.anchor = (t, now)
        if self.stream is None or not (force or now - self.last >= 0.25):
            return
        self.last = now
        start_t, start_wall = self.anchor
        factor = (t - start_t) / max(now - start_wall, 1e-9)
        end = '\n' if force else ''
        self.stream.write(f'\r  t = {t:7.3f} / {self.duration:.3f} s   real-time factor {factor:6.2f}{end}')
        self.stream.flush()


def main(args: argparse.Namespace) -> int:
    if not args.csv and not args.bag:
        raise CliError('nothing to write: give --csv PATH (or - for stdout) and/or --bag DIR')
    simulation, duration = build_simulation(args)
    progress = Progress(duration, None if args.quiet else sys.stderr)
    sinks = []
    if args.bag:
        from wallbot_sim.bag.headless import HeadlessBagWriter  # only when asked: needs message types
        sinks.append(HeadlessBagWriter.open(Path(args.bag), simulation))
    with _open_csv(args.csv) as stream:
        writer = csv.writer(stream) if stream is not None else None
        if writer is not None:
            writer.writerow(CSV_COLUMNS)

        def on_step(out: StepOutputs) -> None:
            with signals.deferred():  # a signal ends the run between two complete steps
                if writer is not None:
                    writer.writerow(csv_row(out))
                for sink in sinks:
                    sink.write(out)
            progress.update(out.t)

        try:
            final = simulation.run(duration, on_step)
        finally:
            for sink in sinks:
                sink.close()
    progress.update(final.t, force=True)
    if not args.quiet:
        print(f'{simulation.selection.label()}: final tracking error {final.tracking_error:.3e} m, '
              f'residual {final.residual:.3e}', file=sys.stderr)
    return 0


class _open_csv:
    """Context manager for the CSV target: a file, stdout, or nothing."""

    def __init__(self, target: str | None) -> None:
        self.target, self.stream = target, None

    def __enter__(self) -> TextIO | None:
        if self.target == '-':
            self.stream = sys.stdout
        elif self.target:
            try:
                self.stream = open(self.target, 'w', newline='', encoding='utf-8')
            except OSError as error:
                raise CliError(f'cannot write {self.target}: {error.strerror}') from None
        return self.stream

    def __exit__(self, *exc: object) -> None:
        if self.stream is not None and self.stream is not sys.stdout:
            self.stream.close()
