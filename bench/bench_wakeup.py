"""Wake-up lateness of a 1 kHz sleep loop, normal scheduling against SCHED_FIFO (a measurement).

Why the dynamics loop thread takes a real-time priority (``realtime_priority``): a thread that
sleeps until each 1 ms deadline is late by however long the kernel takes to run it again. This
runs the same loop as the dynamics' pacer (sleep until due, anchored, no drift) for --seconds,
first under the normal scheduler and then under SCHED_FIFO, each beside --busy processes that
spin in ``while True: pass``, and prints how many wake-ups came more than 1 and 2 ms late.
SCHED_FIFO needs root or an rtprio limit (``ulimit -r``); without it that row says so.

    python bench/bench_wakeup.py [--seconds 10] [--busy 3] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from report import Report, add_write_docs_option
from wallbot_sim.graph import ChildProcesses


def sleep_loop(seconds: float, period: float = 1e-3) -> list[float]:
    """Lateness (s) of each wake-up of a loop due every ``period``."""
    lateness = []
    due = time.perf_counter()
    end = due + seconds
    while due < end:
        due += period
        while (remaining := due - time.perf_counter()) > 0.0:
            time.sleep(remaining)
        lateness.append(time.perf_counter() - due)
    return lateness


def lateness_row(label: str, lateness: list[float]) -> tuple[str, ...]:
    """Print the lateness of a loop's wake-ups; the same as a table row."""
    ordered = sorted(lateness)
    late_1, late_2 = sum(x > 1e-3 for x in ordered), sum(x > 2e-3 for x in ordered)
    print(f'{label:28s} max {1e3 * ordered[-1]:6.2f} ms  p99.9 {1e3 * ordered[int(0.999 * len(ordered))]:5.2f} ms  '
          f'> 1 ms: {late_1:5d}  > 2 ms: {late_2:5d}  of {len(ordered)}')
    return (label, f'{1e3 * ordered[-1]:.2f} ms', f'{1e3 * ordered[int(0.999 * len(ordered))]:.2f} ms', str(late_1),
            str(late_2), f'{len(ordered):,}')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--busy', type=int, default=3, help='busy processes beside the loop')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('wakeup')
    rows = []
    busy = ChildProcesses(Path(tempfile.mkdtemp(prefix='wallbot_bench_wakeup_')), os.environ)
    for index in range(args.busy):
        busy.start([sys.executable, '-c', 'while True: pass'], f'busy-{index}')
    try:
        time.sleep(0.5)
        rows.append(lateness_row('normal scheduling', sleep_loop(args.seconds)))
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
        except OSError as error:
            print(f'SCHED_FIFO 50               not permitted here ({error.strerror})')
            rows.append(('SCHED_FIFO 50', f'not permitted here ({error.strerror})', '', '', '', ''))
        else:
            rows.append(lateness_row('SCHED_FIFO 50', sleep_loop(args.seconds)))
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    finally:
        busy.stop_all()
    print(f'machine: {os.cpu_count()} CPUs, {args.busy} busy processes, Python {sys.version.split()[0]}')
    report.table(('scheduling', 'max lateness', '99.9th percentile', 'wake-ups > 1 ms late', '> 2 ms late', 'of'), rows,
                 f'A 1 kHz sleep loop for {args.seconds:g} s beside {args.busy} busy processes:')
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
