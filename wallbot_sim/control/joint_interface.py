"""The wheels as ros2_control sees them: four effort-commanded joints over two side motors.

ROS-free; ``joint_bridge_node`` speaks it on ``joint_commands`` / ``joint_states``. The model has one
motor per side whose torque the synchronous belt spreads over the side's front and rear wheel (the
robot applies half of it to each). So the four efforts of a ``joint_commands`` message (N m, one
per wheel joint) become the side torques

    tau_L = effort[wheel_left_front] + effort[wheel_left_rear]
    tau_R = effort[wheel_right_front] + effort[wheel_right_rear]

how a side's total is split between its two wheels does not move the robot while the belt holds
them together (the belt takes up the difference); without the belt the model still applies half of
the side's total to each wheel. A message is refused, with a one-line reason, unless it names each
of the four wheel joints exactly once (any order), carries one finite effort per name, and each
side's total is within the torque limit.
"""

from __future__ import annotations

import math
from typing import Sequence

from wallbot_msgs_py import topics

SIDES = ((topics.WHEEL_JOINTS[0], topics.WHEEL_JOINTS[1]), (topics.WHEEL_JOINTS[2], topics.WHEEL_JOINTS[3]))
"""(left, right) side: the wheel joints each side's motor drives."""


def side_torques(names: Sequence[str], efforts: Sequence[float], max_side_torque: float) -> tuple[float, float]:
    """(tau_L, tau_R) in N m of a joint_commands message; ValueError naming what is wrong."""
    expected = set(topics.WHEEL_JOINTS)
    if len(names) != len(set(names)) or set(names) != expected:
        raise ValueError(f'joint_commands must name each of {", ".join(topics.WHEEL_JOINTS)} once, '
                         f'got [{", ".join(names)}]')
    if len(efforts) != len(names):
        raise ValueError(f'joint_commands has {len(efforts)} efforts for {len(names)} joints')
    by_name = dict(zip(names, (float(e) for e in efforts)))
    bad = [name for name, value in by_name.items() if not math.isfinite(value)]
    if bad:
        raise ValueError(f'joint_commands effort of {", ".join(bad)} is not finite')
    left, right = (by_name[front] + by_name[rear] for front, rear in SIDES)
    for side, total in (('left', left), ('right', right)):
        if abs(total) > max_side_torque:
            raise ValueError(f'joint_commands {side} side total {total:g} N m exceeds +-{max_side_torque:g} N m')
    return left, right
