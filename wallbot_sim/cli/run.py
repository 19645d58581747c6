"""``wallbot-sim run``: the main job. The real node graph in its own DDS domain, recorded, plotted.

Starts constraint_config, trajectory, and the dynamics and the recorder in one process (the per-step
topics recorded in process; ``--no-compose``: as separate processes), the dynamics on the compiled
engine (``--engine python``, or a world file or a robot file's motor or adhesion block: the model as
written), with a ROS_DOMAIN_ID of their own (localhost discovery only; the first line on stdout is the
``export`` that attaches another terminal), all at once (each node holds back what it publishes until the recorder hears it), shows
simulation time and real-time factor while they run, stops the graph once the recorder holds the
whole duration (``--duration 0``: at Ctrl-C), then prints a summary and writes the paper's figures.
A node that dies ends the run with its status and log named; Ctrl-C or SIGTERM stops the graph
cleanly; the bag is kept either way (reindexed if its recorder could not close it).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Callable

from wallbot_sim.cli.errors import CliError
from wallbot_sim.cli.engine import StartClock, chosen_engine
from wallbot_sim.cli.options import add_graph_option
from wallbot_sim.cli.progress import Progress
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.config import load_robot_parameters, load_scenario, load_world
from wallbot_sim.domain import (MAX_DOMAIN_ID, MIN_DOMAIN_ID, DomainUnavailable, claim_chosen_domain_id,
                                claim_domain_id)
from wallbot_sim.graph import Graph, NodeDied, NodeSpec
from wallbot_sim.graph_description import (CONTROLLER, DRIVES, DYNAMICS_RECORDER, RECORDER, VIEWER,
                                           GraphDescriptionError, describe_driven_graph, describe_graph)
from wallbot_sim.graph_monitor import Monitor
from wallbot_sim.graph_options import ALL_STRUCTURAL, option
from wallbot_sim.live_view import DEFAULT_HOST, DEFAULT_PORT
from wallbot_sim.model import ConstraintSelection, Robot

HELP = 'run a scenario through the real node graph, record a bag, plot it'
REST = 'rest'
"""The scenario of a run driven by the user (--drive): no trajectory, at rest at the origin."""
OPTIONAL = {CONTROLLER: 'the dynamics falls back to zero torque after command_timeout',
            VIEWER: 'no markers or live view from now on'}
"""Nodes whose exit does not end the run, and what follows: without its controller the dynamics falls
back to zero torque after command_timeout, which is a run worth recording (and a test of that
fallback); the viewer only shows the run."""
START_TIMEOUT = 30.0
"""Wall seconds to wait for the graph to come up (the recorder discovered; twice that for the first clock recorded),
the time the dynamics says it loads its compiled kernel left out (``StartClock``)."""
FINAL_WAIT = 10.0
"""Wall seconds to wait, after the last step is recorded, for the other nodes' last messages: the
dynamics' diagnostics of the stop (published once a second) and the trajectory node's reference
pose at the end (it follows /clock, and lags it on a loaded machine)."""


def domain_id(text: str) -> int:
    """An argparse ``type``: a ROS_DOMAIN_ID a run may claim (whether another run holds it is
    known only when it is claimed)."""
    try:
        value = int(text)
    except ValueError:
        value = None
    if value is None or not MIN_DOMAIN_ID <= value <= MAX_DOMAIN_ID:
        raise argparse.ArgumentTypeError(f'must be an integer in {MIN_DOMAIN_ID}..{MAX_DOMAIN_ID} (0 is the domain '
                                         f'of every ROS process nobody configured), got {text!r}')
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options; those setting a node's parameter (and their help) are the launch file's
    (``graph_options.OPTIONS``), checked by the node's own rule."""
    parser.add_argument('scenario', help=f'circle, figure8, a scenario YAML path, or {REST} (with --drive: at rest '
                                         'at the origin, driven by your commands)')
    add_graph_option(parser, 'constraints', help_suffix=' (default: all of them)')
    parser.add_argument('--tangent-heading', action=argparse.BooleanOptionalAction, default=None,
                        help='heading task along the path (default: on when non_lateral is active)')
    add_graph_option(parser, 'duration', default=None, help_suffix=" (default: the scenario's)")
    parser.add_argument('--domain-id', type=domain_id, metavar='N',
                        help=f'ROS_DOMAIN_ID of the run, {MIN_DOMAIN_ID}..{MAX_DOMAIN_ID}, refused if another run '
                             'holds it (default: a free one); the first line printed is the export that '
                             'attaches another terminal')
    add_graph_option(parser, 'real_time_factor')
    add_graph_option(parser, 'robot', default=None)
    add_graph_option(parser, 'world', default=None)
    add_graph_option(parser, 'contact')
    add_graph_option(parser, 'engine', default=None,
                     help_suffix=' (default numba; python where the world file or the robot file\'s motor or '
                                 'adhesion block needs it, said on stderr)')
    add_graph_option(parser, 'adhesion_force')
    parser.add_argument('--out', help='output directory (default runs/SCENARIO-TIMESTAMP); bag in OUT/bag')
    parser.add_argument('--no-plots', action='store_true', help='skip the figures')
    parser.add_argument('--controller', action='store_true', help=option('controller').setting.help)
    parser.add_argument('--markers', action=argparse.BooleanOptionalAction, default=False,
                        help=option('viewer').setting.help + ' (default: off)')
    add_graph_option(parser, 'foxglove_port', nargs='?', const=DEFAULT_PORT, metavar='PORT',
                     help_suffix=f' (PORT default {DEFAULT_PORT})')
    add_graph_option(parser, 'foxglove_host', default=None, help_suffix=' (with --foxglove)')
    add_graph_option(parser, 'controller_mass_scale')
    parser.add_argument('--drive', choices=tuple(DRIVES), help=f'with scenario {REST}: ' + option('drive').setting.help)
    add_graph_option(parser, 'realtime_priority', metavar='N')
    parser.add_argument('--compose', action=argparse.BooleanOptionalAction, default=True,
                        help=option('compose').setting.help + ' (default: on)')


