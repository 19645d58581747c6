"""``wallbot-sim simulate``: run a scenario headless, straight from the model, and write a CSV."""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path
from typing import Callable, TextIO

import numpy as np

from wallbot_sim.cli import signals
from wallbot_sim.cli.errors import CliError
from wallbot_sim.cli.engine import chosen_engine
from wallbot_sim.cli.options import add_graph_option, add_setting, number
from wallbot_sim.cli.progress import Progress
from wallbot_sim.config import load_robot_parameters, load_scenario, load_world
from wallbot_sim.control import TrackingController
from wallbot_sim.control.sampling import SampledController, TorqueCommand, close_loop, controller_robot
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.graph_options import ALL_STRUCTURAL
from wallbot_sim.model import TIME_STEP, ConstraintSelection, Robot, Simulation, StepOutputs
from wallbot_sim.model.contact import DetachedError
from wallbot_sim.model.numbers import FINITE, POSITIVE
from wallbot_sim.model.outputs import StepTable
from wallbot_sim.model.vacuum import PUMP_COMMAND
from wallbot_sim.rundata.csv_format import CSV_COLUMNS, block_columns, block_groups, csv_line, csv_lines, fill_rows
from wallbot_sim.settings.dynamics import DYNAMICS

HELP = 'run a scenario headless (no ROS) and write a CSV of every step'

REST = 'rest'
"""The scenario with no trajectory task: at rest at the origin, constant motor torques."""
REST_DURATION = 1.0
DETACHED_STATUS = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--scenario', default='circle',
                        help='circle, figure8, a scenario YAML path, or rest (no trajectory task: at rest at the '
                             'origin under constant motor torques)')
    add_setting(parser, '--heading', DYNAMICS['initial_theta'], default=None,
                help_suffix=' (with --scenario rest; default 0)')
    parser.add_argument('--torque', help='with --scenario rest: side motor torques TL,TR in N m (default 0,0)')
    add_graph_option(parser, 'constraints', help_suffix=' (default: all of them, as run; none: the trajectory task '
                                                        'only)')
    add_graph_option(parser, 'contact', help_suffix=' (coulomb needs a run without the trajectory task: rest, or '
                                                    '--controller; default ideal)')
    parser.add_argument('--controller', action='store_true',
                        help=f'closed loop: driven mode (no trajectory task; {", ".join(DRIVEN.active_names())}) '
                             'with the example tracking controller commanding the wheel torques at 25 Hz of '
                             'simulation time, as run --controller does over DDS')
    add_graph_option(parser, 'controller_mass_scale')
    add_graph_option(parser, 'adhesion_force')
    parser.add_argument('--tangent-heading', action=argparse.BooleanOptionalAction, default=None,
                        help='heading task along the path (default: on when non_lateral is active)')
    parser.add_argument('--duration', type=number(POSITIVE), help='seconds to simulate (default: the scenario\'s)')
    parser.add_argument('--dt', type=number(TIME_STEP), default=1e-3, help='RK4 step in seconds (default 0.001)')
    parser.add_argument('--robot', help='robot parameter YAML (default: config/robot.yaml)')
    add_graph_option(parser, 'world', default=None)
    parser.add_argument('--pump-command', type=number(PUMP_COMMAND), default=1.0,
                        help="with the robot file's adhesion block: the vacuum pump's command in [0, 1] (default 1)")
    add_graph_option(parser, 'engine', default=None,
                     help_suffix=' (default numba; python where the world file or the robot file\'s motor or '
                                 'adhesion block needs it, said on stderr)')
    parser.add_argument('--csv', help='CSV output path (- for stdout)')
    parser.add_argument('--bag', help='also write the graph\'s topics to this rosbag2 directory (MCAP)')
    parser.add_argument('--quiet', action='store_true', help='no progress on stderr')


