"""The expectations of a controller test, judged from what the run recorded (``wallbot_sim.rundata``).

Each gives a :class:`Verdict`: whether it holds, the figure measured and its limit, and the simulation time of the
worst instant. The figures are the run data layer's own: the tracking error of ``RunData`` (the recorded plan's
reference), the first slip and lift-off of the run summary (``summary.summarize_run``), the motor torque per side of
the motor report (``motors.motor_report``, what ``wallbot-sim motors`` prints) and the adhesion needed sample by
sample (``motors.adhesion_margins``).

* ``max_tracking_error_after {t, m}``: the largest distance of the centre from the reference from ``t`` on, at most
  ``m`` metres;
* ``no_slip``: no wheel slips (coulomb contact) and the friction use stays at most 1 (ideal contact, whose wheels
  cannot slip: the friction the motion needed stays within mu_s N);
* ``no_detachment``: every wheel's normal load stays >= 0 (a coulomb run whose robot leaves the wall ends there);
* ``min_adhesion_margin``: the least over the run of the adhesion force pressing the robot (its normal loads' sum)
  over the least force keeping every wheel on the wall with its force in its friction disc at that instant
  (``motors.adhesion_margins``; the motor report's margin is the run's median force over the largest needed);
* ``max_motor_torque``: the largest side torque the motors delivered, N m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wallbot_sim.model import RobotParameters
from wallbot_sim.rundata import RunData, RunDataError
from wallbot_sim.rundata.motors import adhesion_margins, motor_report
from wallbot_sim.rundata.summary import RunSummary, summarize_run
from wallbot_sim.testing.spec import Expectations

FRICTION_LIMIT = 1.0
"""The friction use at which a wheel's force reaches mu_s N."""
ROUND_OFF = 1e-9


@dataclass(frozen=True)
class Verdict:
    """One expectation's judgement. ``passed`` None: it could not be judged (``detail`` says why)."""

    name: str
    passed: bool | None
    measured: float
    limit: float
    unit: str
    worst_t: float
    """Simulation time of the worst instant (s; NaN if none)."""
    detail: str

    def line(self) -> str:
        """One line: PASS/FAIL/SKIP, the name, what was measured against what."""
        word = {True: 'PASS', False: 'FAIL', None: 'SKIP'}[self.passed]
        return f'{word} {self.name}: {self.detail}'


@dataclass(frozen=True)
class Ending:
    """How a run that did not cover its duration ended: at ``t`` (s), because ``reason``; ``detached``: the robot
    left the wall."""

    t: float
    reason: str
    detached: bool = False


def judge(expect: Expectations, run: RunData | None, params: RobotParameters, ending: Ending | None) -> list[Verdict]:
    """The verdict of each expectation of ``expect`` on ``run`` (None: nothing recorded) of the robot ``params``."""
    if run is None or not len(run):
        return [Verdict(name, None, math.nan, math.nan, '', math.nan, 'not judged: the run recorded no state')
                for name in expect.names()]
    summary = summarize_run(run, 'run')
    judges = {'max_tracking_error_after': lambda: tracking(run, *expect.max_tracking_error_after),
              'no_slip': lambda: no_slip(run, summary),
              'no_detachment': lambda: no_detachment(run, summary, ending),
              'min_adhesion_margin': lambda: adhesion_margin(run, params, expect.min_adhesion_margin),
              'max_motor_torque': lambda: motor_torque(run, params, expect.max_motor_torque)}
    return [judges[name]() for name in expect.names()]


def tracking(run: RunData, after: float, limit: float) -> Verdict:
    name = 'max_tracking_error_after'
    late = (run.t >= after - ROUND_OFF) & np.isfinite(run.err)
    if not late.any():
        return Verdict(name, None, math.nan, limit, 'm', math.nan,
                       f'not judged: no state with a reference from t = {after:g} s on')
    k = int(np.flatnonzero(late)[np.argmax(run.err[late])])
    error = float(run.err[k])
    return Verdict(name, error <= limit, error, limit, 'm', float(run.t[k]),
                   f'tracking error from t = {after:g} s at most {error:.4g} m (limit {limit:g} m), largest at '
                   f't = {run.t[k]:.3f} s')


