"""Motor sizing from a run (``wallbot-sim motors``): what each side's motor had to deliver.

Per side (left, right), from a bag or a ``simulate`` CSV read through ``wallbot_sim.rundata.load_run``:

* motor torque tau_side = r F_side + the total torque on the side's two wheels
  (``wallbot_sim.model.outputs.side_motor_torques``, docs/model.md section 8): in a tracking run the
  torque motors would need to replace the trajectory task, in a driven run the applied torque;
* spin rate: the mean of the side's two wheels (the belt keeps them equal), and the side's ground
  speed r * spin rate;
* mechanical power tau_side * spin rate (positive: the motor drives, negative: it brakes).

Adsorption the run needed, per instant: the wall supplies the traction F_L + F_R and the lateral
force F_lat by friction, and the press must keep the robot from tipping, so
F_needed = max(m_t g h / min(a, b), |(F_L + F_R, F_lat)| / mu), compared with the applied
F_ad = k_ad F_min of ``wallbot_sim.model.adsorption_analysis``. This is the whole robot's
friction budget (F_ad shared equally by the four wheels), not a per-wheel check.

Wheel-wall contact (docs/model.md 11), when the run recorded it: the peak friction use of each channel,
and the least adhesion force F that would have kept every channel sticking and every wheel on the
wall. The loads are affine in F for the same motion, N_i(F) = N_i + (F - F_run) / 4 with
F_run = sum N_i, so per sample: F >= F_run - 4 N_i (wheel on the wall), |F_k| <= mu_s N_k(F) for
each side k (N_k(F) = N_k + (F - F_run) / 2) and |F_lat| <= mu_s F; the least F is the largest
bound over the run. Exact for a run that stuck throughout, up to the rolling resistance f_r F,
which changes with F; in a run that slipped, the channel forces are what friction transmitted,
so the figure is a lower bound.

Samples where the run has no wheel or drive data (a bag row with NaN) are left out; the RMS is
over samples, which are uniform in time in a 1 kHz run.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from wallbot_sim.model import RobotParameters, adsorption_analysis
from wallbot_sim.model.outputs import DriveForces, side_motor_torques
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.rundata.load import RunData

SIDES = ('left', 'right')
WHEELS = {'left': (0, 1), 'right': (2, 3)}
"""Columns of RunData.dphi / RunData.tau per side (order of topics.WHEEL_JOINTS)."""


@dataclass(frozen=True)
class SideFigures:
    """One side's motor requirements over the run (SI units)."""

    peak_torque: float
    """max |tau_side| (N m)."""
    peak_torque_t: float
    """When it occurred (s)."""
    rms_torque: float
    """sqrt(mean(tau_side^2)) (N m): the continuous (thermal) requirement."""
    peak_spin_rate: float
    """max |spin rate| of the side (rad/s)."""
    peak_ground_speed: float
    """r * peak_spin_rate (m/s)."""
    peak_power: float
    """max |tau_side * spin rate| (W)."""
    peak_power_t: float
    peak_drive_power: float
    """max(tau_side * spin rate, 0): the largest power the motor delivers (W)."""
    peak_brake_power: float
    """max(-tau_side * spin rate, 0): the largest power it absorbs (W)."""


@dataclass(frozen=True)
class AdsorptionFigures:
    """The adsorption force the run needed against the one the robot file applies (N)."""

    peak_needed: float
    peak_needed_t: float
    tipping_limit: float
    """m_t g h / min(a, b): needed at every instant."""
    peak_friction_needed: float
    """max |(F_L + F_R, F_lat)| / mu over the run."""
    applied: float
    """F_ad = k_ad F_min."""
    minimum_static: float
    """F_min of the static analysis (robot at rest)."""
    margin: float
    """applied / peak_needed: below 1 the run asked for more friction than the wall can give."""


