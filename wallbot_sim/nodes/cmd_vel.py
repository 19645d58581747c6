"""cmd_vel_node (``/wallbot/cmd_vel_controller``): drive the robot with velocity commands.

Thin ROS shell around ``wallbot_sim.control.wheel_speed.WheelSpeedController`` (diff_drive_controller's
limits and timeout, then a wheel-speed PI loop per side; see that module):

* subscribes ``cmd_vel`` (geometry_msgs/TwistStamped, the Jazzy convention; geometry_msgs/Twist
  with ``use_stamped_vel`` false): linear.x (m/s) and angular.z (rad/s) in base_link, the other
  components ignored; a command that is not finite is refused (one log line) and never used;
* subscribes ``odom`` (the measured wheel speeds are the odometry twist's rolling speeds, and its
  stamps are the clock);
* publishes ``wheel_torque_cmd`` (std_msgs/Float64MultiArray ``[tau_L, tau_R]``, N m).

Time is simulation time from the odometry stamps, as the tracking controller keeps it: the loop
acts on the first ``odom`` at or after each multiple of 1 / ``rate_hz``, a command counts as
received at the newest odometry stamp (its header stamp is not used: teleop tools stamp with
their own clock), and ``cmd_vel_timeout`` runs in simulation time, so the node behaves the same
at any real-time factor. A stamp going back into the first control period (the dynamics'
``~/reset``) restarts the loop (command, limiter and integrals cleared); one going back less (a
resumed dynamics) carries on from the next instant.

It answers every control instant, with zero-command torques while no command is live, so a
dynamics in lockstep with it (``lockstep_every`` = 1000 / ``rate_hz``) steps only as fast as the loop
answers and a run does not depend on CPU load. With ``wait_for_recorder`` (``wallbot-sim run``
sets it when it records) the node subscribes odom, and so lets such a dynamics start, only once
a recorder hears ``wheel_torque_cmd``: the bag holds every command from t = 0.
"""

from __future__ import annotations

import sys

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.sampling import ControlInstants, Rewind
from wallbot_sim.control.wheel_speed import (GAIN, POSITIVE_LIMIT, SPEED_LOOP_RATE_HZ, AxisLimits,
                                             WheelSpeedController, WheelSpeedSettings)
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.nodes.common import (ROBOT_CLOCK_ARGS, WHEEL_TORQUE_LIMIT, HeldCommands, declare, param_dict,
                                     parameter_result, run, subscribe_odom_when_recorded)

THROTTLE = 1.0
"""Seconds between repeated log lines of one kind."""
GEOMETRY = NumberRange(1e-4, 10.0)
TIMEOUT = NumberRange(1e-3, 1e3)
RANGES = {
    'wheel_separation': GEOMETRY, 'wheel_radius': GEOMETRY, 'cmd_vel_timeout': TIMEOUT,
    'linear.x.max_velocity': POSITIVE_LIMIT, 'linear.x.max_acceleration': POSITIVE_LIMIT,
    'angular.z.max_velocity': POSITIVE_LIMIT, 'angular.z.max_acceleration': POSITIVE_LIMIT,
    'wheel_speed_kp': GAIN, 'wheel_speed_ki': GAIN, 'max_wheel_torque': WHEEL_TORQUE_LIMIT,
}


def check_values(values: dict) -> list[str]:
    """Reasons why a full set of the node's parameters is unusable (empty if fine)."""
    return [reason for name, allowed in RANGES.items() if (reason := allowed.reason(name, values[name]))]


def settings(values: dict) -> WheelSpeedSettings:
    return WheelSpeedSettings(
        float(values['wheel_separation']), float(values['wheel_radius']),
        AxisLimits(float(values['linear.x.max_velocity']), float(values['linear.x.max_acceleration'])),
        AxisLimits(float(values['angular.z.max_velocity']), float(values['angular.z.max_acceleration'])),
        float(values['cmd_vel_timeout']), float(values['wheel_speed_kp']), float(values['wheel_speed_ki']),
        float(values['max_wheel_torque']))


