"""sensor_msgs/Imu (``imu``) and sensor_msgs/FluidPressure (``chamber_pressure``): the robot's own sensors.

Imu follows REP 145: ``linear_acceleration`` is the specific force (what an accelerometer reads: at rest on a
vertical wall facing +X, y = +g), ``angular_velocity`` the turn rate, both in the IMU's frame; the orientation is
not estimated, so ``orientation_covariance[0]`` is -1 (and the orientation the identity, to be ignored). The
covariances' diagonals are the white noise's variances per sample, fixed per encoder. FluidPressure carries an
absolute pressure (Pa) and its variance. Each encoder is a byte template whose numbers are overwritten.
"""

from __future__ import annotations

import struct
from typing import NamedTuple, Sequence

from wallbot_msgs_py import cdr

IMU = 'sensor_msgs/msg/Imu'
FLUID_PRESSURE = 'sensor_msgs/msg/FluidPressure'
NO_ORIENTATION = (-1.0,) + (0.0,) * 8
"""REP 145's covariance of an orientation the sensor does not estimate."""
_STAMP = struct.Struct('<iI')
_THREE = struct.Struct('<3d')
_ONE = struct.Struct('<d')


def _diagonal(variance: float) -> tuple[float, ...]:
    return (variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0, variance)


@cdr.encoder('imu', IMU)
class ImuEncoder:
    """Imu bytes in ``frame`` with the per-axis variances ``gyroscope_variance`` ((rad/s)^2) and
    ``accelerometer_variance`` ((m/s^2)^2)."""

    def __init__(self, frame: str, gyroscope_variance: float = 0.0, accelerometer_variance: float = 0.0) -> None:
        imu = cdr.Writer()
        self._stamp = imu.header(0, frame)
        imu.float64s((0.0, 0.0, 0.0, 1.0))
        imu.float64s(NO_ORIENTATION)
        self._angular = imu.float64s((0.0,) * 3)
        imu.float64s(_diagonal(gyroscope_variance))
        self._linear = imu.float64s((0.0,) * 3)
        imu.float64s(_diagonal(accelerometer_variance))
        self.template = imu.bytes()
        self._buffer = bytearray(self.template)

    def encode(self, sec: int, nanosec: int, angular_velocity: Sequence[float],
               linear_acceleration: Sequence[float]) -> bytes:
        data = self._buffer
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        _THREE.pack_into(data, self._angular, *angular_velocity)
        _THREE.pack_into(data, self._linear, *linear_acceleration)
        return bytes(data)


class ImuMessage(NamedTuple):
    """What an Imu says (covariances row-major 3 x 3)."""

    stamp_ns: int
    frame: str
    orientation: tuple[float, ...]
    orientation_covariance: tuple[float, ...]
    angular_velocity: tuple[float, ...]
    angular_velocity_covariance: tuple[float, ...]
    linear_acceleration: tuple[float, ...]
    linear_acceleration_covariance: tuple[float, ...]


@cdr.decoder('imu', IMU)
def decode_imu(message: cdr.Reader) -> ImuMessage:
    stamp_ns, frame = message.header()
    return ImuMessage(stamp_ns, frame, *(message.float64s(count) for count in (4, 9, 3, 9, 3, 9)))


@cdr.encoder('fluid_pressure', FLUID_PRESSURE)
class FluidPressureEncoder:
    """FluidPressure bytes in ``frame`` with the variance ``variance`` (Pa^2)."""

    def __init__(self, frame: str, variance: float = 0.0) -> None:
        pressure = cdr.Writer()
        self._stamp = pressure.header(0, frame)
        self._pressure = pressure.float64s((0.0, variance))
        self.template = pressure.bytes()
        self._buffer = bytearray(self.template)

    def encode(self, sec: int, nanosec: int, pressure: float) -> bytes:
        """The message of the absolute ``pressure`` (Pa)."""
        data = self._buffer
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        _ONE.pack_into(data, self._pressure, pressure)
        return bytes(data)


class PressureMessage(NamedTuple):
    stamp_ns: int
    frame: str
    pressure: float
    """Absolute (Pa)."""
    variance: float


@cdr.decoder('fluid_pressure', FLUID_PRESSURE)
def decode_fluid_pressure(message: cdr.Reader) -> PressureMessage:
    stamp_ns, frame = message.header()
    return PressureMessage(stamp_ns, frame, *message.float64s(2))
