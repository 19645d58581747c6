"""CPU of ``cmd_vel_node`` alone, idle and answering control instants (issue 14; a measurement, not a test).

Starts the node as ``wallbot-sim run rest --drive cmd_vel`` describes it (``use_sim_time``, ``odom`` remapped
to ``control_odom``; no recorder) on a private ROS domain, and plays the dynamics from this process: for --seconds it
only watches the node idle, then for --seconds it publishes ``control_odom`` at the node's 50 Hz of wall
time (stamps 20 ms apart, the robot at rest: factor 1) and ``/clock`` at 10 Hz, and counts the node's
``wheel_torque_cmd`` answers. Printed: the node's CPU (utime + stime from /proc, all its threads) per
wall second idle and fed, and per control instant. Beside them, the two-pinv model's CPU per simulated
second in this process (bench_graph's baseline): the node's CPU per simulated second over it is the
machine-independent form of the "under 3 % of a core" target.

    python bench/bench_cmd_vel.py [--seconds 10] [--warmup 3] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

import rclpy
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from bench_graph import model_cpu_per_simulated_second
from report import Report, add_write_docs_option
from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.control.wheel_speed import SPEED_LOOP_RATE_HZ
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.graph import ChildProcesses, cpu_seconds
from wallbot_sim.graph_description import DRIVES, describe_driven_graph

CLOCK_RATE_HZ = 10
ANSWERS_TAKEN = 3
"""rclpy.spin_once calls between two instants: each takes one message (an answer, or nothing)."""


class Dynamics:
    """What the node sees of a dynamics in lockstep with it: control_odom at its instants, /clock, and a
    subscription to its commands."""

    def __init__(self) -> None:
        self.node = rclpy.create_node('bench_dynamics', namespace=topics.NAMESPACE)
        self.odom = self.node.create_publisher(Odometry, topics.CONTROL_ODOM.name, qos_profile(topics.CONTROL_ODOM))
        self.clock = self.node.create_publisher(Clock, '/clock', 10)
        self.answers = 0
        self.node.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, self._on_answer,
                                      qos_profile(topics.WHEEL_TORQUE_CMD), raw=True)

    def _on_answer(self, _data: bytes) -> None:
        self.answers += 1

    def wait_until_heard(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while self.odom.get_subscription_count() == 0 or self.node.count_publishers(topics.WHEEL_TORQUE_CMD.name) == 0:
            if time.monotonic() > deadline:
                raise SystemExit('cmd_vel_node did not come up')
            rclpy.spin_once(self.node, timeout_sec=0.05)

    def feed(self, seconds: float) -> int:
        """Publish control instants at the node's rate of wall time for ``seconds``; how many it answered."""
        period = 1.0 / SPEED_LOOP_RATE_HZ
        odom, clock = codec.OdometryEncoder(), codec.ClockEncoder()
        started, answers = time.perf_counter(), self.answers
        instant = 0
        while time.perf_counter() - started < seconds:
            instant += 1
            stamp = divmod(instant * round(period * 1e9), 10**9)
            self.odom.publish(odom.encode(*stamp, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
            if instant % round(SPEED_LOOP_RATE_HZ / CLOCK_RATE_HZ) == 0:
                self.clock.publish(clock.encode(*stamp))
            time.sleep(max(0.0, started + instant * period - time.perf_counter()))
            for _ in range(ANSWERS_TAKEN):
                rclpy.spin_once(self.node, timeout_sec=0.0)
        return self.answers - answers


def cpu_per_second(pid: int, seconds: float, during: Callable[[float], object] = time.sleep) -> float:
    """CPU seconds per wall second process ``pid`` takes over ``seconds`` while ``during(seconds)`` runs."""
    cpu, wall = cpu_seconds(pid), time.perf_counter()
    during(seconds)
    return (cpu_seconds(pid) - cpu) / (time.perf_counter() - wall)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=10.0, help='wall seconds idle, then fed (default 10 each)')
    parser.add_argument('--warmup', type=float, default=3.0, help='wall seconds fed before measuring (default 3)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('cmd-vel')

    model = model_cpu_per_simulated_second(2.0)
    _name, module = DRIVES['cmd_vel']
    spec = next(spec for spec in describe_driven_graph('cmd_vel') if spec.module == module)
    with claim_domain_id() as claim:
        os.environ.update(claim.env())
        nodes = ChildProcesses(Path(tempfile.mkdtemp(prefix='wallbot_bench_cmd_vel_')), os.environ)
        node = nodes.start(spec.command(), spec.name)
        rclpy.init()
        try:
            dynamics = Dynamics()
            dynamics.wait_until_heard(30.0)
            idle = cpu_per_second(node.pid, args.seconds)
            dynamics.feed(args.warmup)
            answered = []
            fed = cpu_per_second(node.pid, args.seconds, lambda seconds: answered.append(dynamics.feed(seconds)))
        finally:
            nodes.stop(node)
            rclpy.try_shutdown()
    instants = SPEED_LOOP_RATE_HZ * args.seconds
    print(f'two-pinv model alone: {model:.3f} CPU s per simulated s')
    print(f'cmd_vel_node idle: {100 * idle:.2f} % of a core')
    print(f'cmd_vel_node at {SPEED_LOOP_RATE_HZ} Hz (factor 1): {100 * fed:.2f} % of a core, '
          f'{1e3 * fed / SPEED_LOOP_RATE_HZ:.3f} ms a control instant ({answered[0]} of {instants:.0f} answered); '
          f'ratio to the two-pinv model {fed / model:.4f}   (target under 3 % of a core)')
    print(f'machine: {os.cpu_count()} CPUs, load average at the end {" ".join(f"{x:.2f}" for x in os.getloadavg())}')
    report.table(('two-pinv model, CPU s per simulated s', 'cmd_vel_node idle, share of a core',
                  f'fed at {SPEED_LOOP_RATE_HZ} Hz, share of a core', 'CPU a control instant', 'answered',
                  'ratio to the two-pinv model (target: under 3 % of a core)'),
                 [(f'{model:.3f}', f'{100 * idle:.2f} %', f'{100 * fed:.2f} %',
                   f'{1e3 * fed / SPEED_LOOP_RATE_HZ:.3f} ms', f'{answered[0]} of {instants:.0f}',
                   f'**{fed / model:.4f}**')])
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
