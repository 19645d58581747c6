"""``wallbot-sim motors BAG|CSV``: per side, the motor torque, speed and power a run needed, and
the adsorption force, for choosing a motor (``wallbot_sim.bag.motors``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from wallbot_sim.cli.errors import CliError

HELP = 'motor sizing of a run: per side peak/RMS torque, peak speed and power, adsorption force needed'


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('run', metavar='BAG|CSV', help='recorded bag directory or a simulate CSV')
    parser.add_argument('--robot', help='robot parameter YAML (default: config/robot.yaml)')
    parser.add_argument('--json', action='store_true', help='print the figures as JSON instead of a table')


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.bag.motors import format_report, motor_report
    from wallbot_sim.cli.plot import load_runs
    from wallbot_sim.config import load_robot_parameters
    from wallbot_sim.plots import RunDataError

    params = load_robot_parameters(args.robot)  # ParameterError: one line from main
    run, = load_runs([args.run])
    try:
        report = motor_report(run, params)
    except RunDataError as error:
        raise CliError(str(error)) from None
    if args.json:
        print(json.dumps({'run': str(Path(args.run)), 'robot': args.robot or 'config/robot.yaml',
                          **report.as_dict()}, indent=2))
    else:
        print(format_report(report, args.robot))
    return 0