def output_directory(requested: str | None, scenario: str) -> Path:
    """The run's directory, created; it must not hold a bag already."""
    out = Path(requested) if requested else Path('runs') / f'{Path(scenario).stem}-{datetime.now():%Y%m%d-%H%M%S}'
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / '.write-test'
        probe.write_text('')
        probe.unlink()
    except OSError as error:
        raise CliError(f'cannot write to output directory {out}: {error.strerror}') from None
    if (out / 'bag').exists():
        raise CliError(f'{out / "bag"} exists already: choose another --out')
    return out


def check_nodes(graph: Graph, reported: set[str]) -> None:
    """Raise NodeDied for the first essential node that has exited; report optional ones once."""
    for name, process in graph.processes.items():
        status = process.poll()
        if status is None:
            continue
        if name not in OPTIONAL:
            raise NodeDied(name, status, graph.log(name))
        if name not in reported:
            reported.add(name)
            print(f'\nwallbot-sim run: node {name} exited with status {status} (its log: {graph.log(name)}); '
                  f'{OPTIONAL[name]}, the run goes on', file=sys.stderr)


def run_graph(graph: Graph, specs: list[NodeSpec], duration: float, progress: Progress,
              reference: bool = True) -> None:
    """Start the graph, return once the recorder holds ``duration`` seconds (0: only by an
    exception, Ctrl-C's KeyboardInterrupt), and stop it (also when interrupted); NodeDied if an
    essential node exits. ``reference``: the graph has a trajectory node, whose last reference
    pose is waited for."""
    # the monitor first: made once the nodes run, it may discover the trajectory node only after its last
    # reference pose under load (seen: the final wait then ran out)
    monitor = Monitor()
    reported: set[str] = set()
    try:
        for spec in specs:  # at once: they load in parallel, each holding back until the recorder hears it
            graph.start_node(spec)
        wait_for_start(graph, monitor, reported, specs[0].name)
        while duration == 0 or monitor.recorded < duration - 1e-9:
            check_nodes(graph, reported)
            monitor.spin(0.1)
            if monitor.recorded > 0:
                progress.update(monitor.recorded)
        progress.update(duration, force=True)
        # The summary's residual is the maximum the diagnostics carry for each window of steps:
        # wait for the window that holds the last steps, published after the dynamics stopped.
        def missing() -> list[str]:
            return [what for what, seen in (("the dynamics' diagnostics of its stop", monitor.dynamics_stopped()),
                                            ('the last reference pose', not reference
                                             or monitor.reference_reached(duration)))
                    if not seen]
        deadline = time.monotonic() + FINAL_WAIT
        while missing() and time.monotonic() < deadline:
            check_nodes(graph, reported)
            monitor.spin(0.1)
        late = missing()
        if late:
            print(f'\nwallbot-sim run: {" and ".join(late)} not seen within {FINAL_WAIT:.0f} s; the bag may end '
                  f'early (logs in {graph.log_dir})', file=sys.stderr)
    finally:
        # The monitor leaves DDS before the nodes do: Fast DDS 2.14 deleting a participant while remote
        # endpoints go away can deadlock in DomainParticipant::set_listener, spinning a core for ever
        # (seen once: run hung there after the graph's signal, a discovery callback waiting for the lock
        # the deletion held); with the graph still up no endpoint is being removed meanwhile
        monitor.close()
        # the recorder last, its bag ending at its signal: every other node has delivered what it published
        # before it left DDS (a message a starved recorder lost in transit is repaired only meanwhile)
        graph.stop_all(last=(RECORDER, DYNAMICS_RECORDER))