def build_simulation(args: argparse.Namespace) -> tuple[Simulation, float]:
    """The simulation and duration the arguments ask for (the closed loop's plant with --controller)."""
    params = load_robot_parameters(args.robot)
    if args.adhesion_force:  # 0: the robot file's
        params = params.replace(adhesion_force=args.adhesion_force)
    robot = Robot(params, load_world(args.world))
    engine = chosen_engine(args.engine, robot, 'simulate')
    if args.pump_command != 1.0 and params.adhesion is None:
        raise CliError("--pump-command drives the robot file's adhesion block (a vacuum chamber): the file has none")
    rest = args.scenario == REST
    if not rest and (args.heading is not None or args.torque is not None):
        raise CliError('--heading and --torque set up --scenario rest; a trajectory scenario starts as its file says')
    if args.controller:
        if rest:
            raise CliError('--controller follows a trajectory scenario (circle, figure8, a YAML): rest has none')
        if args.constraints != ALL_STRUCTURAL or args.tangent_heading is not None:
            raise CliError(f'--controller runs the driven robot ({", ".join(DRIVEN.active_names())}, '
                           'no trajectory task): drop --constraints and --tangent-heading')
        selection = DRIVEN
    else:
        if args.controller_mass_scale != 1.0:
            raise CliError('--controller-mass-scale needs --controller')
        selection = ConstraintSelection.parse(args.constraints, trajectory=not rest,
                                              tangent_heading=args.tangent_heading)
    if args.contact == 'coulomb' and selection.trajectory:
        raise CliError(f'--contact coulomb with the trajectory task of scenario {args.scenario!r}: the task\'s force '
                       'is a virtual actuator, not friction; use --controller, or --scenario rest (driven by --torque)')
    if rest:
        heading = 0.0 if args.heading is None else args.heading
        q0, qd0 = np.array([0.0, 0.0, heading, 0.0, 0.0, 0.0, 0.0]), np.zeros(7)
        simulation = Simulation(robot, None, selection, q0, qd0, dt=args.dt, contact=args.contact, engine=engine)
        simulation.set_motor_torque(*parse_torque(args.torque))
        duration = args.duration if args.duration is not None else REST_DURATION
    else:
        scenario = load_scenario(args.scenario)
        q0, qd0 = scenario.initial_state(robot)
        duration = args.duration if args.duration is not None else scenario.duration
        simulation = Simulation(robot, scenario.reference, selection, q0, qd0, dt=args.dt, contact=args.contact,
                                engine=engine)
    simulation.set_pump_command(args.pump_command)
    return simulation, duration


def build_controller(args: argparse.Namespace, simulation: Simulation,
                     on_command: Callable[[float, TorqueCommand], None] | None = None
                     ) -> Callable[[StepOutputs], None] | None:
    """With --controller, the step hook that closes the loop on ``simulation``; else None.

    The controller's robot is the robot file's with its mass scaled, as tracking_controller_node
    builds it (--adhesion-force is the simulated robot's, not the controller's). ``on_command``
    is given each command with the time of the state it answers.
    """
    if not args.controller:
        return None
    robot = controller_robot(load_robot_parameters(args.robot), args.controller_mass_scale)
    controller = TrackingController(robot, simulation.reference, engine=simulation.engine)
    return close_loop(simulation, SampledController(controller), on_command)


def parse_torque(text: str | None) -> tuple[float, float]:
    """'TL,TR' in N m (None: 0,0)."""
    if text is None:
        return 0.0, 0.0
    try:
        left, right = (float(part) for part in text.split(','))
    except ValueError:
        raise CliError(f'--torque must be two numbers TL,TR in N m, got {text!r}') from None
    problem = FINITE.problem(left) or FINITE.problem(right)
    if problem is not None:
        raise CliError(f'--torque {problem}')
    return left, right


