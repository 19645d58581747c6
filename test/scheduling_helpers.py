"""What the kernel lets this user do with thread scheduling (shared by the pacing and graph tests)."""

from __future__ import annotations

import os
import resource


def may_use_fifo() -> bool:
    """Whether this process may put a thread under SCHED_FIFO at priority 10 (root, or an rtprio limit)."""
    soft, _hard = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return os.geteuid() == 0 or soft == resource.RLIM_INFINITY or soft >= 10
