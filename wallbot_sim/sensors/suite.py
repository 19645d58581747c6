"""The robot file's sensors on the dynamics' published states: each sampled at its rate, encoded as its message.

A sensor of rate f samples the first published state of every period 1/f of simulation time (``ClockSchedule``:
at 1 kHz and 200 Hz, the states at multiples of 5 ms), and again after the time went back (a reset).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from wallbot_msgs_py import cdr, codec, topics
from wallbot_sim.messages import ClockSchedule
from wallbot_sim.model import Robot, StepOutputs
from wallbot_sim.model.sensors import SensorParameters
from wallbot_sim.sensors.encoders import Encoders
from wallbot_sim.sensors.imu import Imu
from wallbot_sim.sensors.pressure import PressureSensor

Encode = Callable[[StepOutputs, int, int], bytes]
"""A sensor's message of a state (its outputs, stamp sec and nanosec)."""


def surface_gravity(robot: Robot) -> np.ndarray:
    """Gravity in the wall frame, (0, -g sin i, -g cos i) (docs/model.md 13.1)."""
    slope_sin, slope_cos = robot.world.slope
    g = robot.params.gravity
    return np.array([0.0, -g * slope_sin, -g * slope_cos])


class SensorSuite:
    """The sensors of ``sensors`` on ``robot`` (the robot file's), their messages in ``frame`` (base_link)."""

    def __init__(self, sensors: SensorParameters, robot: Robot, frame: str) -> None:
        self._sensors: list[tuple[topics.Topic, ClockSchedule, Encode]] = []
        if sensors.imu is not None:
            self._add(topics.IMU, sensors.imu.rate, self._imu(Imu(sensors.imu, surface_gravity(robot)), frame))
        if sensors.encoders is not None:
            self._add(topics.JOINT_STATES, sensors.encoders.rate, self._encoders(Encoders(sensors.encoders)))
        if sensors.pressure is not None:
            self._add(topics.CHAMBER_PRESSURE, sensors.pressure.rate,
                      self._pressure(PressureSensor(sensors.pressure), frame))

    @property
    def topics(self) -> tuple[topics.Topic, ...]:
        """The topics the suite publishes on."""
        return tuple(topic for topic, _schedule, _encode in self._sensors)

    def _add(self, topic: topics.Topic, rate: float, encode: Encode) -> None:
        self._sensors.append((topic, ClockSchedule(rate), encode))

    def encode(self, out: StepOutputs) -> list[tuple[topics.Topic, bytes]]:
        """The messages of the sensors that sample the state ``out`` (call once per published state, in order)."""
        stamp_ns = cdr.to_nanoseconds(out.t)
        sec, nanosec = cdr.split_stamp(stamp_ns)
        return [(topic, encode(out, sec, nanosec)) for topic, schedule, encode in self._sensors
                if schedule.due(stamp_ns)]

    @staticmethod
    def _imu(imu: Imu, frame: str) -> Encode:
        encoder = codec.ImuEncoder(frame, imu.gyroscope_sigma ** 2, imu.accelerometer_sigma ** 2)

        def encode(out: StepOutputs, sec: int, nanosec: int) -> bytes:
            reading = imu.measure(out.q, out.qd, out.acceleration)
            return encoder.encode(sec, nanosec, reading.angular_velocity.tolist(),
                                  reading.linear_acceleration.tolist())
        return encode

    @staticmethod
    def _encoders(encoders: Encoders) -> Encode:
        encoder = codec.JointStateEncoder(topics.WHEEL_JOINTS, filled=('position', 'velocity'))

        def encode(out: StepOutputs, sec: int, nanosec: int) -> bytes:
            angles, speeds = encoders.measure(out.t, out.q[3:])
            return encoder.encode(sec, nanosec, angles.tolist(), speeds.tolist())
        return encode

    @staticmethod
    def _pressure(sensor: PressureSensor, frame: str) -> Encode:
        encoder = codec.FluidPressureEncoder(frame, sensor.params.noise ** 2)

        def encode(out: StepOutputs, sec: int, nanosec: int) -> bytes:
            return encoder.encode(sec, nanosec, sensor.measure(out.vacuum[0]))
        return encode