@dataclass(frozen=True)
class ContactFigures:
    """Friction use and the adhesion force the run needed by its per-channel loads."""

    peak_use: tuple[float, float, float]
    """max friction use of the left, right and lateral channels."""
    peak_use_t: tuple[float, float, float]
    least_adhesion: float
    """The least F_ad keeping every channel sticking and every wheel on the wall (N)."""
    least_adhesion_t: float
    least_adhesion_by: str
    """What binds at that instant: 'left', 'right', 'lateral' or a wheel ('wheel 1' .. 'wheel 4')."""
    run_adhesion: float
    """F_ad of the run (the sum of its normal loads) (N)."""
    slipped: bool
    """Whether a channel slipped in the run: then least_adhesion is a lower bound."""


@dataclass(frozen=True)
class MotorReport:
    label: str
    samples: int
    t_start: float
    t_end: float
    wheel_radius: float
    left: SideFigures
    right: SideFigures
    adsorption: AdsorptionFigures
    contact: ContactFigures | None = None
    """None when the run did not record the wheel-wall contact."""

    def as_dict(self) -> dict:
        return asdict(self)


def side_series(run: RunData, wheel_radius: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{side: (motor torque, spin rate)} per sample; NaN where the run has no data."""
    torques = np.array([side_motor_torques(DriveForces(fl, fr, 0.0), wheel, wheel_radius)
                        for fl, fr, wheel in zip(run.F_left, run.F_right, run.tau)], dtype=float).reshape(len(run), 2)
    return {side: (torques[:, k], run.dphi[:, list(WHEELS[side])].mean(axis=1)) for k, side in enumerate(SIDES)}


def _side(t: np.ndarray, tau: np.ndarray, rate: np.ndarray, radius: float) -> SideFigures:
    power = tau * rate
    i_tau = int(np.argmax(np.abs(tau)))
    i_pow = int(np.argmax(np.abs(power)))
    return SideFigures(float(abs(tau[i_tau])), float(t[i_tau]), float(math.sqrt(np.mean(tau ** 2))),
                       float(np.max(np.abs(rate))), float(radius * np.max(np.abs(rate))),
                       float(abs(power[i_pow])), float(t[i_pow]),
                       float(max(np.max(power), 0.0)) + 0.0, float(max(np.max(-power), 0.0)) + 0.0)


def motor_report(run: RunData, params: RobotParameters) -> MotorReport:
    """The motor and adsorption figures of a run for the robot ``params``; RunDataError if empty."""
    radius = params.wheel_radius
    series = side_series(run, radius)
    valid = np.isfinite(run.t) & np.isfinite(run.F_lateral)
    for tau, rate in series.values():
        valid &= np.isfinite(tau) & np.isfinite(rate)
    if not valid.any():
        raise RunDataError(f'{run.label} has no sample with wheel states and drive forces: nothing to size')
    t = run.t[valid]
    sides = {side: _side(t, tau[valid], rate[valid], radius) for side, (tau, rate) in series.items()}
    analysis = adsorption_analysis(params)
    friction = np.hypot(run.F_left[valid] + run.F_right[valid], run.F_lateral[valid]) / params.wall_friction
    needed = np.maximum(analysis.tipping_limit, friction)
    i = int(np.argmax(needed))
    adsorption = AdsorptionFigures(float(needed[i]), float(t[i]), float(analysis.tipping_limit),
                                   float(np.max(friction)), float(analysis.applied_force),
                                   float(analysis.minimum_force), float(analysis.applied_force / needed[i]))
    return MotorReport(run.label, int(valid.sum()), float(t[0]), float(t[-1]), radius,
                       sides['left'], sides['right'], adsorption, contact_figures(run, params))


def contact_figures(run: RunData, params: RobotParameters) -> ContactFigures | None:
    """Peak friction use and least adhesion force of ``run``; None without contact data."""
    if not len(run.loads):
        return None
    valid = np.all(np.isfinite(run.loads), axis=1) & np.all(np.isfinite(run.use), axis=1) & np.isfinite(run.F_lateral)
    if not valid.any():
        return None
    t, loads, use = run.t[valid], run.loads[valid], run.use[valid]
    forces = np.column_stack((run.F_left[valid], run.F_right[valid], run.F_lateral[valid]))
    run_force = loads.sum(axis=1)
    static = params.wall_friction
    bounds = np.column_stack((
        run_force - 2.0 * (loads[:, 0] + loads[:, 1]) + 2.0 * np.abs(forces[:, 0]) / static,
        run_force - 2.0 * (loads[:, 2] + loads[:, 3]) + 2.0 * np.abs(forces[:, 1]) / static,
        np.abs(forces[:, 2]) / static,
        run_force[:, None] - 4.0 * loads))
    names = ('left', 'right', 'lateral', 'wheel 1', 'wheel 2', 'wheel 3', 'wheel 4')
    i, j = np.unravel_index(int(np.argmax(bounds)), bounds.shape)
    peaks = np.argmax(use, axis=0)
    return ContactFigures(tuple(float(use[k, c]) for c, k in enumerate(peaks)), tuple(float(t[k]) for k in peaks),
                          float(bounds[i, j]), float(t[i]), names[j], float(np.median(run_force)),
                          bool(np.nan_to_num(run.slip[valid]).any()))


def format_report(report: MotorReport, robot: str | Path | None = None) -> str:
    """The table ``wallbot-sim motors`` prints."""
    a = report.adsorption
    lines = [f'Run:    {report.label}: {report.samples} samples, t = {report.t_start:.3f} .. {report.t_end:.3f} s',
             f'Robot:  {robot or "config/robot.yaml"} (wheel radius {report.wheel_radius:g} m)',
             '',
             f'{"side":<6} {"peak |tau|":>11} {"at t":>8} {"RMS tau":>9} {"peak |w|":>9} {"peak speed":>11} '
             f'{"peak |P|":>9} {"drive P":>8} {"brake P":>8}',
             f'{"":<6} {"(N m)":>11} {"(s)":>8} {"(N m)":>9} {"(rad/s)":>9} {"(m/s)":>11} '
             f'{"(W)":>9} {"(W)":>8} {"(W)":>8}']
    for side in SIDES:
        s: SideFigures = getattr(report, side)
        lines.append(f'{side:<6} {s.peak_torque:11.4f} {s.peak_torque_t:8.3f} {s.rms_torque:9.4f} '
                     f'{s.peak_spin_rate:9.3f} {s.peak_ground_speed:11.4f} {s.peak_power:9.4f} '
                     f'{s.peak_drive_power:8.4f} {s.peak_brake_power:8.4f}')
    lines += ['',
              f'Adsorption needed: {a.peak_needed:.2f} N peak at t = {a.peak_needed_t:.3f} s '
              f'(tipping limit {a.tipping_limit:.2f} N, friction needed up to {a.peak_friction_needed:.2f} N)',
              f'Adsorption applied: {a.applied:.2f} N (k_ad x static minimum {a.minimum_static:.2f} N); '
              f'margin applied/needed {a.margin:.2f}']
    if a.margin < 1.0:
        lines.append('WARNING: the run needed more adsorption than the robot applies: on a real wall it would slip')
    c = report.contact
    if c is not None:
        lines += ['',
                  'Friction use (peak):  ' + ', '.join(f'{name} {use:.3f} at t = {t:.3f} s' for name, use, t in
                                                       zip(('left', 'right', 'lateral'), c.peak_use, c.peak_use_t)),
                  f'Least adhesion force: {c.least_adhesion:.2f} N to keep every channel sticking and every wheel on '
                  f'the wall ({c.least_adhesion_by} binds at t = {c.least_adhesion_t:.3f} s; this run had '
                  f'{c.run_adhesion:.2f} N)' + (' - a lower bound: channels slipped, so the forces are the kinetic '
                                                'friction they transmitted' if c.slipped else '')]
    return '\n'.join(lines)
