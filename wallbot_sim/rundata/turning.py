"""What a skid-steer turn in place costs the side motors from rest (docs/model.md 11.5), with gravity.

At rest at heading th nothing moves, so nothing resists but friction (no rolling resistance, no spin).
The loads are those of docs/model.md 11.1 at rest,

    N_i = F/4 - h m_t g (sin th x_i / (4 a^2) + cos th y_i / (4 b^2)),

and the wheels' forces f_i (body axes) hold the robot against its weight, m_t g (-sin th, -cos th).
Side torques tau_L = tau_0 - T, tau_R = tau_0 + T: each wheel's torque balance makes its side's
traction tau_side / r, which the belt shares between the side's wheels by load, f_xi = tau_side N_i /
(r N_side). Holding the robot along its heading takes tau_0 = r m_t g sin th / 2 on each side; T
turns it. What the tractions leave to the lateral forces, sum f_yi = m_t g cos th and, about the
centre, sum x_i f_yi = m_b g (c_x cos th - c_y sin th) - 2 b T / r (the body weight's moment with the
CoM offset c, and the turn's, b (F_R - F_L) = 2 b T / r), is shared by the load-weighted least-norm
split of docs/model.md 11.2: f_yi = N_i (lambda + x_i mu). So each wheel's force is affine in T,
f_i = p_i + T q_i; wheel i leaves its friction disc where |p_i + T q_i| = mu_s N_i, a root of a
quadratic, and the least such |T| over the wheels is the threshold T*(th) of a turn that way. The
side whose motor pushes against the holding torque then delivers |tau_0| + T*.

With gravity negligible every N_i = F/4, tau_0 = 0 and all four wheels reach their discs together:
T* = mu_s F r / (2 sqrt(1 + (b/a)^2)) (docs/model.md 11.4). With gravity the holding forces use part
of every disc, and the worst heading (the largest side torque) is found over all headings and both
turning directions.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from wallbot_sim.model import Robot, RobotParameters

HEADING_GRID = 720
"""Headings tried over a full turn before the worst is refined (every half degree)."""
REFINEMENTS = 3
"""Grids tried: the full turn, then twice one fifty times finer around the largest side torque."""
REFINED = 50
"""Points on each side of the largest of a grid in the next, finer one."""
LEFT, RIGHT = 'left', 'right'
"""Turning directions: left (anticlockwise, the right side pushing forward), right."""


class TurnThresholds(NamedTuple):
    """At each of some headings (rad): the holding torque and the turn's threshold either way, from rest."""

    heading: np.ndarray
    hold_torque: np.ndarray
    """tau_0 = r m_t g sin th / 2 on each side (N m)."""
    left: np.ndarray
    """T* of a turn to the left (N m): side torques tau_0 -+ T* (left, right); NaN where the robot cannot
    hold still (a wheel off the wall, or a disc already full)."""
    right: np.ndarray
    """T* of a turn to the right, side torques tau_0 +- T* (N m); NaN as ``left``."""


class TurnStart(NamedTuple):
    """The worst heading to start a turn in place from rest: the side torque it takes there."""

    heading: float
    """rad, from the wall's X axis."""
    direction: str
    """LEFT or RIGHT."""
    hold_torque: float
    """tau_0 at that heading (N m per side)."""
    turn_torque: float
    """T* at that heading and direction (N m)."""

    @property
    def side_torque(self) -> float:
        """|tau_0| + T*: what the side pushing against the holding torque delivers (N m)."""
        return abs(self.hold_torque) + self.turn_torque


def flat_turn_threshold(params: RobotParameters, adhesion: float) -> float:
    """T* = mu_s F r / (2 sqrt(1 + (b/a)^2)) with in-plane gravity negligible (N m)."""
    ratio = params.half_track / params.half_wheelbase
    return params.wall_friction * adhesion * params.wheel_radius / (2.0 * math.sqrt(1.0 + ratio * ratio))


