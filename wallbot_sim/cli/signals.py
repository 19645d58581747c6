"""SIGINT and SIGTERM for the ``wallbot-sim`` verbs, however the process was started.

A background job of a non-interactive shell (``wallbot-sim play BAG &`` in a script) starts with
SIGINT ignored, and Python then installs no KeyboardInterrupt handler: such a verb could only be
stopped with SIGTERM. :func:`install` sets both handlers explicitly; :data:`deferred` holds the
signals back while a step writes its outputs, so an interrupted run never leaves half a record.
"""

from __future__ import annotations

import signal
import sys
from types import FrameType

SIGNALS = {signal.SIGINT, signal.SIGTERM}
TERMINATED = 128 + signal.SIGTERM
"""Exit status after SIGTERM (the shell's convention; SIGINT gives 130 through KeyboardInterrupt)."""


def _act(signum: int) -> None:
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    sys.exit(TERMINATED)


class _Deferral:
    """Holds a signal back while it is entered; the signal acts when the block ends.

    Python runs signal handlers in the main thread between bytecodes, so a flag the handler reads
    is enough (a block costs two attribute writes, where blocking the signals in the kernel costs
    two system calls: a tenth of a step's time when entered around every step).
    """

    def __init__(self) -> None:
        self.holding = False
        self.pending: int | None = None

    def handle(self, signum: int, _frame: FrameType | None) -> None:
        if self.holding:
            self.pending = self.pending or signum
        else:
            _act(signum)

    def __enter__(self) -> None:
        self.holding = True

    def __exit__(self, *exc: object) -> None:
        self.holding = False
        pending, self.pending = self.pending, None
        if pending is not None:
            _act(pending)


deferred = _Deferral()
"""``with signals.deferred:``: SIGINT and SIGTERM that come inside the block act when it ends
(once :func:`install` has set the handlers)."""


def install() -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM exits with status 143, whatever was inherited."""
    for signum in SIGNALS:
        signal.signal(signum, deferred.handle)
