"""The control law, free of ROS: a point ahead of the centre follows the figure-8, each side's ground speed follows
what that asks, and gravity along the heading is fed forward.

The robot drives like a unicycle on the wall (its wheels roll, it does not move sideways). A point ``look_ahead``
ahead of the centre can move in any direction: its wanted velocity (the reference's, plus ``point_gain`` times its
error) gives the forward speed and turning rate; each side's speed follows its share by a PI loop on the torque, over
the torque that holds the robot against gravity and rolling resistance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Robot:
    """What the law knows of the robot (its own figures, not the simulator's)."""

    mass: float = 9.0
    """kg, with the wheels."""
    wheel_radius: float = 0.04
    half_track: float = 0.12
    rolling_force: float = 5.7
    """N: rolling resistance at the robot's adhesion force."""
    gravity: float = 9.81


@dataclass(frozen=True)
class Gains:
    look_ahead: float = 0.05
    """m."""
    point_gain: float = 2.0
    """1/s."""
    speed_gain: float = 2.0
    """N m per m/s of a side's speed error."""
    integral_gain: float = 10.0
    """N m per m of a side's integrated speed error."""


def figure_eight(t: float, amplitude: float, period: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """Position and velocity of the figure-8 (A sin wt, A/2 sin 2wt) at time t."""
    w = 2.0 * math.pi / period
    return ((amplitude * math.sin(w * t), 0.5 * amplitude * math.sin(2.0 * w * t)),
            (amplitude * w * math.cos(w * t), amplitude * w * math.cos(2.0 * w * t)))


class FigureEightLaw:
    """Side torques (N m) for each measured state, at a fixed control period."""

    def __init__(self, robot: Robot, gains: Gains, amplitude: float = 1.0, period: float = 30.0) -> None:
        self.robot, self.gains, self.amplitude, self.period = robot, gains, amplitude, period
        self.integrals = [0.0, 0.0]
        self.last_t: float | None = None

    def torques(self, t: float, x: float, y: float, heading: float, forward: float,
                turn: float) -> tuple[float, float]:
        """The side torques (left, right) at time ``t`` for the pose (x, y, heading) and the body speeds."""
        robot, gains = self.robot, self.gains
        (rx, ry), (vx, vy) = figure_eight(t, self.amplitude, self.period)
        speed = math.hypot(vx, vy) or 1.0
        ahead = gains.look_ahead
        # the point's reference: ahead of the reference point along the path, where the point is on the path
        px, py = rx + ahead * vx / speed, ry + ahead * vy / speed
        cos, sin = math.cos(heading), math.sin(heading)
        wx = vx + gains.point_gain * (px - (x + ahead * cos))
        wy = vy + gains.point_gain * (py - (y + ahead * sin))
        wanted_forward, wanted_turn = wx * cos + wy * sin, (-wx * sin + wy * cos) / ahead
        dt = 0.0 if self.last_t is None else max(t - self.last_t, 0.0)
        self.last_t = t
        hold = 0.5 * robot.wheel_radius * (robot.mass * robot.gravity * sin
                                           + math.copysign(robot.rolling_force, wanted_forward))
        torques = []
        for side, sign in enumerate((-1.0, 1.0)):
            error = (wanted_forward + sign * robot.half_track * wanted_turn) - (forward + sign * robot.half_track * turn)
            self.integrals[side] += error * dt
            torques.append(hold + gains.speed_gain * error + gains.integral_gain * self.integrals[side])
        return torques[0], torques[1]
