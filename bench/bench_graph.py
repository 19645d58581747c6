"""CPU budget of the recorded graph of ``wallbot-sim run`` (issue 14; a measurement, not a test).

Runs ``wallbot-sim run circle`` (all constraints, the recorder writing every topic) twice, on a
private ROS domain:
  * at real-time factor 1 for --duration simulated seconds: each process's CPU share (utime +
    stime from /proc, over the run's steady part: from --warmup simulated seconds on, when every
    node has started and found the others, until the first one exits), their total in CPU seconds
    per simulated second, and the steps later than 2 ms that the dynamics reported in its
    /diagnostics (read back from the bag);
  * at factor 0 for --fast-duration simulated seconds: the simulated seconds per wall second
    (from the robot's clock messages in the bag, 10 per simulated second: their simulation time
    against the time they were logged, from t = 1 s to the end).
Beside them, the straightforward two-pinv model alone (bench_core's StraightforwardSimulation:
wallbot_sim.model.solve at every RK4 stage) stepping the same scenario in this process, before and
after the runs: its CPU seconds per simulated second. The machine-independent forms are the
ratios: graph CPU per simulated second / model CPU per simulated second (target <= 0.6) and
factor-0 speed / model speed (target >= 5).
Late steps have a baseline of their own: a bare 1 kHz sleep loop (bench_wakeup's, the pacer's wait
and nothing else) in this process, under the dynamics' scheduling, for --sleep-seconds before and
after the runs: its wake-ups later than 2 ms per minute are what the machine gives any sleeping
1 kHz loop, beside the graph's late steps per minute.

    python bench/bench_graph.py [--duration 60] [--fast-duration 20] [--warmup 3] [--engine numba|python]
                                [--markers | --foxglove] [--no-compose] [--controller | --cmd-vel]
                                [--realtime-priority N] [--write-docs [FILE]]

With no options it measures the graph as ``wallbot-sim run circle`` starts it. ``--engine`` is the
dynamics' (``run --engine``; default numba, run's); ``--engine python`` measures the model as written.

``--markers`` runs the graph with ``run --markers`` (viewer_node at its 30 frames per second, nothing
subscribing its markers), ``--foxglove`` with ``run --foxglove`` (the viewer also serving the live
view, which builds the markers every frame; no client connected), so its cost shows beside the others'.

By default the dynamics and the recorder run in one process (dynamics_recorder_node, the per-step
topics recorded in process; ``run``'s default), shown as one line; ``--no-compose`` runs them as two
(``run --no-compose``, everything over DDS).

``--controller`` runs the closed loop, ``run --controller``: the tracking controller answering every
40th state in lockstep, its CPU share beside the others'. ``--cmd-vel`` runs ``run rest --drive
cmd_vel`` instead of the circle: cmd_vel_node answering every 20th state in lockstep (zero commands:
nothing publishes cmd_vel), no trajectory node.

``--write-docs`` writes the figures into the section of docs/performance.md named after the options
(``graph``, ``graph-controller``, ``graph-python-no-compose``, ...).
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench_core import StraightforwardSimulation
from bench_wakeup import sleep_loop
from report import Report, add_write_docs_option
from wallbot_msgs_py import codec, topics
from wallbot_sim.bag.reader import messages
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.graph import ChildProcesses, child_processes, cpu_seconds
from wallbot_sim.model import ConstraintSelection, Robot
from wallbot_sim.model.simulation import ENGINES, NUMBA
from wallbot_sim.loop.status import LATE_LIMIT

NODES = {'dynamics': 'wallbot_sim.nodes.dynamics', 'trajectory': 'wallbot_sim.nodes.trajectory',
         'constraint_config': 'wallbot_sim.nodes.constraint_config', 'recorder': 'wallbot_sim.nodes.recorder'}
"""The recorded graph's nodes, by the module each child of ``run`` runs."""
COMPOSED_NODES = {'dynamics+recorder': 'wallbot_sim.nodes.dynamics_recorder',
                  **{name: module for name, module in NODES.items() if name not in ('dynamics', 'recorder')}}
"""The nodes of ``run`` (``--compose``, its default)."""
LOOPS = {'open': ('circle', [], None, None),
         'controller': ('circle', ['--controller'], None, 'wallbot_sim.nodes.controller'),
         'cmd_vel': ('rest', ['--drive', 'cmd_vel'], 'trajectory', 'wallbot_sim.nodes.cmd_vel')}
"""The graphs measured: scenario, ``run``'s options, the node it lacks, the commanding node's module."""
SAMPLE_PERIOD = 0.25
"""Wall seconds between /proc samples."""


