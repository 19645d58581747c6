"""A controller test's short report: ``report.md`` beside the bag, the verdicts and the run, with a figure of each
failing quantity against time (``plots/FAILED.png``: its limit, the worst instant, the faults of the run)."""

from __future__ import annotations

import math
from pathlib import Path

from wallbot_sim.plots.expectations import Limit, write_expectation_figure
from wallbot_sim.rundata import RunData
from wallbot_sim.rundata.motors import adhesion_margins, side_series
from wallbot_sim.testing.expectations import Verdict
from wallbot_sim.testing.outcome import RUN, Outcome, recorded_run, robot_parameters

CHANNELS = ('left', 'right', 'lateral')


def write_report(outcome: Outcome, out: Path) -> Path:
    """``out/report.md`` and the figures of the failing expectations in ``out/plots``; the report's path."""
    run = recorded_run(outcome.bag)
    figures = {}
    if run is not None:
        events = [(event.stamp_ns * 1e-9, ', '.join(event.changed)) for event in outcome.faults]
        for verdict in outcome.failed:
            if verdict.name != RUN:
                figures[verdict.name] = failing_figure(verdict, run, outcome, out / 'plots', events)
    spec = outcome.spec
    lines = [f'# {spec.name}: {"passed" if outcome.passed else "FAILED"}', '',
             f'Scenario {spec.scenario}, {spec.contact} contact, {outcome.duration:g} s, the controller publishing '
             f'{spec.drive} at {spec.rate} Hz: `{" ".join(spec.controller)}`.', '',
             '| expectation | verdict | measured | limit | worst at t (s) |', '|---|---|---|---|---|']
    for verdict in (outcome.run_verdict, *outcome.verdicts):
        word = {True: 'pass', False: '**FAIL**', None: 'not judged'}[verdict.passed]
        worst = f'{verdict.worst_t:.3f}' if math.isfinite(verdict.worst_t) else ''
        lines.append(f'| {verdict.name} | {word} | {verdict.measured:.4g} {verdict.unit} | {verdict.limit:g} '
                     f'{verdict.unit} | {worst} |')
    lines += ['', *(f'- {verdict.line()}' for verdict in (outcome.run_verdict, *outcome.verdicts))]
    if outcome.faults:
        lines += ['', 'Faults recorded in the bag:', '']
        lines += [f'- t = {event.stamp_ns * 1e-9:.3f} s: {", ".join(event.changed)} ({event.cause}); then '
                  + ', '.join(f'{name} {value}' for name, value in event.values.items()) for event in outcome.faults]
    if figures:
        lines += ['', *(f'![{name}](plots/{path.name})' for name, path in figures.items())]
    lines += ['', f'Bag: `{outcome.bag}`; logs: `{out / "logs"}`.', '']
    path = out / 'report.md'
    path.write_text('\n'.join(lines), encoding='utf-8')
    return path


def failing_figure(verdict: Verdict, run: RunData, outcome: Outcome, folder: Path,
                   events: list[tuple[float, str]]) -> Path:
    """The figure of the quantity ``verdict`` judged, over ``run``."""
    name, title = verdict.name, f'{verdict.name}: {verdict.detail}'
    if name == 'max_tracking_error_after':
        start = outcome.spec.expect.max_tracking_error_after[0]
        series, ylabel, limit = {'tracking error': run.err}, 'tracking error (m)', Limit(verdict.limit, start)
    elif name == 'max_motor_torque':
        sides = side_series(run, robot_parameters(outcome.spec).wheel_radius)
        series = {f'{side} motor': torque for side, (torque, _rate) in sides.items()}
        ylabel, limit = 'side torque (N m)', Limit(verdict.limit, mirrored=True)
    elif name == 'no_slip':
        series = {f'friction use {label}': run.use[:, k] for k, label in enumerate(_labels(run.use.shape[1]))}
        ylabel, limit = 'friction use', Limit(verdict.limit)
    elif name == 'no_detachment':
        series = {f'wheel {k + 1}': run.loads[:, k] for k in range(run.loads.shape[1])}
        ylabel, limit = 'normal load (N)', Limit(0.0)
    else:  # min_adhesion_margin, at the samples with every wheel's contact (judged so there was one)
        t, margin = adhesion_margins(run, robot_parameters(outcome.spec))
        return write_expectation_figure(folder / f'{name}.png', title, t, {'adhesion margin': margin},
                                        'applied / needed adhesion force', Limit(verdict.limit), verdict.worst_t,
                                        events)
    return write_expectation_figure(folder / f'{name}.png', title, run.t, series, ylabel, limit, verdict.worst_t,
                                    events)


def _labels(count: int) -> tuple[str, ...]:
    """The names of the friction use columns: the channels (3), else the wheels."""
    return CHANNELS if count == len(CHANNELS) else tuple(f'wheel {k + 1}' for k in range(count))
