"""A process that draws a sweep's figures, loaded while its chunks compute.

Loading matplotlib takes about half a second of CPU and drawing a sweep's figures about one and a half:
in the command's process, after its chunks, both would add to the sweep's time. The painter is forked
before the chunks compute and loads matplotlib and its font meanwhile (on another core). Once results.csv
is written it forks a helper per further core, each inheriting the loaded matplotlib (a fork costs
milliseconds, a second load half a second), and the figures, dealt out larger first, are drawn on every
core at once. While it waits it sketches every figure the results may have (``figures.sketch``: the
axes and their ticks, a third of the drawing), which the helpers inherit too.

    with FigurePainters(parameter_columns(spec)) as painters:
        ...                                         # compute, write results.csv
        files = painters.paint(results)
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from multiprocessing.connection import Connection
from pathlib import Path
from types import TracebackType
from typing import Any

from wallbot_sim.sweep.errors import SweepError
from wallbot_sim.sweep.figures import SweepTable, sketches, write_figure
from wallbot_sim.sweep.store import read_results

MAX_PAINTERS = 4
"""Processes drawing at once at most (a sweep over two parameters has six figures, two of them large)."""
HELD_SIGNALS = {signal.SIGINT, signal.SIGTERM}
FORK = multiprocessing.get_context('fork')


class FigurePainters:
    """The painter of figures over the varied ``parameters`` columns, forked now; ``processes`` draw the figures
    at once (default: one per core, at most MAX_PAINTERS). A context manager that ends it."""

    def __init__(self, parameters: list[str], processes: int | None = None) -> None:
        count = processes or min(os.cpu_count() or 1, MAX_PAINTERS)
        self._connection, theirs = FORK.Pipe()
        # the signals held while forking: a Ctrl-C before the painter ignores it would reach the command's handler
        # in the painter; a held one waits until the painter has set its own
        held = signal.pthread_sigmask(signal.SIG_BLOCK, HELD_SIGNALS)
        try:
            self._painter = FORK.Process(target=_serve, args=(theirs, parameters, count), name='sweep figures')
            self._painter.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        theirs.close()

    def paint(self, results: Path) -> list[Path]:
        """Draw the figures of ``results`` (a results.csv) into its directory: the files written."""
        self._connection.send(results)
        return _outcome(self._connection, 'the painter')

    def __enter__(self) -> FigurePainters:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        if kind is None:
            self._connection.send(None)
        else:  # the command goes on at once (its error line first)
            self._painter.terminate()
        self._painter.join()
        self._connection.close()


def _outcome(connection: Connection, who: str) -> list[Path]:
    """What a painting process sent back: the files it wrote, or its error raised here."""
    try:
        outcome = connection.recv()
    except EOFError:
        raise SweepError(f'{who} of the figures died before it finished') from None
    if isinstance(outcome, BaseException):
        raise outcome
    return outcome


def _serve(connection: Connection, parameters: list[str], count: int) -> None:
    """The painter: loads matplotlib and sketches, then paints the results it is sent until None (or the command's
    end)."""
    plt = _load_matplotlib()
    sketched = sketches(plt, parameters)
    while True:
        try:
            results = connection.recv()
        except EOFError:  # the command ended without a word
            return
        if results is None:
            return
        try:
            outcome: list[Path] | BaseException = _paint(plt, sketched, count, results, parameters)
        except Exception as error:  # noqa: BLE001 - raised in the command, as if it had drawn the figure itself
            outcome = error
        sketched = {}  # used up: another job sketches anew
        connection.send(outcome)


def _load_matplotlib() -> Any:
    """Ctrl-C, which the terminal sends to every process of the command, left to the command (which ends the
    painter); matplotlib, the maps' triangulation and the font loaded. The pyplot module."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, HELD_SIGNALS)
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    import matplotlib.tri  # noqa: F401 - loaded now rather than while drawing

    fig = plt.figure(figsize=(1, 1))
    fig.text(0.5, 0.5, '0')
    fig.canvas.draw()
    plt.close(fig)
    return plt


def _paint(plt: Any, sketched: dict[str, Any], count: int, results: Path, parameters: list[str]) -> list[Path]:
    """The figures of ``results`` on ``count`` processes, each finishing its ``sketched`` figures: this one and a
    helper forked per further share."""
    names, rows = read_results(results)
    table = SweepTable.of(names, rows, parameters)
    files = table.files()
    shares = [files[first::count] for first in range(min(count, len(files)))]  # files come larger first
    helpers = []
    for share in shares[1:]:
        reader, writer = FORK.Pipe(duplex=False)
        helper = FORK.Process(target=_draw_share, args=(writer, plt, sketched, table, share, results.parent),
                               daemon=True)
        helper.start()
        writer.close()
        helpers.append((helper, reader))
    own = shares[0] if shares else []
    written = [write_figure(plt, table, file, results.parent, sketched.get(file)) for file in own]
    for helper, reader in helpers:
        written += _outcome(reader, 'a helper')
        helper.join()
    return sorted(written, key=lambda path: files.index(path.name))


def _draw_share(connection: Connection, plt: Any, sketched: dict[str, Any], table: SweepTable, files: list[str],
                out_dir: Path) -> None:
    try:
        outcome: list[Path] | BaseException = [write_figure(plt, table, file, out_dir, sketched.get(file))
                                               for file in files]
    except Exception as error:  # noqa: BLE001 - raised in the command
        outcome = error
    connection.send(outcome)
