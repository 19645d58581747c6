"""The whole test suite as CI runs it, from a fresh clone, beside busy loops (a measurement).

Clones the repository's HEAD into a temporary directory, starts ``--busy`` processes spinning in
``while True: pass`` (each takes a core), runs ``.ci/run`` there (``make test``: the venv from
nothing, then the suite) ``--runs`` times in a row, and prints for each run whether it passed, the
counts pytest reported and the wall time of the suite and of the whole command. The first run of a
clone builds its venv and numba cache; later runs of the same clone reuse them, so every run gets a
fresh clone unless ``--reuse-clone``. With ``--write-docs`` the runs are the table of its section of
docs/performance.md (one section per target and number of busy loops).

    python bench/bench_suite.py [--busy 1] [--runs 3] [--target test|test-fast] [--write-docs]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from report import Report, add_write_docs_option

REPO = Path(__file__).resolve().parents[1]
SUMMARY = re.compile(r'^(?:=+ )?(?P<counts>\d+ \w+(?:, \d+ \w+)*) in (?P<seconds>[\d.]+)s', re.MULTILINE)
"""pytest's last line, with its ``=`` rule or without (``-q``)."""


@dataclass
class SuiteRun:
    passed: bool
    counts: str
    suite_seconds: float
    total_seconds: float


def fresh_clone(into: Path) -> Path:
    clone = into / 'wallbot_sim'
    subprocess.run(['git', 'clone', '-q', str(REPO), str(clone)], check=True)
    return clone


def run_suite(clone: Path, target: str, log: Path) -> SuiteRun:
    """``.ci/run`` (target test) or ``make test-fast`` in ``clone``; its output in ``log``."""
    command = ['bash', '.ci/run'] if target == 'test' else ['make', target]
    started = time.monotonic()
    with open(log, 'w') as stream:
        status = subprocess.run(command, cwd=clone, stdout=stream, stderr=subprocess.STDOUT,
                                env={**os.environ, 'CI': 'true'}).returncode
    total = time.monotonic() - started
    found = SUMMARY.findall(log.read_text(errors='replace'))
    counts, seconds = (found[-1][0], float(found[-1][1])) if found else ('no pytest summary', float('nan'))
    return SuiteRun(status == 0, counts, seconds, total)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--busy', type=int, default=1, help='busy loops beside the suite (each takes a core)')
    parser.add_argument('--runs', type=int, default=1)
    parser.add_argument('--target', choices=('test', 'test-fast'), default='test')
    parser.add_argument('--reuse-clone', action='store_true', help='one clone for every run (venv and cache kept)')
    parser.add_argument('--keep', action='store_true', help='keep the clones and logs')
    add_write_docs_option(parser)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix='wallbot_bench_suite_'))
    commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=REPO, capture_output=True,
                            text=True, check=True).stdout.strip()
    busy = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(args.busy)]
    report = Report(f'suite-{args.target}-busy{args.busy}')
    rows: list[tuple[object, ...]] = []
    passed: list[bool] = []
    try:
        clone = None
        for index in range(args.runs):
            if clone is None or not args.reuse_clone:
                clone = fresh_clone(work / f'run{index}')
            load_before = os.getloadavg()[0]
            result = run_suite(clone, args.target, work / f'run{index}.log')
            print(f'run {index + 1}/{args.runs}: {"passed" if result.passed else "FAILED"} ({result.counts}), '
                  f'suite {result.suite_seconds / 60:.1f} min, whole command {result.total_seconds / 60:.1f} min, '
                  f'load average {load_before:.1f} -> {os.getloadavg()[0]:.1f}', flush=True)
            if not result.passed:
                print(f'  log: {work / f"run{index}.log"}')
            passed.append(result.passed)
            rows.append((index + 1, commit, 'reused' if args.reuse_clone and index else 'fresh',
                         f'{"passed" if result.passed else "FAILED"} ({result.counts})',
                         f'{result.suite_seconds / 60:.1f} min', f'{result.total_seconds / 60:.1f} min',
                         f'{load_before:.2f}'))
    finally:
        for process in busy:
            process.kill()
            process.wait()
        if not args.keep and all(passed):
            shutil.rmtree(work, ignore_errors=True)
    report.table(('run', 'commit', 'clone', 'result', 'the suite', 'the whole command (venv included)',
                  'load average before'), rows,
                 f'`{"CI=true bash .ci/run" if args.target == "test" else "make test-fast"}` beside '
                 f'{args.busy} busy loop{"s" if args.busy != 1 else ""}:')
    report.write(args.write_docs)
    return 0 if all(passed) else 1


if __name__ == '__main__':
    sys.exit(main())
