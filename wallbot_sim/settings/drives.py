"""The settings of the nodes that turn a user's commands into wheel_torque_cmd: cmd_vel_node
(``nodes.cmd_vel``) and joint_bridge_node (``nodes.joint_bridge``)."""

from __future__ import annotations

from dataclasses import dataclass

from wallbot_sim.control.wheel_speed import (GAIN, POSITIVE_LIMIT, SPEED_LOOP_RATE_HZ, AxisLimits,
                                             WheelSpeedSettings)
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.settings.common import WHEEL_TORQUE_LIMIT, recorder_wait, sim_time
from wallbot_sim.settings.table import setting, table_of

GEOMETRY = NumberRange(1e-4, 10.0)
ROBOT = RobotParameters()
LOOP = WheelSpeedSettings(2.0 * ROBOT.half_track, ROBOT.wheel_radius, AxisLimits(0.5, 1.0), AxisLimits(2.0, 4.0))
"""The wheel-speed loop's defaults (the geometry: the installed robot file's, which the node reads)."""


@dataclass(frozen=True)
class CmdVelSettings:
    """cmd_vel_node's parameters (diff_drive_controller's names where it has them)."""

    robot_file: str = setting('', 'robot parameter YAML giving the default wheel_separation and wheel_radius; empty = '
                                  'installed config/robot.yaml', read_only=True)
    use_stamped_vel: bool = setting(True, 'cmd_vel is geometry_msgs/TwistStamped (false: geometry_msgs/Twist)',
                                    read_only=True)
    rate_hz: int = setting(SPEED_LOOP_RATE_HZ, 'control rate in simulation time (Hz)', NumberRange(1, 1000),
                           read_only=True)
    wheel_separation: float = setting(LOOP.wheel_separation, 'distance between the left and right wheels (m; '
                                                             "default: the robot file's 2 half_track)", GEOMETRY)
    wheel_radius: float = setting(LOOP.wheel_radius, "wheel radius (m; default: the robot file's)", GEOMETRY)
    cmd_vel_timeout: float = setting(LOOP.cmd_vel_timeout, 'seconds of simulation time after which the last cmd_vel '
                                                           'counts as zero', NumberRange(1e-3, 1e3))
    linear_max_velocity: float = setting(LOOP.linear.max_velocity, 'largest |linear.x| (m/s)', POSITIVE_LIMIT,
                                         name='linear.x.max_velocity')
    linear_max_acceleration: float = setting(LOOP.linear.max_acceleration, 'largest change of linear.x (m/s^2)',
                                             POSITIVE_LIMIT, name='linear.x.max_acceleration')
    angular_max_velocity: float = setting(LOOP.angular.max_velocity, 'largest |angular.z| (rad/s)', POSITIVE_LIMIT,
                                          name='angular.z.max_velocity')
    angular_max_acceleration: float = setting(LOOP.angular.max_acceleration, 'largest change of angular.z (rad/s^2)',
                                              POSITIVE_LIMIT, name='angular.z.max_acceleration')
    wheel_speed_kp: float = setting(LOOP.kp, 'proportional gain of the wheel-speed loop (N m per rad/s)', GAIN)
    wheel_speed_ki: float = setting(LOOP.ki, 'integral gain of the wheel-speed loop (N m per rad)', GAIN)
    max_wheel_torque: float = setting(LOOP.max_wheel_torque, "side torque limit (N m; the dynamics' limit)",
                                      WHEEL_TORQUE_LIMIT)
    wait_for_recorder: bool = recorder_wait('subscribe odom (and so let the dynamics start)')
    answer_commands: bool = setting(False, 'in lockstep with a commander under test: answer a control instant only '
                                           'once a cmd_vel stamped with its state came (the commander answers each '
                                           'control_odom state), and subscribe odom only once every cmd_vel publisher '
                                           'subscribes control_odom', read_only=True)
    use_sim_time: bool = sim_time()


CMD_VEL = table_of(CmdVelSettings)


@dataclass(frozen=True)
class JointBridgeSettings:
    """joint_bridge_node's parameters."""

    rate_hz: int = setting(50, 'joint_states per second of simulation time', NumberRange(1, 1000), read_only=True)
    max_wheel_torque: float = setting(5.0, "largest accepted |side total| of the efforts (N m; the dynamics' limit)",
                                      WHEEL_TORQUE_LIMIT)
    robot_file: str = setting('', 'robot parameter YAML: with sensors.encoders the dynamics publishes joint_states (from '
                                  'the encoders) and this node none; empty = the installed robot.yaml', read_only=True)
    wait_for_recorder: bool = recorder_wait('subscribe joint_commands and wheel_states')
    answer_commands: bool = setting(False, 'in lockstep with a commander under test, which answers each joint_states '
                                           'with one joint_commands: subscribe wheel_states only once every '
                                           'joint_commands publisher hears joint_states', read_only=True)
    use_sim_time: bool = sim_time()


JOINT_BRIDGE = table_of(JointBridgeSettings)
