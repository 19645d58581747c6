"""``wallbot-sim plot BAG|CSV [--out DIR]``: the paper's figure set of one run as PNG files."""

from __future__ import annotations

import argparse
from pathlib import Path

from wallbot_sim.cli.errors import CliError

HELP = "write the paper's figures (path, x/y, tracking error, attitude, wheel tracks, forces) as PNG"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('run', metavar='BAG|CSV', help='recorded bag directory or a simulate CSV')
    parser.add_argument('--out', help='output directory (default: <BAG>/plots, or <CSV stem>_plots next to the CSV)')


def default_out(path: Path) -> Path:
    """Where plots of ``path`` go by default."""
    return path.with_name(f'{path.stem}_plots') if path.is_file() else path / 'plots'


def load_runs(paths: list[str]) -> list:
    """RunData of each path, with bag/CSV errors as CliError."""
    from wallbot_sim.bag import BagError
    from wallbot_sim.plots import RunDataError, load_run
    runs = []
    for text in paths:
        try:
            runs.append(load_run(Path(text)))
        except (BagError, RunDataError) as error:
            raise CliError(str(error)) from None
    return runs


def write(runs: list, out: Path) -> list[Path]:
    from wallbot_sim.plots.figures import PlotError, write_figures
    try:
        return write_figures(runs, out)
    except PlotError as error:
        raise CliError(str(error)) from None


def main(args: argparse.Namespace) -> int:
    runs = load_runs([args.run])
    out = Path(args.out) if args.out else default_out(Path(args.run))
    for path in write(runs, out):
        print(path)
    return 0
