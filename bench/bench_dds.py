"""What one 1 kHz message costs in rclpy + Fast DDS, beside one model step (a measurement, not a test).

The recorded graph carries five messages per 1 ms step (odom, wheel_states, constraint_wrench,
drive_forces, wheel_contact), each published by the dynamics node and taken by the recorder. This
bench measures, on a private ROS domain:
  * the publishing side: CPU time per ``Publisher.publish`` of an Odometry's CDR bytes (as the
    dynamics publishes them) with the recorder's QoS matched (RELIABLE, KEEP_ALL);
  * the receiving side: CPU time per message of a recorder-like process (EventsExecutor, raw
    subscription, a callback that only counts);
  * one model step with its outputs (circle, all constraints), and the two-pinv model's step.
It prints the floor those costs put under the graph: five messages per step, published and
taken once each, plus the step, in CPU seconds per simulated second and as a ratio to the
two-pinv model.

    python bench/bench_dds.py [--messages 20000] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import time

from bench_core import StraightforwardSimulation
from report import Report, add_write_docs_option
from wallbot_msgs_py import codec, topics
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.domain import claim_domain_id
from wallbot_sim.model import ConstraintSelection, Robot
from wallbot_sim.model.simulation import Simulation

MESSAGES_PER_STEP = 5
"""The per-step topics the recorder takes at 1 kHz."""
MATCH_TIMEOUT = 30.0
IDLE_END = 2.0
"""Seconds without a message after which the taker stops counting."""


def cpu_now() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def subscriber(count: int) -> None:
    """Take ``count`` odom messages with a raw recorder-style subscription; print CPU s spent taking them."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.experimental import EventsExecutor

    from wallbot_sim.nodes.recorder import subscription_qos

    rclpy.init()
    node = rclpy.create_node('bench_taker', namespace=topics.NAMESPACE)
    received = [0, 0.0]

    def on_message(_data: bytes) -> None:
        if received[0] == 0:
            received[1] = cpu_now()
        received[0] += 1

    node.create_subscription(Odometry, topics.ODOM.name, on_message, subscription_qos(topics.ODOM), raw=True)
    executor = EventsExecutor()
    executor.add_node(node)
    print('ready', flush=True)
    while received[0] < count:
        before = received[0]
        executor.spin_once(timeout_sec=IDLE_END)
        if before and received[0] == before:
            break  # the publisher is done (messages it overwrote before they were sent never come)
    print(f'{received[0]} {(cpu_now() - received[1]) / max(1, received[0] - 1):.9f}', flush=True)
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


def publish_cost(count: int, env: dict[str, str]) -> tuple[float, float]:
    """(CPU s per publish, CPU s per message taken by the subscriber process)."""
    import rclpy
    from nav_msgs.msg import Odometry

    from wallbot_msgs_py.qos import qos_profile

    taker = subprocess.Popen([sys.executable, __file__, '--subscriber', str(count)], env=env, text=True,
                             stdout=subprocess.PIPE)
    assert taker.stdout is not None
    taker.stdout.readline()  # ready
    rclpy.init()
    node = rclpy.create_node('bench_publisher', namespace=topics.NAMESPACE)
    publisher = node.create_publisher(Odometry, topics.ODOM.name, qos_profile(topics.ODOM))
    deadline = time.monotonic() + MATCH_TIMEOUT
    while publisher.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            raise SystemExit('the subscriber process never matched')
        time.sleep(0.01)
    encoder = codec.OdometryEncoder()
    messages = [encoder.encode(0, k * 1_000_000, (0.1 * k, 0.2, 0.3), (0.4, 0.5, 0.6)) for k in range(count)]
    started, next_step = cpu_now(), time.monotonic()
    for first in range(0, count, MESSAGES_PER_STEP):  # as the graph does: five per 1 ms step
        for data in messages[first:first + MESSAGES_PER_STEP]:
            publisher.publish(data)
        next_step += 1e-3
        pause = next_step - time.monotonic()
        if pause > 0:
            time.sleep(pause)
    per_publish = (cpu_now() - started - sleep_cpu_estimate(count)) / count
    out, _ = taker.communicate(timeout=120)
    node.destroy_node()
    rclpy.shutdown()
    taken, per_take = out.strip().splitlines()[-1].split()
    print(f'taker received {taken} of {count}', file=sys.stderr)
    return per_publish, float(per_take)


def sleep_cpu_estimate(count: int) -> float:
    """CPU time of the pacing loop alone (sleeps and clock reads, no publish) for ``count`` messages."""
    started, next_step = cpu_now(), time.monotonic()
    for _ in range(0, count, MESSAGES_PER_STEP):
        next_step += 1e-3
        pause = next_step - time.monotonic()
        if pause > 0:
            time.sleep(pause)
    return cpu_now() - started


def step_cost(simulation, steps: int, with_outputs: bool) -> float:
    started = time.process_time()
    for _ in range(steps):
        if with_outputs:
            simulation.outputs()
        simulation.step()
    return (time.process_time() - started) / steps


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--messages', type=int, default=20_000, help='messages published and taken')
    parser.add_argument('--subscriber', type=int, default=None, help=argparse.SUPPRESS)
    add_write_docs_option(parser)
    args = parser.parse_args()
    if args.subscriber is not None:
        subscriber(args.subscriber)
        return 0
    report = Report('dds')
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip')
    state = scenario.initial_state(robot)
    with claim_domain_id() as claim:
        env = claim.env(os.environ)
        os.environ.update(env)
        publish, take = publish_cost(args.messages, env)
    step = step_cost(Simulation(robot, scenario.reference, selection, *state), 2000, with_outputs=True)
    plain = step_cost(StraightforwardSimulation(robot, scenario.reference, selection, *state), 2000,
                      with_outputs=False)
    floor = step + MESSAGES_PER_STEP * (publish + take)
    print(f'# {platform.machine()}, Python {platform.python_version()}, load average '
          f'{" ".join(f"{v:.2f}" for v in os.getloadavg())}; {args.messages} Odometry messages, RELIABLE KEEP_ALL')
    print(f'publish (dynamics side)          {publish * 1e6:7.1f} us CPU per message')
    print(f'take (recorder side, raw)        {take * 1e6:7.1f} us CPU per message')
    print(f'model step with outputs          {step * 1e6:7.1f} us CPU')
    print(f'two-pinv model step              {plain * 1e6:7.1f} us CPU')
    print(f'floor of the graph: step + {MESSAGES_PER_STEP} x (publish + take) = {floor * 1e6:.1f} us per 1 ms step '
          f'= {floor * 1e3:.3f} CPU s per simulated s, {floor / plain:.2f}x the two-pinv model '
          f'(messages alone {MESSAGES_PER_STEP * (publish + take) / plain:.2f}x)')
    report.table(('publish (dynamics side)', 'take (recorder side, raw)', 'model step with outputs',
                  'two-pinv model step', f'step + {MESSAGES_PER_STEP} x (publish + take), ratio to the two-pinv step',
                  f'{MESSAGES_PER_STEP} x (publish + take) alone, ratio'),
                 [(f'{publish * 1e6:.1f} us', f'{take * 1e6:.1f} us', f'{step * 1e6:.0f} us', f'{plain * 1e6:.0f} us',
                   f'**{floor / plain:.2f}**', f'**{MESSAGES_PER_STEP * (publish + take) / plain:.2f}**')],
                 f'CPU per message or step, {args.messages:,} Odometry messages, RELIABLE KEEP_ALL:')
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
