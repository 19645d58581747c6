"""Benchmark of the dynamics node (issue 3's performance targets; a measurement, not a test).

Starts the three nodes on a private ROS domain with all constraints on, rate_hz 1000 and
publishing every step, then reports
  * at real_time_factor 1, over --seconds (default 20) of wall time, first with the node's
    realtime_priority 50 and then with 0 (the default, normal scheduling): the achieved step rate,
    the node's own max lateness and late-step count, and the CPU share of each node (/proc);
  * at real_time_factor 0 (set through the SetParameters service), the factor reached.
Simulation time is read from the 1 Hz /diagnostics, not from /clock: a 1 kHz subscriber in
this process would take CPU from the graph it measures.

    python bench/bench_node.py [--seconds 20] [--fast-seconds 10] [--engine python|numba] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from report import Report, add_write_docs_option
from wallbot_msgs_py import codec
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.graph import ChildProcesses, cpu_seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=20.0)
    parser.add_argument('--fast-seconds', type=float, default=10.0)
    parser.add_argument('--engine', choices=('python', 'numba'), default='python',
                        help="the dynamics' engine parameter (default python, the model)")
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('node' if args.engine == 'python' else f'node-{args.engine}')
    rows: list[tuple[str, str, str]] = []

    claim = claim_domain_id()
    os.environ.update(claim.env())
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.srv import SetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    nodes = ChildProcesses(Path(tempfile.mkdtemp(prefix='wallbot_bench_node_')), os.environ, stop_timeout=5.0)

    def start(module: str, *params: str) -> subprocess.Popen:
        cmd = [sys.executable, '-m', f'wallbot_sim.nodes.{module}', '--ros-args']
        for param in params:
            cmd += ['-p', param]
        return nodes.start(cmd, module)

    rclpy.init()
    node = rclpy.create_node('bench_node')
    windows: list[dict[str, str]] = []

    def on_diagnostics(data: bytes) -> None:
        values = codec.decode_diagnostics(data).statuses[0].value_map()
        values['wall'] = time.monotonic()
        windows.append(values)
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10, raw=True)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinning = True

    def spin():
        while spinning:
            executor.spin_once(timeout_sec=0.05)
    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()

    def measure(seconds: float, pids: dict[str, int]) -> tuple[float, list[dict[str, str]], dict[str, float]]:
        """Real-time factor (simulation over wall time, between the first and the last 1 Hz
        /diagnostics of the interval), those diagnostics, and each process's CPU share."""
        windows.clear()
        cpu0 = {name: cpu_seconds(pid) for name, pid in pids.items()}
        time.sleep(seconds)
        cpu1 = {name: cpu_seconds(pid) for name, pid in pids.items()}
        full = windows[1:]  # the first window began before the interval
        first, last = full[0], full[-1]
        factor = (float(last['simulation time']) - float(first['simulation time'])) / (last['wall'] - first['wall'])
        return factor, full, {name: 100 * (cpu1[name] - cpu0[name]) / seconds for name in pids}

    try:
        pids = {'dynamics': start('dynamics', f'engine:={args.engine}').pid, 'trajectory': start('trajectory').pid,
                'constraint_config': start('constraint_config', 'belt:=true', 'non_lateral:=true',
                                           'nonslip:=true').pid}
        deadline = time.monotonic() + 30
        while not windows or float(windows[-1]['simulation time']) < 2.0:
            if time.monotonic() > deadline:
                raise SystemExit('the graph did not start')
            time.sleep(0.1)

        client = node.create_client(SetParameters, '/wallbot/dynamics/set_parameters')
        client.wait_for_service(timeout_sec=5)

        def set_param(name, value):
            future = client.call_async(SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
            while not future.done():
                time.sleep(0.01)
            if not future.result().results[0].successful:
                raise SystemExit(f'{name} := {value!r} refused: {future.result().results[0].reason}')
            time.sleep(1.0)

        # --- factor 1, with a real-time priority for the loop thread, then without (the default) ---
        for priority in (50, 0):
            set_param('realtime_priority', priority)
            factor, full, cpu = measure(args.seconds, pids)
            lateness = max(float(w['lateness max (ms)']) for w in full)
            late = sum(int(w['late steps (> 2 ms)']) for w in full)
            step_mean = sum(float(w['step time mean (ms)']) for w in full) / len(full)
            label = f'realtime_priority {priority}'
            print(f'real_time_factor 1, all constraints, publishing every step, {label}, {args.seconds:g} s:')
            print(f'  loop thread priority   {full[-1]["loop priority"]:>8s}')
            print(f'  achieved step rate     {1000.0 * factor:8.1f} Hz   (target >= 999)')
            print(f'  max lateness           {lateness:8.3f} ms   ({late} steps later than 2 ms; target 0)')
            print(f'  step compute mean      {step_mean:8.3f} ms')
            print('  CPU share (one core)   ' + ', '.join(f'{name} {share:.1f} %' for name, share in cpu.items())
                  + '  (target dynamics <= 50)')
            rows += [(f'factor 1, {label}: achieved step rate', f'{1000.0 * factor:.1f} Hz', '>= 999 Hz'),
                     (f'factor 1, {label}: max lateness (steps later than 2 ms)', f'{lateness:.2f} ms ({late})',
                      '0 steps'),
                     (f'factor 1, {label}: CPU share',
                      ', '.join(f'{name} {share:.1f} %' for name, share in cpu.items()), 'dynamics <= 50 %')]

        # --- factor 0 ---
        for publish_every in (1, 10):
            if publish_every == 1:
                set_param('real_time_factor', 0.0)
            else:
                set_param('publish_every', publish_every)
            factor, _full, cpu = measure(args.fast_seconds, pids)
            print(f'real_time_factor 0, publish_every {publish_every}, {args.fast_seconds:g} s:')
            print(f'  factor reached         {factor:8.2f}      (target >= 5)')
            rows.append((f'factor 0, publish_every {publish_every}: factor reached', f'{factor:.2f}', '>= 5'))
            print('  CPU share (one core)   ' + ', '.join(f'{name} {share:.1f} %' for name, share in cpu.items()))
        print(f'machine: {os.cpu_count()} CPUs, Python {sys.version.split()[0]}; node logs in {nodes.log_dir}')
        report.table(('measure', 'figure', 'target'), rows,
                     f'dynamics (engine {args.engine}), trajectory and constraint_config, all constraints, rate_hz 1000, '
                     f'publishing every step; {args.seconds:g} s at factor 1 for each priority:')
        report.write(args.write_docs)
    finally:
        spinning = False
        nodes.stop_all()
        spinner.join(timeout=1)
        node.destroy_node()
        rclpy.try_shutdown()
        claim.release()
    return 0


if __name__ == '__main__':
    sys.exit(main())