def main(args: argparse.Namespace) -> int:
    if not args.csv and not args.bag:
        raise CliError('nothing to write: give --csv PATH (or - for stdout) and/or --bag DIR')
    simulation, duration = build_simulation(args)
    # the controller is built before the bag is created (a refused controller leaves no bag behind);
    # its commands go to the bag once it is open
    bag = None

    def on_command(t: float, command: TorqueCommand) -> None:
        bag.write_command(t, command.tau_left, command.tau_right)
    controller = build_controller(args, simulation, on_command if args.bag else None)
    progress = Progress(duration, None if args.quiet else sys.stderr)
    sinks = []
    if args.bag:
        from wallbot_sim import messages
        from wallbot_sim.bag.headless import HeadlessBagWriter  # only when asked: loads rosbags
        selection = simulation.selection
        described = messages.selection_from_switches(messages.switches_from_selection(selection))
        if described.active_names() != selection.active_names():
            raise CliError('--tangent-heading without non_lateral is not a set the graph runs (constraint_config '
                           'has no switch for it), so a bag cannot hold it: add non_lateral, or drop --bag')
        bag = HeadlessBagWriter.open(Path(args.bag), simulation)
        sinks.append(bag)
    with _open_csv(args.csv) as stream:
        if stream is not None:
            groups = block_groups(simulation.robot.params)
            csv.writer(stream).writerow(CSV_COLUMNS + block_columns(groups))

        def on_step(out: StepOutputs) -> None:
            with signals.deferred:  # a signal ends the run between two complete steps
                if stream is not None:
                    stream.write(csv_line(out, groups))
                for sink in sinks:
                    sink.write(out)
                if controller is not None:  # after the state was written, as the graph answers a published state
                    controller(out)
            progress.update(out.t)

        try:
            if stream is not None and not sinks and controller is None and simulation.tabulates:
                final = simulation.run_table(duration, _table_writer(stream, progress, simulation.motor_torque))
            else:
                final = simulation.run(duration, on_step)
        except DetachedError as detached:
            print(f'detached: wheel {detached.wheel}, normal load {detached.load:.2f} N, t = {detached.t:.3f} s '
                  f'({detached})', file=sys.stderr)
            return DETACHED_STATUS
        finally:
            for sink in sinks:
                sink.close()
    progress.update(final.t, force=True)
    if not args.quiet:
        loop = ' under the tracking controller' if controller is not None else ''
        tracking = ('no reference' if simulation.reference is None else
                    f'final tracking error {final.tracking_error:.3e} m')
        print(f'{simulation.selection.label()}{loop}: {tracking}, residual {final.residual:.3e}', file=sys.stderr)
    return 0


def _table_writer(stream: TextIO, progress: Progress, motor_torque: tuple[float, float]) -> Callable[[StepTable], None]:
    """``run_table``'s hook writing each chunk's CSV lines at once (``on_step``'s lines, a chunk at a time), under
    the run's constant ``motor_torque``."""
    rows = np.empty((0, len(CSV_COLUMNS)))

    def on_table(table: StepTable) -> None:
        nonlocal rows
        if len(rows) != len(table.t):
            rows = np.empty((len(table.t), len(CSV_COLUMNS)))
        fill_rows(table, rows, motor_torque)
        with signals.deferred:  # a signal ends the run between two complete chunks
            stream.write(csv_lines(rows))
        progress.update(float(table.t[-1]))
    return on_table


class _open_csv:
    """Context manager for the CSV target: a file, stdout, or nothing."""

    def __init__(self, target: str | None) -> None:
        self.target, self.stream = target, None

    def __enter__(self) -> TextIO | None:
        if self.target == '-':
            self.stream = sys.stdout
        elif self.target:
            try:
                self.stream = open(self.target, 'w', newline='', encoding='utf-8')
            except OSError as error:
                raise CliError(f'cannot write {self.target}: {error.strerror}') from None
        return self.stream

    def __exit__(self, *exc: object) -> None:
        if self.stream is not None and self.stream is not sys.stdout:
            self.stream.close()
