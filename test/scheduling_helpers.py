"""What the kernel lets this user do with thread scheduling, and a virtual clock to pace on (shared by the
pacing, loop and graph tests)."""

from __future__ import annotations

import os
import resource


def may_use_fifo() -> bool:
    """Whether this process may put a thread under SCHED_FIFO at priority 10 (root, or an rtprio limit)."""
    soft, _hard = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return os.geteuid() == 0 or soft == resource.RLIM_INFINITY or soft >= 10


class VirtualTime:
    """perf_counter/monotonic/sleep on a virtual clock (in place of a module's ``time``); every sleep
    overshoots by ``overshoot``. Code paced on it is never late however busy the machine is."""

    def __init__(self, overshoot: float = 0.0) -> None:
        self.now = 100.0
        self.overshoot = overshoot
        self.sleeps = 0

    def perf_counter(self) -> float:
        return self.now

    monotonic = perf_counter

    def sleep(self, seconds: float) -> None:
        self.sleeps += 1
        self.now += seconds + self.overshoot