def late_wakeups(seconds: float, priority: int) -> list[float]:
    """Lateness (s) of every wake-up later than 2 ms of a bare 1 kHz sleep loop run for ``seconds``,
    under SCHED_FIFO ``priority`` where given and permitted (as the dynamics' loop thread)."""
    if priority:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except OSError:
            pass  # the dynamics falls back to normal scheduling too
    try:
        return [late for late in sleep_loop(seconds) if late > LATE_LIMIT]
    finally:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


def model_cpu_per_simulated_second(simulated: float) -> float:
    """CPU seconds the two-pinv model takes per simulated second (circle, all constraints, 1 kHz)."""
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    simulation = StraightforwardSimulation(robot, scenario.reference, ConstraintSelection.parse(
        'belt,non_lateral,nonslip'), *scenario.initial_state(robot))
    steps = round(simulated / simulation.dt)
    started = time.process_time()
    for _ in range(steps):
        simulation.step()
    return (time.process_time() - started) / (steps * simulation.dt)


@dataclass
class Run:
    """What one ``wallbot-sim run`` took: CPU seconds per process over the window, the window's wall
    span (time.time() seconds) and the dynamics' diagnostics (receive time s, key -> value)."""

    cpu: dict[str, float] = field(default_factory=dict)
    window: tuple[float, float] = (0.0, 0.0)
    diagnostics: list[tuple[float, dict[str, str]]] = field(default_factory=list)
    clocks: list[tuple[float, float]] = field(default_factory=list)
    """The robot's clock messages in the bag: (log time s, simulation time s)."""

    def simulated(self) -> float:
        """Simulated seconds within the window (the diagnostics' simulation time, interpolated)."""
        wall = [w for w, _ in self.diagnostics]
        sim = [float(d['simulation time']) for _, d in self.diagnostics]
        return float(np.interp(self.window[1], wall, sim) - np.interp(self.window[0], wall, sim))

    def simulation_time(self, wall: float) -> float:
        """The robot's simulation time (s) at wall time ``wall`` (time.time()), from the clock messages;
        0 before the first."""
        if not self.clocks or wall < self.clocks[0][0]:
            return 0.0
        return float(np.interp(wall, *zip(*self.clocks)))

    def speed(self, after: float = 1.0) -> float:
        """Simulated s per wall s from simulation time ``after`` to the last clock message (10 a simulated
        second: a short fast run still has many, where the 1 Hz diagnostics may have one)."""
        timed = [(log, sim) for log, sim in self.clocks if sim >= after]
        if len(timed) < 2 or timed[-1][0] <= timed[0][0]:
            raise SystemExit('too few clock messages in the bag to time the run: raise --fast-duration')
        return (timed[-1][1] - timed[0][1]) / (timed[-1][0] - timed[0][0])


def graph_run(launcher: ChildProcesses, out: Path, factor: float, duration: float, warmup: float,
              engine: str, viewer: list[str], compose: bool, priority: int, loop: str) -> Run:
    """Run the circle scenario at ``factor`` for ``duration`` simulated seconds with the dynamics'
    ``engine``, sampling /proc; ``viewer``: the run's options that start the viewer (none: no viewer);
    ``compose``: ``run --compose`` or ``--no-compose``; ``priority``: its ``--realtime-priority``; ``loop``: the
    ``LOOPS`` entry (open loop, ``run --controller``, ``run rest --drive cmd_vel``)."""
    name = f'run_factor_{factor:g}'
    scenario, options, without, controller = LOOPS[loop]
    nodes = {node: module for node, module in (COMPOSED_NODES if compose else NODES).items() if node != without}
    if viewer:
        nodes = {**nodes, 'viewer': 'wallbot_sim.nodes.viewer'}
    if controller:
        nodes = {**nodes, loop: controller}
    run = launcher.start([sys.executable, '-m', 'wallbot_sim.cli.main', 'run', scenario, '--duration', duration,
                          '--real-time-factor', factor, '--no-plots', '--out', out, '--engine', engine,
                          '--realtime-priority', priority, *viewer, '--compose' if compose else '--no-compose',
                          *options], name)
    pids: dict[str, int] = {}
    samples: list[tuple[float, dict[str, float]]] = []
    while run.poll() is None:
        time.sleep(SAMPLE_PERIOD)
        if len(pids) < len(nodes):
            pids = {node: pid for pid, cmd in child_processes(run.pid).items()
                    for node, module in nodes.items() if module in cmd.split()}
            if len(pids) == len(nodes):
                pids['run'] = run.pid
            continue
        try:
            samples.append((time.time(), {node: cpu_seconds(pid) for node, pid in pids.items()}))
        except (OSError, IndexError):
            break  # a node has exited: the run is stopping
    if run.wait() != 0:
        raise SystemExit(f'{name} failed with status {run.returncode}: see {launcher.log(name)}')
    result = Run()
    for raw in messages(out / 'bag', [topics.CLOCK.resolve()]):
        result.clocks.append((raw.timestamp * 1e-9, codec.leading_stamp_ns(raw.data) * 1e-9))
    steady = [sample for sample in samples if result.simulation_time(sample[0]) >= warmup]
    if len(steady) < 2 or steady[-1][0] <= steady[0][0]:
        raise SystemExit(f'{name}: too short to measure; raise the duration')
    (start, first), (end, last) = steady[0], steady[-1]
    result.cpu, result.window = {node: last[node] - first[node] for node in pids}, (start, end)
    for raw in messages(out / 'bag', ['/diagnostics']):
        for report in codec.decode_diagnostics(raw.data).statuses:
            if 'simulation' in report.name:  # the dynamics' report
                result.diagnostics.append((raw.timestamp * 1e-9, report.value_map()))
    if len(result.diagnostics) < 2:
        raise SystemExit(f'{name}: fewer than two /diagnostics of the dynamics in the bag')
    return result


