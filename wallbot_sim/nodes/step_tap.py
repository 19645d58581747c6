"""The dynamics' per-step messages handed to a recorder in the same process, without DDS.

In the composed process (``dynamics_recorder``) the dynamics still publishes each step's
messages for live subscribers, and also puts the same CDR bytes here, from its loop thread, with
one log time per step. The recorder takes them out on the executor thread (the bag writer is
written from one thread only): from a short timer, before it writes any message it received over
DDS, and at the stop, so log times never go backwards in the bag and nothing logged after the
stop is written.

ROS-free, so its order and log-time rules are tested without DDS (test_step_tap.py).
"""

from __future__ import annotations

from collections import deque
from typing import Callable, Mapping, Sequence

from wallbot_msgs_py import topics

Write = Callable[[topics.Topic, str, bytes, int], None]
"""How a drained message is written: (topic, resolved name, CDR bytes, log time in ns)."""


class StepTap:
    """A queue of steps from the dynamics' loop thread to the recorder's executor thread.

    ``names``: the tapped topics and the names they are written under (the recorder's resolved
    names); other topics of a step are left out. ``now_ns``: the recorder's log-time clock.
    ``deque.append`` and ``popleft`` are atomic, so the two threads share no lock.
    """

    def __init__(self, names: Mapping[topics.Topic, str], now_ns: Callable[[], int]) -> None:
        self.names = dict(names)
        self.now_ns = now_ns
        self._steps: deque[tuple[int, bool, Sequence[tuple[topics.Topic, bytes]], int | None]] = deque()
        self.newest_stamp_ns: int | None = None
        """The stamp of the newest step a drain wrote (None: none yet, or put without stamps)."""

    def put(self, encoded: Sequence[tuple[topics.Topic, bytes]], clock: bool, stamp_ns: int | None = None,
            ahead: float = 0.0) -> None:
        """One step's messages as the dynamics sends them (``clock``: its clock message is sent too),
        logged now, or ``ahead`` seconds from now (a state handed over before it is due is logged when
        it is due, and no drain writes it before); ``stamp_ns``: their header stamp (the step's
        simulation time). Loop thread; the messages' bytes must not change afterwards."""
        self._steps.append((self.now_ns() + round(ahead * 1e9), clock, encoded, stamp_ns))

    def drain(self, write: Write, floor_ns: int, stopped_at: Callable[[], int | None] = lambda: None) -> int:
        """Write the steps logged before this drain began, oldest first, at their log times but never
        before ``floor_ns`` or the previous message's. ``stopped_at``: when a stop was requested
        (None: not yet); a step logged after it is not written (nor kept: one handed over ahead of a
        time after the stop included). Returns how many messages were not written for that. Executor
        thread only.

        The drain's own time is read before the stop: a stop requested after that read comes later
        than every step the drain writes, even when it is requested while the drain runs and the
        loop thread goes on putting steps (those stay queued for the next drain).
        """
        until_ns = self.now_ns()
        stop_ns = stopped_at()
        refused = 0
        steps, names = self._steps, self.names
        while steps and (steps[0][0] <= until_ns or stop_ns is not None and steps[0][0] > stop_ns):
            logged_ns, clock, encoded, stamp_ns = steps.popleft()
            sent = [(topic, names[topic], data) for topic, data in encoded
                    if topic in names and (clock or topic is not topics.CLOCK)]
            if stop_ns is not None and logged_ns > stop_ns:
                refused += len(sent)
                continue
            floor_ns = max(logged_ns, floor_ns)
            for topic, name, data in sent:
                write(topic, name, data, floor_ns)
            if stamp_ns is not None:
                self.newest_stamp_ns = stamp_ns
        return refused
