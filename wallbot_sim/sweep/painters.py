"""Processes that draw a sweep's figures, loaded while its chunks compute.

Loading matplotlib takes about half a second of CPU and drawing a sweep's figures about one and a half:
in the command's process, after its chunks, both would add to the sweep's time. The painters are forked
before the chunks compute and load matplotlib and its font meanwhile (on another core); once results.csv
is written, each figure goes to the next free painter, so two cores draw two figures at once.

    with FigurePainters() as painters:
        ...                                         # compute, write results.csv
        files = painters.paint(results, parameter_columns(spec))
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import TracebackType

from wallbot_sim.sweep.figures import SweepTable, write_figure
from wallbot_sim.sweep.store import read_results

MAX_PAINTERS = 4
"""Painters at most (a sweep over two parameters has six figures, two of them large)."""
HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def _start_painter() -> None:
    """A painter's start: Ctrl-C, which the terminal sends to every process of the command, left to the command
    (which stops the painters), and matplotlib and its font loaded."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, HELD_SIGNALS)
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    import matplotlib.tri  # noqa: F401 - the maps' triangulation, loaded now rather than while drawing

    fig = plt.figure(figsize=(1, 1))
    fig.text(0.5, 0.5, '0')
    fig.canvas.draw()
    plt.close(fig)


def _paint(results: Path, parameters: list[str], file: str) -> Path:
    import matplotlib.pyplot as plt

    names, rows = read_results(results)
    return write_figure(plt, SweepTable.of(names, rows, parameters), file, results.parent)


class FigurePainters:
    """``processes`` painters (default: one per core, at most MAX_PAINTERS), forked now; a context manager that
    ends them."""

    def __init__(self, processes: int | None = None) -> None:
        count = processes or min(os.cpu_count() or 1, MAX_PAINTERS)
        self._executor = ProcessPoolExecutor(count, mp_context=multiprocessing.get_context('fork'),
                                             initializer=_start_painter)
        # the signals held while forking: a Ctrl-C before a painter ignores it would reach the command's handler
        # in the painter; a held one waits until the painter has set its own
        held = signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
        try:
            self._executor.submit(os.getpid)  # the first task forks every painter (fork starts all at once)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)

    def paint(self, results: Path, parameters: list[str]) -> list[Path]:
        """Draw the figures of ``results`` (a results.csv) over the varied ``parameters`` columns into its
        directory: the files written."""
        names, rows = read_results(results)
        files = SweepTable.of(names, rows, parameters).files()
        return list(self._executor.map(_paint, [results] * len(files), [parameters] * len(files), files))

    def __enter__(self) -> FigurePainters:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        # after an error the command goes on at once (its error line first); the painters end once loaded
        self._executor.shutdown(wait=kind is None, cancel_futures=True)
