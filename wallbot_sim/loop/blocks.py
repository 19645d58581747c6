"""Blocks of steps computed ahead and published one state at a time (the compiled engine's fast path).

On the compiled engine with ideal contact (under the trajectory task, or driven under one torque), the loop
computes blocks of steps ahead and publishes each state when due: an event drops the states not yet published,
so it applies as between single steps. A state no subscriber outside the process hears (a composed recorder
takes the per-step topics from its tap) is handed over ahead of time, logged at its due time, under the
trajectory task or with lockstep: the loop then wakes once per block and for the states that carry /clock or are
heard outside. The states and messages are the single steps', to the bit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from wallbot_msgs_py import codec
from wallbot_sim.loop.events import Event, NewPlan, RecordProgress
from wallbot_sim.loop.graph import PreparedState
from wallbot_sim.loop.snapshots import snapshot_every
from wallbot_sim.loop.status import count_step
from wallbot_sim.model.outputs import StepBlock
from wallbot_sim.model.trajectories import STAMP_RESOLUTION

if TYPE_CHECKING:
    from wallbot_sim.loop.loop import DynamicsLoop
    from wallbot_sim.model.compiled import ReferenceRows

BLOCK_MOST = 50
"""Most steps computed as one block at real-time factor 0 (:meth:`Blocks.size`), all published in one tick: an
event waits at most this many steps (about 2 ms of wall time) for its step boundary."""
BLOCK_PACED = 20
"""Most steps computed as one block while paced: each is published when due, one a tick, and an event
arriving between them drops the rest (:meth:`Blocks.rewind`). Small enough that computing a
block stays well inside the 1 ms before the next state is due."""
HANDOVER_LEAD = 0.010
"""Wall seconds before a state handed over ahead of time is due that the loop wakes to hand it over
(:meth:`Blocks.publish_ahead`): a wake-up up to this much later than asked makes no state late (the
project's VMs woke a sleeping 1 kHz loop late by 2-5 ms mostly, in some hours by up to 10-16 ms). Half
a paced block, so an event waits at most 30 ms at factor 1."""


@dataclass
class Ahead:
    """A block of steps computed ahead of publishing (:meth:`Blocks.start`)."""

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
    (:meth:`Blocks.publish_ahead`)."""


class Blocks:
    """The blocks of ``loop`` (its loop thread only): the one being published and, paced, the next."""

    def __init__(self, loop: DynamicsLoop) -> None:
        self.loop = loop
        self.ahead: Ahead | None = None
        """A block of steps computed, not all published yet (the simulation is at its end)."""
        self.next: Ahead | None = None
        """Paced: the block after ``ahead``, computed (and encoded) between its last states, not taken yet."""
        self._sampled: ReferenceRows | None = None
        """Paced: the reference of the block after ``ahead``, sampled a state before it is computed."""

    def keep_through(self, events: Sequence[Event]) -> bool:
        """Whether the block being published stays through ``events``: a recorder's progress, and plans that give
        the states computed ahead (:meth:`_plan_keeps`); the next block is dropped if a plan does not keep it."""
        if self.ahead is None or not all(isinstance(event, RecordProgress)
                                         or isinstance(event, NewPlan) and self._plan_keeps(event, self.ahead)
                                         for event in events):
            return False
        if self.next is not None and not all(self._plan_keeps(event, self.next)
                                             for event in events if isinstance(event, NewPlan)):
            self.next = None
        return True

    def drop(self, events: Sequence[Event]) -> None:
        """Events the block being published does not stay through came: the next block goes (unless they are a
        recorder's progress only) and the simulation goes back to the last state published (:meth:`rewind`)."""
        if not all(isinstance(event, RecordProgress) for event in events):
            self.next = None  # computed before the event
        if self.ahead is not None:
            self.rewind()

    def _plan_keeps(self, plan: NewPlan, ahead: Ahead) -> bool:
        """Whether ``plan`` gives the steps of ``ahead`` not published yet as the plan in force gave them, to the bit.

        The trajectory node's plans lie on one sample grid, so a renewal agrees with the plan it replaces over
        their overlap: the states computed ahead stand, and the state after a plan is not computed in the
        millisecond before it is due while the executor decodes the plan.
        """
        loop = self.loop
        dt = loop.sim.dt  # the steps' times are within half a nanosecond of their stamps
        start = ahead.stamps[ahead.published] * 1e-9 - dt - STAMP_RESOLUTION
        end = ahead.stamps[-1] * 1e-9 + STAMP_RESOLUTION
        return loop.plan is not None and plan.reference.agrees(loop.plan.reference, start, end)

    def size(self) -> int:
        """How many steps this tick may take as one block (1: a single step).

        Blocks are taken on the compiled engine with ideal contact (``Simulation.tabulates``), publishing every
        state, not resuming, under one motor torque: zero under the trajectory task; driven, the command's, set
        by the single step after it changes. A block ends where a single step would do something between its
        steps: at the last step the plan covers (trajectory task), before the command in force times out, before a
        scheduled fault, at a lockstep state (the step after it waits for the controller's answer), before stop_at,
        at the recorder's window and at the next snapshot. So the states and messages are the single steps', to the
        bit.
        """
        loop = self.loop
        sim, settings = loop.sim, loop.settings
        if (not sim.tabulates or loop.paused or loop.resume.catching_up or settings.publish_every != 1
                or loop.torque_at(sim.t) != sim.motor_torque or loop.waits.answer_awaited()
                or not loop.graph.encodes_blocks(loop.factor <= 0.0)):
            return 1
        size = BLOCK_PACED if loop.factor > 0.0 else BLOCK_MOST
        every = snapshot_every(settings.snapshot_period, sim.dt)
        if every > 0:
            size = min(size, every - sim.steps % every)
        fault = loop.schedule.steps_before_next(sim.t, sim.dt)
        if fault is not None:  # a scheduled fault applies at the boundary after the block's last state
            size = min(size, max(fault, 1))
        lockstep = settings.lockstep_every
        if lockstep > 0 and not sim.selection.trajectory and not loop.lockstep.lost:
            size = min(size, lockstep - sim.steps % lockstep)
        window = settings.backpressure_window * sim.dt
        stop_at = settings.stop_at
        while size > 1:
            t = sim.initial_time + (sim.steps + size - 1) * sim.dt  # the block's last step starts here
            if ((sim.selection.trajectory and not loop.plan.covers(t, t + sim.dt))
                    or loop.torque_at(t) != sim.motor_torque
                    or (stop_at > 0.0 and t >= stop_at - 0.5 * sim.dt)
                    or not loop.backpressure.allows(t, window)):
                size -= 1
                continue
            break
        return size

    def start(self, size: int) -> bool:
        """Take a block of at most ``size`` steps (:meth:`size`): the one computed ahead (:meth:`_prepare_next`)
        if it starts here, else ``size`` steps computed now; publish its first state, or all at factor 0.
        False, nothing taken, if a state among them is not finite (a single step then meets it)."""
        loop = self.loop
        sim = loop.sim
        ahead, self.next = self.next, None
        if ahead is None or ahead.before[0] != sim.steps or len(ahead.stamps) > size:
            ahead = self._compute(size)
            if ahead is None:
                return False
        if not ahead.senders:
            ahead.senders = loop.graph.prepare_block(ahead.block)
        sim.take(ahead.block)
        loop.stepped = True
        ahead.ahead_of_time = self._hands_over_ahead() and not all(state.heard for state in ahead.senders)
        self.ahead = ahead
        self.publish_ahead()
        return True

    def _hands_over_ahead(self) -> bool:
        """Whether a block's states may be handed over ahead of their due times: paced, and no command awaited
        between two of its states (under the trajectory task commands are ignored; with lockstep the next is the
        answer to the block's last state). A free-running driven loop publishes each when due: a command then
        applies within a step of its arrival, not after the states handed over before it."""
        loop = self.loop
        lockstep = loop.settings.lockstep_every > 0 and not loop.lockstep.lost
        return loop.factor > 0.0 and (loop.sim.selection.trajectory or lockstep)

    def _compute(self, size: int) -> Ahead | None:
        """``size`` steps from the simulation's state, not taken yet and not encoded; None if one is not finite."""
        sim = self.loop.sim
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
        Any event but a recorder's progress drops the block (``DynamicsLoop.tick``); so does a boundary that is not
        where it starts."""
        graph = self.loop.graph
        if all_at_once:
            if self.next is None and (size := self.size()) > 1:
                self.next = self._compute(size)
            if self.next is not None and not self.next.senders:
                self.next.senders = graph.prepare_block(self.next.block)
            return
        left = len(self.ahead.stamps) - self.ahead.published
        if self.next is None and left == 3:
            size = self.size()
            if size > 1:
                self._sampled = self.loop.sim.sample_reference(size)
        elif self.next is None and left <= 2:
            size = self.size()  # from the simulation's state: the end of the block being published
            if size > 1:
                self.next = self._compute(size)
        elif self.next is not None and left == 1 and not self.next.senders:
            self.next.senders = graph.prepare_block(self.next.block)

    def publish_ahead(self) -> None:
        """Publish the next state of the block computed ahead when it is due (at factor 0, all of them).

        Handing over ahead of time (``Ahead.ahead_of_time``), the states up to the next one that carries /clock
        or is heard outside the process (``PreparedState.heard``), which waits until due, go out at once,
        ``HANDOVER_LEAD`` before the first of them is due, each logged at its due time by a composed recorder's
        tap: with nobody outside hearing the per-step topics, a wake-up per block and per /clock instead of one
        per state, and the next block prepared whole before each wait. Events still apply at the boundary after
        the last state published, then the last handed over; they wait at most a block and the lead for it.
        """
        woke = False  # handing over ahead of time, the first state of this call waits, the rest go with it
        while True:
            early, woke, last = self._publish_one(woke)
            if last:
                self._finish()
                return
            if early:
                continue
            if self.loop.factor > 0.0:
                if not self.ahead.ahead_of_time:
                    self._prepare_next()
                return

    def _publish_one(self, woke: bool) -> tuple[bool, bool, bool]:
        """Publish the next state of the block when it is due (or, handed over ahead of time, with the first of
        this call's: ``woke``); whether it was handed over early, ``woke`` after it, and whether it was the last."""
        loop, ahead = self.loop, self.ahead
        sim, pacer, window = loop.sim, loop.pacer, loop.statistics.window
        row = ahead.published
        steps, last = ahead.before[0] + row + 1, row == len(ahead.stamps) - 1
        clock = loop.clock_schedule.due(ahead.stamps[row], final=last and loop.waits_next())
        state, factor = ahead.senders[row], loop.factor  # another thread may set the factor to 0 meanwhile
        early = ahead.ahead_of_time and not (clock or state.heard) and factor > 0.0
        if early:
            due = pacer.due(steps, sim.dt, factor)
            if not woke and due - time.perf_counter() > HANDOVER_LEAD:
                self._prepare_next(all_at_once=True)
                pacer.wait(steps, sim.dt, lambda: loop.factor, loop.stopping, lead=HANDOVER_LEAD)
            woke = True
            lateness = time.perf_counter() - due
        else:
            if ahead.ahead_of_time:
                self._prepare_next(all_at_once=True)
            lateness = pacer.wait(steps, sim.dt, lambda: loop.factor, loop.stopping)
        count_step(window, ahead.step_time, lateness)
        state.send(clock, max(-lateness, 0.0))
        loop.lockstep.mark_sync(loop.waits.commander_hears())
        loop.statistics.note_residual(float(ahead.block.table.residual[row]), float(ahead.block.table.t[row]))
        ahead.published += 1
        return early, woke, last

    def _finish(self) -> None:
        """The block's last state is out: a snapshot if one is due there."""
        loop = self.loop
        self.ahead = None
        every = snapshot_every(loop.settings.snapshot_period, loop.sim.dt)
        if every > 0 and loop.sim.steps % every == 0:
            loop.snapshot()
        loop.last_outputs = loop.sim.outputs()

    def rewind(self) -> None:
        """Drop the states of the block computed ahead that are not published: the simulation goes back to
        the last state published (``Simulation.restore``, which continues bit for bit)."""
        loop = self.loop
        loop.sim.restore(*self.published_state())
        self.ahead = self.next = None
        loop.last_outputs = loop.sim.outputs()

    def published_state(self) -> tuple[int, np.ndarray, np.ndarray]:
        """The step count, q and qd of the last state published: the simulation's, or a row of the block ahead."""
        ahead, sim = self.ahead, self.loop.sim
        if ahead is None:
            return sim.steps, sim.q, sim.qd
        row = ahead.published
        if row == 0:
            return ahead.before
        return ahead.before[0] + row, ahead.block.q[row - 1], ahead.block.qd[row - 1]
