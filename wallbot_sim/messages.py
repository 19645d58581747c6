"""The simulator's side of the interface: model objects as the graph's messages and back.

``wallbot_msgs_py.codec`` encodes and decodes each message in plain numbers and knows no model;
this module adds what needs the model: the plan a trajectory node publishes and how a follower
interpolates it, the reference pose with its tangent heading, the constraint switches as a
``ConstraintSelection``, and the dynamics' diagnostics. The nodes and ``simulate --bag`` both
use it, so a headless bag holds the graph's messages. No ROS import.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Mapping, Sequence

from wallbot_msgs_py import cdr, codec, topics
from wallbot_msgs_py.constraint_modules import CONSTRAINT_MODULES
from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.constraints import BaumgarteGains
from wallbot_sim.model.contact import IDEAL, WHEEL_POSITIONS
from wallbot_sim.model.outputs import ContactOutputs
from wallbot_sim.model.robot import Adsorption
from wallbot_sim.model.trajectories import Plan, Reference, ReferenceSample, SampledReference, sample_plan, tangent_heading

# --- the trajectory node's plans --------------------------------------------------------------
SAMPLE_DT = 0.05
"""Default plan sample spacing (s)."""
HORIZON = 10.0
"""Default span of a plan of an endless reference (s); it is renewed at half-way."""
PUBLISH_RATE_HZ = 100.0
"""Default rate of the reference pose, in simulation time."""

# --- /clock -------------------------------------------------------------------------------------
CLOCK_RATE_HZ = 10.0
"""Default rate of /clock in simulation time, as gazebo_ros publishes it. Every node with
use_sim_time pays a callback per /clock message, and none of the graph's needs more: the
controller follows odometry, the trajectory node replans every few seconds and publishes its
100 Hz reference poses for the grid points each /clock has passed."""


class ClockSchedule:
    """Which states /clock is published for: the first of every period of 1 / ``rate_hz`` seconds of
    simulation time (on a grid of 1 ms steps and 100 Hz, the states at multiples of 10 ms), and
    every state marked ``final`` (the last before a stop, the state at a start or reset), so the
    newest /clock is the newest state whenever the simulation waits."""

    def __init__(self, rate_hz: float) -> None:
        self.period_ns = max(1, round(1e9 / rate_hz))
        self._last_period: int | None = None
        self._last_ns: int | None = None

    def due(self, t_ns: int, final: bool = False) -> bool:
        """Whether the state at ``t_ns`` carries /clock (call once per state, in order)."""
        period = t_ns // self.period_ns
        if not (final or period != self._last_period or t_ns < self._last_ns):
            return False
        self._last_period, self._last_ns = period, t_ns
        return True


def plan_ahead(reference: Reference, now: float, sample_dt: float = SAMPLE_DT, horizon: float = HORIZON,
               rest_at: float | None = None) -> Plan:
    """The plan ``horizon`` seconds ahead of ``now``, or up to ``rest_at`` (plus a sample) for a
    reference that comes to rest sooner: a plan never grows with the run's length, so no subscriber
    has to decode an unbounded one.

    It starts a sample before ``now`` (on the grid, from t = 0 at the earliest): a follower at
    ``now`` then interpolates the segment the plan before gave it, to the bit. From ``now`` itself
    on the grid, the first sample's stamp could read back a rounding after ``now``.
    """
    end = now + horizon
    if rest_at is not None:
        end = max(min(end, rest_at + sample_dt), now)
    return sample_plan(reference, max(now - sample_dt, 0.0), end, sample_dt)


def replan_due(plan: Plan, now: float) -> bool:
    """Whether simulation time ``now`` has passed the middle of a plan that does not end at rest."""
    return not plan_is_final(plan) and now > 0.5 * (plan.times[0] + plan.times[-1])


def plan_is_final(plan: Plan, tolerance: float = 1e-12) -> bool:
    """True if the plan ends at rest (zero velocity and acceleration at its last sample).

    Holding the last point after such a plan is the exact continuation of the reference, so
    the dynamics may run past its end; a plan that ends moving only covers up to its end.
    """
    (vx, vy), (ax, ay) = plan.velocities[-1], plan.accelerations[-1]
    return max(abs(vx), abs(vy), abs(ax), abs(ay)) <= tolerance


def plan_sample_times(plan: Plan) -> list[float]:
    """The sample times of a plan as a follower sees them (through integer nanoseconds)."""
    return [codec.to_nanoseconds(t) * 1e-9 for t in plan.times]


def sampled_reference(plan: Plan) -> SampledReference:
    """The reference a follower interpolates from ``plan`` (quintic Hermite): identical to the
    one decoded from ``trajectory_message(plan)``, without building the message."""
    return SampledReference(plan_sample_times(plan), plan.positions, plan.velocities, plan.accelerations)


def plan_headings(plan: Plan, fallback_yaw: float = 0.0) -> list[tuple[float, float]]:
    """Tangent heading and its rate at each sample (the last heading carried over where at rest)."""
    result, yaw = [], fallback_yaw
    for p, v, a in zip(plan.positions, plan.velocities, plan.accelerations):
        heading = tangent_heading(ReferenceSample(p, v, a, (0.0, 0.0)))
        if heading is None:
            result.append((yaw, 0.0))
        else:
            yaw = heading.angle
            result.append((yaw, heading.rate))
    return result


def trajectory_message(plan: Plan, fallback_yaw: float = 0.0, frame: str = topics.WALL_FRAME) -> bytes:
    """``reference_trajectory`` of ``plan`` (CDR) in ``frame`` (the wall)."""
    return codec.trajectory(codec.PlanSamples(*plan), plan_headings(plan, fallback_yaw), frame)


def path_message(plan: Plan, max_poses: int = 2000, fallback_yaw: float = 0.0,
                 frame: str = topics.WALL_FRAME) -> bytes:
    """``reference_path`` (CDR) in ``frame`` (the wall): the plan's points with their tangent
    heading, at most ``max_poses`` (evenly strided, the last point always kept)."""
    stride = max(1, -(-len(plan.times) // max_poses))
    indices = list(range(0, len(plan.times), stride))
    if indices[-1] != len(plan.times) - 1:
        indices.append(len(plan.times) - 1)
    headings = plan_headings(plan, fallback_yaw)
    return codec.path([(plan.times[i], *plan.positions[i], headings[i][0]) for i in indices], plan.times[0],
                      frame)


def plan_from_cdr(data: bytes) -> Plan:
    """The plan of a serialized ``reference_trajectory``; ValueError if it is not a usable plan."""
    return Plan(*codec.decode_plan(data))


def reference_message(sample: ReferenceSample, t: float, fallback_yaw: float = 0.0,
                      frame: str = topics.WALL_FRAME) -> tuple[bytes, float]:
    """``reference`` at time t (CDR, pose in ``frame``, the wall) and the heading it carries.

    The child frame ``reference`` points along the path (the tangent heading; ``fallback_yaw``
    while the reference is at rest), so the twist is (speed, 0, turning rate) in that frame,
    like the odometry of a robot driving the path exactly.
    """
    heading = tangent_heading(sample)
    yaw = heading.angle if heading is not None else fallback_yaw
    rate = heading.rate if heading is not None else 0.0
    data = _reference_encoder(frame).encode(*cdr.split_stamp(cdr.to_nanoseconds(t)), (*sample.position, yaw),
                                            (*sample.velocity, rate))
    return data, yaw


_ENCODERS = threading.local()
"""The reference encoders of each thread (an encoder serves one thread), by frame."""


def _reference_encoder(frame: str) -> codec.OdometryEncoder:
    encoders = _ENCODERS.__dict__.setdefault('by_frame', {})
    if frame not in encoders:
        encoders[frame] = codec.OdometryEncoder(frame, topics.REFERENCE_FRAME)
    return encoders[frame]


# --- the constraint set --------------------------------------------------------------------------
def selection_from_switches(switches: Mapping[str, bool]) -> ConstraintSelection:
    """The model's selection from the constraint_config switches.

    ``tangent_heading`` true keeps the model's default (heading task on whenever non_lateral is
    active with the trajectory task); false switches it off (the paper's inconsistent set).
    """
    on = {module: bool(switches[switch.parameter]) for module, switch in CONSTRAINT_MODULES.items()}
    heading = on.pop('tangent_heading')
    return ConstraintSelection(**on, tangent_heading=None if heading else False)


def switches_from_selection(selection: ConstraintSelection) -> dict[str, bool]:
    """The constraint_config switches that give ``selection`` (a heading task forced on without
    non_lateral has no switch: the graph runs its default there), in the order of the switches."""
    return {switch.parameter: (selection.tangent_heading is not False if module == 'tangent_heading'
                               else getattr(selection, module))
            for module, switch in CONSTRAINT_MODULES.items()}


def constraints_message(switches: Mapping[str, bool], gains: BaumgarteGains) -> bytes:
    """``constraints`` (CDR): the switches, the gains and the modules they activate."""
    selection = selection_from_switches(switches)
    return codec.constraints(switches, gains.alpha, gains.beta, selection.active_names(), selection.label())


def constraints_from_cdr(data: bytes) -> tuple[ConstraintSelection, BaumgarteGains]:
    """The selection and gains of a serialized ``constraints``; ValueError naming what is wrong."""
    decoded = codec.decode_constraints(data)
    try:
        gains = BaumgarteGains(decoded.alpha, decoded.beta)
    except Exception as error:  # ParameterError of the model
        raise ValueError(f'constraints message: {error}') from None
    return selection_from_switches(decoded.switches), gains


# --- the dynamics' diagnostics ----------------------------------------------------------------------
COMMAND_IGNORED = 'ignored (trajectory task on)'
"""The diagnostics' ``command`` while the trajectory task drives the robot."""


def applied_command(tau_left: float, tau_right: float) -> str:
    """The diagnostics' ``command`` while motor torques are applied."""
    return f'applied ({tau_left:.4g}, {tau_right:.4g}) N m'


LOADING_KERNEL = "loading the compiled kernel (a machine's first start compiles it into numba's cache, about a minute)"
"""The dynamics' status while it loads the compiled kernel its steps take, before its first step."""
STOPPED = 'stopped at t = {t:.3f} s (stop_at)'
"""The dynamics' status once simulation time ``t`` reached its stop (a format string)."""


def stopped_status(t: float) -> str:
    """The dynamics' status once simulation time reached its stop."""
    return STOPPED.format(t=t)


@dataclass(frozen=True)
class LoopFigures:
    """What the loop measured in wall-clock time over one diagnostics window."""

    achieved_rate: float
    """Steps per wall second."""
    real_time_factor: float
    real_time_factor_target: float
    step_time_mean_ms: float
    step_time_max_ms: float
    lateness_max_ms: float
    late_steps: int
    loop_priority: str


def contact_values(contact_model: str, coulomb_applies: bool, contact: ContactOutputs | None) -> list[tuple[str, object]]:
    """The wheel-wall contact entries of the dynamics' status (docs/model.md section 11)."""
    model = contact_model
    if model != IDEAL and not coulomb_applies:
        model += ' (ideal while the trajectory task is on)'
    if contact is None:
        return [('contact model', model)]
    return [('contact model', model),
            ('normal loads (N)', ', '.join(f'{load:.2f}' for load in contact.loads)),
            (f'friction use ({", ".join(WHEEL_POSITIONS)})',
             ', '.join(f'{use:.3f}' for use in contact.wheel_use.tolist())),
            ('slipping wheels', ', '.join(slipping_wheels(contact)) or 'none')]


def slipping_wheels(contact: ContactOutputs) -> list[str]:
    """The wheels sliding in ``contact``, by position."""
    return [wheel for wheel, flag in zip(WHEEL_POSITIONS, contact.wheel_slipping) if flag]


def settled_residual(largest: float, residual: float, t: float) -> float:
    """``largest`` (the largest residual of a window's states after the start, nan while none) with the state at
    simulation time ``t``'s ``residual`` counted if ``t`` is ``topics.RESIDUAL_SETTLED_AFTER`` or later."""
    if t < topics.RESIDUAL_SETTLED_AFTER - 1e-9:
        return largest
    return residual if math.isnan(largest) else max(largest, residual)


def simulation_status(node_name: str, status: str, diverged: bool, command: str, t: float, loop: LoopFigures,
                      residual: float, residual_max: float, constraints_label: str,
                      adsorption: Adsorption, *, residual_settled: float = math.nan, detached: bool = False,
                      contact: Sequence[tuple[str, object]] = (), sliding: Mapping[str, float] | None = None,
                      slipping: Sequence[str] = (), motor: Sequence[tuple[str, object]] = (),
                      saturated: str = '') -> codec.Status:
    """The dynamics' status on ``/diagnostics``: OK while running, paused or stopped, WARN while
    waiting, without torque commands, slipping, sliding with nothing holding the robot or with a motor
    saturated, ERROR once diverged or detached. ``motor``: the motor block's entries and ``saturated`` the
    saturated sides (``loop.status.MotorSaturation``)."""
    level = 'error' if diverged or detached else (
        'ok' if status in ('running', 'paused') or status.startswith('stopped') else 'warn')
    timed_out = command.startswith('timed out')
    if level == 'ok' and timed_out:
        level = 'warn'
    values = [
        ('status', status), ('simulation time', t), ('achieved rate (Hz)', loop.achieved_rate),
        ('real-time factor', loop.real_time_factor), ('real-time factor target', loop.real_time_factor_target),
        ('step time mean (ms)', loop.step_time_mean_ms), ('step time max (ms)', loop.step_time_max_ms),
        ('lateness max (ms)', loop.lateness_max_ms), ('late steps (> 2 ms)', loop.late_steps),
        ('loop priority', loop.loop_priority),
        ('constraint residual', residual), (topics.DIAGNOSTIC_RESIDUAL_MAX, residual_max),
        (topics.DIAGNOSTIC_RESIDUAL_SETTLED, residual_settled),
        ('active constraints', constraints_label),
        ('command', command),
        ('adsorption force (N)', float(adsorption.applied_force)),
        ('adsorption minimum (N)', float(adsorption.minimum_force)),
        ('adsorption margin', float(adsorption.margin)),
        *contact,
        *motor,
    ]
    message = f'{status}; no wheel_torque_cmd: zero torque' if level == 'warn' and timed_out else status
    if (sliding or slipping) and level != 'error':
        level = 'warn'
        moving = ', '.join(f'{channel} at {speed:.3g} m/s' for channel, speed in (sliding or {}).items())
        message += f'; sliding: {moving}' if sliding else '; slipping: ' + ', '.join(slipping)
    if saturated and level != 'error':
        level = 'warn'
        message += f'; motor saturated: {saturated}'
    return codec.Status(codec.simulation_status_name(node_name), level, message, values)

