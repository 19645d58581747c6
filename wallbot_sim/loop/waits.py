"""The loop's waits on other nodes once it runs: lockstep (the controller's answer to a published state) and
back-pressure (a recorder's progress). Each gives up after a timeout of wall time, so a dead controller or
recorder costs that once and never stops the simulation for ever.

Back-pressure (lossless recording at any factor). DDS acknowledgements are not enough: a reliable KEEP_LAST
reader acknowledges a sample once it is in its history, not once the application has taken it, so a recorder
slower than the simulation still loses samples (measured: ``wait_for_all_acked`` every 200 steps returned within
4 ms while a slow subscriber lost 70 % of the samples), and acknowledgements may wait for Fast DDS's heartbeat
period (up to 3 s per wait measured). So the recorder reports its progress instead: it publishes on
``record_progress`` the newest /clock stamp up to which it has taken every message. While at least one publisher
exists on that topic, the loop never runs more than ``backpressure_window`` steps (default 200, well below the
recorded topics' depth of 1000) ahead of the reported progress: at factor 0 that paces the loop to the recorder;
at factor 1 it only acts when the recorder falls behind (a loaded machine, or the burst of a loop catching up
after a stall), which then slows the simulation instead of losing messages. Without a recorder it runs free.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable

from wallbot_sim.loop.graph import Log
from wallbot_sim.loop.status import RunState, Status

if TYPE_CHECKING:
    from wallbot_sim.loop.loop import DynamicsLoop

BACKPRESSURE_TIMEOUT = 2.0
"""Wall seconds the loop waits for a recorder's progress to move before stepping on without it: a
recorder that was killed, restarted or starved must not stop the simulation for ever (a restarted
dynamics, or one beside a restarted recorder, would otherwise wait for a report that never comes)."""
RECORDER_CHECK = 0.2
"""Wall seconds between two looks for a record_progress publisher (a graph query costs time)."""


class Lockstep:
    """Lockstep (driven mode, ``lockstep_every`` N > 0): after the state of every Nth step is published, the next
    step waits for a command that arrived after it: the controller's answer to that very state, so the loop
    behaves like a controller sampling every N steps with no delay, at any pace or CPU load. Without an answer
    within ``lockstep_timeout`` (wall) it steps on, free-running until commands return (then command_timeout
    brings zero torque, as without lockstep). The timeout is long against a loaded machine's scheduling delays (a
    0.25 s one was exceeded under load, and the loop then no longer equalled the model's), short against a
    controller's death."""

    def __init__(self) -> None:
        self.serial = self.sync_serial = 0
        """Commands received; that count when a sync state went out."""
        self.sync_delivered = True
        """Whether the controller's odometry carried the last state published."""
        self.first_sync: int | None = None
        """``serial`` when this process published its first state (None: none yet)."""
        self.since: float | None = None
        """Clock time the wait for the awaited answer began."""
        self.lost = False
        """Whether lockstep gave up until commands return."""

    def command_came(self) -> bool:
        """A command arrived; whether it brings lockstep back."""
        self.serial += 1
        lost, self.lost = self.lost, False
        return lost

    def mark_sync(self, delivered: bool = True) -> None:
        """A state was just published: lockstep waits for a command newer than this, if the controller's odometry
        carried it (``delivered``; a sensor dropout silences it)."""
        self.sync_serial, self.sync_delivered = self.serial, delivered
        if self.first_sync is None:
            self.first_sync = self.serial

    def awaited(self, every: int, steps: int, trajectory: bool, catching_up: bool) -> bool:
        """Whether the last published state, the simulation at ``steps``, was a sync state whose answer (a command
        that arrived after it) is still to come."""
        return (every > 0 and not trajectory and not self.lost and steps % every == 0 and self.sync_delivered
                and self.serial == self.sync_serial and not catching_up)

    def first_answer_pending(self) -> bool:
        """Whether no command came since this process published its first state."""
        return self.first_sync is not None and self.serial == self.first_sync

    def holds(self, now: float, timeout: float) -> bool:
        """Whether to go on waiting for the awaited answer at clock time ``now``; False once ``timeout`` has passed
        since the wait began (then :attr:`lost` until commands return)."""
        if self.since is None:
            self.since = now
        if now - self.since <= timeout:
            return True
        self.since, self.lost = None, True
        return False


