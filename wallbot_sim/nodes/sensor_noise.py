"""Seeded Gaussian sensor noise on what the dynamics node publishes, never on what it simulates.

The simulation integrates the exact state; a ``SensorNoise`` turns a step's state into what a
robot's sensors would report (odometry pose and twist, wheel encoders), and the node publishes
that on ``odom`` and ``wheel_states`` with the exact odometry beside it on ``ground_truth/odom``.
The odometry covariance is the noise's variance (zero without noise: the simulated state is
exact). ROS-free, tested without DDS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class NoiseLevels:
    """Standard deviations of the independent zero-mean Gaussian noise on each published value."""

    position: float = 0.0
    """On the odometry's X and Y (m)."""
    heading: float = 0.0
    """On the odometry's yaw (rad)."""
    linear: float = 0.0
    """On each of the odometry twist's linear components (m/s)."""
    angular: float = 0.0
    """On the odometry twist's turning rate (rad/s)."""
    encoder: float = 0.0
    """On each wheel's spin angle in wheel_states (rad)."""
    encoder_velocity: float = 0.0
    """On each wheel's spin rate in wheel_states (rad/s)."""

    @property
    def on(self) -> bool:
        return any(level > 0.0 for level in (self.position, self.heading, self.linear, self.angular,
                                             self.encoder, self.encoder_velocity))

    def pose_variances(self) -> tuple[float, ...]:
        """The odometry pose covariance's diagonal (x, y, z, roll, pitch, yaw): z, roll and pitch
        are exact on the wall."""
        return (self.position ** 2, self.position ** 2, 0.0, 0.0, 0.0, self.heading ** 2)

    def twist_variances(self) -> tuple[float, ...]:
        """The odometry twist covariance's diagonal. Rotating isotropic noise on the wall-frame
        velocity into the base frame leaves it isotropic with the same variance."""
        return (self.linear ** 2, self.linear ** 2, 0.0, 0.0, 0.0, self.angular ** 2)


@dataclass(frozen=True)
class SensedState:
    """Generalized coordinates and velocities (x, y, theta, four wheel spins) as measured."""

    q: np.ndarray
    qd: np.ndarray


class SensorNoise:
    """Draws the noise of each published state from one generator seeded with ``seed``, so a run
    with the same seed publishes the same measurements."""

    def __init__(self, levels: NoiseLevels, seed: int) -> None:
        self.levels = levels
        self._rng = np.random.default_rng(seed)
        self._q_sigma = np.array([levels.position, levels.position, levels.heading] + [levels.encoder] * 4)
        # on the wall-frame velocity (isotropic, so the same in the base frame), the turning rate, the spins
        self._qd_sigma = np.array([levels.linear, levels.linear, levels.angular] + [levels.encoder_velocity] * 4)

    def sense(self, q: np.ndarray, qd: np.ndarray) -> SensedState:
        """The measurement of the state (q, qd); the arguments are not changed."""
        return SensedState(q + self._q_sigma * self._rng.standard_normal(q.shape),
                           qd + self._qd_sigma * self._rng.standard_normal(qd.shape))
