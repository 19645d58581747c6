"""Summarizing a recorded run (what ``wallbot-sim run`` does after the graph stops): one pass over the bag,
message by message (``rundata.summarize``), against loading every series first (``load_run``, then
``summarize_run``: the figures' data), on bags of a short and a four times longer run (a measurement).

The bags are written here as the graph records a 1 kHz run near the circle: odom, wheel_states,
constraint_wrench, drive_forces and wheel_contact every step, /clock at 10 Hz, reference poses at 100 Hz,
a plan every 5 s, /diagnostics every second. Prints, for each way and length, the wall seconds per
recorded second (the shortest of ROUNDS, the ways in turn) and the peak memory traced (tracemalloc, in a
pass of its own), and the ratios.

    python bench/bench_summary.py [--seconds 30] [--keep DIR] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from types import SimpleNamespace
from typing import Callable

import numpy as np

from report import Report, add_write_docs_option
from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim import messages
from wallbot_sim.bag.writer import BagWriter
from wallbot_sim.model import Circle
from wallbot_sim.model.trajectories import sample_plan
from wallbot_sim.rundata import load_run, summarize
from wallbot_sim.rundata.summary import summarize_run

BLOCK = 1000
"""Steps encoded at once."""


def write_bag(path: Path, seconds: float) -> None:
    """A recorded-like bag of ``seconds`` at 1 kHz (see the module's docstring)."""
    rng, circle, encoder = np.random.default_rng(1), Circle(), StepEncoder()
    writer = BagWriter(path)
    connection = {topic: writer.add_graph_topic(topic) for topic in topics.NOISELESS_RECORDED}
    steps = round(seconds * 1000) + 1
    for first in range(0, steps, BLOCK):
        k = np.arange(first, min(first + BLOCK, steps))
        t = k * 1e-3
        xy = np.array([circle.sample(ti).position for ti in t.tolist()])
        count = len(k)
        rows = SimpleNamespace(
            t=t, q=np.column_stack([xy, rng.normal(size=(count, 5))]), qd=rng.normal(size=(count, 7)),
            wheel_torques=rng.normal(size=(count, 4)), chassis_wrench=rng.normal(size=(count, 3)),
            drive=rng.normal(size=(count, 3)), loads=rng.uniform(20, 80, size=(count, 4)),
            wheel_use=rng.uniform(size=(count, 4)), wheel_slipping=np.zeros((count, 4), bool),
            wheel_forces=rng.normal(size=(count, 4, 2)), slip_velocity=rng.normal(size=(count, 4, 2)))
        for step, encoded in zip(k.tolist(), encoder.encode_rows(rows)):
            log_ns, ti = step * 1_000_000, step * 1e-3
            if step % 5000 == 0:
                plan = sample_plan(circle, max(ti - 0.05, 0.0), ti + 10.0, 0.05)
                writer.write(connection[topics.REFERENCE_TRAJECTORY], log_ns, messages.trajectory_message(plan))
            for topic, data in encoded:
                if topic is not topics.CLOCK or step % 100 == 0:
                    writer.write(connection[topic], log_ns, data)
            if step % 10 == 0:
                writer.write(connection[topics.REFERENCE], log_ns,
                             messages.reference_message(circle.sample(ti), ti)[0])
            if step % 1000 == 0:
                status = codec.Status(codec.simulation_status_name('/wallbot/dynamics'), 'ok', 'running',
                                      [(topics.DIAGNOSTIC_RESIDUAL_MAX, float(rng.uniform()))])
                writer.write(connection[topics.DIAGNOSTICS], log_ns + 1, codec.diagnostics(ti, [status]))
    writer.close()


ROUNDS = 3
"""Each way is timed this many times, the ways in turn, and its shortest time kept: on a shared machine the
others' load comes and goes."""


def measure(ways: dict[str, Callable[[Path], object]], bag: Path) -> dict[str, tuple[float, int]]:
    """(wall seconds, peak bytes traced) of each way's summary of ``bag``."""
    walls = dict.fromkeys(ways, float('inf'))
    for _round in range(ROUNDS):
        for name, summary in ways.items():
            started = time.perf_counter()
            summary(bag)
            walls[name] = min(walls[name], time.perf_counter() - started)
    peaks = {}
    for name, summary in ways.items():
        tracemalloc.start()
        summary(bag)
        peaks[name] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return {name: (walls[name], peaks[name]) for name in ways}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seconds', type=float, default=30.0, help='simulated seconds of the short run (default 30)')
    parser.add_argument('--keep', help='write the bags here and keep them (default: a temporary directory)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('summary')
    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix='bench_summary_'))
    lengths = (args.seconds, 4 * args.seconds)
    ways = {'one pass (summarize)': summarize,
            'every series loaded (load_run)': lambda bag: summarize_run(load_run(bag), bag)}
    try:
        results = {}
        for seconds in lengths:
            bag = out / f'run_{seconds:g}s'
            write_bag(bag, seconds)
            summarize(bag)  # the first call's imports are no summary's
            for name, figures in measure(ways, bag).items():
                results[name, seconds] = figures
    finally:
        if not args.keep:
            shutil.rmtree(out, ignore_errors=True)
    rows = []
    for name in ways:
        (short_wall, short_peak), (long_wall, long_peak) = (results[name, s] for s in lengths)
        rows.append((name, f'{short_wall / lengths[0]:.4f} s', f'{short_peak / 2**20:.1f} MiB',
                     f'{long_wall / lengths[1]:.4f} s', f'{long_peak / 2**20:.1f} MiB',
                     f'**{long_wall / lengths[1] / (short_wall / lengths[0]):.2f}**',
                     f'**{long_peak / short_peak:.2f}**'))
        print(' | '.join(str(cell) for cell in rows[-1]))
    rows.append(('one pass / every series loaded', *(
        f'**{results[next(iter(ways)), s][i] / results[list(ways)[1], s][i]:.2f}**' for s in lengths for i in (0, 1)),
        '', ''))
    print(' | '.join(str(cell) for cell in rows[-1]))
    report.table(('summary of a bag', f'{lengths[0]:g} s run: wall s per recorded s', 'peak memory',
                  f'{lengths[1]:g} s run: wall s per recorded s', 'peak memory', 'long / short: time per s', 'memory'),
                 rows, 'A 1 kHz run recorded as the graph records it, summarized (the shortest of three times; peak '
                       'memory traced by tracemalloc, in a pass of its own):')
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
