"""How a run starts: what it waits for before its first step (a recorder, a keeper's snapshot, the start's plan,
the controller and its first command) and when a start gives up.

A start that waits for its controller (``wait_for_command``) longer than ``command_wait_timeout`` gives up: the
loop stops with :attr:`CommandWait.gave_up` saying why, and the node exits with status 1.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from wallbot_msgs_py import codec
from wallbot_msgs_py.snapshot import DynamicsSnapshot
from wallbot_sim.loop.events import ConstraintSwitch
from wallbot_sim.loop.faults import faults_on
from wallbot_sim.loop.graph import Log
from wallbot_sim.loop.snapshots import kept_constraints, kept_contact
from wallbot_sim.loop.status import RunState, Status
from wallbot_sim.settings.dynamics import DynamicsSettings

if TYPE_CHECKING:
    from wallbot_sim.loop.loop import DynamicsLoop

COMMAND_WAIT_WARNING = 5.0
"""Wall seconds of a wait for the controller (wait_for_command) after which the log says so: a
controller started with the dynamics is there well before, so a longer wait is worth a line."""
MISSING = {RunState.WAITING_CONTROLLER: 'no controller (a wheel_torque_cmd publisher subscribing odom, matched both '
                                        'ways)',
           RunState.WAITING_FIRST_COMMAND: 'no wheel_torque_cmd answering the t = 0 state',
           RunState.WAITING_RESUMED_COMMAND: 'no wheel_torque_cmd answering the resumed state at t = {t:.3f} s'}
"""What a wait for the controller found missing when it gave up."""
ANSWER_WAITS = (RunState.WAITING_FIRST_COMMAND, RunState.WAITING_RESUMED_COMMAND)
"""The waits for the answer to a state already published."""
RESEND_EVERY = 5.0
"""Wall seconds without the answer to the awaited state after which the loop sends that state to the controller
again (``Graph.resend_to_controller``). Discovery matches each direction on its own: a controller whose odometry
reader matched the dynamics' writer only after the state went out never gets it (seen under load, 1 run in ~10:
the start then waited for command_wait_timeout and gave up). A controller acting at control instants answers a
state once; sent again to one that did answer, it is ignored (its instant has passed)."""


class CommandWait:
    """The wait for the controller or its first command (``wait_for_command``), and giving up on it."""

    def __init__(self) -> None:
        self.current: tuple[RunState, float, bool] | None = None
        """The wait under way: which, since when (clock), whether the log said it."""
        self.gave_up: str | None = None
        """Why the loop stopped without starting (then the node exits), or None."""
        self.sent_at = 0.0
        """Clock time the awaited state last went out again (``resend_due``)."""

    def wait(self, state: RunState, now: float, limit: float, t: float, log: Log) -> Status:
        """Wait (``state``) at clock time ``now`` and simulation time ``t``: the status saying so, or that the wait
        gave up, after ``limit`` (wall s, 0: never) from its own beginning.

        Each wait counts from its own beginning: the answer to the t = 0 state can only come once that state is
        out, which a wait for the recorder or for the constraints may delay. Giving up logs one error line naming
        what was missing and sets :attr:`gave_up`.
        """
        if self.current is None or self.current[0] is not state:
            self.current = (state, now, False)
        _state, since, said = self.current
        waited = now - since
        status = Status(state, t=t, waited=waited, limit=limit)
        if 0.0 < limit < waited:
            missing = MISSING[state].format(t=t)
            self.gave_up = (f'{missing} within command_wait_timeout {limit:g} s (wall) with wait_for_command set: '
                            'start the controller first, or set command_wait_timeout 0 to wait for ever')
            log.error(f'{self.gave_up}; exiting')
            return Status(RunState.GAVE_UP, reason=missing)
        if waited > COMMAND_WAIT_WARNING and not said:
            self.current = (state, since, True)
            log.warning(str(status))
        return status

    def resend_due(self, now: float) -> bool:
        """Whether the wait under way, one for an answer (ANSWER_WAITS), has gone RESEND_EVERY without one since it
        began or since the state last went out again; if so, the state goes out again now."""
        if self.current is None or self.current[0] not in ANSWER_WAITS:
            return False
        if now - max(self.current[1], self.sent_at) < RESEND_EVERY:
            return False
        self.sent_at = now
        return True

    def end(self) -> None:
        """No wait is under way (the loop runs)."""
        self.current = None


def driven_start_wait(settings: DynamicsSettings, resuming: bool, planned: bool,
                      controller_listening: Callable[[], bool]) -> RunState | None:
    """Why a driven run may not create (or resume, ``resuming``) its simulation yet (None: it may).

    A moving start (initial_at_rest false) takes the reference velocity at t = 0, so it needs the plan
    (``planned``; a resume takes the kept velocity). With wait_for_command, a controller must be there to hear the
    first state, the initial or the resumed one: a wheel_torque_cmd publisher exists, its node subscribes odom,
    and every discovered odom subscription is matched (odom is volatile: a subscriber matched later would miss
    that state, and the first step would wait for ever).
    """
    if not resuming and not settings.initial_at_rest and not planned:
        return RunState.WAITING_START_PLAN
    if settings.wait_for_command and not controller_listening():
        return RunState.WAITING_CONTROLLER
    return None


class StartGate:
    """The start of ``loop``'s run: the waits before its first step, and the simulation it starts with (from its
    initial state at the first constraint set, or from a kept snapshot: ``loop.resume``)."""

    def __init__(self, loop: DynamicsLoop) -> None:
        self.loop = loop
        self.command_wait = CommandWait()

    def started(self) -> bool:
        """Whether a simulation runs, after applying a pending constraint set if the start's waits allow (a
        recorder, a keeper's snapshot, the start's plan, the controller)."""
        loop = self.loop
        if loop.sim is None and loop.settings.wait_for_recorder and not loop.graph.recorder_listening():
            loop.status = Status(RunState.WAITING_RECORDER)
            return False
        # the wait counts from the constraint set's arrival: by then discovery is under way
        if (loop.sim is None and loop.pending_constraints is not None
                and not loop.resume.settle(loop.clock(), loop.graph.keeper_seen())):
            loop.status = Status(RunState.WAITING_KEEPER)
            return False
        pending = loop.pending_constraints
        if pending is not None:
            if loop.sim is None and not pending.selection.trajectory:
                waiting = driven_start_wait(loop.settings, loop.resume.snapshot is not None, loop.plan is not None,
                                            loop.graph.controller_listening)
                if waiting is RunState.WAITING_CONTROLLER:
                    self.wait_for_command(waiting)
                    return False
                if waiting is not None:
                    loop.status = Status(waiting)
                    return False
            if pending.selection.trajectory and loop.plan is None:
                loop.status = Status(RunState.WAITING_PLAN)
                if loop.sim is None:
                    return False
            else:
                loop.pending_constraints = None
                loop.switch(pending)
        return loop.sim is not None

    def wait_for_command(self, state: RunState) -> None:
        """Wait (``state``) for the controller or its first command, saying so; a start gives up after
        ``command_wait_timeout`` (wall, 0: never) of either wait, and the loop stops."""
        loop = self.loop
        if self.command_wait.gave_up is not None:  # said once; the loop is stopping
            return
        start = not loop.stepped or state is RunState.WAITING_RESUMED_COMMAND
        limit = loop.settings.command_wait_timeout if start else 0.0
        loop.status = self.command_wait.wait(state, loop.clock(), limit, loop.sim.t if loop.sim is not None else 0.0,
                                             loop.log)
        if self.command_wait.gave_up is not None:
            loop.stopping.set()
        elif self.command_wait.resend_due(loop.clock()):
            loop.graph.resend_to_controller()
            loop.log.info(f'no answer yet: the t = {loop.status.t:.3f} s state goes to the controller again')

    def resumed_unanswered(self) -> bool:
        """Lockstep in a process that resumed a kept snapshot: whether the sync state awaiting its
        answer would be the first answer since the process published its first state.

        That answer waits as a start's does (command_wait_timeout), not lockstep_timeout: the
        resumed node is a new participant, and the controller sends its answer only once it
        hears the node (``HeldCommands``), which needs the node's name from discovery. Measured
        on the project's 2-core VM under load: 1.9-2.4 s after the first resumed state, longer
        than the 2 s of lockstep_timeout; a lockstep given up then let the loop run on the kept
        command while the controller's answers, held and replaced by newer ones, never went out
        (86 commands missing from the bag). The first resumed state is seldom a control instant
        (the controller acts again from the next one), so the wait is at the first sync state,
        which is.
        """
        loop = self.loop
        return loop.resume.snapshot is not None and loop.lockstep.first_answer_pending() and loop.waits.answer_awaited()

    def begin(self, switch: ConstraintSwitch) -> None:
        """Start the run with the constraint set ``switch``: from the kept snapshot if a keeper gave one, else
        from the initial state at t = 0."""
        loop = self.loop
        if loop.resume.snapshot is not None:
            self._restore(loop.resume.snapshot, switch)
            return
        loop.selection, loop.gains = switch.selection, switch.gains
        loop.sim = loop.segments.simulation(*loop.segments.initial_state(), 0.0)
        fresh = f' from the initial state ({loop.resume.timed_out})' if loop.resume.timed_out else ''
        loop.log.info(f'starting with constraints {switch.selection.label()}{fresh}')
        loop.publish(loop.sim.outputs())
        loop.snapshot()
        if faults_on(loop.settings):  # faults set at start: the run's record says so from t = 0
            loop.tell_faults(faults_on(loop.settings), 'start')

    def _restore(self, kept: DynamicsSnapshot, switch: ConstraintSwitch) -> None:
        """Continue from a kept snapshot; then apply the constraint set in force now, if it differs."""
        loop = self.loop
        loop.selection, loop.gains = kept_constraints(kept, switch, loop.plan is not None)
        if kept.dt == 1.0 / loop.settings.rate_hz:
            loop.sim = loop.segments.simulation(kept.q, kept.qd, kept.anchor, kept.motor_torque)
            loop.sim.restore(kept.steps, kept.q, kept.qd, kept_contact(kept))
        else:  # another rate_hz: a new run segment from the kept time, as a rate change makes
            loop.sim = loop.segments.simulation(kept.q, kept.qd, kept.t, kept.motor_torque)
            loop.sim.restore(0, kept.q, kept.qd, kept_contact(kept))
        loop.commands.command = (kept.command, kept.command_since) if kept.command is not None else None
        loop.commands.expired = kept.command_expired
        loop.paused = kept.paused
        loop.resume.catch_up_to(kept.seen_until_ns)
        behind = max(0, kept.seen_until_ns - kept.stamp_ns) * 1e-9
        loop.log.info(
            f'resuming from the kept snapshot at t = {kept.t:.3f} s (step {kept.steps}, constraints '
            f'{loop.selection.label()}{", paused" if kept.paused else ""}); the graph has seen up to '
            f't = {kept.seen_until_ns * 1e-9:.3f} s: {behind:.3f} s recomputed unpublished')
        if (switch.selection, switch.gains) != (loop.selection, loop.gains):
            loop.switch(switch)
        out = loop.sim.outputs()  # the solve the first step reuses, as after every step of the first life
        if loop.resume.publishes(codec.to_nanoseconds(loop.sim.t)):
            loop.publish(out)
        loop.snapshot()
