"""``example_controller``: the figure-8 law (``law``) as a ROS 2 node, the way a controller on the robot runs.

It answers each odometry message on ``control_odom`` (the states at its control instants, 25 Hz) with one
``wheel_torque_cmd`` ([left, right] N m), clamped to ``max_torque``; its namespace comes from WALLBOT_NAMESPACE
(default /wallbot), which ``wallbot-sim test`` sets. A command is sent once every subscriber of its topic is matched:
one sent before the simulator hears it would be lost.
"""

from __future__ import annotations

import math
import os
import sys

import rclpy
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray

from wallbot_example_controller.law import FigureEightLaw, Gains, Robot

RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'
"""The node name rmw gives an endpoint whose node it has not yet discovered."""


class ExampleController(Node):
    def __init__(self) -> None:
        super().__init__('example_controller', namespace=os.environ.get('WALLBOT_NAMESPACE', '/wallbot'))
        gains = Gains(*(self.declare_parameter(name, getattr(Gains(), name)).value
                        for name in ('look_ahead', 'point_gain', 'speed_gain', 'integral_gain')))
        self.max_torque = self.declare_parameter('max_torque', 5.0).value
        self.law = FigureEightLaw(Robot(), gains, self.declare_parameter('amplitude', 1.0).value,
                                  self.declare_parameter('period', 30.0).value)
        self.publisher = self.create_publisher(Float64MultiArray, 'wheel_torque_cmd', RELIABLE)
        self.subscription = self.create_subscription(Odometry, 'control_odom', self.on_odom, RELIABLE)
        self.unsent: list[Float64MultiArray] = []
        self.answered: tuple[int, int] | None = None
        self.create_timer(0.02, self.send)

    def on_odom(self, odom: Odometry) -> None:
        stamp, pose, twist = odom.header.stamp, odom.pose.pose, odom.twist.twist
        # the simulator sends a state again when no answer came within seconds (the first one can miss a reader
        # matched late): a state already answered is not answered twice, or the answers would run one behind
        if (stamp.sec, stamp.nanosec) == self.answered:
            return
        self.answered = (stamp.sec, stamp.nanosec)
        heading = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
        left, right = self.law.torques(stamp.sec + 1e-9 * stamp.nanosec, pose.position.x, pose.position.y, heading,
                                       twist.linear.x, twist.angular.z)
        command = Float64MultiArray()
        command.data = [max(-self.max_torque, min(self.max_torque, value)) for value in (left, right)]
        self.unsent.append(command)
        self.send()

    def send(self) -> None:
        if self.unsent and self.simulator_listens():
            for command in self.unsent:
                self.publisher.publish(command)
            self.unsent = []

    def simulator_listens(self) -> bool:
        """Whether the node sending control_odom (the simulator) subscribes wheel_torque_cmd and every subscription
        of it the graph shows is matched: a command published sooner can miss the simulator's reader (the
        recorder's matched first), and the state it answered, sent again, gets no second answer."""
        writers = self.get_publishers_info_by_topic(self.subscription.topic_name)
        readers = self.get_subscriptions_info_by_topic(self.publisher.topic_name)
        senders = {(i.node_namespace, i.node_name) for i in writers}
        listeners = {(i.node_namespace, i.node_name) for i in readers}
        identified = all(name != UNKNOWN_NODE for _, name in senders | listeners)
        return (bool(senders) and identified and senders <= listeners
                and self.publisher.get_subscription_count() >= len(readers))


def main() -> None:
    rclpy.init()
    node = ExampleController()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
