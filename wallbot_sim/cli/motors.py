"""``wallbot-sim motors BAG|CSV``: per side, the motor torque, speed and power a run needed, what a turn in
place takes, and the adhesion force, for choosing a motor (``wallbot_sim.rundata.motors``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

HELP = ('motor sizing of a run: per side peak/RMS torque, peak speed and power, what a turn in place takes, '
        'the adhesion force needed')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('run', metavar='BAG|CSV', help='recorded bag directory or a simulate CSV')
    parser.add_argument('--robot', help='robot parameter YAML (default: config/robot.yaml)')
    parser.add_argument('--json', action='store_true', help='print the figures as JSON instead of a table')


def main(args: argparse.Namespace) -> int:
    from wallbot_sim.config import load_robot_parameters
    from wallbot_sim.paths import robot_yaml
    from wallbot_sim.rundata import load_run
    from wallbot_sim.rundata.motors import format_report, motor_report

    robot_file = args.robot or robot_yaml()
    report = motor_report(load_run(args.run), load_robot_parameters(robot_file), robot_file)
    if args.json:
        print(json.dumps({'run': str(Path(args.run)), **report.as_dict()}, indent=2))
    else:
        print(format_report(report))
    return 0
