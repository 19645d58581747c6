"""Load benchmark: the 1 kHz graph, recorded, while another process keeps one core busy.

    python bench/bench_load.py [--duration 20] [--no-controller] [--no-busy] [--scenario circle] [--json]
                               [--write-docs [FILE]]

Runs ``wallbot-sim run SCENARIO --duration D --no-plots`` (its own claimed DDS domain: recorder,
constraint_config, trajectory, dynamics at real-time factor 1 with belt + non_lateral + nonslip,
and with ``--controller`` the tracking controller in driven mode) beside a python busy loop, then
reads the run's bag:

* achieved rate, deadline misses: from the dynamics' /diagnostics as recorded ('achieved rate (Hz)',
  'late steps (> 2 ms)', 'lateness max (ms)'; one window per wall second, the start-up window
  left out of the rate);
* messages lost: recorded odometry (and the other 1 kHz topics) against the steps simulated
  (duration x 1000 + 1 for the start state), duplicated stamps, and the largest gap between
  consecutive odometry stamps (1 ms when nothing is lost);
* the busy loop's CPU share (from /proc), to show the core was really taken.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from report import Report, add_write_docs_option
from wallbot_sim.graph import ChildProcesses, cpu_seconds

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from wallbot_msgs_py import codec  # noqa: E402
from wallbot_sim.bag.reader import info, messages  # noqa: E402

STEP_TOPICS = ('odom', 'wheel_states', 'constraint_wrench', 'drive_forces')
"""The topics with a message at every step (/clock goes out at clock_rate_hz)."""


def analyse(bag: Path, duration: float) -> dict:
    names = {t.name.rsplit('/', 1)[-1]: t.name for t in info(bag).topics}
    wanted = {names[leaf]: leaf for leaf in (*STEP_TOPICS, 'diagnostics', 'wheel_torque_cmd') if leaf in names}
    stamps: dict[str, list[int]] = {leaf: [] for leaf in wanted.values()}
    receive_ns: list[int] = []
    windows = []
    for raw in messages(bag, list(wanted)):
        leaf = wanted[raw.topic]
        if leaf == 'diagnostics':
            values = {key: value for status in codec.decode_diagnostics(raw.data).statuses
                      for key, value in status.values}
            if 'achieved rate (Hz)' in values:
                windows.append(values)
            continue
        if leaf == 'wheel_torque_cmd':
            stamps[leaf].append(raw.timestamp)
            continue
        stamps[leaf].append(codec.leading_stamp_ns(raw.data))
        if leaf == 'odom':
            receive_ns.append(raw.timestamp)
    expected = round(duration * 1000) + 1
    result = {'expected_steps': expected, 'topics': {}}
    for leaf in STEP_TOPICS:
        s = stamps.get(leaf, [])
        unique = sorted(set(s))
        gaps = [b - a for a, b in zip(unique, unique[1:])]
        in_run = [x for x in unique if x <= round(duration * 1e9)]
        result['topics'][leaf] = {'recorded': len(s), 'unique_stamps': len(unique), 'duplicates': len(s) - len(unique),
                                  'lost': expected - len(in_run),
                                  'max_stamp_gap_ms': max(gaps) / 1e6 if gaps else None}
    if 'wheel_torque_cmd' in stamps:
        result['wheel_torque_cmd_recorded'] = len(stamps['wheel_torque_cmd'])
    running = [w for w in windows if w.get('status') == 'running' or 'running' in str(w.get('status', ''))]
    rates = [float(w['achieved rate (Hz)']) for w in running[1:]]  # the first window holds the start-up
    result['diagnostics_windows'] = len(windows)
    result['achieved_rate_hz'] = {'mean': sum(rates) / len(rates) if rates else None,
                                  'min': min(rates) if rates else None, 'max': max(rates) if rates else None}
    result['late_steps'] = sum(int(float(w.get('late steps (> 2 ms)', 0))) for w in windows)
    result['lateness_max_ms'] = max((float(w.get('lateness max (ms)', 0)) for w in windows), default=None)
    result['step_time_max_ms'] = max((float(w.get('step time max (ms)', 0)) for w in windows), default=None)
    if len(receive_ns) > 1:
        wall = (receive_ns[-1] - receive_ns[0]) * 1e-9
        result['odom_wall_span_s'] = wall
        result['odom_max_receive_gap_ms'] = max(b - a for a, b in zip(receive_ns, receive_ns[1:])) / 1e6
    return result


def write_table(report: Report, result: dict) -> None:
    """The run's figures as one row of a table."""
    rate, share = result['achieved_rate_hz'], result['busy_loop_cpu_share']
    lost = ' / '.join(str(result['topics'][leaf]['lost']) for leaf in STEP_TOPICS)
    if 'wheel_torque_cmd_recorded' in result:
        lost += f" ({result['wheel_torque_cmd_recorded']} wheel_torque_cmd)"
    achieved = (f"{rate['mean']:.1f} Hz ({rate['min']:.1f} .. {rate['max']:.1f})" if rate['mean'] is not None
                else 'no full window')
    report.table(('run', 'busy loop got', 'achieved rate (mean of 1 s windows, min .. max)', 'steps > 2 ms late',
                  'max lateness', 'lost on ' + ' / '.join(STEP_TOPICS), 'run wall time'),
                 [(f"{result['scenario']} {result['duration_s']:g} s, controller "
                   f"{'on' if result['controller'] else 'off'}",
                   f'{100 * share:.0f} % of a core' if share is not None else 'no busy loop', achieved,
                   f"{result['late_steps']} of {result['expected_steps'] - 1}", f"{result['lateness_max_ms']} ms", lost,
                   f"{result['run_wall_s']:.1f} s")])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--duration', type=float, default=20.0)
    parser.add_argument('--scenario', default='circle')
    parser.add_argument('--no-controller', action='store_true', help='tracking run (trajectory task), no controller')
    parser.add_argument('--no-busy', action='store_true', help='no busy loop (baseline)')
    parser.add_argument('--out', help='keep the run here (default: a temporary directory, removed)')
    parser.add_argument('--json', action='store_true')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('-'.join(['load', *(['no-controller'] if args.no_controller else []),
                              *(['no-busy'] if args.no_busy else [])]))

    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix='bench_load_'))
    busy = None
    busy_loops = ChildProcesses(out / 'busy', os.environ)
    if not args.no_busy:
        busy = busy_loops.start([sys.executable, '-c', 'while True: pass'], 'busy')
    try:
        cmd = [sys.executable, '-m', 'wallbot_sim.cli.main', 'run', args.scenario, '--duration', str(args.duration),
               '--no-plots', '--out', str(out / 'run')] + ([] if args.no_controller else ['--controller'])
        began = time.monotonic()
        busy_cpu0 = cpu_seconds(busy.pid) if busy else 0.0
        run = subprocess.run(cmd, capture_output=True, text=True, timeout=args.duration * 10 + 120)
        wall = time.monotonic() - began
        busy_share = (cpu_seconds(busy.pid) - busy_cpu0) / wall if busy else None
    finally:
        busy_loops.stop_all()
    if run.returncode != 0:
        print(run.stdout[-3000:], run.stderr[-3000:], file=sys.stderr)
        return 1
    result = {'scenario': args.scenario, 'duration_s': args.duration, 'controller': not args.no_controller,
              'busy_loop_cpu_share': busy_share, 'run_wall_s': wall, 'cores': os.cpu_count(),
              **analyse(out / 'run' / 'bag', args.duration)}
    if not args.out:
        shutil.rmtree(out, ignore_errors=True)
    write_table(report, result)
    report.write(args.write_docs)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    rate = result['achieved_rate_hz']
    print(f"{args.scenario}, {args.duration:g} s, controller {'on' if result['controller'] else 'off'}, "
          f"busy loop {'%.0f %% of a core' % (100 * busy_share) if busy_share is not None else 'off'}, "
          f"{result['cores']} cores, run took {wall:.1f} s wall")
    if rate['mean'] is not None:
        print(f"achieved rate: mean {rate['mean']:.1f} Hz (windows {rate['min']:.1f} .. {rate['max']:.1f})")
    print(f"deadline misses: {result['late_steps']} steps > 2 ms late of {result['expected_steps'] - 1}; "
          f"max lateness {result['lateness_max_ms']} ms; max step time {result['step_time_max_ms']} ms")
    for leaf, t in result['topics'].items():
        print(f"  {leaf:18s} recorded {t['recorded']:6d}  lost {t['lost']:4d}  duplicates {t['duplicates']:3d}  "
              f"max stamp gap {t['max_stamp_gap_ms']} ms")
    if 'wheel_torque_cmd_recorded' in result:
        print(f"  wheel_torque_cmd   recorded {result['wheel_torque_cmd_recorded']}")
    print(f"odom receive gap max {result.get('odom_max_receive_gap_ms')} ms")
    return 0


if __name__ == '__main__':
    sys.exit(main())
