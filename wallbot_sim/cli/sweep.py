"""``wallbot-sim sweep SPEC.yaml --out DIR``: many robots over varied parameters, one results row each."""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import nullcontext
from typing import TextIO

from wallbot_sim.cli import signals
from wallbot_sim.cli.errors import CliError
from wallbot_sim.cli.progress import LOG_PERIOD, TERMINAL_PERIOD

HELP = 'design sweep: run many robots over varied parameters (on Dask), write results.csv and figures'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('spec', metavar='SPEC.yaml', help='the sweep spec (scenario, constraints, grid/vary, ...)')
    parser.add_argument('--out', required=True, help='output directory; running again resumes what is missing')
    parser.add_argument('--workers', type=int,
                        help='worker processes of the local cluster (default: one per core)')
    parser.add_argument('--scheduler', help='address of an existing Dask scheduler, tcp://HOST:PORT '
                                            '(or tls://HOST:PORT with --security)')
    parser.add_argument('--security', help='with a tls:// scheduler: a YAML of the Dask TLS settings '
                                           '(tls_ca_file, tls_client_cert, tls_client_key)')
    parser.add_argument('--no-figures', action='store_true', help='write results.csv only')
    parser.add_argument('--quiet', action='store_true', help='no progress on stderr')


class SweepProgress:
    """Robots done, robot-steps per second and time left, shown as chunks finish."""

    def __init__(self, robots: int, done: int, steps: int, stream: TextIO | None) -> None:
        self.robots, self.done, self.steps, self.stream = robots, done, steps, stream
        self.terminal = stream is not None and stream.isatty()
        self.period = TERMINAL_PERIOD if self.terminal else LOG_PERIOD
        self.start = self.last = time.monotonic()
        self.computed = 0

    def update(self, robots: int, force: bool = False) -> None:
        """``robots`` more robots are done."""
        self.done += robots
        self.computed += robots
        now = time.monotonic()
        if self.stream is None or not (force or now - self.last >= self.period):
            return
        self.last = now
        elapsed = max(now - self.start, 1e-9)
        rate = self.computed * self.steps / elapsed
        left = (self.robots - self.done) * self.steps / rate if rate > 0 else float('nan')
        text = (f'  {self.done} / {self.robots} robots   {rate:,.0f} robot-steps/s   '
                f'{left:,.0f} s left')
        self.stream.write('\r' + text + ('\n' if force else '') if self.terminal else text + '\n')
        self.stream.flush()


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.sweep import load_spec
    from wallbot_sim.sweep.cluster import computes_here, reach_scheduler, run_chunks
    from wallbot_sim.sweep.compute import load_kernels
    from wallbot_sim.sweep.errors import SweepError
    from wallbot_sim.sweep.painters import FigurePainters
    from wallbot_sim.sweep.store import SweepDirectory, parameter_columns

    if args.workers is not None and args.workers < 1:
        raise CliError(f'--workers must be >= 1, got {args.workers}')
    if args.scheduler is not None and args.workers is not None:
        raise CliError('--workers sizes the local cluster; an existing cluster (--scheduler) has its own workers')
    if args.security is not None and not (args.scheduler or '').startswith('tls://'):
        raise CliError('--security is for a tls:// scheduler')
    security = _security(args.security) if args.security else None
    spec = load_spec(args.spec)
    if args.scheduler is not None:  # before the output directory is made: a wrong address leaves nothing behind
        reach_scheduler(args.scheduler)
    directory = SweepDirectory(args.out, spec)
    created = directory.open()
    pending = directory.pending()
    chunks = spec.chunks()
    done = len(spec.robots) - sum(len(chunks[index]) for index in pending)
    progress = SweepProgress(len(spec.robots), done, spec.settings.steps + 1, None if args.quiet else sys.stderr)
    if not args.quiet:
        print(f'sweep: {len(spec.robots)} robots in {len(chunks)} chunks of {spec.chunk_size}'
              + (f', {len(chunks) - len(pending)} chunks already done' if len(pending) < len(chunks) else ''),
              file=sys.stderr)

    def store(index: int, rows: list[list[float]]) -> None:
        directory.write_chunk(index, rows)
        progress.update(len(rows), force=len(directory.pending()) == 0)

    # the painter starts before the chunks compute: matplotlib loads in it meanwhile
    with nullcontext() if args.no_figures else FigurePainters(parameter_columns(spec)) as painters:
        if pending and computes_here(pending, args.workers, args.scheduler):
            with signals.deferred:  # a Ctrl-C while numba loads would be lost in its callbacks: it acts after
                load_kernels(spec.settings)
        try:
            run_chunks(spec, pending, store, workers=args.workers, scheduler=args.scheduler, security=security)
        except SweepError:
            if created:
                directory.remove_unused()
            raise
        results = directory.assemble()
        figures = painters.paint(results) if painters is not None else []
    if not args.quiet:
        print(f'wrote {results}' + (f' and {len(figures)} figures' if figures else ''), file=sys.stderr)
    return 0


def _security(path: str) -> object:
    """The Dask Security of a YAML file of its TLS settings."""
    from distributed import Security

    from wallbot_sim.config import read_yaml

    values = read_yaml(path)
    known = ('tls_ca_file', 'tls_client_cert', 'tls_client_key')
    if not isinstance(values, dict) or set(values) - set(known):
        raise CliError(f'{path}: a security file maps {", ".join(known)} to file paths')
    return Security(require_encryption=True, **values)
