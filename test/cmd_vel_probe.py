"""Drives a running graph with cmd_vel from another terminal, as teleop_twist_keyboard would.

Run as a script in the environment under test (e.g. after ``wallbot-sim run``'s printed
``export``): ``cmd_vel_probe.py LINEAR ANGULAR SECONDS [NAME:=VALUE ...]`` sets the parameters on
``/wallbot/cmd_vel_controller`` (like ``ros2 param set``), then publishes the TwistStamped every
20 ms until odometry shows SECONDS of simulation time since the first command, prints
``drove T0 T1`` (simulation seconds) and exits 0.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rclpy  # noqa: E402
from geometry_msgs.msg import TwistStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

import message_fields  # noqa: E402
from wallbot_msgs_py import topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402


REPLY_WAIT = 2.0
"""Wall seconds to wait for the parameter service's reply before sending the request again."""


def main(argv: list[str]) -> int:
    linear, angular, seconds = (float(a) for a in argv[:3])
    settings = dict(a.split(':=', 1) for a in argv[3:])
    rclpy.init()
    node = rclpy.create_node('cmd_vel_probe')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stamps: list[float] = []
    node.create_subscription(Odometry, topics.ODOM.resolve(), lambda msg: stamps.append(
        message_fields.seconds(msg.header.stamp)), qos_profile(topics.ODOM))
    try:
        if settings:
            client = node.create_client(SetParameters, f'{topics.NAMESPACE}/{topics.NODE_CMD_VEL}/set_parameters')
            while not client.wait_for_service(timeout_sec=0.1):
                executor.spin_once(timeout_sec=0.05)
            request = SetParameters.Request(parameters=[Parameter(k, value=float(v)).to_parameter_msg()
                                                        for k, v in settings.items()])
            future = client.call_async(request)
            # a service is "available" once its request reader matches; its reply is lost while the server has
            # not yet matched this client's reply reader (seen under load: no answer ever), so a request without
            # an answer is sent again (setting the same values twice changes nothing)
            executor.spin_until_future_complete(future, timeout_sec=REPLY_WAIT)
            while not future.done():
                client.remove_pending_request(future)
                future = client.call_async(request)
                executor.spin_until_future_complete(future, timeout_sec=REPLY_WAIT)
            if not all(result.successful for result in future.result().results):
                print(f'refused: {future.result().results}', flush=True)
                return 1
        publisher = node.create_publisher(TwistStamped, topics.CMD_VEL.resolve(), qos_profile(topics.CMD_VEL))
        while publisher.get_subscription_count() == 0 or not stamps:
            executor.spin_once(timeout_sec=0.05)
        message = TwistStamped()
        message.twist.linear.x, message.twist.angular.z = linear, angular
        publisher.publish(message)
        first, sent = stamps[-1], time.monotonic()
        while stamps[-1] < first + seconds:
            executor.spin_once(timeout_sec=0.02)
            if time.monotonic() - sent >= 0.02:
                publisher.publish(message)
                sent = time.monotonic()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    print(f'drove {first:.3f} {stamps[-1]:.3f}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
