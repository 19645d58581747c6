"""The robot's sensors (the robot file's ``sensors`` block, docs/model.md 13.5): what an IMU, wheel encoders and a
chamber pressure sensor read of the simulated state, with their noise, bias and quantization.

ROS-free: the measurement models (``imu``, ``encoders``, ``pressure``) take a step's outputs and return numbers;
``suite.SensorSuite`` samples them at their rates and encodes their messages, which the dynamics node publishes.
"""

from wallbot_sim.sensors.encoders import Encoders, quantized
from wallbot_sim.sensors.imu import Imu, ImuReading, specific_force
from wallbot_sim.sensors.pressure import PressureSensor
from wallbot_sim.sensors.suite import SensorSuite

__all__ = ['Encoders', 'Imu', 'ImuReading', 'PressureSensor', 'SensorSuite', 'quantized', 'specific_force']
