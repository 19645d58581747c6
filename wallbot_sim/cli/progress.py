"""The progress of a run on stderr: simulation time and the real-time factor reached."""

from __future__ import annotations

import time
from typing import TextIO

TERMINAL_PERIOD = 0.25
"""Seconds between redraws of the progress line in a terminal."""
LOG_PERIOD = 2.0
"""Seconds between progress lines when stderr is not a terminal (a log file, a pipe)."""


class Progress:
    """Simulation time and real-time factor, shown while a run goes on.

    In a terminal one line is redrawn in place a few times a second; anywhere else (a log
    file, a pipe) a plain line is printed every LOG_PERIOD seconds, so a log never holds one
    line thousands of characters long. The factor is measured from the first time simulation
    time moved, so start-up is not in it, and again from a time that went back (a reset of the
    dynamics). ``duration`` 0: a run until stopped, shown without an end. ``label`` and ``rate``
    name what is shown (reading a bag: how far, and bag seconds read per wall second).
    """

    def __init__(self, duration: float, stream: TextIO | None, label: str = '',
                 rate: str = 'real-time factor') -> None:
        self.duration, self.stream = duration, stream
        self.label, self.rate = label, rate
        self.terminal = stream is not None and stream.isatty()
        self.period = TERMINAL_PERIOD if self.terminal else LOG_PERIOD
        self.last = time.monotonic()
        self.anchor: tuple[float, float] | None = None
        self.latest: float | None = None
        """The newest simulation time given to :meth:`update` (None before the first)."""
        self.shown = False
        """Whether a line has been written."""

    def update(self, t: float, force: bool = False) -> None:
        """Show simulation time ``t`` if the period is up; ``force`` shows it now (and ends the line)."""
        now = time.monotonic()
        if self.anchor is None or (self.latest is not None and t < self.latest):
            self.anchor = (t, now)
        self.latest = t
        if self.stream is None or not (force or now - self.last >= self.period):
            return
        self.last, self.shown = now, True
        start_t, start_wall = self.anchor
        factor = (t - start_t) / max(now - start_wall, 1e-9)
        end = f' / {self.duration:.3f} s' if self.duration > 0 else ' s (until stopped)'
        text = f'  {self.label}t = {t:7.3f}{end}   {self.rate} {factor:6.2f}'
        if self.terminal:  # redraw in place; a forced (final) line ends it
            text = '\r' + text + ('\n' if force else '')
        else:
            text += '\n'
        self.stream.write(text)
        self.stream.flush()
