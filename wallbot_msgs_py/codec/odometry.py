"""nav_msgs/Odometry: ``odom``, ``control_odom``, ``ground_truth/odom`` and ``reference``.

The pose is of the centre in ``frame`` (the wall), the twist in ``child`` (REP 105): twist.linear =
(v_long, v_lat), twist.angular.z the turning rate. The covariances' diagonals are fixed per
encoder (the sensor noise's variances; zero for the exact state), so every message of an encoder is
one byte template whose numbers are overwritten: a few ``struct.pack_into`` per message.
"""

from __future__ import annotations

import math
import struct
from typing import NamedTuple, Sequence

import numpy as np

from wallbot_msgs_py import cdr, topics

TYPE = 'nav_msgs/msg/Odometry'
NO_VARIANCE = (0.0,) * 6
"""The covariance diagonal of an exact state: the simulation's own (ground truth, or odometry without noise)."""

_TWO = struct.Struct('<2d')
_ONE = struct.Struct('<d')


def yaw_of(x: float, y: float, z: float, w: float) -> float:
    """Rotation about Z of the quaternion (x, y, z, w), in (-pi, pi]."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """The quaternion (x, y, z, w) of a rotation by ``yaw`` about Z."""
    return 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)


@cdr.encoder('odometry', TYPE)
class OdometryEncoder:
    """Odometry bytes of one pair of frames and covariance diagonals (row-major 6 x 6, x y z roll pitch
    yaw). ``encode`` takes the wall-frame state and rotates the velocity into ``child``."""

    def __init__(self, frame: str = topics.WALL_FRAME, child: str = topics.BASE_FRAME,
                 pose_variances: Sequence[float] = NO_VARIANCE, twist_variances: Sequence[float] = NO_VARIANCE) -> None:
        odom = cdr.Writer()
        self._stamp = odom.header(0, frame)
        odom.string(child)
        self._position = odom.float64s((0.0,) * 3)
        self._orientation = odom.float64s((0.0, 0.0, 0.0, 1.0)) + 16  # z, w
        odom.float64s(_diagonal(pose_variances))
        self._twist = odom.float64s((0.0,) * 6)
        odom.float64s(_diagonal(twist_variances))
        self.template = odom.bytes()
        self._buffer = bytearray(self.template)
        self._rows = cdr.Rows(self.template, cdr.stamped(
            self._stamp, position=(self._position, cdr.doubles(2)), orientation=(self._orientation, cdr.doubles(2)),
            twist=(self._twist, cdr.doubles(2)), turn=(self._twist + 40, '<f8')))

    def encode(self, sec: int, nanosec: int, q: Sequence[float], qd: Sequence[float]) -> bytes:
        """The message of the state q = (x, y, theta, ...), qd = (xd, yd, thd, ...) in the wall frame."""
        data = self._buffer
        theta, xd, yd = q[2], qd[0], qd[1]
        c, s = math.cos(theta), math.sin(theta)
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        _TWO.pack_into(data, self._position, q[0], q[1])
        _TWO.pack_into(data, self._orientation, math.sin(0.5 * theta), math.cos(0.5 * theta))
        _TWO.pack_into(data, self._twist, c * xd + s * yd, -s * xd + c * yd)
        _ONE.pack_into(data, self._twist + 40, qd[2])
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray, q: np.ndarray, qd: np.ndarray) -> list[bytes]:
        """``encode`` of each row of q, qd (T, >= 3), the same bytes."""
        theta = q[:, 2].tolist()
        # math's sin and cos, as encode calls them: NumPy's may differ in the last bit
        c = np.array([math.cos(angle) for angle in theta])
        s = np.array([math.sin(angle) for angle in theta])
        half = np.array([(math.sin(0.5 * angle), math.cos(0.5 * angle)) for angle in theta])
        xd, yd = qd[:, 0], qd[:, 1]
        return self._rows.fill(len(theta), sec=sec, nanosec=nanosec, position=q[:, :2], orientation=half,
                               twist=np.stack((c * xd + s * yd, -s * xd + c * yd), axis=1), turn=qd[:, 2])


_STAMP = struct.Struct('<iI')


def _diagonal(variances: Sequence[float]) -> list[float]:
    matrix = [0.0] * 36
    for i, variance in enumerate(variances):
        matrix[7 * i] = float(variance)
    return matrix


class PlanarState(NamedTuple):
    """The planar state an Odometry carries, velocities in the wall frame."""

    stamp_ns: int
    x: float
    y: float
    theta: float
    """Yaw of the pose quaternion, in (-pi, pi] (the simulation's angle is unwrapped)."""
    xd: float
    yd: float
    thd: float

    @property
    def t(self) -> float:
        return self.stamp_ns * 1e-9


class OdometryMessage(NamedTuple):
    """What an Odometry says in the plane: its frames, stamp, pose, and twist in the child frame."""

    stamp_ns: int
    frame: str
    child: str
    x: float
    y: float
    yaw: float
    """Of the pose quaternion, in (-pi, pi]."""
    forward: float
    """twist.linear.x (the child frame's)."""
    sideways: float
    """twist.linear.y."""
    turn: float
    """twist.angular.z."""

    def planar_state(self) -> PlanarState:
        """The state with the twist rotated back into wall-frame velocities; ValueError if a value is not finite."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        u, v = self.forward, self.sideways
        state = PlanarState(self.stamp_ns, self.x, self.y, self.yaw, c * u - s * v, s * u + c * v, self.turn)
        if not all(math.isfinite(value) for value in state[1:]):
            raise ValueError(f'odometry at t = {state.t:.3f} s is not finite')
        return state


@cdr.decoder('odometry', TYPE)
def decode_odometry(message: cdr.Reader) -> OdometryMessage:
    """The frames, stamp, planar pose and twist of a serialized Odometry (the covariances are skipped)."""
    stamp_ns, frame = message.header()
    child = message.string()
    x, y, _z, qx, qy, qz, qw = message.float64s(7)
    message.skip_float64s(36)
    forward, sideways, _up, _roll, _pitch, turn = message.float64s(6)
    message.skip_float64s(36)
    if message.offset > len(message.data):
        raise IndexError('the covariance runs past the end')
    return OdometryMessage(stamp_ns, frame, child, x, y, yaw_of(qx, qy, qz, qw), forward, sideways, turn)