class BackPressure:
    """A recorder's progress and whether the loop waits for it."""

    def __init__(self) -> None:
        self.progress_ns: int | None = None
        """The newest /clock stamp a recorder has taken every message up to."""
        self.present = False
        """Whether a recorder (a record_progress publisher) was there at the last look."""
        self._checked = -math.inf
        self._held_since: tuple[float, int | None] | None = None
        """Clock time a wait began, and the progress then."""

    def allows(self, t: float, window: float) -> bool:
        """Whether a step from simulation time ``t`` is within ``window`` seconds of the progress (or no
        recorder is there)."""
        return not self.present or (self.progress_ns is not None and t - self.progress_ns * 1e-9 <= window)

    def held_back(self, now: float, recorder_present: Callable[[], bool], t: float, window: float,
                  log: Log) -> bool:
        """Whether a recorder's progress is more than ``window`` seconds behind the step from ``t`` (at any
        factor: a recorder that falls behind on a loaded machine slows the simulation down instead of losing
        messages), until it has not moved for BACKPRESSURE_TIMEOUT. Whether a recorder is there the graph is
        asked (``recorder_present``) at most every RECORDER_CHECK."""
        if now - self._checked > RECORDER_CHECK:
            self._checked = now
            self.present = recorder_present()
        if not self.present:
            return False
        progress = -math.inf if self.progress_ns is None else self.progress_ns * 1e-9
        if t - progress <= window:
            self._held_since = None
            return False
        if self._held_since is None or self._held_since[1] != self.progress_ns:  # a new wait, or progress moved
            self._held_since = (now, self.progress_ns)
        if now - self._held_since[0] <= BACKPRESSURE_TIMEOUT:
            return True
        if self._held_since[0] > -math.inf:  # once per stalled progress value
            log.warning(f'no record_progress for {BACKPRESSURE_TIMEOUT:g} s (wall) at t = {t:.3f} s: stepping on '
                        'until the recorder reports again')
            self._held_since = (-math.inf, self.progress_ns)
        return False


class RunningWaits:
    """The waits of ``loop`` on other nodes once it runs, decided at each tick from its ``lockstep`` and
    ``backpressure`` and its settings: whether the controller's answer holds the next step, whether a recorder
    does."""

    def __init__(self, loop: DynamicsLoop) -> None:
        self.loop = loop

    def commander_hears(self) -> bool:
        """Whether the commander's sensor (``command_sensor``) carries the states published now (no dropout)."""
        settings = self.loop.settings
        return not (settings.drop_odom if settings.command_sensor == 'odom' else settings.drop_wheel_states)

    def answer_awaited(self) -> bool:
        """Lockstep: whether the last published state was a sync state whose answer is still to come
        (``Lockstep.awaited``)."""
        loop = self.loop
        every = loop.settings.lockstep_every
        if every <= 0:
            return False
        sim = loop.sim
        return loop.lockstep.awaited(every, sim.steps, sim.selection.trajectory, loop.resume.catching_up)

    def lockstep_blocked(self) -> bool:
        """Lockstep: whether to wait for the controller (``Lockstep``); giving up re-anchors the pace."""
        loop = self.loop
        if not self.answer_awaited():
            loop.lockstep.since = None
            return False
        if loop.lockstep.holds(loop.clock(), loop.settings.lockstep_timeout):
            return True
        if loop.settings.strict_lockstep:
            return self._give_up_lockstep()
        loop.pacer.reanchor()  # the time spent waiting for a dead controller is not caught up in a burst
        loop.log.warning(f'no wheel_torque_cmd within {loop.settings.lockstep_timeout:g} s (wall) of the state '
                         f'at t = {loop.sim.t:.3f} s: stepping on without lockstep until commands return')
        return False

    def _give_up_lockstep(self) -> bool:
        """A strict lockstep's answer did not come: the run ends, naming the state left unanswered."""
        loop = self.loop
        if loop.lockstep_gave_up is None:
            loop.lockstep_gave_up = (f'no wheel_torque_cmd answering the state at t = {loop.sim.t:.3f} s within '
                                     f'lockstep_timeout {loop.settings.lockstep_timeout:g} s (wall)')
            loop.log.error(f'{loop.lockstep_gave_up} with strict_lockstep set; exiting')
            loop.status = Status(RunState.GAVE_UP, reason=loop.lockstep_gave_up)
            loop.stopping.set()
        return True

    def held_back(self) -> bool:
        """Whether a recorder's progress is more than the window behind (``BackPressure``)."""
        loop = self.loop
        return loop.backpressure.held_back(loop.clock(), loop.graph.recorder_present, loop.sim.t,
                                           loop.settings.backpressure_window * loop.sim.dt, loop.log)
