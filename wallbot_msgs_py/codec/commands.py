"""What drives the robot and what describes it: ``wheel_torque_cmd`` (std_msgs/Float64MultiArray),
``pump_command`` (std_msgs/Float64),
``cmd_vel`` (geometry_msgs/TwistStamped or Twist), ``initialpose`` (PoseWithCovarianceStamped) and
``robot_description`` (std_msgs/String)."""

from __future__ import annotations

import math
import struct

from wallbot_msgs_py import cdr, topics

FLOAT64_MULTIARRAY = 'std_msgs/msg/Float64MultiArray'
FLOAT64 = 'std_msgs/msg/Float64'
TWIST_STAMPED = 'geometry_msgs/msg/TwistStamped'
POSE_WITH_COVARIANCE_STAMPED = 'geometry_msgs/msg/PoseWithCovarianceStamped'
STRING = 'std_msgs/msg/String'


@cdr.encoder('pump_command', FLOAT64)
def pump_command(command: float) -> bytes:
    """``pump_command``: the vacuum pump's command u in [0, 1] (1: full flow) as a std_msgs/Float64."""
    out = cdr.Writer()
    out.float64s((command,))
    return out.bytes()


@cdr.decoder('pump_command', FLOAT64)
def decode_pump_command(message: cdr.Reader) -> float:
    """u of a serialized ``pump_command``; ValueError naming the value unless it is a number in [0, 1]."""
    command, = message.float64s(1)
    if not 0.0 <= command <= 1.0:  # NaN too
        raise ValueError(f'pump_command must be in [0, 1], got {command!r}')
    return command


class _TorqueCommand:
    """``[tau_L, tau_R]`` with an empty layout: a template whose two numbers are overwritten."""

    def __init__(self) -> None:
        out = cdr.Writer()
        out.float64_multiarray((), (0.0, 0.0))
        self.template = out.bytes()
        self._values = struct.Struct('<2d')
        self._offset = len(self.template) - 16

    def encode(self, tau_left: float, tau_right: float) -> bytes:
        data = bytearray(self.template)
        self._values.pack_into(data, self._offset, tau_left, tau_right)
        return bytes(data)


_TORQUE_COMMAND = _TorqueCommand()


@cdr.encoder('wheel_torque_cmd', FLOAT64_MULTIARRAY)
def wheel_torque_cmd(tau_left: float, tau_right: float) -> bytes:
    """``wheel_torque_cmd``: the side motor torques (N m) as a std_msgs/Float64MultiArray
    ``[tau_L, tau_R]`` with an empty layout (what a controller publishes at every control instant)."""
    return _TORQUE_COMMAND.encode(tau_left, tau_right)


@cdr.decoder('wheel_torque_cmd', FLOAT64_MULTIARRAY)
def decode_wheel_torque_cmd(message: cdr.Reader, max_torque: float) -> tuple[float, float]:
    """(tau_L, tau_R) of a serialized ``wheel_torque_cmd``.

    ValueError with the reason for a wrong length, NaN or inf, or |tau| > max_torque.
    """
    _dims, data = message.float64_multiarray()
    if len(data) != 2:
        raise ValueError(f'wheel_torque_cmd needs data = [tau_L, tau_R], got {len(data)} values')
    for side, value in zip(('tau_L', 'tau_R'), data):
        if not math.isfinite(value):
            raise ValueError(f'wheel_torque_cmd {side} is not finite ({value})')
        if abs(value) > max_torque:
            raise ValueError(f'wheel_torque_cmd {side} = {value:g} N m is beyond max_wheel_torque {max_torque:g} N m')
    return data[0], data[1]


@cdr.decoder('cmd_vel', TWIST_STAMPED)
def decode_cmd_vel(message: cdr.Reader, stamped: bool = True) -> tuple[float, float]:
    """(linear.x, angular.z) of a serialized ``cmd_vel``: a TwistStamped, or a Twist if not ``stamped``."""
    if stamped:
        message.header()
    forward, _sideways, _up, _roll, _pitch, turn = message.float64s(6)
    return forward, turn


@cdr.decoder('initialpose', POSE_WITH_COVARIANCE_STAMPED)
def decode_initial_pose(message: cdr.Reader, wall_frame: str = topics.WALL_FRAME) -> tuple[float, float, float]:
    """(x, y, heading) of a serialized ``initialpose``; ValueError naming what is wrong: a frame other
    than ``wall_frame`` (the graph has no tf to convert it), a non-finite number, an orientation that is
    not a turn about the wall's normal Z. The covariance is not used."""
    _stamp_ns, frame = message.header()
    x, y, z, qx, qy, qz, qw = message.float64s(7)
    message.float64s(36)  # the covariance, there though unused
    if frame != wall_frame:
        raise ValueError(f'initialpose: frame {frame!r}, not {wall_frame!r} (set the fixed frame to {wall_frame!r})')
    values = (x, y, z, qx, qy, qz, qw)
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f'initialpose: a pose value is not finite: {values}')
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm == 0.0 or math.hypot(qx, qy) > 1e-6 * norm:
        raise ValueError(f'initialpose: orientation ({qx}, {qy}, {qz}, {qw}) is not a turn about Z')
    return x, y, math.atan2(2.0 * qw * qz, qw * qw - qz * qz)  # any norm


@cdr.encoder('robot_description', STRING)
def robot_description(urdf: str) -> bytes:
    """``robot_description``: the URDF document as a std_msgs/String."""
    out = cdr.Writer()
    out.string(urdf)
    return out.bytes()


@cdr.decoder('robot_description', STRING)
def decode_robot_description(message: cdr.Reader) -> str:
    return message.string()
