"""Motor sizing from a run (``wallbot-sim motors``): what each side's motor had to deliver, what a turn in
place takes, and the adhesion force the run needed.

Per side (left, right), from a bag or a ``simulate`` CSV read through ``wallbot_sim.rundata.load_run``:

* motor torque tau_side = r F_side + the total torque on the side's two wheels
  (``wallbot_sim.model.outputs.side_motor_torques``, docs/model.md section 8): in a tracking run the
  torque motors would need to replace the trajectory task, in a driven run the applied torque;
* spin rate: the mean of the side's two wheels (the belt keeps them equal), and the side's ground
  speed r * spin rate;
* mechanical power tau_side * spin rate (positive: the motor drives, negative: it brakes).

Turning (``turning``, docs/model.md 11.5): the side torque that starts a turn in place from rest at the
worst heading, with the run's adhesion force and gravity, against the torque of a steady straight climb
(r (m_t g + f_r F) / 2 per side, the paper's way of sizing) and the differential side torque the run's
turns took, r |F_R - F_L| / 2 with each side's traction the sum of its wheels' longitudinal forces. The
largest of these, and of the run's own peak, governs the motor.

The adhesion force the run needed, when it recorded its wheels' contact: ``least_adhesion.least_adhesion``.

Samples where the run has no wheel or drive data (a bag row with NaN) are left out; the RMS is
over samples, which are uniform in time in a 1 kHz run.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from wallbot_sim.model import Robot, RobotParameters
from wallbot_sim.model.contact import WHEEL_POSITIONS
from wallbot_sim.model.outputs import DriveForces, side_motor_torques
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.rundata.least_adhesion import least_adhesion, needed_adhesion
from wallbot_sim.rundata.run_data import RunData
from wallbot_sim.rundata.turning import LEFT, flat_turn_threshold, worst_turn_start

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
    """The adhesion force the run needed, against the run's and the robot file's (N)."""

    needed: float
    """The least F keeping every wheel on the wall with its force in its friction disc, for the run's motion
    (``least_adhesion``); NaN when the run did not record its wheels' contact."""
    needed_t: float
    """When it binds (s)."""
    needed_by: str
    """The wheel that binds there, and how: e.g. 'left front wheel, friction' or 'right rear wheel, lift-off'."""
    run_adhesion: float
    """F_ad of the run, the sum of its normal loads; NaN when not recorded."""
    applied: float
    """F_ad of the robot file: k_ad F_min unless it gives adhesion_force."""
    minimum_static: float
    """F_min of the static analysis (robot at rest, docs/model.md section 3)."""
    tipping_limit: float
    """m_t g h / min(a, b)."""
    margin: float
    """The run's F_ad / needed: below 1 the run asked for more than its adhesion gives; NaN when not recorded."""
    lower_bound: bool
    """Whether wheels slid in the run: then ``needed`` is a lower bound."""


@dataclass(frozen=True)
class ContactFigures:
    """Each wheel's peak friction use, in the order of the wheels (left front, left rear, right front, right rear)."""

    peak_use: tuple[float, ...]
    peak_use_t: tuple[float, ...]
    slipped: bool
    """Whether a wheel slid in the run."""


@dataclass(frozen=True)
class TurningFigures:
    """What turning costs the side motors (N m per side unless said), with the adhesion force ``adhesion``."""

    adhesion: float
    """F (N): the run's, or the robot file's when the run did not record its loads."""
    flat_threshold: float
    """The side torque starting a turn in place with in-plane gravity negligible, mu_s F r / (2 sqrt(1 + (b/a)^2))."""
    heading: float
    """The worst heading to start a turn in place from rest (rad; NaN if the robot cannot hold still everywhere)."""
    direction: str
    """The way it turns there: 'left' or 'right'."""
    side: str
    """The side whose motor delivers ``start_torque`` there."""
    hold_torque: float
    """tau_0 = r m_t g sin(heading) / 2: each side's torque holding the robot where it stands."""
    turn_torque: float
    """T*: the differential torque at which the first wheel's force leaves its disc."""
    start_torque: float
    """|tau_0| + T*: the largest side torque a turn in place takes to start, over every heading."""
    climb_torque: float
    """r (m_t g + f_r F) / 2: a side's torque climbing straight up at a steady speed."""
    run_turn_torque: float
    """The largest differential side torque of the run, r |F_R - F_L| / 2 of its wheels' longitudinal forces
    (NaN when not recorded)."""
    run_turn_t: float
    governs: str
    """What the largest side torque is: 'turning in place', 'climbing straight up' or 'this run'."""
    governing_torque: float


