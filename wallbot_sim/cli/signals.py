"""SIGINT and SIGTERM for the ``wallbot-sim`` verbs, however the process was started.

A background job of a non-interactive shell (``wallbot-sim play BAG &`` in a script) starts with
SIGINT ignored, and Python then installs no KeyboardInterrupt handler: such a verb could only be
stopped with SIGTERM. :func:`install` sets both handlers explicitly; :func:`deferred` holds the
signals back while a step writes its outputs, so an interrupted run never leaves half a record.
"""

from __future__ import annotations

import signal
import sys
from contextlib import contextmanager
from typing import Iterator

SIGNALS = {signal.SIGINT, signal.SIGTERM}
TERMINATED = 128 + signal.SIGTERM
"""Exit status after SIGTERM (the shell's convention; SIGINT gives 130 through KeyboardInterrupt)."""


def _terminate(_signum: int, _frame: object) -> None:
    sys.exit(TERMINATED)


def install() -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM exits with status 143, whatever was inherited."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _terminate)


@contextmanager
def deferred() -> Iterator[None]:
    """Block SIGINT and SIGTERM inside the block; one that came meanwhile acts when it ends."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
