"""How a dynamics node starts: from a kept snapshot (a restart) or from its initial state.

A keeper (the recorder) republishes the dynamics' newest snapshot on ``resume_state``
(``wallbot_msgs_py.snapshot``). Once the loop could start, it waits for that message: a
snapshot means "continue from here", an empty message means "the keeper holds nothing: start
fresh" (so a fresh start beside a recorder does not wait). Without a keeper in the graph the
wait ends after ``resume_wait`` wall seconds (counted from the constraint set's arrival, so
discovery is under way); once a keeper is discovered (its publisher seen) its transient-local
message is on the way, so the wait lasts up to KEEPER_ANSWER from then.

Snapshots are taken every ``snapshot_period``, so the rest of the graph usually saw a few steps
past the snapshot before the kill (the keeper reports the newest stamp it received as
``seen_until``). The restored loop recomputes those steps without publishing them (a catch-up),
and publishes from the first state the graph has not seen: no stamp is ever published twice.

ROS-free, so it is tested without DDS (test_resume.py); the node applies it in its loop thread.
"""

from __future__ import annotations

from wallbot_msgs_py.snapshot import DynamicsSnapshot

KEEPER_ANSWER = 3.0
"""Wall seconds a discovered keeper has to deliver its message (discovery of the reader, then the
transient-local sample); beyond that the node starts fresh and says why."""


class ResumeGate:
    """The start-up decision and the catch-up after a resume (loop thread only)."""

    def __init__(self, wait: float) -> None:
        self._wait = wait
        self._deadline: float | None = None
        self._keeper_deadline: float | None = None
        self._settled = wait <= 0.0
        self.timed_out: str | None = None
        """Why the wait ended without a keeper's answer (None: it did not)."""
        self.snapshot: DynamicsSnapshot | None = None
        """The snapshot to resume from (None: start from the initial state)."""
        self._quiet_until_ns: int | None = None

    @property
    def settled(self) -> bool:
        """Whether the start-up decision is made (later keeper messages are ignored)."""
        return self._settled

    def offer(self, snapshot: DynamicsSnapshot | None) -> None:
        """A keeper's message: a snapshot, or None (it holds nothing). The first one decides."""
        if not self._settled:
            self.snapshot, self._settled = snapshot, True

    def settle(self, now: float, keeper_seen: bool) -> bool:
        """Whether the decision is made. The wait starts at the first call; it ends ``resume_wait``
        later without a keeper, KEEPER_ANSWER after one was first seen (then: start fresh)."""
        if self._settled:
            return True
        if self._deadline is None:
            self._deadline = now + self._wait
        if keeper_seen and self._keeper_deadline is None:
            self._keeper_deadline = now + KEEPER_ANSWER
        if self._keeper_deadline is not None:
            if now >= self._keeper_deadline:
                self._settled = True
                self.timed_out = f'a keeper (resume_state publisher) sent nothing within {KEEPER_ANSWER:g} s'
        elif now >= self._deadline:
            self._settled = True
            self.timed_out = f'no keeper (resume_state publisher) within resume_wait {self._wait:g} s'
        return self._settled

    def catch_up_to(self, seen_until_ns: int) -> None:
        """Publish nothing stamped at or before ``seen_until_ns`` (the graph has it)."""
        self._quiet_until_ns = seen_until_ns

    @property
    def catching_up(self) -> bool:
        return self._quiet_until_ns is not None

    def stop_catch_up(self) -> None:
        """Publish from now on (a reset, or a plan that forces publishing an earlier state)."""
        self._quiet_until_ns = None

    def publishes(self, stamp_ns: int) -> bool:
        """Whether the state stamped ``stamp_ns`` is published; the first one past seen-until ends the catch-up."""
        if self._quiet_until_ns is None:
            return True
        if stamp_ns <= self._quiet_until_ns:
            return False
        self._quiet_until_ns = None
        return True
