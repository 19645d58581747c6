"""The dynamics loop's state and decisions, free of ROS (the node only wires it to the graph).

Everything that reaches the loop from outside is a typed event (a constraint switch, a plan, a
torque command, a reset, a pause, a step or a teleport while paused, a kept snapshot, a parameter
change, a recorder's progress)
posted to one thread-safe queue; the loop thread applies the queued events at each step boundary
(:meth:`DynamicsLoop.tick`), so no physics runs in a callback and the state sequence depends on
the events' order, not on their timing. What the loop needs of the graph (publishing, the
discovery of a recorder, keeper or controller) goes through a :class:`Graph`, and its wall-clock
waits through an injected clock, so it is tested without DDS (test_dynamics_loop.py).

Each tick ends in a :class:`Decision`: a step was taken, or why not (the run state, see
:class:`RunState`, says which wait it is), lockstep waits for the controller, or back-pressure
waits for a recorder. A start that waits for its controller longer than ``command_wait_timeout``
gives up: the loop stops with :attr:`DynamicsLoop.gave_up` saying why, and the node exits. The
node's module docstring explains determinism, pacing, back-pressure and resume.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from dataclasses import dataclass, field
from enum import Enum, auto
from typing import TYPE_CHECKING, Callable, Mapping, Protocol, Sequence, Union

import numpy as np

from wallbot_msgs_py import codec
from wallbot_msgs_py.snapshot import SWITCHES, DynamicsSnapshot
from wallbot_sim import messages
from wallbot_sim.model import (DOF, BaumgarteGains, ConstraintSelection, DivergedError, Robot, RobotParameters,
                               SampledReference, Simulation, StepOutputs)
from wallbot_sim.model.contact import DetachedError
from wallbot_sim.model.outputs import StepBlock
from wallbot_sim.model.scenario import moving_start
from wallbot_sim.model.trajectories import STAMP_RESOLUTION
from wallbot_sim.nodes.pacing import Pacer
from wallbot_sim.nodes.resume import ResumeGate

if TYPE_CHECKING:
    from wallbot_sim.model.compiled import ReferenceRows

BACKPRESSURE_TIMEOUT = 2.0
"""Wall seconds the loop waits for a recorder's progress to move before stepping on without it: a
recorder that was killed, restarted or starved must not stop the simulation for ever (a restarted
dynamics, or one beside a restarted recorder, would otherwise wait for a report that never comes)."""
RECORDER_CHECK = 0.2
"""Wall seconds between two looks for a record_progress publisher (a graph query costs time)."""
LATE_LIMIT = 2e-3
"""A step published more than this after its due time counts as late (s)."""
THROTTLE = 1.0
"""Seconds between repeated warnings of one kind."""
BLOCK_MOST = 50
"""Most steps computed as one block at real-time factor 0 (:meth:`DynamicsLoop._block_size`), all
published in one tick: an event waits at most this many steps (about 2 ms of wall time) for its step
boundary."""
BLOCK_PACED = 20
"""Most steps computed as one block while paced: each is published when due, one a tick, and an event
arriving between them drops the rest (:meth:`DynamicsLoop._rewind`). Small enough that computing a
block stays well inside the 1 ms before the next state is due."""
HANDOVER_LEAD = 0.010
"""Wall seconds before a state handed over ahead of time is due that the loop wakes to hand it over
(``DynamicsLoop._publish_ahead``): a wake-up up to this much later than asked makes no state late (the
project's VMs woke a sleeping 1 kHz loop late by 2-5 ms mostly, in some hours by up to 10-16 ms). Half
a paced block, so an event waits at most 30 ms at factor 1."""
COMMAND_WAIT_WARNING = 5.0
"""Wall seconds of a wait for the controller (wait_for_command) after which the log says so: a
controller started with the dynamics is there well before, so a longer wait is worth a line."""


# --- events: posted from any thread, applied by the loop thread at a step boundary ----------------
@dataclass(frozen=True)
class ConstraintSwitch:
    """A constraint set to run with (applied once it can be: the trajectory task needs a plan)."""

    selection: ConstraintSelection
    gains: BaumgarteGains


@dataclass(frozen=True)
class NewPlan:
    """A received plan: its reference and the span it covers."""

    reference: SampledReference
    start: float
    end: float
    final: bool

    def covers(self, t0: float, t1: float) -> bool:
        """Whether a step from t0 to t1 may use this plan.

        A plan that ends moving must extend strictly past t1: at its last sample time the
        quintic is evaluated at the segment's far end, which equals the sample only to
        rounding, while the next plan evaluates it exactly; the step waits for that plan. Within
        STAMP_RESOLUTION of its first sample a step is inside it, as the reference samples it.
        """
        return self.start <= t0 + STAMP_RESOLUTION and (self.final or t1 < self.end - STAMP_RESOLUTION)


@dataclass(frozen=True)
class TorqueCommand:
    """A validated wheel_torque_cmd (tau_L, tau_R) in N m."""

    torque: tuple[float, float]


@dataclass(frozen=True)
class Reset:
    """Back to the initial state at t = 0 (once lockstep's pending answer arrived)."""


@dataclass(frozen=True)
class Pause:
    """Pause (True) or run again (False)."""

    paused: bool


@dataclass(frozen=True)
class Step:
    """While paused: take ``count`` steps, then hold again (ignored while running)."""

    count: int


@dataclass(frozen=True)
class Teleport:
    """Put the robot at rest at (x, y) m in the wall frame with heading ``theta`` rad; simulation
    time and the wheels' angles go on."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True)
class ResumeSnapshot:
    """A keeper's answer at start: the snapshot to continue from, or None (it holds nothing)."""

    snapshot: DynamicsSnapshot | None


@dataclass(frozen=True)
class ParameterChange:
    """Accepted parameter values, by name."""

    changes: Mapping[str, object]


@dataclass(frozen=True)
class RecordProgress:
    """A recorder has taken every message up to this /clock stamp (ns)."""

    stamp_ns: int


Event = Union[ConstraintSwitch, NewPlan, TorqueCommand, Reset, Pause, Step, Teleport, ResumeSnapshot, ParameterChange,
              RecordProgress]


# --- what the loop reports ------------------------------------------------------------------------
class RunState(Enum):
    """The loop's run state; the value is the diagnostics' ``status`` text ({t}: simulation time,
    {reason}: why the robot left the wall)."""

    WAITING_CONSTRAINTS = 'waiting for constraints'
    WAITING_RECORDER = 'waiting for a recorder'
    WAITING_KEEPER = 'waiting for a kept snapshot to resume from (resume_state)'
    WAITING_START_PLAN = 'waiting for reference_trajectory (the moving start takes its velocity)'
    WAITING_CONTROLLER = 'waiting for a controller (a wheel_torque_cmd publisher that hears odom)'
    WAITING_PLAN = 'waiting for reference_trajectory'
    WAITING_COVERING_PLAN = 'waiting for a reference_trajectory covering t = {t:.3f} s'
    WAITING_FIRST_COMMAND = 'waiting for the first wheel_torque_cmd (the answer to the t = 0 state)'
    WAITING_RESUMED_COMMAND = ('waiting for the first wheel_torque_cmd since the resume '
                               '(the answer to the t = {t:.3f} s state)')
    GAVE_UP = 'gave up: {reason}'
    RUNNING = 'running'
    PAUSED = 'paused'
    STOPPED = messages.STOPPED
    DIVERGED = 'diverged'
    DETACHED = 'detached: {reason}'
    FAILED = 'internal error'


@dataclass(frozen=True)
class Status:
    """A run state with what its text names (set once, read by the diagnostics thread): ``waited``
    wall seconds of a wait for the controller, which gives up after ``limit`` (0: never)."""

    state: RunState
    t: float = 0.0
    reason: str = ''
    waited: float | None = None
    limit: float = 0.0

    def __str__(self) -> str:
        text = self.state.value.format(t=self.t, reason=self.reason)
        if self.waited is not None:
            text += f' for {self.waited:.0f} s (wall)'
            if self.limit > 0:
                text += f', giving up after {self.limit:g} s (command_wait_timeout)'
        return text


class Decision(Enum):
    """How a tick ended."""

    STEPPED = auto()
    NOT_READY = auto()
    """Nothing to step yet or now: see the status."""
    LOCKSTEP = auto()
    """Waiting for the controller's answer to the last published state."""
    HELD_BACK = auto()
    """Waiting for a recorder's progress (back-pressure)."""


WAIT_AFTER = {Decision.NOT_READY: 0.005, Decision.LOCKSTEP: 0.0005, Decision.HELD_BACK: 0.0005}
"""Longest wall wait (s) before the next tick; any posted event ends it early."""


@dataclass
class Window:
    """Loop statistics since the last diagnostics message."""

    started: float = field(default_factory=time.perf_counter)
    steps: int = 0
    step_time_sum: float = 0.0
    step_time_max: float = 0.0
    lateness_max: float = 0.0
    late: int = 0
    residual_max: float = 0.0
    """Largest constraint residual of every state of the window (not a sample of one)."""


class Graph(Protocol):
    """What the loop needs of the ROS graph around it (the node implements it)."""

    def prepare(self, out: StepOutputs, clock: bool) -> Callable[[], None]:
        """Encode a state's per-step messages, with /clock if ``clock``; calling the result publishes them."""

    def encodes_blocks(self, burst: bool) -> bool:
        """Whether ``prepare_block`` may be called (the messages carry the states as they are: no sensor noise);
        ``burst``: its states will be published back to back (factor 0), not each when it is due."""

    def prepare_block(self, block: StepBlock) -> Sequence[PreparedState]:
        """``prepare`` of each state of ``block`` at once, in order."""

    def publish_snapshot(self, snapshot: DynamicsSnapshot) -> None: ...

    def recorder_present(self) -> bool:
        """Whether some node publishes record_progress."""

    def recorder_listening(self) -> bool:
        """Whether a recorder publishes record_progress and every step topic has a subscriber."""

    def keeper_seen(self) -> bool:
        """Whether some node publishes resume_state."""

    def controller_listening(self) -> bool:
        """Whether a wheel_torque_cmd publisher exists and hears odom (see ``heard_by_every``)."""


@dataclass(frozen=True)
class PreparedState:
    """A state of a block with its messages encoded (``Graph.prepare_block``)."""

    send: Callable[[bool, float], None]
    """Publishes it, with /clock if the first argument is true; the second: how many seconds before its due time
    it is handed over (0: when due; only a state not ``heard`` is handed over ahead of time)."""
    heard: bool
    """Whether a subscriber outside the loop's process takes one of its messages over DDS."""


class Log(Protocol):
    def info(self, message: str, **kwargs: object) -> object: ...

    def warning(self, message: str, **kwargs: object) -> object: ...

    def error(self, message: str, **kwargs: object) -> object: ...


@dataclass
class Ahead:
    """A block of steps computed ahead of publishing (``DynamicsLoop._start_block``)."""

    block: StepBlock
    senders: Sequence[PreparedState]
    """Its states' messages, from the graph's ``prepare_block``."""
    stamps: list[int]
    """Each state's simulation time (ns)."""
    before: tuple[int, np.ndarray, np.ndarray]
    """The simulation's step count, q and qd before the block: where a rewind with nothing published goes."""
    step_time: float
    """The block's compute time per step (s)."""
    published: int = 0
    ahead_of_time: bool = False
    """Whether its states nobody outside the process hears are handed over ahead of their due times
    (``DynamicsLoop._publish_ahead``)."""


class DynamicsLoop:
    """The simulation and the state around it; every attribute is written by the loop thread only.

    ``params`` holds the node's parameter values (those of the node's declarations); a
    :class:`ParameterChange` updates them at the next step boundary.
    """

    def __init__(self, params: Mapping[str, object], robot_file: RobotParameters, graph: Graph, log: Log,
                 pacer: Pacer, clock: Callable[[], float] = time.monotonic) -> None:
        self.params = dict(params)
        self._robot_file = robot_file
        self.robot = Robot(self._robot_params(self.params['adhesion_force']))
        self._graph, self._log, self.pacer, self._clock = graph, log, pacer, clock
        self._events: queue.SimpleQueue[Event] = queue.SimpleQueue()
        self._wake = threading.Event()
        self.stopping = threading.Event()
        self._factor = float(self.params['real_time_factor'])  # read by the pacer while it sleeps

        self.sim: Simulation | None = None
        self.plan: NewPlan | None = None
        self.selection: ConstraintSelection | None = None
        self.gains: BaumgarteGains | None = None
        self.pending_constraints: ConstraintSwitch | None = None
        self.paused = self.diverged = False
        self.steps_to_take = 0
        """Steps a Step event still allows while paused."""
        self.detached: str | None = None
        """Why the robot left the wall (coulomb contact), until a reset."""
        self.status = Status(RunState.WAITING_CONSTRAINTS)
        self.command_wait: tuple[RunState, float, bool] | None = None
        """The wait for the controller under way: which, since when (clock), whether the log said it."""
        self.stepped = False
        """Whether a step was taken: only a start's wait for the controller gives up (a resumed
        start's wait for its first answer comes after the steps of its catch-up)."""
        self.gave_up: str | None = None
        """Why the loop stopped without starting (then the node exits), or None."""
        self.command: tuple[tuple[float, float], float] | None = None  # (torque, simulation time it came)
        self.command_expired = False
        self.command_serial = self.sync_serial = 0  # commands received; that count when a sync state went out
        self.first_sync: int | None = None
        """command_serial when this process published its first state (None: none yet)."""
        self.lockstep_since: float | None = None
        self.lockstep_lost = False
        self.reset_requested: float | None = None  # clock time of a reset not yet applied
        self.progress_ns: int | None = None
        self.recorder_present = False
        self.recorder_checked = -math.inf
        self.held_since: tuple[float, int | None] | None = None  # clock time a back-pressure wait began, progress then
        self.last_outputs: StepOutputs | None = None
        self.resume = ResumeGate(float(self.params['resume_wait']))
        self.clock_schedule = messages.ClockSchedule(float(self.params['clock_rate_hz']))
        self._window = Window()
        self._window_lock = threading.Lock()
        self._ahead: Ahead | None = None
        """A block of steps computed, not all published yet (the simulation is at its end)."""
        self._next: Ahead | None = None
        """Paced: the block after ``_ahead``, computed (and encoded) between its last states, not taken yet."""
        self._sampled: ReferenceRows | None = None
        """Paced: the reference of the block after ``_ahead``, sampled a state before it is computed."""

    # --- any thread ---------------------------------------------------------------------------------
    def post(self, event: Event) -> None:
        """Queue an event for the next step boundary and end the loop's wait."""
        if isinstance(event, ParameterChange) and 'real_time_factor' in event.changes:
            self._factor = float(event.changes['real_time_factor'])  # a sleeping step sees it at once
        self._events.put(event)
        self._wake.set()

    def stop(self) -> None:
        self.stopping.set()
        self._wake.set()

    def take_window(self) -> Window:
        """The statistics since the last call; a new window starts."""
        with self._window_lock:
            window, self._window = self._window, Window()
        return window

    def command_state(self) -> str:
        """The 'command' value of /diagnostics."""
        sim = self.sim
        if sim is None:
            return 'no simulation yet'
        if sim.selection.trajectory:
            return messages.COMMAND_IGNORED
        if self.command is None:
            return 'none yet, zero torque'
        if self.command_expired:
            return 'timed out, zero torque'
        (left, right), _since = self.command
        return messages.applied_command(left, right)

    # --- loop thread --------------------------------------------------------------------------------
    def run(self) -> None:
        """Tick until :meth:`stop`."""
        while not self.stopping.is_set():
            wait = WAIT_AFTER.get(self.tick())
            if wait is not None:
                self._wake.wait(wait)
                self._wake.clear()

    def fail(self) -> None:
        """The loop crashed (the caller logged why)."""
        self.status, self.diverged = Status(RunState.FAILED), True

    @property
    def in_error(self) -> bool:
        """Whether the diagnostics' level is ERROR: diverged, crashed or given up."""
        return self.diverged or self.gave_up is not None

    def tick(self) -> Decision:
        """Apply the queued events, then take one step if nothing holds it back.

        A state of a block computed ahead is published instead while no event came but a recorder's progress
        and plans that give the states computed ahead (``_plan_keeps``); any other event drops the rest of the
        block first (:meth:`_rewind`), so it applies at the boundary after the last state published, as it does
        between single steps.
        """
        events = self._take_events()
        if self._ahead is not None and all(self._keeps_ahead(event) for event in events):
            if self._next is not None and not all(self._plan_keeps(event, self._next)
                                                  for event in events if isinstance(event, NewPlan)):
                self._next = None
            for event in events:
                self._apply(event)
            self._publish_ahead()
            return Decision.STEPPED
        if not all(isinstance(event, RecordProgress) for event in events):
            self._next = None  # computed before the event
        if self._ahead is not None:
            self._rewind()
        for event in events:
            self._apply(event)
        if self.reset_requested is not None and (
                not self._answer_pending() or self._clock() - self.reset_requested > self.params['lockstep_timeout']):
            self.reset_requested = None
            self._reset()
        if not self._ready():
            self.pacer.reanchor()
            return Decision.NOT_READY
        if self._lockstep_blocked():  # no re-anchor: a prompt answer costs no pace
            return Decision.LOCKSTEP
        if self._held_back():
            return Decision.HELD_BACK
        size = self._block_size()
        if size > 1 and self._start_block(size):
            return Decision.STEPPED
        self._step()
        if self.paused:  # a step that a Step event allowed
            self.steps_to_take -= 1
        return Decision.STEPPED

    def _keeps_ahead(self, event: Event) -> bool:
        """Whether the block computed ahead stays through ``event``: a recorder's progress, or a plan that keeps it."""
        return isinstance(event, RecordProgress) or isinstance(event, NewPlan) and self._plan_keeps(event, self._ahead)

    def _plan_keeps(self, plan: NewPlan, ahead: Ahead) -> bool:
        """Whether ``plan`` gives the steps of ``ahead`` not published yet as the plan in force gave them, to the bit.

        The trajectory node's plans lie on one sample grid, so a renewal agrees with the plan it replaces over
        their overlap: the states computed ahead stand, and the state after a plan is not computed in the
        millisecond before it is due while the executor decodes the plan.
        """
        dt = self.sim.dt  # the steps' times are within half a nanosecond of their stamps
        start = ahead.stamps[ahead.published] * 1e-9 - dt - STAMP_RESOLUTION
        end = ahead.stamps[-1] * 1e-9 + STAMP_RESOLUTION
        return self.plan is not None and plan.reference.agrees(self.plan.reference, start, end)

    def _take_events(self) -> list[Event]:
        events = []
        while True:
            try:
                events.append(self._events.get_nowait())
            except queue.Empty:
                return events

    def _apply(self, event: Event) -> None:
        match event:
            case ConstraintSwitch():
                self.pending_constraints = event
            case NewPlan():
                self.plan = event
                if self.sim is not None:
                    self.sim.set_reference(event.reference)
                    self._snapshot()
            case TorqueCommand():
                self.command = (event.torque, self.sim.t if self.sim is not None else 0.0)
                self.command_expired = False
                self.command_serial += 1
                if self.lockstep_lost:
                    self.lockstep_lost = False
                    self._log.info(f'wheel_torque_cmd again at t = {self.sim.t:.3f} s: lockstep resumed')
                self._snapshot()  # so a resume recomputes the steps after it with the commands they had
            case Reset():
                self.reset_requested = self._clock()
            case Pause():
                self.paused, self.steps_to_take = event.paused, 0
                self._log.info('paused' if event.paused else 'running again')
                self._snapshot()
            case Step():
                if self.paused:
                    self.steps_to_take += event.count
                else:
                    self._log.warning('~/step ignored: the simulation is running (it steps while paused)')
            case Teleport():
                self._teleport(event)
            case ResumeSnapshot():
                self.resume.offer(event.snapshot)
            case ParameterChange():
                self._apply_params(event.changes)
            case RecordProgress():
                self.progress_ns = event.stamp_ns

    def _apply_params(self, changes: Mapping[str, object]) -> None:
        self.params.update(changes)
        if 'realtime_priority' in changes:
            self.pacer.priority = changes['realtime_priority']
        if 'rate_hz' in changes and self.sim is not None:
            self.sim = self._simulation(self.sim.q, self.sim.qd, self.sim.t, self.sim.motor_torque)
            self._snapshot()
        if 'adhesion_force' in changes:
            self.robot = Robot(self._robot_params(changes['adhesion_force']))
            if self.sim is not None:
                self.sim.set_adhesion_force(self.robot.params.adhesion_force)
        if 'contact_model' in changes and self.sim is not None:
            self.sim.set_contact_model(changes['contact_model'])
        self.pacer.reanchor()
        self._log.info('parameters: ' + ', '.join(f'{k} = {v}' for k, v in changes.items()))

    def _robot_params(self, adhesion_force: float) -> RobotParameters:
        """The robot file's parameters, with the adhesion_force parameter (N) unless it is 0."""
        params = self._robot_file
        return params.replace(adhesion_force=adhesion_force) if adhesion_force else params

    def _simulation(self, q, qd, t0: float, torque=(0.0, 0.0)) -> Simulation:
        reference = self.plan.reference if self.plan is not None else None
        sim = Simulation(self.robot, reference, self.selection, q, qd, dt=1.0 / self.params['rate_hz'],
                         t0=t0, gains=self.gains, contact=self.params['contact_model'], engine=self.params['engine'])
        sim.set_motor_torque(*torque)
        return sim

    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        p = self.params
        q0 = np.array([p['initial_x'], p['initial_y'], p['initial_theta'], 0, 0, 0, 0], dtype=float)
        if p['initial_at_rest'] or self.plan is None:
            return q0, np.zeros(DOF)
        return q0, moving_start(self.robot, self.plan.reference, p['initial_theta'])

    def _reset(self) -> None:
        self.command, self.diverged, self.detached = None, False, None
        self.resume.stop_catch_up()
        if self.sim is not None:
            self.sim = self._simulation(*self._initial_state(), 0.0)
            self._log.info('reset to the initial state at t = 0')
            self._publish(self.sim.outputs())
            self._snapshot()
        self.pacer.reanchor()

    def _teleport(self, pose: Teleport) -> None:
        """A new run segment from the current time, at rest at ``pose``; published at once, so a
        paused robot is seen where it was put."""
        sim = self.sim
        if sim is None:
            self._log.warning('initialpose ignored: the simulation starts with the first constraint set')
            return
        self.diverged, self.detached = False, None
        q = np.array([pose.x, pose.y, pose.theta, *sim.q[3:]])
        self.sim = self._simulation(q, np.zeros(DOF), sim.t, sim.motor_torque)
        self._log.info(f'placed at rest at x = {pose.x:.3f} m, y = {pose.y:.3f} m, heading {pose.theta:.3f} rad '
                       f'at t = {sim.t:.3f} s')
        self._publish(self.sim.outputs())
        self._snapshot()
        self.pacer.reanchor()

    def _restore(self, kept: DynamicsSnapshot, switch: ConstraintSwitch) -> None:
        """Continue from a kept snapshot; then apply the constraint set in force now, if it differs."""
        self.selection = messages.selection_from_switches(dict(zip(SWITCHES, kept.switches)))
        self.gains = BaumgarteGains(*kept.gains)
        if self.selection.trajectory and self.plan is None:  # the task was switched off meanwhile, no plan here
            self.selection, self.gains = switch.selection, switch.gains
        if kept.dt == 1.0 / self.params['rate_hz']:
            self.sim = self._simulation(kept.q, kept.qd, kept.anchor, kept.motor_torque)
            self.sim.restore(kept.steps, kept.q, kept.qd)
        else:  # another rate_hz: a new run segment from the kept time, as a rate change makes
            self.sim = self._simulation(kept.q, kept.qd, kept.t, kept.motor_torque)
        self.command = (kept.command, kept.command_since) if kept.command is not None else None
        self.command_expired = kept.command_expired
        self.paused = kept.paused
        self.resume.catch_up_to(kept.seen_until_ns)
        behind = max(0, kept.seen_until_ns - kept.stamp_ns) * 1e-9
        self._log.info(
            f'resuming from the kept snapshot at t = {kept.t:.3f} s (step {kept.steps}, constraints '
            f'{self.selection.label()}{", paused" if kept.paused else ""}); the graph has seen up to '
            f't = {kept.seen_until_ns * 1e-9:.3f} s: {behind:.3f} s recomputed unpublished')
        if (switch.selection, switch.gains) != (self.selection, self.gains):
            self._switch(switch)
        out = self.sim.outputs()  # the solve the first step reuses, as after every step of the first life
        if self.resume.publishes(codec.to_nanoseconds(self.sim.t)):
            self._publish(out)
        self._snapshot()

    def _switch(self, switch: ConstraintSwitch) -> None:
        selection, gains = switch.selection, switch.gains
        if self.sim is None and self.resume.snapshot is not None:
            self._restore(self.resume.snapshot, switch)
            return
        if self.sim is None:
            self.selection, self.gains = selection, gains
            self.sim = self._simulation(*self._initial_state(), 0.0)
            fresh = f' from the initial state ({self.resume.timed_out})' if self.resume.timed_out else ''
            self._log.info(f'starting with constraints {selection.label()}{fresh}')
            self._publish(self.sim.outputs())
            self._snapshot()
            return
        report = self.sim.set_constraints(selection, gains)
        self.selection, self.gains = selection, gains
        self._log.info(
            f'constraints {report.previous.label()} -> {selection.label()} at t = {self.sim.t:.3f} s: '
            f'velocity violation {report.violation_before:.3e} before, {report.violation_after:.3e} after projection')
        self._snapshot()

    def _ready(self) -> bool:
        """Apply a pending constraint set if possible; say whether the next step may run."""
        if self.sim is None and self.params['wait_for_recorder'] and not self._graph.recorder_listening():
            self.status = Status(RunState.WAITING_RECORDER)
            return False
        # the wait counts from the constraint set's arrival: by then discovery is under way
        if (self.sim is None and self.pending_constraints is not None
                and not self.resume.settle(self._clock(), self._graph.keeper_seen())):
            self.status = Status(RunState.WAITING_KEEPER)
            return False
        pending = self.pending_constraints
        if pending is not None:
            if self.sim is None and not pending.selection.trajectory:
                waiting = self._driven_start_blocked()
                if waiting is RunState.WAITING_CONTROLLER:
                    self._wait_for_command(waiting)
                    return False
                if waiting is not None:
                    self.status = Status(waiting)
                    return False
            if pending.selection.trajectory and self.plan is None:
                self.status = Status(RunState.WAITING_PLAN)
                if self.sim is None:
                    return False
            else:
                self.pending_constraints = None
                self._switch(pending)
        sim = self.sim
        if sim is None:
            return False
        if (self.paused and self.steps_to_take <= 0) or self.diverged or self.detached:
            self.status = (Status(RunState.DIVERGED) if self.diverged else
                           Status(RunState.DETACHED, reason=self.detached) if self.detached else Status(RunState.PAUSED))
            return False
        stop_at = self.params['stop_at']
        if stop_at > 0.0 and sim.t >= stop_at - 0.5 * sim.dt:
            self.status = Status(RunState.STOPPED, t=sim.t)
            return False
        if sim.selection.trajectory and not self.plan.covers(sim.t, sim.t + sim.dt):
            if self.resume.catching_up and self.plan.start > sim.t + STAMP_RESOLUTION:
                # the plan of the kept state was replaced before the kill: publishing this earlier
                # state makes the trajectory node replan from it (its clock went back)
                self._log.warning(f'the newest plan starts at {self.plan.start:.3f} s, after the kept '
                                  f'state at {sim.t:.3f} s: publishing from there')
                self.resume.stop_catch_up()
                self._publish(sim.outputs())
            self.status = Status(RunState.WAITING_COVERING_PLAN, t=sim.t)
            return False
        if self.params['wait_for_command'] and not sim.selection.trajectory:
            if sim.steps == 0 and self.command is None:
                self._wait_for_command(RunState.WAITING_FIRST_COMMAND)
                return False
            if self._resumed_unanswered():
                self._wait_for_command(RunState.WAITING_RESUMED_COMMAND)
                return False
        self.command_wait = None
        self.status = Status(RunState.RUNNING)
        return True

    def _wait_for_command(self, state: RunState) -> None:
        """Wait (``state``) for the controller or its first command, saying so; a start gives up after
        ``command_wait_timeout`` (wall, 0: never) of either wait.

        Each wait counts from its own beginning: the answer to the t = 0 state can only come once
        that state is out, which a wait for the recorder or for the constraints may delay.
        Giving up logs one error line naming what was missing, sets :attr:`gave_up` and stops the
        loop; the node then exits with status 1, as it does for a start it cannot make otherwise.
        """
        if self.gave_up is not None:  # said once; the loop is stopping
            return
        now = self._clock()
        if self.command_wait is None or self.command_wait[0] is not state:
            self.command_wait = (state, now, False)
        _state, since, said = self.command_wait
        waited = now - since
        start = not self.stepped or state is RunState.WAITING_RESUMED_COMMAND
        limit = float(self.params['command_wait_timeout']) if start else 0.0
        t = self.sim.t if self.sim is not None else 0.0
        self.status = Status(state, t=t, waited=waited, limit=limit)
        if 0.0 < limit < waited:
            missing = {RunState.WAITING_CONTROLLER: 'no controller (a wheel_torque_cmd publisher subscribing odom, '
                                                    'matched both ways)',
                       RunState.WAITING_FIRST_COMMAND: 'no wheel_torque_cmd answering the t = 0 state',
                       RunState.WAITING_RESUMED_COMMAND: f'no wheel_torque_cmd answering the resumed state at '
                                                         f't = {t:.3f} s'}[state]
            self.gave_up = (f'{missing} within command_wait_timeout {limit:g} s (wall) with wait_for_command set: '
                            'start the controller first, or set command_wait_timeout 0 to wait for ever')
            self.status = Status(RunState.GAVE_UP, reason=missing)
            self._log.error(f'{self.gave_up}; exiting')
            self.stopping.set()
        elif waited > COMMAND_WAIT_WARNING and not said:
            self.command_wait = (state, since, True)
            self._log.warning(str(self.status))

    def _driven_start_blocked(self) -> RunState | None:
        """Why a driven run may not create (or resume) its simulation yet (None: it may).

        A moving start (initial_at_rest false) takes the reference velocity at t = 0, so it
        needs the plan (a resume takes the kept velocity). With wait_for_command, a controller
        must be there to hear the first state, the initial or the resumed one: a wheel_torque_cmd
        publisher exists, its node subscribes odom, and every discovered odom subscription is
        matched (odom is volatile: a subscriber matched later would miss that state, and the
        first step would wait for ever).
        """
        if self.resume.snapshot is None and not self.params['initial_at_rest'] and self.plan is None:
            return RunState.WAITING_START_PLAN
        if self.params['wait_for_command'] and not self._graph.controller_listening():
            return RunState.WAITING_CONTROLLER
        return None

    def _resumed_unanswered(self) -> bool:
        """Lockstep in a process that resumed a kept snapshot: whether the sync state awaiting its
        answer would be the first answer since the process published its first state.

        That answer waits as a start's does (command_wait_timeout), not lockstep_timeout: the
        resumed node is a new participant, and the controller sends its answer only once it
        hears the node (``HeldCommands``), which needs the node's name from discovery. Measured
        on the project's 2-core VM under load (2026-12-02): 1.9-2.4 s after the first resumed
        state, longer than the 2 s of lockstep_timeout; a lockstep given up then let the loop
        run on the kept command while the controller's answers, held and replaced by newer
        ones, never went out (86 commands missing from the bag). The first resumed state is
        seldom a control instant (the controller acts again from the next one), so the wait is
        at the first sync state, which is.
        """
        return (self.resume.snapshot is not None and self.first_sync is not None
                and self.command_serial == self.first_sync and self._answer_awaited())

    def _answer_awaited(self) -> bool:
        """Lockstep (driven mode, lockstep_every N > 0): whether the last published state was a
        sync state whose answer (a command that arrived after it) is still to come."""
        every, sim = self.params['lockstep_every'], self.sim
        return (every > 0 and not sim.selection.trajectory and not self.lockstep_lost
                and sim.steps % every == 0 and self.command_serial == self.sync_serial
                and not self.resume.catching_up)

    def _lockstep_blocked(self) -> bool:
        """Lockstep: whether to wait for the controller.

        After the state of every Nth step is published, the next step waits for a command that
        arrived after it: the controller's answer to that very state, so the loop behaves like
        a controller sampling every N steps with no delay, at any pace or CPU load. Without an
        answer within ``lockstep_timeout`` (wall) it steps on, free-running until commands return
        (then command_timeout brings zero torque, as without lockstep). The timeout is long
        against a loaded machine's scheduling delays (a 0.25 s one was exceeded under load, and
        the loop then no longer equalled the model's), short against a controller's death.
        """
        if not self._answer_awaited():
            self.lockstep_since = None
            return False
        now = self._clock()
        if self.lockstep_since is None:
            self.lockstep_since = now
        if now - self.lockstep_since <= self.params['lockstep_timeout']:
            return True
        self.lockstep_since, self.lockstep_lost = None, True
        self.pacer.reanchor()  # the time spent waiting for a dead controller is not caught up in a burst
        self._log.warning(f'no wheel_torque_cmd within {self.params["lockstep_timeout"]:g} s (wall) of the state at '
                          f't = {self.sim.t:.3f} s: stepping on without lockstep until commands return')
        return False

    def _answer_pending(self) -> bool:
        """Whether lockstep's answer to the last published state is still to come.

        A reset waits for it (at most lockstep_timeout): arriving after the reset, that answer to a
        state of the old run would be taken for the answer to the reset state.
        """
        return self.sim is not None and self._answer_awaited()

    def _mark_sync(self) -> None:
        """The current state was just published: lockstep waits for a command newer than this."""
        self.sync_serial = self.command_serial
        if self.first_sync is None:
            self.first_sync = self.command_serial

    def _held_back(self) -> bool:
        """Whether a recorder's progress is more than the window behind (at any factor: a recorder
        that falls behind on a loaded machine slows the simulation down instead of losing messages)."""
        now = self._clock()
        if now - self.recorder_checked > RECORDER_CHECK:
            self.recorder_checked = now
            self.recorder_present = self._graph.recorder_present()
        if not self.recorder_present:
            return False
        window = self.params['backpressure_window'] * self.sim.dt
        progress = -math.inf if self.progress_ns is None else self.progress_ns * 1e-9
        if self.sim.t - progress <= window:
            self.held_since = None
            return False
        if self.held_since is None or self.held_since[1] != self.progress_ns:  # a new wait, or progress moved
            self.held_since = (now, self.progress_ns)
        if now - self.held_since[0] <= BACKPRESSURE_TIMEOUT:
            return True
        if self.held_since[0] > -math.inf:  # once per stalled progress value
            self._log.warning(f'no record_progress for {BACKPRESSURE_TIMEOUT:g} s (wall) at t = {self.sim.t:.3f} s: '
                              'stepping on until the recorder reports again')
            self.held_since = (-math.inf, self.progress_ns)
        return False

    def _motor_torque(self) -> tuple[float, float]:
        """The torque of the step from the current state (``_torque_at``), saying once when the command timed out."""
        sim = self.sim
        if not sim.selection.trajectory and self._timed_out(sim.t) and not self.command_expired:
            self.command_expired = True
            self._log.warning(
                f'no wheel_torque_cmd for {self.params["command_timeout"]:g} s of simulation time (the last '
                f'at t = {self.command[1]:.3f} s): zero torque from t = {sim.t:.3f} s', throttle_duration_sec=THROTTLE)
        return self._torque_at(sim.t)

    def _torque_at(self, t: float) -> tuple[float, float]:
        """The motor torque of a step from time ``t``: the command in force while driven, zero under the
        trajectory task, before the first command and once the command is command_timeout old."""
        if self.sim.selection.trajectory or self.command is None or self._timed_out(t):
            return (0.0, 0.0)
        return self.command[0]

    def _timed_out(self, t: float) -> bool:
        return self.command is not None and t - self.command[1] > self.params['command_timeout'] + 1e-12

    def _step(self) -> None:
        self.stepped = True
        sim = self.sim
        torque = self._motor_torque()
        if torque != sim.motor_torque:
            sim.set_motor_torque(*torque)
        began = time.perf_counter()
        try:
            sim.step()
            out = sim.outputs()
            if not (math.isfinite(float(np.sum(out.constraint_force))) and math.isfinite(out.residual)):
                raise DivergedError(f'constraint force is no longer finite at t = {sim.t:.3f} s')
        except DivergedError as error:
            self.diverged = True
            self.status = Status(RunState.DIVERGED)
            self._log.error(f'{error}: simulation paused (reset with ~/reset)')
            return
        except DetachedError as error:
            self.detached = str(error)
            self.status = Status(RunState.DETACHED, reason=self.detached)
            self._log.error(f'{error}: simulation paused (reset with ~/reset)')
            return
        step_time = time.perf_counter() - began
        if self.resume.catching_up and not self.resume.publishes(codec.to_nanoseconds(sim.t)):
            self.last_outputs = out  # the graph has this state: recomputed, not published nor paced
            return
        window = self._window
        window.steps += 1
        window.step_time_sum += step_time
        window.step_time_max = max(window.step_time_max, step_time)
        publish = sim.steps % self.params['publish_every'] == 0
        if publish:
            clock = self.clock_schedule.due(codec.to_nanoseconds(out.t), final=self._waits_next())
            send = self._graph.prepare(out, clock)
        lateness = self.pacer.wait(sim.steps, sim.dt, lambda: self._factor, self.stopping)
        window.lateness_max = max(window.lateness_max, lateness)
        if lateness > LATE_LIMIT:
            window.late += 1
        if publish:
            send()
            self._mark_sync()
            every = round(self.params['snapshot_period'] / sim.dt)
            if every > 0 and sim.steps % every == 0:
                self._snapshot()
        self._note_residual(out.residual)
        self.last_outputs = out

    def _block_size(self) -> int:
        """How many steps this tick may take as one block (1: a single step).

        Blocks are taken on the compiled engine with ideal contact (``Simulation.tabulates``), publishing every
        state, not resuming, under one motor torque: zero under the trajectory task; driven, the command's, set
        by the single step after it changes. A block ends where a single step would do something between its
        steps: at the last step the plan covers (trajectory task), before the command in force times out, at a
        lockstep state (the step after it waits for the controller's answer), before stop_at, at the recorder's
        window and at the next snapshot. So the states and messages are the single steps', to the bit.
        """
        sim, params = self.sim, self.params
        if (not sim.tabulates or self.paused or self.resume.catching_up or params['publish_every'] != 1
                or self._torque_at(sim.t) != sim.motor_torque or self._answer_awaited()
                or not self._graph.encodes_blocks(self._factor <= 0.0)):
            return 1
        size = BLOCK_PACED if self._factor > 0.0 else BLOCK_MOST
        every = round(params['snapshot_period'] / sim.dt)
        if every > 0:
            size = min(size, every - sim.steps % every)
        lockstep = params['lockstep_every']
        if lockstep > 0 and not sim.selection.trajectory and not self.lockstep_lost:
            size = min(size, lockstep - sim.steps % lockstep)
        window = params['backpressure_window'] * sim.dt
        stop_at = params['stop_at']
        while size > 1:
            t = sim.initial_time + (sim.steps + size - 1) * sim.dt  # the block's last step starts here
            if ((sim.selection.trajectory and not self.plan.covers(t, t + sim.dt))
                    or self._torque_at(t) != sim.motor_torque
                    or (stop_at > 0.0 and t >= stop_at - 0.5 * sim.dt)
                    or (self.recorder_present and (self.progress_ns is None
                                                   or t - self.progress_ns * 1e-9 > window))):
                size -= 1
                continue
            break
        return size

    def _start_block(self, size: int) -> bool:
        """Take a block of at most ``size`` steps (``_block_size``): the one computed ahead (``_prepare_next``)
        if it starts here, else ``size`` steps computed now; publish its first state, or all at factor 0.
        False, nothing taken, if a state among them is not finite (``_step`` then meets it)."""
        sim = self.sim
        ahead, self._next = self._next, None
        if ahead is None or ahead.before[0] != sim.steps or len(ahead.stamps) > size:
            ahead = self._compute_block(size)
            if ahead is None:
                return False
        if not ahead.senders:
            ahead.senders = self._graph.prepare_block(ahead.block)
        sim.take(ahead.block)
        self.stepped = True
        ahead.ahead_of_time = self._hands_over_ahead() and not all(state.heard for state in ahead.senders)
        self._ahead = ahead
        self._publish_ahead()
        return True

    def _hands_over_ahead(self) -> bool:
        """Whether a block's states may be handed over ahead of their due times: paced, and no command awaited
        between two of its states (under the trajectory task commands are ignored; with lockstep the next is the
        answer to the block's last state). A free-running driven loop publishes each when due: a command then
        applies within a step of its arrival, not after the states handed over before it."""
        lockstep = self.params['lockstep_every'] > 0 and not self.lockstep_lost
        return self._factor > 0.0 and (self.sim.selection.trajectory or lockstep)

    def _compute_block(self, size: int) -> Ahead | None:
        """``size`` steps from the simulation's state, not taken yet and not encoded; None if one is not finite."""
        sim = self.sim
        before = (sim.steps, sim.q, sim.qd)
        began = time.perf_counter()
        block = sim.compute_block(size, self._sampled)
        self._sampled = None
        if block is None:
            return None
        step_time = (time.perf_counter() - began) / size
        return Ahead(block, (), [codec.to_nanoseconds(t) for t in block.t.tolist()], before, step_time)

    def _prepare_next(self, all_at_once: bool = False) -> None:
        """Paced, after publishing a state of a block: with three states of it left, sample the next block's
        reference (the Python part of computing it); with two, compute the next block; with one, encode its
        messages. So each part takes the time up to the next state's due time, and the block boundary
        publishes a state without computing any: on a slow machine computing and encoding a block of 20 takes
        2-4 ms, which made the first state of every block late. ``all_at_once``: the three parts now (before
        a wait of a block handed over ahead of time).
        Any event but a recorder's progress drops the block (``tick``); so does a boundary that is not where
        it starts."""
        if all_at_once:
            if self._next is None and (size := self._block_size()) > 1:
                self._next = self._compute_block(size)
            if self._next is not None and not self._next.senders:
                self._next.senders = self._graph.prepare_block(self._next.block)
            return
        left = len(self._ahead.stamps) - self._ahead.published
        if self._next is None and left == 3:
            size = self._block_size()
            if size > 1:
                self._sampled = self.sim.sample_reference(size)
        elif self._next is None and left <= 2:
            size = self._block_size()  # from the simulation's state: the end of the block being published
            if size > 1:
                self._next = self._compute_block(size)
        elif self._next is not None and left == 1 and not self._next.senders:
            self._next.senders = self._graph.prepare_block(self._next.block)

    def _publish_ahead(self) -> None:
        """Publish the next state of the block computed ahead when it is due (at factor 0, all of them).

        Handing over ahead of time (``Ahead.ahead_of_time``), the states up to the next one that carries /clock
        or is heard outside the process (``PreparedState.heard``), which waits until due, go out at once,
        ``HANDOVER_LEAD`` before the first of them is due, each logged at its due time by a composed recorder's
        tap: with nobody outside hearing the per-step topics, a wake-up per block and per /clock instead of one
        per state, and the next block prepared whole before each wait. Events still apply at the boundary after
        the last state published, then the last handed over; they wait at most a block and the lead for it.
        """
        ahead, sim, window = self._ahead, self.sim, self._window
        woke = False  # handing over ahead of time, the first state of this call waits, the rest go with it
        while True:
            row = ahead.published
            steps, last = ahead.before[0] + row + 1, row == len(ahead.stamps) - 1
            clock = self.clock_schedule.due(ahead.stamps[row], final=last and self._waits_next())
            state, factor = ahead.senders[row], self._factor  # another thread may set the factor to 0 meanwhile
            early = ahead.ahead_of_time and not (clock or state.heard) and factor > 0.0
            if early:
                due = self.pacer.due(steps, sim.dt, factor)
                if not woke and due - time.perf_counter() > HANDOVER_LEAD:
                    self._prepare_next(all_at_once=True)
                    self.pacer.wait(steps, sim.dt, lambda: self._factor, self.stopping, lead=HANDOVER_LEAD)
                woke = True
                lateness = time.perf_counter() - due
            else:
                if ahead.ahead_of_time:
                    self._prepare_next(all_at_once=True)
                lateness = self.pacer.wait(steps, sim.dt, lambda: self._factor, self.stopping)
            window.steps += 1
            window.step_time_sum += ahead.step_time
            window.step_time_max = max(window.step_time_max, ahead.step_time)
            window.lateness_max = max(window.lateness_max, lateness)
            if lateness > LATE_LIMIT:
                window.late += 1
            state.send(clock, max(-lateness, 0.0))
            self._mark_sync()
            self._note_residual(float(ahead.block.table.residual[row]))
            ahead.published += 1
            if last:
                self._ahead = None
                every = round(self.params['snapshot_period'] / sim.dt)
                if every > 0 and sim.steps % every == 0:
                    self._snapshot()
                self.last_outputs = sim.outputs()
                return
            if early:
                continue
            if self._factor > 0.0:
                if not ahead.ahead_of_time:
                    self._prepare_next()
                return

    def _rewind(self) -> None:
        """Drop the states of the block computed ahead that are not published: the simulation goes back to
        the last state published (``Simulation.restore``, which continues bit for bit)."""
        self.sim.restore(*self._published_state())
        self._ahead = self._next = None
        self.last_outputs = self.sim.outputs()

    def _published_state(self) -> tuple[int, np.ndarray, np.ndarray]:
        """The step count, q and qd of the last state published: the simulation's, or a row of the block ahead."""
        ahead, sim = self._ahead, self.sim
        if ahead is None:
            return sim.steps, sim.q, sim.qd
        row = ahead.published
        if row == 0:
            return ahead.before
        return ahead.before[0] + row, ahead.block.q[row - 1], ahead.block.qd[row - 1]

    def _waits_next(self) -> bool:
        """Whether the loop will wait after this state (stop_at, or the end of its plan), as _ready
        decides: then /clock goes with it, so every node's simulation time is the newest state's."""
        sim, stop_at = self.sim, self.params['stop_at']
        return ((stop_at > 0.0 and sim.t >= stop_at - 0.5 * sim.dt)
                or (sim.selection.trajectory and not self.plan.covers(sim.t, sim.t + sim.dt)))

    def _snapshot(self) -> None:
        """Publish the loop's state on state_snapshot (a keeper holds it for a restarted node)."""
        sim = self.sim
        if sim is None:
            return
        steps, q, qd = self._published_state()
        command, since = self.command if self.command is not None else (None, 0.0)
        switches = messages.switches_from_selection(sim.selection)
        self._graph.publish_snapshot(DynamicsSnapshot(
            anchor=sim.initial_time, steps=steps, dt=sim.dt, q=tuple(q), qd=tuple(qd),
            motor_torque=sim.motor_torque, command=command, command_since=since,
            command_expired=self.command_expired,
            switches=tuple(switches[name] for name in SWITCHES),
            gains=(float(sim.gains.alpha), float(sim.gains.beta)), paused=self.paused,
            seen_until_ns=codec.to_nanoseconds(sim.initial_time + steps * sim.dt)))

    def _publish(self, out: StepOutputs) -> None:
        """Publish the messages of the current state (start, reset)."""
        self.last_outputs = out
        self._note_residual(out.residual)
        self._graph.prepare(out, self.clock_schedule.due(codec.to_nanoseconds(out.t), final=True))()
        self._mark_sync()

    def _note_residual(self, residual: float) -> None:
        with self._window_lock:  # the diagnostics swap windows on the executor thread: lose no step
            self._window.residual_max = max(self._window.residual_max, residual)