class CmdVelNode(Node):
    """cmd_vel + odom -> wheel_torque_cmd at rate_hz of simulation time."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_CMD_VEL, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)
        robot_file = declare(self, 'robot_file', '', 'robot parameter YAML giving the default wheel_separation and '
                             'wheel_radius; empty = installed config/robot.yaml', read_only=True)
        robot = load_robot_parameters(robot_file or None)
        defaults = WheelSpeedSettings(2.0 * robot.half_track, robot.wheel_radius, AxisLimits(0.5, 1.0),
                                      AxisLimits(2.0, 4.0))
        self.use_stamped = bool(declare(self, 'use_stamped_vel', True, 'cmd_vel is geometry_msgs/TwistStamped '
                                        '(false: geometry_msgs/Twist)', read_only=True))
        self.rate_hz = declare(self, 'rate_hz', SPEED_LOOP_RATE_HZ, 'control rate in simulation time (Hz)', low=1, high=1000,
                               read_only=True)
        described = {
            'wheel_separation': (defaults.wheel_separation, "distance between the left and right wheels (m; "
                                 "default: the robot file's 2 half_track)"),
            'wheel_radius': (defaults.wheel_radius, "wheel radius (m; default: the robot file's)"),
            'cmd_vel_timeout': (defaults.cmd_vel_timeout, 'seconds of simulation time after which the last cmd_vel '
                                'counts as zero'),
            'linear.x.max_velocity': (defaults.linear.max_velocity, 'largest |linear.x| (m/s)'),
            'linear.x.max_acceleration': (defaults.linear.max_acceleration, 'largest change of linear.x (m/s^2)'),
            'angular.z.max_velocity': (defaults.angular.max_velocity, 'largest |angular.z| (rad/s)'),
            'angular.z.max_acceleration': (defaults.angular.max_acceleration,
                                           'largest change of angular.z (rad/s^2)'),
            'wheel_speed_kp': (defaults.kp, 'proportional gain of the wheel-speed loop (N m per rad/s)'),
            'wheel_speed_ki': (defaults.ki, 'integral gain of the wheel-speed loop (N m per rad)'),
            'max_wheel_torque': (defaults.max_wheel_torque, "side torque limit (N m; the dynamics' limit)"),
        }
        self.values = {name: declare(self, name, float(default), description, allowed=RANGES[name])
                       for name, (default, description) in described.items()}
        reasons = check_values(self.values)
        if reasons:
            raise ValueError('; '.join(reasons))
        self.controller = WheelSpeedController(settings(self.values))
        self.instants = ControlInstants(int(self.rate_hz))
        self.now_ns: int | None = None
        """The newest odometry stamp: simulation time as this node knows it."""
        self.early: tuple[float, float] | None = None
        """The newest cmd_vel that came before any odometry."""

        publisher = self.create_publisher(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name,
                                          qos_profile(topics.WHEEL_TORQUE_CMD))
        self.commands = HeldCommands(self, publisher, topics.ODOM.name)
        self.create_subscription(TwistStamped if self.use_stamped else Twist, topics.CMD_VEL.name, self._on_cmd_vel,
                                 qos_profile(topics.CMD_VEL), raw=True)
        subscribe_odom_when_recorded(self, publisher, self._subscribe_odom)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.get_logger().info(
            f'cmd_vel ({"TwistStamped" if self.use_stamped else "Twist"}) -> wheel_torque_cmd at {self.rate_hz} Hz '
            'of simulation time; ' + ', '.join(f'{name} {value:g}' for name, value in self.values.items()))

    def _subscribe_odom(self) -> None:
        # raw: of the 1 kHz odometry only the states acted on are decoded
        self.create_subscription(Odometry, topics.ODOM.name, self._on_odom, qos_profile(topics.ODOM), raw=True)

    def _on_cmd_vel(self, data: bytes) -> None:
        self._command(*codec.decode_cmd_vel(data, self.use_stamped))

    def _command(self, linear: float, angular: float) -> None:
        if self.now_ns is None:  # before the first odometry: received when simulation time is known
            self.early = (linear, angular)
            return
        try:
            self.controller.command(linear, angular, self.now_ns * 1e-9)
        except ValueError as error:
            self.get_logger().warning(f'rejected cmd_vel: {error}', throttle_duration_sec=THROTTLE)

    def _on_odom(self, data: bytes) -> None:
        stamp_ns = codec.leading_stamp_ns(data)
        if stamp_ns is None:
            self.get_logger().error('ignoring a malformed odom message', throttle_duration_sec=THROTTLE)
            return
        rewind = self.instants.observe(stamp_ns)
        self.now_ns = stamp_ns
        if self.early is not None:
            early, self.early = self.early, None
            self._command(*early)
        if rewind is Rewind.RESTART:
            self.controller.reset()
            self.get_logger().info(f'simulation time went back to {stamp_ns * 1e-9:.3f} s: velocity loop restarted')
        if not self.instants.due(stamp_ns):
            return
        self.instants.acted(stamp_ns)
        try:
            odom = codec.decode_odometry(data)
        except ValueError as error:
            self.get_logger().error(f'ignoring odom: {error}', throttle_duration_sec=THROTTLE)
            return
        forward, yaw_rate = odom.forward, odom.turn
        s = self.controller.settings
        half = 0.5 * s.wheel_separation
        measured = ((forward - half * yaw_rate) / s.wheel_radius, (forward + half * yaw_rate) / s.wheel_radius)
        was_timed_out = self.controller.timed_out
        out = self.controller.update(stamp_ns * 1e-9, *measured)
        if self.controller.timed_out and not was_timed_out:
            self.get_logger().info(f'no cmd_vel for {s.cmd_vel_timeout:g} s of simulation time: stopping')
        if out.saturated:
            self.get_logger().warning(f'side torques clamped to +-{s.max_wheel_torque:g} N m',
                                      throttle_duration_sec=THROTTLE)
        if not self.commands.send(codec.wheel_torque_cmd(out.tau_left, out.tau_right)):
            self.get_logger().info('holding the command until the dynamics hears wheel_torque_cmd',
                                   throttle_duration_sec=THROTTLE)

    def _on_set(self, parameters):
        return parameter_result(check_values({**self.values, **param_dict(parameters, self.values)}))

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, self.values)
        if changes:
            self.values.update(changes)
            self.controller.configure(settings(self.values))
            self.get_logger().info('parameters: ' + ', '.join(f'{k} = {v}' for k, v in changes.items()))


def main(args: list[str] | None = None) -> None:
    sys.exit(run(CmdVelNode, args, events=True))


if __name__ == '__main__':
    main()
