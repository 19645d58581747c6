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

With ``answer_commands`` (``wallbot-sim test`` sets it: a controller under test publishes cmd_vel) the
commander is in the lockstep too: it answers each control_odom state with a TwistStamped stamped with
that state's stamp, and the node answers that instant only once that cmd_vel came, taking it as the
command at that instant. It subscribes odom, and so lets the dynamics start, only once every cmd_vel
publisher subscribes control_odom, so the commander hears the first state.
"""

from __future__ import annotations

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.sampling import ControlInstants, Rewind
from wallbot_sim.control.wheel_speed import AxisLimits, WheelSpeedController, WheelSpeedSettings
from wallbot_sim.nodes.common import (ROBOT_CLOCK_ARGS, HeldCommands, exit_process, run, senders_listen,
                                      steady_timer, subscribe_odom_when_recorded)
from wallbot_sim.nodes.parameters import declare_setting, declare_typed, param_dict, parameter_result
from wallbot_sim.settings.drives import CMD_VEL, CmdVelSettings
from wallbot_sim.settings.table import changed, parameters

THROTTLE = 1.0
"""Seconds between repeated log lines of one kind."""
COMMANDER_CHECK = 0.02
"""Wall seconds between looks for a commander hearing odom (answer_commands)."""
TUNED = ('wheel_separation', 'wheel_radius', 'cmd_vel_timeout', 'linear.x.max_velocity', 'linear.x.max_acceleration',
         'angular.z.max_velocity', 'angular.z.max_acceleration', 'wheel_speed_kp', 'wheel_speed_ki',
         'max_wheel_torque')
"""The settings of the wheel-speed loop (changeable while the node runs)."""


def loop_settings(settings: CmdVelSettings) -> WheelSpeedSettings:
    """What the wheel-speed loop needs of the node's settings."""
    return WheelSpeedSettings(
        settings.wheel_separation, settings.wheel_radius,
        AxisLimits(settings.linear_max_velocity, settings.linear_max_acceleration),
        AxisLimits(settings.angular_max_velocity, settings.angular_max_acceleration),
        settings.cmd_vel_timeout, settings.wheel_speed_kp, settings.wheel_speed_ki, settings.max_wheel_torque)


class CmdVelNode(Node):
    """cmd_vel + odom -> wheel_torque_cmd at rate_hz of simulation time."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_CMD_VEL, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)
        robot_file = declare_setting(self, CMD_VEL['robot_file'], '')[0]  # first: it gives defaults
        robot = load_robot_parameters(robot_file or None)
        self.settings: CmdVelSettings = declare_typed(self, CmdVelSettings, CMD_VEL, {
            'wheel_separation': 2.0 * robot.half_track, 'wheel_radius': robot.wheel_radius})
        self.use_stamped, self.rate_hz = self.settings.use_stamped_vel, self.settings.rate_hz
        if self.settings.answer_commands and not self.use_stamped:
            raise ValueError('answer_commands needs use_stamped_vel: an answer names its state by its stamp')
        self.controller = WheelSpeedController(loop_settings(self.settings))
        self.instants = ControlInstants(int(self.rate_hz))
        self.now_ns: int | None = None
        """The newest odometry stamp: simulation time as this node knows it."""
        self.early: tuple[float, float] | None = None
        """The newest cmd_vel that came before any odometry."""
        self.answers: dict[int, tuple[float, float]] = {}
        """With answer_commands: the cmd_vel answering each state (its stamp), not used yet."""
        self.unanswered: tuple[int, tuple[float, float]] | None = None
        """With answer_commands: the control instant (stamp, measured wheel speeds) waiting for its cmd_vel."""
        self.commander_check = None

        publisher = self.create_publisher(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name,
                                          qos_profile(topics.WHEEL_TORQUE_CMD))
        self.commands = HeldCommands(self, publisher, topics.ODOM.name)
        self.create_subscription(TwistStamped if self.use_stamped else Twist, topics.CMD_VEL.name, self._on_cmd_vel,
                                 qos_profile(topics.CMD_VEL), raw=True)
        subscribe_odom_when_recorded(self, self.settings.wait_for_recorder, publisher, self._subscribe_odom)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.get_logger().info(
            f'cmd_vel ({"TwistStamped" if self.use_stamped else "Twist"}) -> wheel_torque_cmd at {self.rate_hz} Hz '
            'of simulation time; ' + ', '.join(f'{name} {parameters(self.settings)[name]:g}' for name in TUNED))

    def _subscribe_odom(self) -> None:
        if self.settings.answer_commands and not senders_listen(self, self.resolve_topic_name(topics.CMD_VEL.name),
                                                                 self.resolve_topic_name(topics.ODOM.name)):
            if self.commander_check is None:  # until the commander hears the states it answers
                self.commander_check = steady_timer(self, COMMANDER_CHECK, self._subscribe_odom)
            return
        if self.commander_check is not None:
            self.commander_check.cancel()
            self.get_logger().info('the commander hears odom: subscribing it')
        # raw: of the 1 kHz odometry only the states acted on are decoded
        self.create_subscription(Odometry, topics.ODOM.name, self._on_odom, qos_profile(topics.ODOM), raw=True)

    def _on_cmd_vel(self, data: bytes) -> None:
        command = codec.decode_cmd_vel(data, self.use_stamped)
        if not self.settings.answer_commands:
            self._command(*command)
            return
        stamp_ns = codec.leading_stamp_ns(data)
        if stamp_ns is None:
            return
        self.answers[stamp_ns] = command
        if self.unanswered is not None and self.unanswered[0] in self.answers:
            self._answer(*self.unanswered)

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
        if self.settings.answer_commands:
            self.answers = {stamp: command for stamp, command in self.answers.items() if stamp >= stamp_ns}
            self.unanswered = (stamp_ns, measured)
            if stamp_ns in self.answers:
                self._answer(stamp_ns, measured)
            return
        self._act(stamp_ns, measured)

    def _answer(self, stamp_ns: int, measured: tuple[float, float]) -> None:
        """The control instant at ``stamp_ns`` with the commander's answer to it (answer_commands)."""
        self.unanswered = None
        self._command(*self.answers.pop(stamp_ns))
        self._act(stamp_ns, measured)

    def _act(self, stamp_ns: int, measured: tuple[float, float]) -> None:
        """The wheel-speed loop at the control instant ``stamp_ns``, the wheels turning at ``measured`` (rad/s)."""
        s = self.controller.settings
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

    def _on_set(self, parameters_):
        return parameter_result(CMD_VEL.reasons(param_dict(parameters_)))

    def _after_set(self, parameters_) -> None:
        changes = param_dict(parameters_, TUNED)
        if changes:
            self.settings = changed(self.settings, changes)
            self.controller.configure(loop_settings(self.settings))
            self.get_logger().info('parameters: ' + ', '.join(f'{k} = {v}' for k, v in changes.items()))


def main(args: list[str] | None = None) -> None:
    exit_process(run(CmdVelNode, args, events=True))


if __name__ == '__main__':
    main()
