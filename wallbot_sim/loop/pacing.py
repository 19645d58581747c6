"""Wall-clock pacing of the dynamics loop, and the loop thread's real-time priority.

At real-time factor f > 0 the step reaching step number k is due at wall time
``anchor + (k - anchor_step) * dt / f``: one anchor per run segment, so lateness never
accumulates into drift. The node re-anchors after a pause, a wait or a factor change.

Priority. A paced loop sleeps most of each period; what makes a step late is the time the
kernel takes to run it again after the sleep, which on a busy machine can exceed 2 ms under
the normal scheduler (measured: bench/bench_node.py). Under SCHED_FIFO the loop thread wakes
ahead of every normal thread. A FIFO thread that never sleeps would starve the normal ones
(on a loaded machine that includes the DDS threads the loop's own messages need), so the
priority is taken only for a step that has time to sleep: at factor 0, and for every step
already due when its wait begins (a loop catching up), the thread runs under the normal
scheduler. Linux only; where the priority is not permitted (an unprivileged user without an
rtprio limit) the loop runs under the normal scheduler after one warning.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Callable

LONGEST_SLEEP = 0.05
"""A wait sleeps in slices of at most this (s), to notice factor changes and shutdown."""


class Pacer:
    """Sleeps the loop thread until each step is due; reports how late it woke.

    Call :meth:`wait` from the loop thread only: the scheduling policy it sets applies to the
    calling thread.
    """

    def __init__(self, priority: int, warn: Callable[[str], None]) -> None:
        self._priority = priority
        self._warn = warn
        self._anchor: tuple[float, int] | None = None
        self._refused = False
        self._applied = 0

    def reanchor(self) -> None:
        """The next step starts a new run segment (after a pause, wait or factor change)."""
        self._anchor = None

    @property
    def priority(self) -> int:
        """SCHED_FIFO priority wanted while paced (1-99); 0 = normal scheduling."""
        return self._priority

    @priority.setter
    def priority(self, value: int) -> None:
        self._priority, self._refused = value, False

    @property
    def policy(self) -> str:
        """What the loop thread is set to do: the decision, whether or not a step has slept since."""
        if not self._priority:
            return 'normal'
        if self._refused:
            return f'normal (SCHED_FIFO {self._priority} not permitted)'
        return f'SCHED_FIFO {self._priority} while paced'

    @property
    def applied_priority(self) -> int:
        """The SCHED_FIFO priority the loop thread holds now (0: normal scheduling)."""
        return self._applied

    def wait(self, step: int, dt: float, factor: Callable[[], float], stopping: threading.Event,
             lead: float = 0.0) -> float:
        """Sleep until step number ``step`` is due at the current factor, or ``lead`` seconds before; return
        the lateness (s) against that time.

        ``factor()`` is read again while sleeping: when it changes, the step is due at once and
        the next one starts a new segment. At factor 0 nothing waits and the lateness is 0.
        """
        paced = factor()
        if paced <= 0.0:
            self._schedule(0)
            return 0.0
        due = self.due(step, dt, paced) - lead
        remaining = due - time.perf_counter()
        self._schedule(self._priority if remaining > 0.0 else 0)
        while remaining > 0.0 and not stopping.is_set():
            time.sleep(min(remaining, LONGEST_SLEEP))
            if factor() != paced:
                self.reanchor()
                due = time.perf_counter()
                break
            remaining = due - time.perf_counter()
        return time.perf_counter() - due

    def due(self, step: int, dt: float, factor: float) -> float:
        """The ``time.perf_counter()`` time step number ``step`` is due at ``factor`` (> 0); the first
        step of a run segment is due a step from now."""
        if self._anchor is None:
            self._anchor = (time.perf_counter(), step - 1)
        anchor_wall, anchor_step = self._anchor
        return anchor_wall + (step - anchor_step) * dt / factor

    def _schedule(self, wanted: int) -> None:
        """Run the calling thread under SCHED_FIFO ``wanted`` (0: the normal scheduler)."""
        if self._refused:
            wanted = 0
        if wanted == self._applied:
            return
        try:
            if wanted:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(wanted))
            else:
                os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except (OSError, AttributeError) as error:  # AttributeError: no sched_setscheduler (not Linux)
            self._refused = True
            reason = error.strerror if isinstance(error, OSError) and error.strerror else 'not supported here'
            self._warn(f'realtime_priority {wanted} not applied ({reason}): normal scheduling; allow it with an '
                       f'rtprio limit (ulimit -r, /etc/security/limits.conf) or set realtime_priority 0')
            return
        self._applied = wanted
