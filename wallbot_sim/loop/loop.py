"""The dynamics loop: its run state and decisions, a tick at a time (see the package's docstring)."""

from __future__ import annotations

import contextlib
import math
import queue
import threading
import time
from typing import Callable, Iterator, Mapping

import numpy as np

from wallbot_msgs_py import codec, topics
from wallbot_sim import messages
from wallbot_sim.loop.blocks import Blocks
from wallbot_sim.loop.commands import Commands
from wallbot_sim.loop.events import (ConstraintSwitch, Event, NewPlan, ParameterChange, Pause, PumpCommand,
                                     RecordProgress, Reset, ResumeSnapshot, Step, Teleport, TorqueCommand)
from wallbot_sim.loop.faults import (FaultChange, FaultSchedule, delivered, fault_changes, fault_values, parse_schedule,
                                     silenced)
from wallbot_sim.loop.graph import Graph, Log
from wallbot_sim.loop.pacing import Pacer
from wallbot_sim.loop.resume import ResumeGate
from wallbot_sim.loop.segments import Segments
from wallbot_sim.loop.snapshots import snapshot_every, snapshot_of
from wallbot_sim.loop.start import StartGate
from wallbot_sim.loop.status import WAIT_AFTER, Decision, MotorSaturation, RunState, Statistics, Status, count_step
from wallbot_sim.loop.waits import BackPressure, Lockstep, RunningWaits
from wallbot_sim.model import (BaumgarteGains, ConstraintSelection, DivergedError, Robot, RobotParameters, Simulation,
                               StepOutputs, adsorption_analysis)
from wallbot_sim.model.contact import DetachedError
from wallbot_sim.model.python_only import refuse_compiled
from wallbot_sim.model.simulation import NUMBA
from wallbot_sim.model.world import World
from wallbot_sim.model.trajectories import STAMP_RESOLUTION
from wallbot_sim.settings.dynamics import DynamicsSettings
from wallbot_sim.settings.table import changed


def robot_with(params: RobotParameters, adhesion_force: float, adhesion_scale: float = 1.0,
               world: World | None = None) -> Robot:
    """The robot of the robot file's ``params`` on ``world``, with the adhesion_force setting (N) unless it is 0
    (then the file's), times the adhesion_scale setting (a suction fault below 1)."""
    if adhesion_scale == 1.0:
        return Robot(params.replace(adhesion_force=adhesion_force) if adhesion_force else params, world)
    force = adhesion_force or adsorption_analysis(params).applied_force
    return Robot(params.replace(adhesion_force=force * adhesion_scale), world)