@dataclass(frozen=True)
class MotorReport:
    label: str
    robot: str
    """The robot file the figures are for."""
    samples: int
    t_start: float
    t_end: float
    wheel_radius: float
    left: SideFigures
    right: SideFigures
    adsorption: AdsorptionFigures
    turning: TurningFigures
    contact: ContactFigures | None = None
    """None when the run did not record the wheel-wall contact."""

    def as_dict(self) -> dict:
        return asdict(self)


def side_series(run: RunData, wheel_radius: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{side: (motor torque, spin rate)} per sample; NaN where the run has no data."""
    torques = np.column_stack(side_motor_torques(DriveForces(run.F_left, run.F_right, run.F_lateral), run.tau.T,
                                                 wheel_radius))  # every sample at once, the same operations
    return {side: (torques[:, k], run.dphi[:, list(WHEELS[side])].mean(axis=1)) for k, side in enumerate(SIDES)}


def _side(t: np.ndarray, tau: np.ndarray, rate: np.ndarray, radius: float) -> SideFigures:
    power = tau * rate
    i_tau = int(np.argmax(np.abs(tau)))
    i_pow = int(np.argmax(np.abs(power)))
    return SideFigures(float(abs(tau[i_tau])), float(t[i_tau]), float(math.sqrt(np.mean(tau ** 2))),
                       float(np.max(np.abs(rate))), float(radius * np.max(np.abs(rate))),
                       float(abs(power[i_pow])), float(t[i_pow]),
                       float(max(np.max(power), 0.0)) + 0.0, float(max(np.max(-power), 0.0)) + 0.0)


def motor_report(run: RunData, params: RobotParameters, robot_file: str | Path = 'the robot file') -> MotorReport:
    """The motor, turning and adsorption figures of a run for the robot ``params`` (read from ``robot_file``);
    RunDataError if empty."""
    radius = params.wheel_radius
    series = side_series(run, radius)
    valid = np.isfinite(run.t) & np.isfinite(run.F_lateral)
    for tau, rate in series.values():
        valid &= np.isfinite(tau) & np.isfinite(rate)
    if not valid.any():
        raise RunDataError(f'{run.label} has no sample with wheel states and drive forces: nothing to size')
    t = run.t[valid]
    sides = {side: _side(t, tau[valid], rate[valid], radius) for side, (tau, rate) in series.items()}
    wheels = _wheel_samples(run)
    robot = Robot(params)
    adsorption = _adsorption(run, wheels, robot)
    run_peak = max(sides['left'].peak_torque, sides['right'].peak_torque)
    return MotorReport(run.label, str(robot_file), int(valid.sum()), float(t[0]), float(t[-1]), radius,
                       sides['left'], sides['right'], adsorption,
                       turning_figures(wheels, robot, adsorption.run_adhesion, run_peak),
                       None if wheels is None else _contact(wheels))


class WheelSamples(NamedTuple):
    """The samples of a run with every wheel's contact recorded."""

    t: np.ndarray
    loads: np.ndarray
    """(T, 4)."""
    use: np.ndarray
    """(T, 4)."""
    slip: np.ndarray
    """(T, 4)."""
    forces: np.ndarray
    """(T, 4, 2), body axes."""


def _wheel_samples(run: RunData) -> WheelSamples | None:
    if not len(run.loads) or not len(run.wheel_forces):
        return None
    valid = (np.all(np.isfinite(run.loads), axis=1) & np.all(np.isfinite(run.use), axis=1)
             & np.all(np.isfinite(run.wheel_forces), axis=(1, 2)))
    if not valid.any():
        return None
    return WheelSamples(run.t[valid], run.loads[valid], run.use[valid], np.nan_to_num(run.slip[valid]),
                        run.wheel_forces[valid])


def adhesion_margins(run: RunData, params: RobotParameters) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, the adhesion force pressing the robot over the least it needed there) at each sample with every wheel's
    contact recorded; None when the run recorded none."""
    wheels = _wheel_samples(run)
    if wheels is None:
        return None
    return wheels.t, wheels.loads.sum(axis=1) / needed_adhesion(wheels.loads, wheels.forces, Robot(params))


def _contact(wheels: WheelSamples) -> ContactFigures:
    peaks = np.argmax(wheels.use, axis=0)
    return ContactFigures(tuple(float(wheels.use[k, i]) for i, k in enumerate(peaks)),
                          tuple(float(wheels.t[k]) for k in peaks), bool(wheels.slip.any()))


def _adsorption(run: RunData, wheels: WheelSamples | None, robot: Robot) -> AdsorptionFigures:
    analysis = robot.adsorption
    sums = run.loads.sum(axis=1) if len(run.loads) else np.empty(0)
    sums = sums[np.isfinite(sums)]
    run_adhesion = _median(sums) if sums.size else math.nan
    if wheels is None:
        return AdsorptionFigures(math.nan, math.nan, 'not recorded', run_adhesion, float(analysis.applied_force),
                                 float(analysis.minimum_force), float(analysis.tipping_limit), math.nan, False)
    needed, k, wheel, lift_off = least_adhesion(wheels.loads, wheels.forces, robot)
    return AdsorptionFigures(needed, float(wheels.t[k]),
                             f'{WHEEL_POSITIONS[wheel]} wheel, {"lift-off" if lift_off else "friction"}',
                             run_adhesion, float(analysis.applied_force), float(analysis.minimum_force),
                             float(analysis.tipping_limit), run_adhesion / needed, bool(wheels.slip.any()))


def _median(values: np.ndarray) -> float:
    """np.median of finite ``values`` (the mean of the middle one or two) without its general machinery."""
    count = len(values)
    return float(np.mean(np.sort(values)[(count - 1) // 2:count // 2 + 1]))


def turning_figures(wheels: WheelSamples | None, robot: Robot, run_adhesion: float,
                    run_peak: float) -> TurningFigures:
    """What turning costs (``TurningFigures``) the robot; the run's adhesion force unless NaN (then the robot
    file's)."""
    params = robot.params
    adhesion = run_adhesion if math.isfinite(run_adhesion) else float(robot.adsorption.applied_force)
    radius = params.wheel_radius
    climb = 0.5 * radius * (robot.total_mass * params.gravity + params.rolling_resistance * adhesion)
    start = worst_turn_start(params, adhesion)
    run_turn, run_turn_t = math.nan, math.nan
    if wheels is not None:
        longitudinal = wheels.forces[:, :, 0]
        differential = 0.5 * radius * np.abs(longitudinal[:, 2] + longitudinal[:, 3] - longitudinal[:, 0]
                                             - longitudinal[:, 1])
        k = int(np.argmax(differential))
        run_turn, run_turn_t = float(differential[k]), float(wheels.t[k])
    if start is None:
        heading, direction, side, hold, turn, start_torque = math.nan, '', '', math.nan, math.nan, math.nan
    else:
        heading, direction, hold, turn, start_torque = (start.heading, start.direction, start.hold_torque,
                                                        start.turn_torque, start.side_torque)
        pushes_right = (direction == LEFT) == (hold >= 0.0)
        side = 'right' if pushes_right else 'left'
    candidates = {'turning in place': start_torque, 'climbing straight up': climb, 'this run': run_peak}
    governs = max((name for name in candidates if math.isfinite(candidates[name])), key=candidates.get)
    return TurningFigures(adhesion, flat_turn_threshold(params, adhesion), heading, direction, side, hold, turn,
                          start_torque, climb, run_turn, run_turn_t, governs, candidates[governs])


