"""Entry point of ``wallbot-sim``: dispatches to one module per subcommand.

A subcommand module has ``HELP`` (one line), ``add_arguments(parser)`` and ``main(args) -> int``.
Modules are imported only when their verb runs, so ``simulate`` never loads ROS.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import NoReturn, Sequence

from wallbot_sim.bag.errors import BagError
from wallbot_sim.cli import signals
from wallbot_sim.cli.errors import CliError
from wallbot_sim.model.errors import ModelError
from wallbot_sim.plots.errors import PlotError
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.sweep.errors import SweepError
from wallbot_sim.testing.errors import ControllerWouldNotStart, SpecError

USER_ERRORS = (CliError, BagError, ModelError, PlotError, RunDataError, SweepError, SpecError, ControllerWouldNotStart)
"""What a verb may raise for bad input: printed as one line, exit status 2 (or a CliError's code).
The libraries' errors know nothing of the command line; this is the one place that maps them."""

VERBS = {
    'simulate': 'wallbot_sim.cli.simulate',
    'run': 'wallbot_sim.cli.run',
    'play': 'wallbot_sim.cli.play',
    'info': 'wallbot_sim.cli.info',
    'plot': 'wallbot_sim.cli.plot',
    'compare': 'wallbot_sim.cli.compare',
    'bag': 'wallbot_sim.cli.bag',
    'motors': 'wallbot_sim.cli.motors',
    'sweep': 'wallbot_sim.cli.sweep',
    'test': 'wallbot_sim.cli.test',
}


class OneLineParser(argparse.ArgumentParser):
    """Argument errors as a single line and exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f'{self.prog}: error: {message}\n')


def _available_verbs() -> dict[str, object]:
    modules = {}
    for verb, module_name in VERBS.items():
        try:
            modules[verb] = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name != module_name:
                raise
    return modules


def build_parser() -> argparse.ArgumentParser:
    """The parser with every available subcommand."""
    parser = OneLineParser(prog='wallbot-sim', description='Wall-climbing robot simulation (Udwadia-Phohomsiri model).')
    verbs = parser.add_subparsers(dest='verb', metavar='VERB', parser_class=OneLineParser)
    verbs.required = True
    for verb, module in _available_verbs().items():
        sub = verbs.add_parser(verb, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(handler=module.main)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse, run the subcommand, turn user errors into one line and exit status 2; Ctrl-C (SIGINT)
    gives 130 and SIGTERM 143."""
    signals.install()
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except USER_ERRORS as error:
        print(f'wallbot-sim {args.verb}: error: {error}', file=sys.stderr)
        return getattr(error, 'code', 2)
    except KeyboardInterrupt:
        print(f'wallbot-sim {args.verb}: interrupted', file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 141


if __name__ == '__main__':
    sys.exit(main())
