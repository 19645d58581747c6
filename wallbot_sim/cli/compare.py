"""``wallbot-sim compare RUN RUN ... [--out DIR]``: several runs overlaid in one figure set."""

from __future__ import annotations

import argparse
from pathlib import Path

from wallbot_sim.cli.errors import CliError

HELP = 'overlay several runs (bags or simulate CSVs) in one set of the paper\'s figures'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('runs', metavar='BAG|CSV', nargs='+', help='two or more bags or simulate CSVs')
    parser.add_argument('--out', default='compare_plots', help='output directory (default: ./compare_plots)')
    parser.add_argument('--labels', help='comma list of legend labels, one per run (default: file names)')


def main(args: argparse.Namespace) -> int:
    if len(args.runs) < 2:
        raise CliError('compare needs at least two runs (use plot for one)')
    from wallbot_sim.plots.figures import write_figures
    from wallbot_sim.rundata import load_run
    runs = [load_run(path) for path in args.runs]
    if args.labels:
        labels = [s.strip() for s in args.labels.split(',')]
        if len(labels) != len(runs):
            raise CliError(f'--labels has {len(labels)} labels for {len(runs)} runs')
        for run, text in zip(runs, labels):
            run.label = text
    for path in write_figures(runs, Path(args.out)):
        print(path)
    return 0
