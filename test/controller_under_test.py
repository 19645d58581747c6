"""A small outside controller for the tests of ``wallbot-sim test``, written as a user writes one: plain rclpy and the
standard messages, its namespace and drive from the environment the test gives it (WALLBOT_NAMESPACE, WALLBOT_DRIVE).

    controller_under_test.py answer A B [--mute-after T]   # answer each state: wheel_torque_cmd [A, B] N m, cmd_vel
                                                         # A m/s and B rad/s (stamped with the state's stamp), or
                                                         # joint_commands A N m on each left and B on each right wheel;
                                                         # from simulation time T on, answer nothing more
    controller_under_test.py silent                      # a node that subscribes and publishes nothing
    controller_under_test.py exit N                      # exits at once with status N
"""

from __future__ import annotations

import os
import sys

WHEELS = ('wheel_left_front', 'wheel_left_rear', 'wheel_right_front', 'wheel_right_rear')


def main(argv: list[str]) -> int:
    if argv[0] == 'exit':
        print(f'exiting with status {argv[1]} before doing anything', flush=True)
        return int(argv[1])
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    rclpy.init()
    node = rclpy.create_node('controller_under_test', namespace=os.environ['WALLBOT_NAMESPACE'])
    if argv[0] == 'answer':
        Answering(node, float(argv[1]), float(argv[2]), float(argv[4]) if argv[3:4] == ['--mute-after'] else None,
                  os.environ['WALLBOT_DRIVE'])
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    return 0


class Answering:
    """Answers each state it gets with one command, once its publisher is matched to every subscriber discovered (a
    command sent before the simulator hears it would be lost). Discovery can still lag: a subscriber not yet
    discovered misses the answer, and the simulator, with no answer, sends the state again; that state is answered
    again, unless its answer is still held."""

    def __init__(self, node, a: float, b: float, mute_after: float | None, drive: str) -> None:
        from geometry_msgs.msg import TwistStamped
        from nav_msgs.msg import Odometry
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        self.node, self.a, self.b, self.mute_after, self.drive = node, a, b, mute_after, drive
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        kind, topic, sensor, state = {'wheel_torque_cmd': (Float64MultiArray, 'wheel_torque_cmd', 'control_odom',
                                                            Odometry),
                                      'cmd_vel': (TwistStamped, 'cmd_vel', 'control_odom', Odometry),
                                      'joint_commands': (JointState, 'joint_commands', 'joint_states', JointState)}[drive]
        self.kind = kind
        self.publisher = node.create_publisher(kind, topic, reliable)
        node.create_subscription(state, sensor, self.on_state, reliable)
        self.held = []
        self.answered: tuple[int, int] | None = None
        node.create_timer(0.02, self.flush)

    def on_state(self, message) -> None:
        stamp = message.header.stamp
        if self.mute_after is not None and stamp.sec + 1e-9 * stamp.nanosec >= self.mute_after - 1e-9:
            return
        if (stamp.sec, stamp.nanosec) == self.answered and self.held:  # sent again while its answer is held
            return
        self.answered = (stamp.sec, stamp.nanosec)
        command = self.kind()
        if self.drive == 'wheel_torque_cmd':
            command.data = [self.a, self.b]
        elif self.drive == 'cmd_vel':
            command.header.stamp = stamp
            command.twist.linear.x, command.twist.angular.z = self.a, self.b
        else:
            command.header.stamp = stamp
            command.name = list(WHEELS)
            command.effort = [self.a, self.a, self.b, self.b]
        self.held.append(command)
        self.flush()

    def flush(self) -> None:
        matched = self.publisher.get_subscription_count()
        if matched and matched >= self.node.count_subscribers(self.publisher.topic_name):
            for command in self.held:
                self.publisher.publish(command)
            self.held = []


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
