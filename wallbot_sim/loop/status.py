"""What the dynamics loop reports: its run state (the diagnostics' status), how a tick ended, and the
statistics of the steps since the last diagnostics message."""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from enum import Enum, auto

from wallbot_msgs_py import topics
from wallbot_sim import messages

LATE_LIMIT = 2e-3
"""A step published more than this after its due time counts as late (s)."""


class RunState(Enum):
    """The loop's run state; the value is the diagnostics' ``status`` text ({t}: simulation time,
    {reason}: why the robot left the wall)."""

    LOADING_KERNEL = messages.LOADING_KERNEL
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
    residual_settled: float = math.nan
    """Largest constraint residual of the window's states at or after ``topics.RESIDUAL_SETTLED_AFTER``."""


class Statistics:
    """The :class:`Window` the loop thread fills and the diagnostics (executor thread) take once a second."""

    def __init__(self) -> None:
        self.window = Window()
        """The window being filled: the loop thread captures it before counting a step's figures into it."""
        self._lock = threading.Lock()

    def take(self) -> Window:
        """The statistics since the last call; a new window starts."""
        with self._lock:
            window, self.window = self.window, Window()
        return window

    def note_residual(self, residual: float, t: float) -> None:
        """The residual of the state at simulation time ``t``."""
        with self._lock:  # the diagnostics swap windows on the executor thread: lose no step
            self.window.residual_max = max(self.window.residual_max, residual)
            self.window.residual_settled = messages.settled_residual(self.window.residual_settled, residual, t)


def count_step(window: Window, step_time: float, lateness: float) -> None:
    """A step computed in ``step_time`` seconds and published ``lateness`` seconds after it was due, into
    ``window``."""
    window.steps += 1
    window.step_time_sum += step_time
    window.step_time_max = max(window.step_time_max, step_time)
    window.lateness_max = max(window.lateness_max, lateness)
    if lateness > LATE_LIMIT:
        window.late += 1


SIDES = ('left', 'right')


@dataclass(frozen=True)
class SideMotor:
    """One side motor at a state: the torque it was commanded (after a motor_efficiency fault) and the torque its
    envelope let it apply (N m), and since when (simulation s) it has applied less than commanded (None: it applies
    its command)."""

    commanded: float
    applied: float
    saturated_since: float | None


class MotorSaturation:
    """The side motors' saturation (docs/model.md 13.2) over the step from each state: noted at every state (by the
    loop thread, by ``simulate --bag``), read by the diagnostics (a tuple replaced whole: a reader sees one state's). Without a motor block (``present`` false)
    it notes nothing and reports nothing."""

    def __init__(self, present: bool) -> None:
        self.present = present
        self.sides: tuple[SideMotor, ...] = ()
        """The left and right motor at the newest state noted (empty before the first)."""

    def note(self, t: float, commanded: tuple[float, float], applied: tuple[float, float]) -> None:
        """The step from the state at ``t`` (s) applies ``applied`` for ``commanded``: a side saturates where they differ (the
        envelope clips exactly, so a command inside it is applied to the bit)."""
        if not self.present:
            return
        before = self.sides or (None, None)
        self.sides = tuple(
            SideMotor(command, torque, None if torque == command else
                      (prior.saturated_since if prior is not None and prior.saturated_since is not None else t))
            for prior, command, torque in zip(before, commanded, applied))

    def report(self) -> tuple[list[tuple[str, object]], str]:
        """The diagnostics' entries (each side's commanded and applied torque and since when it saturates) and the
        saturated sides, e.g. 'left since t = 1.234 s (commanded 3 N m, applied 1.2 N m)' ('' for none), of one
        state."""
        sides, entries = self.sides, []
        for side, motor in zip(SIDES, sides):
            since = motor.saturated_since
            entries += [(topics.DIAGNOSTIC_MOTOR_COMMANDED.format(side=side), motor.commanded),
                        (topics.DIAGNOSTIC_MOTOR_APPLIED.format(side=side), motor.applied),
                        (f'{side} motor saturated since (s)', 'not saturated' if since is None else since)]
        saturated = ', '.join(f'{side} since t = {motor.saturated_since:.3f} s (commanded {motor.commanded:.3g} N m, '
                              f'applied {motor.applied:.3g} N m)'
                              for side, motor in zip(SIDES, sides) if motor.saturated_since is not None)
        return entries, saturated
