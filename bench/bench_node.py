"""Benchmark of the dynamics node (issue 3's performance targets; a measurement, not a test).

Starts the three nodes on a private ROS domain with all constraints on, rate_hz 1000 and
publishing every step, then reports
  * at real_time_factor 1, over --seconds (default 20) of wall time: the achieved step rate
    (from simulation time on /clock), the node's own max lateness and late-step count (from
    /diagnostics), and the CPU share of the dynamics process (from /proc);
  * at real_time_factor 0 (set through the SetParameters service), the factor reached.

    python bench/bench_node.py [--seconds 20] [--fast-seconds 10]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time

from wallbot_sim.domain import claim_domain_id


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process, in seconds."""
    with open(f'/proc/{pid}/stat') as stream:
        fields = stream.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=20.0)
    parser.add_argument('--fast-seconds', type=float, default=10.0)
    args = parser.parse_args()

    claim = claim_domain_id()
    os.environ.update(claim.env())
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.srv import SetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    procs = []

    def start(module: str, *params: str) -> subprocess.Popen:
        cmd = [sys.executable, '-m', f'wallbot_sim.nodes.{module}', '--ros-args']
        for param in params:
            cmd += ['-p', param]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        procs.append(proc)
        return proc

    rclpy.init()
    node = rclpy.create_node('bench_node')
    latest = {'clock': None}
    windows: list[dict[str, str]] = []
    node.create_subscription(Clock, '/clock', lambda m: latest.__setitem__('clock', m.clock.sec + m.clock.nanosec * 1e-9),
                             QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    node.create_subscription(DiagnosticArray, '/diagnostics',
                             lambda m: windows.append({kv.key: kv.value for kv in m.status[0].values}), 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinning = True

    def spin():
        while spinning:
            executor.spin_once(timeout_sec=0.05)
    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()

    def sample():
        time.sleep(0.05)
        return time.monotonic(), latest['clock']

    try:
        start('trajectory')
        dynamics = start('dynamics')
        start('constraint_config', 'belt:=true', 'non_lateral:=true', 'nonslip:=true')
        deadline = time.monotonic() + 30
        while (latest['clock'] or 0.0) < 2.0:
            if time.monotonic() > deadline:
                raise SystemExit('the graph did not start')
            time.sleep(0.1)

        # --- factor 1 ---
        windows.clear()
        cpu0, (wall0, sim0) = cpu_seconds(dynamics.pid), sample()
        time.sleep(args.seconds)
        cpu1, (wall1, sim1) = cpu_seconds(dynamics.pid), sample()
        wall = wall1 - wall0
        rate = (sim1 - sim0) * 1000.0 / wall
        full = windows[1:-1] or windows
        lateness = max(float(w['lateness max (ms)']) for w in full)
        late = sum(int(w['late steps (> 2 ms)']) for w in full)
        step_mean = sum(float(w['step time mean (ms)']) for w in full) / len(full)
        print(f'real_time_factor 1, all constraints, publishing every step, {wall:.1f} s wall:')
        print(f'  achieved step rate     {rate:8.1f} Hz   (target >= 999)')
        print(f'  max lateness           {lateness:8.3f} ms   ({late} steps later than 2 ms; target 0)')
        print(f'  step compute mean      {step_mean:8.3f} ms')
        print(f'  dynamics CPU share     {100 * (cpu1 - cpu0) / wall:8.1f} % of one core (target <= 50)')

        # --- factor 0 ---
        client = node.create_client(SetParameters, '/wallbot/dynamics/set_parameters')
        client.wait_for_service(timeout_sec=5)

        def set_param(name, value):
            future = client.call_async(SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()]))
            while not future.done():
                time.sleep(0.01)
            time.sleep(1.0)

        for publish_every in (1, 10):
            if publish_every == 1:
                set_param('real_time_factor', 0.0)
            else:
                set_param('publish_every', publish_every)
            cpu0, (wall0, sim0) = cpu_seconds(dynamics.pid), sample()
            time.sleep(args.fast_seconds)
            cpu1, (wall1, sim1) = cpu_seconds(dynamics.pid), sample()
            wall = wall1 - wall0
            print(f'real_time_factor 0, publish_every {publish_every}, {wall:.1f} s wall:')
            print(f'  factor reached         {(sim1 - sim0) / wall:8.2f}      (target >= 5)')
            print(f'  dynamics CPU share     {100 * (cpu1 - cpu0) / wall:8.1f} % of one core')
        print(f'machine: {os.cpu_count()} CPUs, Python {sys.version.split()[0]}')
    finally:
        spinning = False
        for proc in procs:
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
        spinner.join(timeout=1)
        node.destroy_node()
        rclpy.try_shutdown()
        claim.release()
    return 0


if __name__ == '__main__':
    sys.exit(main())