class DynamicsLoop:
    """The simulation and the state around it, written by the loop thread only (its rooms: ``start``, ``segments``,
    ``commands``, ``lockstep``, ``backpressure`` and ``waits``, ``resume``, ``pacer``, ``blocks``, ``statistics``).
    ``settings``: the node's parameter values, which a :class:`ParameterChange` updates at the next step boundary."""

    def __init__(self, settings: DynamicsSettings, robot_file: RobotParameters, graph: Graph, log: Log,
                 pacer: Pacer, clock: Callable[[], float] = time.monotonic, world: World | None = None) -> None:
        """``world``: the world file's surface (None: a vertical, uniform wall); what only the python engine
        computes is refused here on the numba engine (ParameterError)."""
        self.settings = settings
        self._robot_file, self._world = robot_file, world
        self.robot = robot_with(robot_file, settings.adhesion_force, settings.adhesion_scale, world)
        if settings.engine == NUMBA:
            refuse_compiled(self.robot)
        self.schedule = FaultSchedule(parse_schedule(settings.fault_schedule))
        """The faults still to apply at their simulation times (``loop.faults``)."""
        self.graph, self.log, self.pacer, self.clock = graph, log, pacer, clock
        self._events: queue.SimpleQueue[Event] = queue.SimpleQueue()
        self._wake = threading.Event()
        self.stopping = threading.Event()
        self.factor = settings.real_time_factor
        """The real-time factor, read by the pacer while it sleeps (:meth:`post` sets it at once)."""
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
        self.stepped = False
        """Whether a step was taken: only a start's wait for the controller gives up (a resumed
        start's wait for its first answer comes after the steps of its catch-up)."""
        self.reset_requested: float | None = None  # clock time of a reset not yet applied
        self.last_outputs: StepOutputs | None = None
        self.pump_command = 1.0
        """The vacuum pump's command u (pump_command), held by every simulation the loop makes."""
        self.commands, self.lockstep, self.backpressure = Commands(), Lockstep(), BackPressure()
        self.waits = RunningWaits(self)
        self.lockstep_gave_up: str | None = None
        """Why a strict lockstep ended the run (the controller left a state unanswered), or None."""
        self.start = StartGate(self)
        self.segments = Segments(self)
        self.resume = ResumeGate(settings.resume_wait)
        self.clock_schedule = messages.ClockSchedule(settings.clock_rate_hz)
        self.statistics = Statistics()
        self.saturation = MotorSaturation(robot_file.motor is not None)
        self.blocks = Blocks(self)

    # --- any thread ---------------------------------------------------------------------------------
    def post(self, event: Event) -> None:
        """Queue an event for the next step boundary and end the loop's wait."""
        if isinstance(event, ParameterChange) and 'real_time_factor' in event.changes:
            self.factor = float(event.changes['real_time_factor'])  # a sleeping step sees it at once
        self._events.put(event)
        self._wake.set()

    def stop(self) -> None:
        self.stopping.set()
        self._wake.set()

    def command_state(self) -> str:
        """The 'command' value of /diagnostics."""
        return 'no simulation yet' if self.sim is None else self.commands.state(self.sim.selection.trajectory)

    @property
    def gave_up(self) -> str | None:
        """Why the loop stopped for good, its start given up or a strict lockstep's answer missing (then the node
        exits), or None."""
        return self.start.command_wait.gave_up or self.lockstep_gave_up

    @property
    def silenced(self) -> frozenset[topics.Topic]:
        """The topics a sensor dropout keeps silent now (read by the loop thread as it publishes)."""
        return silenced(self.settings)

    @property
    def in_error(self) -> bool:
        """Whether the diagnostics' level is ERROR: diverged, crashed or given up."""
        return self.diverged or self.gave_up is not None

    # --- loop thread --------------------------------------------------------------------------------
    @contextlib.contextmanager
    def loading_kernel(self) -> Iterator[None]:
        """The status says the compiled kernel is loading while the node loads it (before :meth:`run`)."""
        self.status = Status(RunState.LOADING_KERNEL)
        try:
            yield
        finally:
            self.status = Status(RunState.WAITING_CONSTRAINTS)

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

    def tick(self) -> Decision:
        """Apply the queued events, then take one step if nothing holds it back.

        A state of a block computed ahead is published instead while no event came but a recorder's progress
        and plans that give the states computed ahead (``Blocks.keep_through``); any other event drops the rest
        of the block first (``Blocks.drop``), so it applies at the boundary after the last state published, as
        it does between single steps.
        """
        events = self._take_events()
        if self.blocks.ahead is not None and self.blocks.keep_through(events):
            for event in events:
                self._apply(event)
            self.blocks.publish_ahead()
            return Decision.STEPPED
        if events or self.blocks.ahead is not None:
            self.blocks.drop(events)
        for event in events:
            self._apply(event)
        if self.reset_requested is not None:
            self.segments.reset_when_answered()
        if not self._ready():
            self.pacer.reanchor()
            return Decision.NOT_READY
        for fault in self.schedule.due(self.sim.t, self.sim.dt):
            self._apply_settings(dict(fault.changes), cause='scheduled')
        if self.waits.lockstep_blocked():  # no re-anchor: a prompt answer costs no pace
            return Decision.LOCKSTEP
        if self.waits.held_back():
            return Decision.HELD_BACK
        size = self.blocks.size()
        if size > 1 and self.blocks.start(size):
            return Decision.STEPPED
        self._step()
        if self.paused:  # a step that a Step event allowed
            self.steps_to_take -= 1
        return Decision.STEPPED

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
                    self.snapshot()
            case TorqueCommand():
                self.commands.receive(event.torque, self.sim.t if self.sim is not None else 0.0)
                if self.lockstep.command_came():
                    self.log.info(f'wheel_torque_cmd again at t = {self.sim.t:.3f} s: lockstep resumed')
                self.snapshot()  # so a resume recomputes the steps after it with the commands they had
            case PumpCommand():
                self._command_pump(event.command)
            case Reset():
                self.reset_requested = self.clock()
            case Pause():
                self.paused, self.steps_to_take = event.paused, 0
                self.log.info('paused' if event.paused else 'running again')
                self.snapshot()
            case Step():
                if self.paused:
                    self.steps_to_take += event.count
                else:
                    self.log.warning('~/step ignored: the simulation is running (it steps while paused)')
            case Teleport():
                self.segments.teleport(event)
            case ResumeSnapshot():
                self.resume.offer(event.snapshot)
            case ParameterChange():
                self._apply_settings(event.changes)
            case RecordProgress():
                self.backpressure.progress_ns = event.stamp_ns

    def _apply_settings(self, changes: Mapping[str, object], cause: str = 'parameter') -> None:
        self.settings = changed(self.settings, changes)
        if 'realtime_priority' in changes:
            self.pacer.priority = changes['realtime_priority']
        if 'rate_hz' in changes and self.sim is not None:
            self.sim = self.segments.simulation(self.sim.q, self.sim.qd, self.sim.t, self.sim.motor_torque)
            self.snapshot()
        if {'adhesion_force', 'adhesion_scale'} & set(changes):
            self.robot = robot_with(self._robot_file, self.settings.adhesion_force, self.settings.adhesion_scale,
                                    self._world)
            if self.sim is not None:
                self.sim.set_adhesion_force(self.robot.params.adhesion_force)
        if 'contact_model' in changes and self.sim is not None:
            self.sim.set_contact_model(changes['contact_model'])
        self.pacer.reanchor()
        self.log.info(('scheduled faults: ' if cause == 'scheduled' else 'parameters: ')
                      + ', '.join(f'{k} = {v}' for k, v in changes.items())
                      + (f' at t = {self.sim.t:.3f} s' if self.sim is not None else ''))
        faults = fault_changes(changes)
        if faults:
            self.tell_faults(faults, cause)

    def _command_pump(self, command: float) -> None:
        if self.robot.params.adhesion is None:
            self.log.warning(f'pump_command {command:g} ignored: the robot file has no adhesion block')
            return
        self.pump_command = command
        if self.sim is not None:
            self.sim.set_pump_command(command)

    def tell_faults(self, names: tuple[str, ...], cause: str) -> None:
        """Tell the graph that the fault settings ``names`` changed (an event it records)."""
        self.graph.publish_fault(FaultChange(self.sim.t if self.sim is not None else 0.0, names,
                                             fault_values(self.settings), cause))

    def switch(self, switch: ConstraintSwitch) -> None:
        """Run with the constraint set ``switch`` from now on (the first one starts the run: ``StartGate.begin``)."""
        if self.sim is None:
            self.start.begin(switch)
            return
        selection, gains = switch.selection, switch.gains
        report = self.sim.set_constraints(selection, gains)
        self.selection, self.gains = selection, gains
        self.log.info(
            f'constraints {report.previous.label()} -> {selection.label()} at t = {self.sim.t:.3f} s: '
            f'velocity violation {report.violation_before:.3e} before, {report.violation_after:.3e} after projection')
        self.snapshot()

    def _ready(self) -> bool:
        """Apply a pending constraint set if possible; say whether the next step may run."""
        if (self.sim is None or self.pending_constraints is not None) and not self.start.started():
            return False
        sim = self.sim
        if (self.paused and self.steps_to_take <= 0) or self.diverged or self.detached:
            self.status = (Status(RunState.DIVERGED) if self.diverged else Status(RunState.DETACHED, reason=self.detached)
                           if self.detached else Status(RunState.PAUSED))
            return False
        if self.settings.stop_at > 0.0 and sim.t >= self.settings.stop_at - 0.5 * sim.dt:
            if self.status.state is not RunState.STOPPED:
                self.snapshot()  # the state it stands at, for whoever asked for the stop
            self.status = Status(RunState.STOPPED, t=sim.t)
            return False
        if sim.selection.trajectory and not self.plan.covers(sim.t, sim.t + sim.dt):
            if self.resume.catching_up and self.plan.start > sim.t + STAMP_RESOLUTION:
                # the plan of the kept state was replaced before the kill: publishing this earlier
                # state makes the trajectory node replan from it (its clock went back)
                self.log.warning(f'the newest plan starts at {self.plan.start:.3f} s, after the kept '
                                  f'state at {sim.t:.3f} s: publishing from there')
                self.resume.stop_catch_up()
                self.publish(sim.outputs())
            self.status = Status(RunState.WAITING_COVERING_PLAN, t=sim.t)
            return False
        if self.settings.wait_for_command and not sim.selection.trajectory:
            if sim.steps == 0 and self.commands.command is None:
                self.start.wait_for_command(RunState.WAITING_FIRST_COMMAND)
                return False
            if self.start.resumed_unanswered():
                self.start.wait_for_command(RunState.WAITING_RESUMED_COMMAND)
                return False
        if self.start.command_wait.current is not None:
            self.start.command_wait.end()
        self.status = Status(RunState.RUNNING)
        return True

    def torque_at(self, t: float) -> tuple[float, float]:
        """The motor torque of a step from time ``t``: the command in force (``Commands.torque_at``) as the motors
        deliver it (``faults.delivered``)."""
        return delivered(self.commands.torque_at(t, self.sim.selection.trajectory, self.settings.command_timeout),
                         self.settings)

    def _step(self) -> None:
        self.stepped = True
        sim, commands, timeout = self.sim, self.commands, self.settings.command_timeout
        if commands.command is not None and not commands.expired:
            commands.note_expiry(sim.t, sim.selection.trajectory, timeout, self.log)
        torque = self.torque_at(sim.t)
        if torque != sim.motor_torque:
            sim.set_motor_torque(*torque)
        if self.saturation.present:
            self.saturation.note(sim.t, sim.motor_torque, sim.applied_torque)
        began = time.perf_counter()
        try:
            sim.step()
            out = sim.outputs()
            if not (math.isfinite(float(np.sum(out.constraint_force))) and math.isfinite(out.residual)):
                raise DivergedError(f'constraint force is no longer finite at t = {sim.t:.3f} s')
        except (DivergedError, DetachedError) as error:  # the simulation holds until a reset
            if isinstance(error, DetachedError):
                self.detached, self.status = str(error), Status(RunState.DETACHED, reason=str(error))
            else:
                self.diverged, self.status = True, Status(RunState.DIVERGED)
            self.log.error(f'{error}: simulation paused (reset with ~/reset)')
            return
        step_time = time.perf_counter() - began
        if self.resume.catching_up and not self.resume.publishes(codec.to_nanoseconds(sim.t)):
            self.last_outputs = out  # the graph has this state: recomputed, not published nor paced
            return
        window = self.statistics.window
        publish = sim.steps % self.settings.publish_every == 0
        if publish:
            clock = self.clock_schedule.due(codec.to_nanoseconds(out.t), final=self.waits_next())
            send = self.graph.prepare(out, clock)
        count_step(window, step_time, self.pacer.wait(sim.steps, sim.dt, lambda: self.factor, self.stopping))
        if publish:
            send()
            self.lockstep.mark_sync(self.waits.commander_hears())
            every = snapshot_every(self.settings.snapshot_period, sim.dt)
            if every > 0 and sim.steps % every == 0:
                self.snapshot()
        self.statistics.note_residual(out.residual, out.t)
        self.last_outputs = out

    def waits_next(self) -> bool:
        """Whether the loop will wait after this state (stop_at, or the end of its plan), as _ready
        decides: then /clock goes with it, so every node's simulation time is the newest state's."""
        sim, stop_at = self.sim, self.settings.stop_at
        return ((stop_at > 0.0 and sim.t >= stop_at - 0.5 * sim.dt)
                or (sim.selection.trajectory and not self.plan.covers(sim.t, sim.t + sim.dt)))

    def snapshot(self) -> None:
        """Publish the loop's state on state_snapshot (a keeper holds it for a restarted node)."""
        if self.sim is not None:
            self.graph.publish_snapshot(snapshot_of(self.sim, self.blocks.published_state(), self.commands,
                                                    self.paused))

    def publish(self, out: StepOutputs) -> None:
        """Publish the messages of the current state (start, reset)."""
        self.last_outputs = out
        self.statistics.note_residual(out.residual, out.t)
        self.saturation.note(out.t, self.sim.motor_torque, out.motor_torque)
        self.graph.prepare(out, self.clock_schedule.due(codec.to_nanoseconds(out.t), final=True))()
        self.lockstep.mark_sync(self.waits.commander_hears())