def wait_for_start(graph: Graph, monitor: Monitor, reported: set[str], recorder: str) -> None:
    """Return once the recorder has recorded simulation time; CliError if the recorder (the process ``recorder``)
    is not discovered within START_TIMEOUT, or nothing is recorded within twice that, not counting the time the
    dynamics says it loads its compiled kernel (said on the terminal when that takes long: ``StartClock``)."""
    clock = StartClock(time.monotonic())
    while monitor.recorded < 0:
        check_nodes(graph, reported)
        if clock.tick(time.monotonic(), monitor.kernel_loading()):
            print("wallbot-sim run: the dynamics is still loading its compiled kernel: a machine's first run "
                  "compiles it into numba's cache (about a minute)...", file=sys.stderr, flush=True)
        if not monitor.recorder_ready() and clock.waited() > START_TIMEOUT:
            raise CliError(f'the recorder did not come up within {START_TIMEOUT:.0f} s; its log: {graph.log(recorder)}')
        if clock.waited() > 2 * START_TIMEOUT:
            raise CliError(f'no simulation time recorded after {2 * START_TIMEOUT:.0f} s; logs in {graph.log_dir}')
        monitor.spin(0.05)


def main(args: argparse.Namespace) -> int:
    if args.foxglove_host is not None and not args.foxglove:
        raise CliError('--foxglove-host needs --foxglove')
    if (args.scenario == REST) != (args.drive is not None):
        raise CliError(f'--drive and scenario {REST} go together: {REST} has no trajectory to track, a drive '
                       'replaces it')
    if args.drive is not None:
        return main_driven(args)
    scenario = load_scenario(args.scenario)
    selection = ConstraintSelection.parse(args.constraints, tangent_heading=args.tangent_heading)
    if args.tangent_heading and not selection.non_lateral:
        raise CliError('--tangent-heading acts with non_lateral in the graph (constraint_config); '
                       'add non_lateral to --constraints, or use simulate for a heading task without it')
    duration = scenario.duration if args.duration is None else args.duration
    factor = args.real_time_factor
    mass_scale = None
    if args.controller:
        if args.constraints != ALL_STRUCTURAL or args.tangent_heading is not None:
            raise CliError(f'--controller runs the driven robot ({", ".join(DRIVEN.active_names())}, no trajectory '
                           'task): drop --constraints and --tangent-heading')
        mass_scale = args.controller_mass_scale
        selection = DRIVEN
    elif args.controller_mass_scale != 1.0:
        raise CliError('--controller-mass-scale needs --controller')
    if args.contact == 'coulomb' and not args.controller:
        raise CliError("--contact coulomb needs --controller or --drive: with the trajectory task on, the task's force "
                       'is a virtual actuator, not friction')
    robot_file = Path(args.robot).resolve() if args.robot else None
    loop = '' if mass_scale is None else f' under tracking_controller_node (mass scale {mass_scale:g})'

    def describe(bag: Path, engine: str) -> list[NodeSpec]:
        try:
            return describe_graph(scenario, selection, duration=duration, real_time_factor=factor, bag=bag,
                                  controller_mass_scale=mass_scale, robot_file=robot_file,
                                  contact_model=args.contact, adhesion_force=args.adhesion_force, engine=engine,
                                  compose=args.compose, realtime_priority=args.realtime_priority,
                                  world_file=world_path(args), **viewer_options(args))
        except GraphDescriptionError as error:
            raise CliError(str(error)) from None
    return run_described(args, describe, f'{scenario.name}, {selection.label()}{loop}', duration, robot_file)


def main_driven(args: argparse.Namespace) -> int:
    """``run rest --drive DRIVE``: the driven robot at rest at the origin under the user's commands."""
    if args.constraints != ALL_STRUCTURAL or args.tangent_heading is not None or args.controller:
        raise CliError(f'--drive runs the driven robot ({", ".join(DRIVEN.active_names())}, no trajectory task): '
                       'drop --constraints, --tangent-heading and --controller')
    if args.controller_mass_scale != 1.0:
        raise CliError('--controller-mass-scale needs --controller')
    duration = 0.0 if args.duration is None else args.duration
    robot_file = Path(args.robot).resolve() if args.robot else None

    def describe(bag: Path, engine: str) -> list[NodeSpec]:
        return describe_driven_graph(args.drive, duration=duration, real_time_factor=args.real_time_factor, bag=bag,
                                     robot_file=robot_file, contact_model=args.contact,
                                     adhesion_force=args.adhesion_force, engine=engine, compose=args.compose,
                                     realtime_priority=args.realtime_priority, world_file=world_path(args),
                                     **viewer_options(args))
    return run_described(args, describe, f'{REST}, {DRIVEN.label()} driven by {args.drive}', duration, robot_file,
                         reference=False)