def turn_thresholds(params: RobotParameters, adhesion: float, headings: np.ndarray) -> TurnThresholds:
    """The thresholds of a turn in place from rest at ``headings`` (H,), adhesion force ``adhesion`` (N)."""
    robot = Robot(params.replace(adhesion_force=adhesion))
    headings = np.asarray(headings, dtype=float)
    g, r, h = params.gravity, params.wheel_radius, params.com_height
    a, b = params.half_wheelbase, params.half_track
    weight = robot.total_mass * g
    along, across = robot.wheel_offsets[:, 0], robot.wheel_offsets[:, 1]
    sin_t, cos_t = np.sin(headings)[:, None], np.cos(headings)[:, None]
    loads = adhesion / 4.0 - h * weight * (sin_t * along / (4.0 * a * a) + cos_t * across / (4.0 * b * b))
    left = across > 0.0
    side_loads = np.where(left, loads[:, left].sum(axis=1, keepdims=True), loads[:, ~left].sum(axis=1, keepdims=True))
    share = loads / side_loads  # each wheel's part of its side's traction
    hold_traction = 0.5 * weight * sin_t  # each side's, tau_0 / r
    turn_traction = np.where(left, -1.0, 1.0) / r  # per unit T
    total, first, second = loads.sum(axis=1), loads @ along, loads @ (along * along)
    spread = total * second - first * first

    def lateral(force: np.ndarray, moment: np.ndarray) -> np.ndarray:
        """f_yi = N_i (lambda + x_i mu) with sum f_yi = force, sum x_i f_yi = moment."""
        lam = (second * force - first * moment) / spread
        mu = (total * moment - first * force) / spread
        return loads * (lam[:, None] + mu[:, None] * along)

    c_x, c_y = params.com_offset
    body_moment = params.body_mass * g * (c_x * np.cos(headings) - c_y * np.sin(headings))
    hold = np.stack((share * hold_traction, lateral(weight * np.cos(headings), body_moment)), axis=2)
    turn = np.stack((share * turn_traction, lateral(np.zeros_like(headings), np.full_like(headings, -2.0 * b / r))),
                    axis=2)
    quadratic = np.sum(turn * turn, axis=2)
    linear = np.sum(hold * turn, axis=2)
    constant = np.sum(hold * hold, axis=2) - (params.wall_friction * loads) ** 2
    holds = np.all(loads > 0.0, axis=1) & np.all(constant < 0.0, axis=1)
    root = np.sqrt(np.maximum(linear * linear - quadratic * constant, 0.0))
    with np.errstate(divide='ignore', invalid='ignore'):
        to_left = np.where(quadratic > 0.0, (root - linear) / quadratic, np.inf).min(axis=1)
        to_right = np.where(quadratic > 0.0, (root + linear) / quadratic, np.inf).min(axis=1)
    return TurnThresholds(headings, 0.5 * r * weight * np.sin(headings), np.where(holds, to_left, np.nan),
                          np.where(holds, to_right, np.nan))


def worst_turn_start(params: RobotParameters, adhesion: float) -> TurnStart | None:
    """The heading and direction whose turn in place takes the largest side torque to start; None when the robot
    cannot hold still at some heading (it would slide or peel off before any turn).

    Every half degree, then on grids fifty times finer around the largest: the side torque is continuous in
    the heading, with kinks where the wheel that leaves its disc first changes.
    """
    step = 2.0 * math.pi / HEADING_GRID
    grid = turn_thresholds(params, adhesion, np.arange(HEADING_GRID) * step)
    if np.isnan(grid.left).any():
        return None
    starts = []
    for direction in (LEFT, RIGHT):
        at, width = grid, step
        for _ in range(REFINEMENTS - 1):
            at = turn_thresholds(params, adhesion, at.heading[_largest(at, direction)]
                                 + (width / REFINED) * np.arange(-REFINED, REFINED + 1))
            width /= REFINED
        k = _largest(at, direction)
        starts.append(TurnStart(float(at.heading[k] % (2.0 * math.pi)), direction, float(at.hold_torque[k]),
                                float(_threshold(at, direction)[k])))
    return max(starts, key=lambda start: start.side_torque)


def _threshold(at: TurnThresholds, direction: str) -> np.ndarray:
    return at.left if direction == LEFT else at.right


def _largest(at: TurnThresholds, direction: str) -> int:
    """The index of the largest side torque |tau_0| + T* of a turn that way."""
    return int(np.argmax(np.abs(at.hold_torque) + _threshold(at, direction)))
