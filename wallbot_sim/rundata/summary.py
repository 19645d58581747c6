"""What a finished run says: the numbers ``wallbot-sim run`` prints, every one from per-step data.

    summary = summarize(bag_dir)            # RunSummary (BagError / RunDataError if unreadable)
    print(format_summary(summary))

A bag is summarized in one pass over its messages (``streaming``), a simulate CSV from its columns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from wallbot_msgs_py.topics import RESIDUAL_SETTLED_AFTER
from wallbot_sim.model.contact import WHEEL_POSITIONS
from wallbot_sim.rundata.load import is_csv, load_run
from wallbot_sim.rundata.run_data import RunData


@dataclass(frozen=True)
class RunSummary:
    """Peaks are of absolute values over the whole run; NaN when the bag lacks the topic."""

    path: Path
    duration: float
    """Simulation time covered by odometry (s)."""
    odom_count: int
    final_tracking_error: float
    peak_tracking_error: float
    peak_tracking_error_after_5s: float
    peak_constraint_force_x: float
    peak_constraint_force_y: float
    peak_constraint_torque_z: float
    peak_drive_force_left: float
    peak_drive_force_right: float
    peak_lateral_force: float
    max_residual: float
    max_residual_settled: float
    """The largest residual at or after ``topics.RESIDUAL_SETTLED_AFTER`` (a start off the constraints left out)."""
    restarts: int = 0
    """Times simulation time jumped back in the bag; the figures are of the last run."""
    first_slip: tuple[float, str] | None = None
    """(time, wheels) of the first sample where a wheel slides; None if none did."""
    lift_off: tuple[float, int, float] | None = None
    """(time, wheel 1..4, load) of the first negative normal load: the detachment that ends a
    coulomb run, or where an ideal run's robot would have peeled off."""
    peak_wheel_use: tuple[float, ...] = (math.nan,) * 4
    """The largest friction use |f_i| / (mu_s N_i) of each wheel; NaN when the run did not record it."""


def _peak(values: np.ndarray) -> float:
    finite = np.abs(values[np.isfinite(values)])
    return float(finite.max()) if finite.size else math.nan


def summarize(path: Path | str, progress: Callable[[float, float], None] | None = None) -> RunSummary:
    """Summary of a bag (or simulate CSV) at ``path``; ``progress(done, total)``: how far the bag has
    been read (log time, s), every few thousand messages."""
    from wallbot_sim.rundata.streaming import summarize_bag
    path = Path(path)
    if is_csv(path):
        return summarize_run(load_run(path), path)
    return summarize_bag(path, progress)


def summarize_run(run: RunData, path: Path | str) -> RunSummary:
    """Summary of ``run``, loaded from ``path`` (or computed in memory: ``path`` then only names it)."""
    err = run.err
    late = err[run.t >= run.t[0] + 5.0]
    finite_err = err[np.isfinite(err)]
    series = [err, run.Fx, run.Fy, run.Mz, run.F_left, run.F_right, run.F_lateral, run.residual, run.residual_settled]
    (peak_err, *peaks), use = _peaks(np.column_stack(series)), (math.nan,) * 4
    if len(run.use):
        use = tuple(_peaks(run.use))
    return RunSummary(
        Path(path), float(run.t[-1] - run.t[0]), len(run.t),
        float(finite_err[-1]) if finite_err.size else math.nan, peak_err, _peak(late), *peaks, run.restarts,
        _first_slip(run), _lift_off(run), use)


def _peaks(columns: np.ndarray) -> list[float]:
    """``_peak`` of each column of ``columns`` (N, K), in one pass."""
    magnitude = np.abs(columns)
    largest = np.where(np.isfinite(magnitude), magnitude, -np.inf).max(axis=0, initial=-np.inf)
    return [float(value) if value >= 0.0 else math.nan for value in largest.tolist()]


def _first_slip(run) -> tuple[float, str] | None:
    slipping = run.slip > 0.5 if len(run.slip) else np.zeros((len(run.t), 4), dtype=bool)  # NaN: not recorded
    rows = np.flatnonzero(slipping.any(axis=1))
    if not rows.size:
        return None
    return float(run.t[rows[0]]), sliding_wheels(slipping[rows[0]])


def sliding_wheels(flags) -> str:
    """The wheels whose flags are set, by position ('left front, right rear')."""
    return ', '.join(name for name, flag in zip(WHEEL_POSITIONS, flags) if flag)


def _lift_off(run) -> tuple[float, int, float] | None:
    if not len(run.loads):
        return None
    rows = np.flatnonzero((run.loads < 0.0).any(axis=1))
    if not rows.size:
        return None
    wheel = int(np.argmin(run.loads[rows[0]]))
    return float(run.t[rows[0]]), wheel + 1, float(run.loads[rows[0], wheel])


RESIDUAL_EXPLAINED = 1e-6
"""A residual above this in a run with a reference is explained beside it (a consistent set's is rounding)."""


def format_residual(s: RunSummary) -> str:
    """The largest residual, and after the start (``topics.RESIDUAL_SETTLED_AFTER``); why it is large when the run
    tracks a reference."""
    text = f'max {s.max_residual:.3e}'
    if not math.isnan(s.max_residual_settled):
        text += f', after {RESIDUAL_SETTLED_AFTER:g} s max {s.max_residual_settled:.3e}'
    if s.max_residual > RESIDUAL_EXPLAINED and not math.isnan(s.peak_tracking_error):
        text += (' (|A qdd - b|, the least-squares misfit of a set that cannot all hold: off its reference, the '
                 "trajectory task pulls the robot onto it in directions the wheels' constraints forbid; it falls as "
                 'the robot joins its path)')
    return text


def format_summary(summary: RunSummary) -> str:
    """Lines for the terminal."""
    s = summary
    return '\n'.join([
        f'run:                 {s.path} ({s.duration:.3f} s, {s.odom_count} odometry messages)',
        ('tracking error:      none (no reference recorded: a driven run)' if math.isnan(s.peak_tracking_error) else
         f'tracking error:      final {s.final_tracking_error:.3e} m, peak {s.peak_tracking_error:.3e} m, '
         + (f'peak after 5 s {s.peak_tracking_error_after_5s:.3e} m' if s.duration >= 5.0
            else 'no peak after 5 s (the run is shorter than 5 s)')),
        f'constraint wrench:   peak |F_X| {s.peak_constraint_force_x:.3f} N, |F_Y| {s.peak_constraint_force_y:.3f} N, '
        f'|M_Z| {s.peak_constraint_torque_z:.4f} N m',
        f'drive forces:        peak |F_L| {s.peak_drive_force_left:.3f} N, |F_R| {s.peak_drive_force_right:.3f} N, '
        f'|F_lat| {s.peak_lateral_force:.3f} N',
        'constraint residual: ' + format_residual(s),
        'wheel-wall contact:  ' + ('' if all(math.isnan(use) for use in s.peak_wheel_use) else
                                   'peak friction use ' + ', '.join(f'{name} {use:.3f}' for name, use in
                                                                    zip(WHEEL_POSITIONS, s.peak_wheel_use)) + '; ')
        + ('no slip' if s.first_slip is None else f'first slip at t = {s.first_slip[0]:.3f} s ({s.first_slip[1]})')
        + ('' if s.lift_off is None else
           f'; wheel {s.lift_off[1]} lifts off at t = {s.lift_off[0]:.3f} s (normal load {s.lift_off[2]:.2f} N)'),
    ] + ([f'note:                simulation time jumped back {s.restarts} time(s) in this bag (reset or '
          f'restart of the dynamics); these figures are of the last run'] if s.restarts else []))

