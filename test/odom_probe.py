"""Prints the first odometry a running graph publishes, as another terminal's tool would see it.

Run as a script in the environment under test (e.g. after ``wallbot-sim run``'s printed
``export``); it prints ``domain N`` (its ROS_DOMAIN_ID), then ``odom T`` (the stamp, s) of the
first ``/wallbot/odom`` message it receives, and exits 0.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rclpy  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from message_fields import seconds  # noqa: E402
from wallbot_msgs_py import topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402


def spin_until(node, received: list) -> None:
    """Spin ``node`` until ``received`` holds something, then leave ROS."""
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not received:
            executor.spin_once(timeout_sec=0.1)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def main() -> int:
    print(f'domain {os.environ.get("ROS_DOMAIN_ID", "unset")}', flush=True)
    received: list[Odometry] = []
    rclpy.init()
    node = rclpy.create_node('odom_probe')
    node.create_subscription(Odometry, topics.ODOM.resolve(), received.append, qos_profile(topics.ODOM))
    spin_until(node, received)
    print(f'odom {seconds(received[0].header.stamp):.3f}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