def section_name(args: argparse.Namespace) -> str:
    """The docs section of this variant: ``graph`` and each option that differs from ``run``'s defaults."""
    parts = ['graph']
    parts += [] if args.engine == NUMBA else [args.engine]
    parts += [] if args.compose else ['no-compose']
    parts += [] if args.loop == 'open' else [args.loop.replace('_', '-')]
    parts += ['markers'] if args.markers else ['foxglove'] if args.foxglove else []
    parts += [f'rt{args.realtime_priority}'] if args.realtime_priority else []
    return '-'.join(parts)


def free_port() -> int:
    """A TCP port nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--duration', type=float, default=60.0, help='simulated seconds at factor 1 (default 60)')
    parser.add_argument('--fast-duration', type=float, default=20.0,
                        help='simulated seconds at factor 0 (default 20)')
    parser.add_argument('--warmup', type=float, default=3.0,
                        help='simulated seconds before CPU is counted (default 3): start-up is not steady work')
    parser.add_argument('--model-seconds', type=float, default=2.0,
                        help='simulated seconds the two-pinv model steps, before and after the runs (default 2)')
    parser.add_argument('--sleep-seconds', type=float, default=20.0,
                        help='seconds the bare 1 kHz sleep loop runs, before and after the runs (default 20)')
    parser.add_argument('--engine', choices=ENGINES, default=NUMBA,
                        help="the dynamics' engine (run --engine; default numba, run's)")
    choice = parser.add_mutually_exclusive_group()
    choice.add_argument('--markers', action='store_true', help='run with --markers (viewer_node)')
    choice.add_argument('--foxglove', action='store_true', help='run with --foxglove on a free port')
    parser.add_argument('--compose', action=argparse.BooleanOptionalAction, default=True,
                        help="the dynamics and the recorder in one process (run's default), or two (--no-compose)")
    closed = parser.add_mutually_exclusive_group()
    closed.add_argument('--controller', action='store_const', dest='loop', const='controller', default='open',
                        help='run with --controller (the tracking controller in lockstep, driven mode)')
    closed.add_argument('--cmd-vel', action='store_const', dest='loop', const='cmd_vel',
                        help='run rest --drive cmd_vel (cmd_vel_node in lockstep) instead of the circle')
    parser.add_argument('--realtime-priority', type=int, default=0,
                        help="run with --realtime-priority N (SCHED_FIFO for the dynamics' loop thread; default 0)")
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report(section_name(args))
    viewer = ['--markers'] if args.markers else ['--foxglove', str(free_port())] if args.foxglove else []

    claim = claim_domain_id()
    work = Path(tempfile.mkdtemp(prefix='wallbot_bench_graph_'))
    launcher = ChildProcesses(work / 'logs', claim.env(os.environ), stop_timeout=120.0)
    try:
        model_before = model_cpu_per_simulated_second(args.model_seconds)
        bare_late = late_wakeups(args.sleep_seconds, args.realtime_priority)
        realtime = graph_run(launcher, work / 'factor1', 1.0, args.duration, args.warmup, args.engine, viewer,
                             args.compose, args.realtime_priority, args.loop)
        fast = graph_run(launcher, work / 'factor0', 0.0, args.fast_duration, args.warmup, args.engine, viewer,
                         args.compose, args.realtime_priority, args.loop)
        model_after = model_cpu_per_simulated_second(args.model_seconds)
        bare_late += late_wakeups(args.sleep_seconds, args.realtime_priority)
    finally:
        launcher.stop_all(first=tuple(name for name in launcher.processes if name.startswith('run')))
        claim.release()
    model = (model_before + model_after) / 2

    wall = realtime.window[1] - realtime.window[0]
    simulated = realtime.simulated()
    total = sum(realtime.cpu.values())
    late = sum(int(d['late steps (> 2 ms)']) for _, d in realtime.diagnostics)
    lateness = max(float(d['lateness max (ms)']) for _, d in realtime.diagnostics)
    print(f'two-pinv model alone (circle, all constraints, 1 kHz): {model:.3f} CPU s per simulated s '
          f'(before the runs {model_before:.3f}, after {model_after:.3f})')
    scenario, options, _without, _controller = LOOPS[args.loop]
    composed = (('' if args.compose else ' --no-compose') + ''.join(f' {option}' for option in options)
                + (f' --realtime-priority {args.realtime_priority}' if args.realtime_priority else ''))
    print(f'\nwallbot-sim run {scenario} --engine {args.engine}{composed}, factor 1, {args.duration:g} simulated s; '
          f'measured over {wall:.1f} wall s = {simulated:.1f} simulated s:')
    rows = []
    for node, seconds in realtime.cpu.items():
        print(f'  {node:18s} {100 * seconds / wall:6.1f} % of a core   {seconds / simulated:6.3f} CPU s per '
              'simulated s')
        rows.append((f'{node}, CPU s per simulated s (share of a core)',
                     f'{seconds / simulated:.3f} ({100 * seconds / wall:.1f} %)', '< 0.03 (3 %) for a node that does '
                     'not step the model' if node in ('trajectory', 'constraint_config', *LOOPS) else ''))
    print(f'  {"total":18s} {100 * total / wall:6.1f} % of a core   {total / simulated:6.3f} CPU s per simulated s'
          '   (target <= 50 %)')
    print(f'  ratio to the two-pinv model: {total / simulated / model:.2f}   (target <= 0.6)')
    print(f'  steps later than 2 ms over the whole run: {late}   (max lateness {lateness:.3f} ms; target 0)')
    graph_rate, bare_rate = late / (args.duration / 60), len(bare_late) / (2 * args.sleep_seconds / 60)
    print(f'  per minute: {graph_rate:.0f}; a bare 1 kHz sleep loop here, same scheduling, '
          f'{2 * args.sleep_seconds:g} s: {bare_rate:.0f} wake-ups later than 2 ms per minute '
          f'(max {1e3 * max(bare_late, default=0.0):.2f} ms)')

    rows += [('**whole graph**, CPU s per simulated s (share of a core)',
              f'**{total / simulated:.3f}** ({100 * total / wall:.1f} %)', '<= 0.5 (50 %)'),
             ('two-pinv model alone, CPU s per simulated s (before / after the runs)',
              f'{model:.3f} ({model_before:.3f} / {model_after:.3f})', ''),
             ('**ratio of the whole graph to the two-pinv model**', f'**{total / simulated / model:.2f}**', '<= 0.6'),
             (f'steps later than 2 ms in {args.duration:g} s (max lateness)', f'{late} ({lateness:.2f} ms)', '0'),
             (f'bare 1 kHz sleep loop, wake-ups later than 2 ms a minute ({2 * args.sleep_seconds:g} s; max)',
              f'{bare_rate:.0f} ({1e3 * max(bare_late, default=0.0):.2f} ms)', '')]
    speed = fast.speed()
    fast_wall = fast.window[1] - fast.window[0]
    print(f'\nwallbot-sim run {scenario} --engine {args.engine}{composed}, factor 0, {args.fast_duration:g} simulated s:')
    print(f'  simulated s per wall s: {speed:.2f}   (target >= 5)')
    print(f'  ratio to the two-pinv model\'s speed ({1 / model:.2f} simulated s per CPU s): {speed * model:.2f}'
          '   (target >= 5)')
    print('  CPU share: ' + ', '.join(f'{node} {100 * s / fast_wall:.0f} %' for node, s in fast.cpu.items()))
    rows += [(f'factor 0 ({args.fast_duration:g} s): simulated s per wall s', f'{speed:.2f}', ''),
             ("**factor 0: ratio to the two-pinv model's speed**", f'**{speed * model:.2f}**', '>= 5')]
    report.table(('measure', 'figure', 'target'), rows,
                 f'`wallbot-sim run {scenario} --engine {args.engine}{composed}`, {args.duration:g} simulated s at '
                 f'factor 1 (CPU over {wall:.1f} wall s = {simulated:.1f} simulated s of steady running):')
    report.write(args.write_docs)
    load = os.getloadavg()
    print(f'\nmachine: {os.cpu_count()} CPUs, load average at the end {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, '
          f'Python {sys.version.split()[0]}')
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