def format_report(report: MotorReport) -> str:
    """The table ``wallbot-sim motors`` prints."""
    a, turning = report.adsorption, report.turning
    lines = [f'Run:    {report.label}: {report.samples} samples, t = {report.t_start:.3f} .. {report.t_end:.3f} s',
             f'Robot:  {report.robot} (wheel radius {report.wheel_radius:g} m)',
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
    run_peak = max(report.left.peak_torque, report.right.peak_torque)
    lines += ['', *_turning_lines(turning, run_peak), '', *_adhesion_lines(a)]
    c = report.contact
    if c is not None:
        lines += ['', 'Friction use (peak):  ' + ', '.join(
            f'{name} {use:.3f} at t = {t:.3f} s' for name, use, t in zip(WHEEL_POSITIONS, c.peak_use, c.peak_use_t))]
    return '\n'.join(lines)


def _turning_lines(turning: TurningFigures, run_peak: float) -> list[str]:
    f = turning
    lines = [f'Turning in place from rest, adhesion {f.adhesion:.2f} N (side torque to start it: the first wheel '
             'leaves its friction disc):']
    if math.isfinite(f.heading):
        lines.append(f'  worst heading {math.degrees(f.heading):.1f} deg (90: facing up), turning {f.direction}: '
                     f'{f.start_torque:.4f} N m on the {f.side} side (holding {abs(f.hold_torque):.4f} + turning '
                     f'{f.turn_torque:.4f} N m)')
    else:
        lines.append('  the robot cannot hold still at every heading with this adhesion: it slides or peels off '
                     'before any turn')
    lines += [f'  with gravity negligible: {f.flat_threshold:.4f} N m per side (mu_s F r / (2 sqrt(1 + (b/a)^2)))',
              f'Climbing straight up at a steady speed: {f.climb_torque:.4f} N m per side (r (m_t g + f_r F) / 2)',
              "This run's turns: " + ('not recorded (no wheel forces)' if math.isnan(f.run_turn_torque) else
                                      f'{f.run_turn_torque:.4f} N m differential side torque at most, '
                                      f"r |F_R - F_L| / 2 of the wheels' forces (t = {f.run_turn_t:.3f} s)"),
              f'Sizing: {f.governs} governs, {f.governing_torque:.4f} N m per side (turning in place '
              f'{f.start_torque:.4f}, climbing straight up {f.climb_torque:.4f}, this run {run_peak:.4f} N m)']
    return lines


def _adhesion_lines(a: AdsorptionFigures) -> list[str]:
    if math.isnan(a.needed):
        needed = ['Adhesion needed: not known (the run did not record its wheels\' contact)']
    else:
        needed = [f'Adhesion needed: {a.needed:.2f} N ({a.needed_by} binds at t = {a.needed_t:.3f} s): the least '
                  'adhesion force keeping every wheel on the wall with its force inside its friction disc, for '
                  "this run's motion" + (' - a lower bound: wheels slid, so their forces are the kinetic friction '
                                         'they transmitted' if a.lower_bound else '')]
    run = '' if math.isnan(a.run_adhesion) else f'Adhesion of the run: {a.run_adhesion:.2f} N; '
    margin = '' if math.isnan(a.margin) else f'margin {a.margin:.2f}; '
    lines = needed + [f'{run}{margin}the robot file applies {a.applied:.2f} N (static minimum '
                      f'{a.minimum_static:.2f} N, tipping limit {a.tipping_limit:.2f} N)']
    if a.margin < 1.0:
        lines.append('WARNING: the run needed more adhesion than it had: on a real wall its wheels would slide or '
                     'lift off')
    return lines
