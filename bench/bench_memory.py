"""Resident memory of the dynamics node and the recorder in a long real run at 1 kHz.

Starts ``wallbot-sim run circle`` (the real graph, factor 1, all constraints, recorder writing the
bag), samples VmRSS of its dynamics and recorder processes every few seconds, and stops the run
with Ctrl-C after ``--duration`` seconds. Prints the RSS after 10 s, at the end, and the growth.

    python bench/bench_memory.py --duration 600      # the issue's 10-minute figure: run's defaults, one process
    python bench/bench_memory.py --duration 600 --controller   # the closed loop
    python bench/bench_memory.py --duration 600 --no-compose --engine python   # two processes, the model as written

``--write-docs [FILE]`` writes the figures into the section of docs/performance.md named after the options.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

from report import Report, add_write_docs_option
from wallbot_sim.graph import ChildProcesses, child_processes, resident_mib
from wallbot_sim.model.simulation import ENGINES, NUMBA

NODES = {'dynamics': 'wallbot_sim.nodes.dynamics', 'recorder': 'wallbot_sim.nodes.recorder'}
COMPOSED_NODES = {'dynamics+recorder': 'wallbot_sim.nodes.dynamics_recorder'}
"""The process of ``run`` (``--compose``, its default) that holds both."""
CONTROLLER = {'controller': 'wallbot_sim.nodes.controller'}
"""The tracking controller of ``run --controller``."""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=600.0, help='wall seconds of running (default 600)')
    parser.add_argument('--compose', action=argparse.BooleanOptionalAction, default=True,
                        help="the dynamics and the recorder in one process (run's default), or two (--no-compose)")
    parser.add_argument('--engine', choices=ENGINES, default=NUMBA,
                        help="the dynamics' engine (default numba, run's)")
    parser.add_argument('--controller', action='store_true', help='run --controller: the closed loop (driven mode)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('-'.join(['memory', *([] if args.engine == NUMBA else [args.engine]),
                              *([] if args.compose else ['no-compose']), *(['controller'] if args.controller else [])]))
    nodes = {**(COMPOSED_NODES if args.compose else NODES), **(CONTROLLER if args.controller else {})}
    work = Path(tempfile.mkdtemp(prefix='wallbot_bench_mem_'))
    launcher = ChildProcesses(work / 'logs', os.environ, stop_timeout=120.0)
    run = launcher.start([sys.executable, '-m', 'wallbot_sim.cli.main', 'run', 'circle', '--duration', '1e6',
                          '--no-plots', '--out', str(work / 'run'), '--engine', args.engine,
                          '--compose' if args.compose else '--no-compose',
                          *(['--controller'] if args.controller else [])],
                         'run')
    try:
        pids: dict[str, int] = {}
        while len(pids) < len(nodes):
            if run.poll() is not None:
                raise SystemExit(f'the run ended early with status {run.returncode}')
            pids = {name: pid for pid, cmd in child_processes(run.pid).items()
                    for name, module in nodes.items() if module in cmd.split()}
            time.sleep(0.2)
        started = time.monotonic()
        samples: list[tuple[float, dict[str, float]]] = []
        while time.monotonic() - started < args.duration:
            time.sleep(5.0)
            samples.append((time.monotonic() - started, {name: resident_mib(pid) for name, pid in pids.items()}))
            print(f'{samples[-1][0]:6.0f} s  ' + '  '.join(f'{n} {v:6.1f} MiB' for n, v in samples[-1][1].items()),
                  flush=True)
        at_10 = next(values for t, values in samples if t >= 10.0)
        end = samples[-1][1]
        print(f'\nafter {samples[-1][0]:.0f} s of the 1 kHz graph (wall time, factor 1):')
        for name in nodes:
            print(f'  {name:17s} RSS after 10 s {at_10[name]:6.1f} MiB, at the end {end[name]:6.1f} MiB, '
                  f'growth {end[name] - at_10[name]:+.1f} MiB')
        report.table(('process', 'RSS after 10 s', f'after {samples[-1][0]:.0f} s', 'growth', 'target'),
                     [(name, f'{at_10[name]:.1f} MiB', f'{end[name]:.1f} MiB',
                       f'**{end[name] - at_10[name]:+.1f} MiB**', 'within 50 MB') for name in nodes])
    finally:
        launcher.stop_all(first=('run',))  # SIGINT, as at a terminal
        shutil.rmtree(work, ignore_errors=True)
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
