"""Velocity commands (v, omega) to side torques: a differential drive's wheel-speed PI loop.

ROS-free; ``cmd_vel_node`` runs it on the odometry it receives, at a rate of simulation time.
Modelled on ros2_controllers' diff_drive_controller: the command is limited per axis like its
``SpeedLimiter`` (velocity, then acceleration against the previous limited command), a command
older than ``cmd_vel_timeout`` of simulation time becomes zero (still through the limiter, so
the robot ramps down), and the limited (v, omega) becomes wheel speeds by the differential
drive's kinematics with ``wheel_separation`` and ``wheel_radius``. Where diff_drive_controller
hands those speeds to the hardware's velocity interface, this robot's motors take torque, so one
PI loop per side turns the speed error into that side's motor torque (the synchronous belt makes
the two wheels of a side one drive).

Measured wheel speeds are the rolling speeds of the odometry twist (v_long -+ omega s / 2) / r:
while a side slips on the wall (coulomb contact) its wheels spin faster than that, and the loop,
seeing the robot lag, pushes on up to its torque limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from wallbot_sim.model.numbers import NumberRange

POSITIVE_LIMIT = NumberRange(1e-6, 1e3)
"""A velocity or acceleration limit: above 0, from 1e-6 on so that a parameter descriptor's closed
range says exactly what is accepted."""
SPEED_LOOP_RATE_HZ = 50
"""cmd_vel_node's default rate (Hz of simulation time), every 20th state of the 1 kHz dynamics: a
scripted square on the wall ends within 0.2 degrees of its heading and 4.3 cm of its last corner, as
at 100 Hz (test_cmd_vel_graph.py), for half the node's wake-ups."""
GAIN = NumberRange(0.0, 1e3)
"""A PI gain (>= 0)."""


@dataclass(frozen=True)
class AxisLimits:
    """One axis of diff_drive_controller's speed limiter: |value| <= max_velocity, its rate of
    change within max_acceleration (both > 0)."""

    max_velocity: float
    max_acceleration: float

    def limit(self, target: float, previous: float, dt: float) -> float:
        clamped = min(self.max_velocity, max(-self.max_velocity, target))
        step = self.max_acceleration * dt
        return min(previous + step, max(previous - step, clamped))


@dataclass(frozen=True)
class WheelSpeedSettings:
    """Everything the loop needs, under diff_drive_controller's names where they apply."""

    wheel_separation: float
    """m: the distance between the left and right wheels' contact lines (2 b)."""
    wheel_radius: float
    """m."""
    linear: AxisLimits
    angular: AxisLimits
    cmd_vel_timeout: float = 0.5
    """s of simulation time after which the last command counts as zero."""
    kp: float = 0.3
    """N m per rad/s of wheel-speed error. The sampled loop holds each torque for a whole period, so
    too high a gain for the rate oscillates and diverges: with this robot the square diverged from
    kp 0.7 at 50 Hz and 0.3 at 25 Hz (stable at 1.3 at 100 Hz), a limit near 0.012-0.013 N m s/rad
    times the rate in Hz. 0.3 leaves a factor of 2 at the default rate."""
    ki: float = 5.0
    """N m per rad of integrated wheel-speed error."""
    max_wheel_torque: float = 5.0
    """N m per side: the PI output is clamped to it (the dynamics' limit by default)."""


@dataclass(frozen=True)
class SideTorques:
    """The torques to send (N m) and what the loop aimed at, for logs and tests."""

    tau_left: float
    tau_right: float
    linear: float
    """The limited linear velocity command (m/s)."""
    angular: float
    """The limited angular velocity command (rad/s)."""
    saturated: bool
    """Whether a side's torque was clamped to max_wheel_torque."""


def wheel_speeds(linear: float, angular: float, wheel_separation: float, wheel_radius: float) -> tuple[float, float]:
    """(left, right) wheel spin rates (rad/s) of a differential drive moving at (linear, angular)."""
    half = 0.5 * wheel_separation
    return (linear - angular * half) / wheel_radius, (linear + angular * half) / wheel_radius


class WheelSpeedController:
    """cmd_vel in, side torques out, at the instants the caller chooses (simulation time)."""

    def __init__(self, settings: WheelSpeedSettings) -> None:
        self.settings = settings
        self.reset()

    def reset(self) -> None:
        """Forget the command, the limiter's state and the integrals (time went back)."""
        self.target: tuple[float, float] = (0.0, 0.0)
        self.target_time: float | None = None
        self.limited: tuple[float, float] = (0.0, 0.0)
        self.integral = [0.0, 0.0]
        self.last_time: float | None = None
        self.timed_out = False

    def configure(self, settings: WheelSpeedSettings) -> None:
        """New settings from the next update on; the loop's state is kept."""
        self.settings = settings

    def command(self, linear: float, angular: float, t: float) -> None:
        """A velocity command (m/s, rad/s; finite) received at simulation time ``t``."""
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f'velocity command must be finite, got linear {linear!r}, angular {angular!r}')
        self.target, self.target_time, self.timed_out = (float(linear), float(angular)), float(t), False

    def expired(self, t: float) -> bool:
        """Whether at ``t`` the last command is older than cmd_vel_timeout (or there is none)."""
        return self.target_time is None or t - self.target_time > self.settings.cmd_vel_timeout + 1e-12

    def update(self, t: float, measured_left: float, measured_right: float) -> SideTorques:
        """Torques for the state at simulation time ``t`` with the given wheel speeds (rad/s).

        The first update after a reset has no interval: the limiter holds, the integrals stay.
        """
        s = self.settings
        dt = 0.0 if self.last_time is None else max(0.0, t - self.last_time)
        self.last_time = t
        target = (0.0, 0.0) if self.expired(t) else self.target
        self.timed_out = self.target_time is not None and self.expired(t)
        linear = s.linear.limit(target[0], self.limited[0], dt)
        angular = s.angular.limit(target[1], self.limited[1], dt)
        self.limited = (linear, angular)
        wanted = wheel_speeds(linear, angular, s.wheel_separation, s.wheel_radius)
        torques, saturated = [], False
        for side, (goal, measured) in enumerate(zip(wanted, (measured_left, measured_right))):
            error = goal - measured
            integral = self.integral[side] + s.ki * error * dt
            raw = s.kp * error + integral
            clamped = min(s.max_wheel_torque, max(-s.max_wheel_torque, raw))
            if clamped == raw or (raw > clamped) != (error > 0):
                self.integral[side] = integral  # no wind-up while the output is saturated in the error's direction
            torques.append(clamped)
            saturated = saturated or clamped != raw
        return SideTorques(torques[0], torques[1], linear, angular, saturated)
