"""An IMU at the robot's centre (``sensors.imu``): specific force and turn rate in base_link's axes.

The accelerometer reads the specific force f = a - g (REP 145): the centre's acceleration a minus gravity, both in
the wall frame (a = (xdd, ydd, 0): the robot stays on the surface; g = (0, -g sin i, -g cos i), docs/model.md 13.1),
turned into the body axes by R(theta)^T. At rest on a vertical wall facing +X it reads (0, g, 0); on the floor
(0, 0, g). The gyroscope reads (0, 0, theta_dot).

Each axis of each instrument errs by white noise of standard deviation sigma_d sqrt(rate) per sample (sigma_d the
noise density) plus a bias that starts at 0 and takes a Gaussian step of standard deviation sigma_w / sqrt(rate)
per sample (sigma_w the random walk), all drawn from one generator seeded with ``seed``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wallbot_sim.model.sensors import ImuParameters


class ImuReading(NamedTuple):
    """One sample, body axes: angular velocity (rad/s) and specific force (m/s^2)."""

    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray


def specific_force(theta: float, acceleration: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """f = R(theta)^T (a - g) (3,) of the centre's wall-frame ``acceleration`` (xdd, ydd) under ``gravity`` (3,)."""
    fx, fy, fz = acceleration[0] - gravity[0], acceleration[1] - gravity[1], -gravity[2]
    c, s = math.cos(theta), math.sin(theta)
    return np.array([c * fx + s * fy, -s * fx + c * fy, fz])


class Imu:
    """The IMU of ``params`` on a surface whose gravity in the wall frame is ``gravity`` (3,)."""

    def __init__(self, params: ImuParameters, gravity: np.ndarray) -> None:
        self.params, self.gravity = params, np.asarray(gravity, dtype=float)
        root_rate = math.sqrt(params.rate)
        self.gyroscope_sigma = params.gyroscope_noise_density * root_rate
        self.accelerometer_sigma = params.accelerometer_noise_density * root_rate
        self._walk = np.array([params.gyroscope_random_walk] * 3 + [params.accelerometer_random_walk] * 3) / root_rate
        self._sigma = np.array([self.gyroscope_sigma] * 3 + [self.accelerometer_sigma] * 3)
        self._bias = np.zeros(6)
        self._rng = np.random.default_rng(params.seed)

    @property
    def bias(self) -> tuple[np.ndarray, np.ndarray]:
        """The gyroscope's and the accelerometer's bias now (3 each)."""
        return self._bias[:3].copy(), self._bias[3:].copy()

    def exact(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> ImuReading:
        """What an ideal IMU reads at the state (q, qd) with accelerations qdd."""
        return ImuReading(np.array([0.0, 0.0, float(qd[2])]), specific_force(float(q[2]), qdd, self.gravity))

    def measure(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> ImuReading:
        """One sample: the exact reading, the bias after its step, and the white noise."""
        truth = self.exact(q, qd, qdd)
        self._bias += self._walk * self._rng.standard_normal(6)
        errors = self._bias + self._sigma * self._rng.standard_normal(6)
        return ImuReading(truth.angular_velocity + errors[:3], truth.linear_acceleration + errors[3:])
