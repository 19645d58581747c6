"""``wallbot-sim test SPEC.yaml [--junit FILE] [--out DIR]``: a controller under test, run against the simulated robot
and judged (``wallbot_sim.testing``).

The run goes in a domain of its own, the dynamics in strict lockstep with the controller at factor 0, recorded to
``OUT/bag``; then each expectation is judged from the bag. It writes the JUnit file (default ``OUT/junit.xml``) and
``OUT/report.md`` (with a figure of each failing quantity in ``OUT/plots``) and prints a line per verdict.

Exit status: 0 when the run and every expectation hold, 1 when one fails (the controller not answering within its
timeout included), 2 for a bad spec or a controller that would not start (one line naming what is wrong).
"""

from __future__ import annotations

import argparse
import sys
from datetime import datetime
from pathlib import Path

from wallbot_sim.cli.errors import CliError
from wallbot_sim.cli.progress import Progress

HELP = 'test a controller: run it against the simulated robot, judge the spec\'s expectations, write JUnit XML'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('spec', metavar='SPEC.yaml', help='the test spec (scenario, controller, faults, expect)')
    parser.add_argument('--junit', metavar='FILE', help='where to write the JUnit XML (default OUT/junit.xml)')
    parser.add_argument('--out', metavar='DIR', help='output directory: bag, logs, report.md, plots (default '
                                                     'runs/test-SPEC-TIMESTAMP)')


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.testing import load_spec, run_spec
    spec = load_spec(args.spec)
    out = Path(args.out) if args.out else Path('runs') / f'test-{Path(args.spec).stem}-{datetime.now():%Y%m%d-%H%M%S}'
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise CliError(f'cannot create output directory {out}: {error.strerror}') from None
    duration = spec.run_duration()
    print(f'wallbot-sim test: {spec.name}: {spec.scenario}, {duration:g} s, controller `{" ".join(spec.controller)}` '
          f'publishing {spec.drive}; output in {out}')
    progress = Progress(duration, sys.stderr)
    outcome = run_spec(spec, out, Path(args.junit) if args.junit else None,
                       lambda t: progress.update(t, force=t >= duration - 1e-9))
    print(outcome.summary())
    print(f'junit:  {Path(args.junit) if args.junit else out / "junit.xml"}\nreport: {out / "report.md"}')
    return 0 if outcome.passed else 1
