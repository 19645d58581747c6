"""``wallbot-sim plot BAG|CSV [--out DIR]``: the paper's figure set of one run as PNG files."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "write the paper's figures (path, x/y, tracking error, attitude, wheel tracks, forces) as PNG"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('run', metavar='BAG|CSV', help='recorded bag directory or a simulate CSV')
    parser.add_argument('--out', help='output directory (default: <BAG>/plots, or <CSV stem>_plots next to the CSV)')


def default_out(path: Path) -> Path:
    """Where plots of ``path`` go by default."""
    return path.with_name(f'{path.stem}_plots') if path.is_file() else path / 'plots'


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.plots.figures import write_figures
    from wallbot_sim.rundata import load_run
    out = Path(args.out) if args.out else default_out(Path(args.run))
    for path in write_figures([load_run(args.run)], out):
        print(path)
    return 0