def world_path(args: argparse.Namespace) -> Path | None:
    """--world resolved (the nodes run elsewhere), None without it."""
    return Path(args.world).resolve() if args.world else None


def viewer_options(args: argparse.Namespace) -> dict[str, object]:
    """The graph description's viewer arguments for --markers, --foxglove and --foxglove-host."""
    return {'viewer': args.markers, 'foxglove_port': args.foxglove,
            'foxglove_host': args.foxglove_host or DEFAULT_HOST}


def run_described(args: argparse.Namespace, describe: Callable[[Path, str], list[NodeSpec]], title: str,
                  duration: float, robot_file: Path | None, reference: bool = True) -> int:
    """Claim a domain, run the graph ``describe`` gives for the bag's path and the engine (``chosen_engine``),
    summarize and plot."""
    factor = args.real_time_factor
    params = load_robot_parameters(robot_file)
    robot = Robot(params.replace(adhesion_force=args.adhesion_force) if args.adhesion_force else params,
                  load_world(args.world))
    engine = chosen_engine(args.engine, robot, 'run')
    try:
        claim = claim_domain_id() if args.domain_id is None else claim_chosen_domain_id(args.domain_id)
    except DomainUnavailable as error:
        raise CliError(str(error)) from None
    with claim:
        out = output_directory(args.out, args.scenario)
        bag = out / 'bag'
        specs = describe(bag, engine)
        print(f'{claim.export_line()}  # in another terminal, to see this run with ros2 topic, RViz, ...', flush=True)
        os.environ.update(claim.env())  # the monitor node joins the run's domain
        graph = Graph(out / 'logs', claim.env())
        length = f'{duration:g} s' if duration > 0 else 'until Ctrl-C'
        print(f'wallbot-sim run: {title}, {length} at real-time factor {factor:g}, '
              f'ROS_DOMAIN_ID {claim.domain_id}; logs in {graph.log_dir}', file=sys.stderr)
        if args.foxglove:
            print(f'wallbot-sim run: live view for Foxglove on ws://{args.foxglove_host or DEFAULT_HOST}:'
                  f'{args.foxglove}',
                  file=sys.stderr)
        progress = Progress(duration, sys.stderr)
        try:
            run_graph(graph, specs, duration, progress, reference)
        except NodeDied as died:
            from wallbot_sim.bag.reindex import repair_unclosed
            raise CliError(f'{died}; partial bag kept in {bag}{repair_unclosed(bag)}', code=1) from None
        except KeyboardInterrupt:
            if duration > 0 or not recorded_steps(bag):
                print(f'\nwallbot-sim run: interrupted; partial bag kept in {bag}', file=sys.stderr)
                return 130
            # a run until Ctrl-C ends here: its summary, and still the status of an interrupted command
            print('\nwallbot-sim run: stopped by Ctrl-C; the bag as recorded:', file=sys.stderr)
            report(bag, out, robot, plots=not args.no_plots)
            return 130
    return report(bag, out, robot, plots=not args.no_plots)


def recorded_steps(bag: Path) -> bool:
    """Whether the closed bag holds odometry: a run stopped before this command saw its first recorded step (its
    view of the graph lags the graph's) has one to summarize as well."""
    from wallbot_msgs_py import topics
    from wallbot_sim.bag.errors import BagError
    from wallbot_sim.bag.reader import info
    try:
        return info(bag).topic(topics.ODOM.resolve()).count > 0
    except (BagError, OSError):  # no bag, or no odometry topic in it (UnknownTopicError)
        return False


def report(bag: Path, out: Path, robot: Robot, plots: bool) -> int:
    """Print the summary of the recorded run and write its figures."""
    from wallbot_sim.plots.figures import write_figures
    from wallbot_sim.rundata import format_summary, load_run, summarize
    reading = Progress(0.0, sys.stderr, label='summary: bag read to ', rate='bag seconds per second')

    def read_to(done: float, total: float) -> None:
        reading.duration = total  # the bag's length, which the summary reads from its metadata once
        reading.update(done)
    summary = summarize(bag, read_to)
    if reading.shown:
        reading.update(reading.duration, force=True)
    adsorption = robot.adsorption
    print(format_summary(summary))
    print(f'adsorption force:    {adsorption.applied_force:.2f} N applied, {adsorption.minimum_force:.2f} N minimum '
          f'(margin {adsorption.margin:.2f})')
    print(f'bag:                 {bag}')
    if plots:
        files = write_figures([load_run(bag)], out / 'plots')
        print(f'plots:               {out / "plots"} ({len(files)} figures)')
    return 0