def no_slip(run: RunData, summary: RunSummary) -> Verdict:
    name = 'no_slip'
    use = run.use if len(run.use) else np.full((len(run), 1), math.nan)
    peaks = np.nanmax(np.where(np.isfinite(use), use, -math.inf), axis=1)
    if not np.isfinite(peaks).any():
        return Verdict(name, None, math.nan, FRICTION_LIMIT, '', math.nan, 'not judged: no wheel contact recorded')
    k = int(np.argmax(peaks))
    peak = float(peaks[k])
    if summary.first_slip is not None:
        t, wheels = summary.first_slip
        return Verdict(name, False, peak, FRICTION_LIMIT, '', t,
                       f'slips first at t = {t:.3f} s ({wheels}); friction use up to {peak:.3f}')
    held = peak <= FRICTION_LIMIT + ROUND_OFF
    return Verdict(name, held, peak, FRICTION_LIMIT, '', float(run.t[k]),
                   f'friction use at most {peak:.3f} (limit {FRICTION_LIMIT:g}{"" if held else ": the wall cannot give it"})'
                   f', largest at t = {run.t[k]:.3f} s')


def no_detachment(run: RunData, summary: RunSummary, ending: Ending | None) -> Verdict:
    name = 'no_detachment'
    loads = run.loads if len(run.loads) else np.full((len(run), 1), math.nan)
    least = np.nanmin(np.where(np.isfinite(loads), loads, math.inf), axis=1)
    k = int(np.argmin(least)) if np.isfinite(least).any() else None
    measured = float(least[k]) if k is not None else math.nan
    if ending is not None and ending.detached:
        return Verdict(name, False, measured, 0.0, 'N', ending.t, f'the robot left the wall at t = {ending.t:.3f} s: '
                                                                  f'{ending.reason}')
    if k is None:
        return Verdict(name, None, math.nan, 0.0, 'N', math.nan, 'not judged: no normal load recorded')
    if summary.lift_off is not None:
        t, wheel, load = summary.lift_off
        return Verdict(name, False, measured, 0.0, 'N', t,
                       f'wheel {wheel} lifts off at t = {t:.3f} s (normal load {load:.2f} N); least load {measured:.2f} N')
    return Verdict(name, True, measured, 0.0, 'N', float(run.t[k]),
                   f'least normal load {measured:.2f} N (limit 0 N) at t = {run.t[k]:.3f} s')


def adhesion_margin(run: RunData, params: RobotParameters, limit: float) -> Verdict:
    name = 'min_adhesion_margin'
    margins = adhesion_margins(run, params)
    if margins is None:
        return Verdict(name, None, math.nan, limit, '', math.nan, 'not judged: the run recorded no wheel contact')
    t, margin = margins
    k = int(np.argmin(margin))
    least = float(margin[k])
    return Verdict(name, least >= limit, least, limit, '', float(t[k]),
                   f'adhesion margin at least {least:.3f} (limit {limit:g}), least at t = {t[k]:.3f} s: '
                   f'the adhesion pressing the robot over the least that holds every wheel there')


def motor_torque(run: RunData, params: RobotParameters, limit: float) -> Verdict:
    name = 'max_motor_torque'
    try:
        report = motor_report(run, params)
    except RunDataError as error:
        return Verdict(name, None, math.nan, limit, 'N m', math.nan, f'not judged: {error}')
    side, figures = max((('left', report.left), ('right', report.right)), key=lambda item: item[1].peak_torque)
    peak, t = figures.peak_torque, figures.peak_torque_t
    return Verdict(name, peak <= limit, peak, limit, 'N m', t,
                   f'motor torque at most {peak:.3f} N m (limit {limit:g} N m), largest on the {side} side at '
                   f't = {t:.3f} s')
