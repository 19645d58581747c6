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
_HEADINGS = np.arange(HEADING_GRID) * (2.0 * math.pi / HEADING_GRID)
_GRID = (_HEADINGS, np.sin(_HEADINGS), np.cos(_HEADINGS))
"""The first grid's headings, their sines and cosines."""


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
    headings = np.asarray(headings, dtype=float)
    return _TurnModel(params, adhesion).thresholds(headings, np.sin(headings), np.cos(headings))


class _TurnModel:
    """What the thresholds of one robot with one adhesion force take, whatever the heading."""

    def __init__(self, params: RobotParameters, adhesion: float) -> None:
        robot = Robot(params)  # its mass and wheels: the same whatever its adhesion force
        self.params, self.adhesion = params, adhesion
        self.weight = robot.total_mass * params.gravity
        self.along, self.across = robot.wheel_offsets[:, 0, None], robot.wheel_offsets[:, 1, None]
        self.left = self.across > 0.0
        self.square = self.along * self.along
        self.turn_traction = np.where(self.left, -1.0, 1.0) / params.wheel_radius  # per unit T

    def thresholds(self, headings: np.ndarray, sin_h: np.ndarray, cos_h: np.ndarray) -> TurnThresholds:
        """``turn_thresholds`` at ``headings`` (H,), whose sines and cosines are ``sin_h``, ``cos_h``; the arrays
        of the wheels' values are (4, H), each wheel's in a row."""
        params = self.params
        g, r, h = params.gravity, params.wheel_radius, params.com_height
        a, b = params.half_wheelbase, params.half_track
        weight, along, across, left = self.weight, self.along, self.across, self.left
        loads = self.adhesion / 4.0 - h * weight * (sin_h * along / (4.0 * a * a) + cos_h * across / (4.0 * b * b))
        side_load = (loads[left[:, 0]].sum(axis=0), loads[~left[:, 0]].sum(axis=0))
        share = loads / np.where(left, *side_load)  # each wheel's part of its side's traction
        total, first, second = loads.sum(axis=0), _sum(loads * along), _sum(loads * self.square)
        spread = total * second - first * first

        def lateral(force: np.ndarray | float, moment: np.ndarray | float) -> np.ndarray:
            """f_yi = N_i (lambda + x_i mu) with sum f_yi = force, sum x_i f_yi = moment."""
            lam = (second * force - first * moment) / spread
            mu = (total * moment - first * force) / spread
            return loads * (lam + mu * along)

        c_x, c_y = params.com_offset
        hold_along = share * (0.5 * weight * sin_h)  # each side's traction holding the robot, tau_0 / r
        hold_across = lateral(weight * cos_h, params.body_mass * g * (c_x * cos_h - c_y * sin_h))
        turn_along = share * self.turn_traction
        turn_across = lateral(0.0, -2.0 * b / r)
        quadratic = turn_along * turn_along + turn_across * turn_across
        linear = hold_along * turn_along + hold_across * turn_across
        limit = params.wall_friction * loads
        constant = hold_along * hold_along + hold_across * hold_across - limit * limit
        holds = np.all((loads > 0.0) & (constant < 0.0), axis=0)
        root = np.sqrt(np.maximum(linear * linear - quadratic * constant, 0.0))
        with np.errstate(divide='ignore', invalid='ignore'):
            turns = quadratic > 0.0
            to_left = np.where(turns, (root - linear) / quadratic, np.inf).min(axis=0)
            to_right = np.where(turns, (root + linear) / quadratic, np.inf).min(axis=0)
        return TurnThresholds(headings, 0.5 * r * weight * sin_h, np.where(holds, to_left, np.nan),
                              np.where(holds, to_right, np.nan))


def worst_turn_start(params: RobotParameters, adhesion: float) -> TurnStart | None:
    """The heading and direction whose turn in place takes the largest side torque to start; None when the robot
    cannot hold still at some heading (it would slide or peel off before any turn).

    Every half degree, then on grids fifty times finer around the largest: the side torque is continuous in
    the heading, with kinks where the wheel that leaves its disc first changes.
    """
    model = _TurnModel(params, adhesion)
    grid = model.thresholds(*_GRID)
    if np.isnan(grid.left).any():
        return None
    directions = (LEFT, RIGHT)
    grids = [grid, grid]
    centres = [grid.heading[_largest(grid, direction)] for direction in directions]
    width = 2.0 * math.pi / HEADING_GRID
    points = 2 * REFINED + 1
    for _ in range(REFINEMENTS - 1):  # both directions' finer grids at once
        offsets = (width / REFINED) * np.arange(-REFINED, REFINED + 1)
        headings = np.concatenate([centre + offsets for centre in centres])
        both = model.thresholds(headings, np.sin(headings), np.cos(headings))
        grids = [TurnThresholds(*(values[k * points:(k + 1) * points] for values in both)) for k in range(2)]
        centres = [at.heading[_largest(at, direction)] for at, direction in zip(grids, directions)]
        width /= REFINED
    starts = []
    for at, direction in zip(grids, directions):
        k = _largest(at, direction)
        starts.append(TurnStart(float(at.heading[k] % (2.0 * math.pi)), direction, float(at.hold_torque[k]),
                                float(_threshold(at, direction)[k])))
    return max(starts, key=lambda start: start.side_torque)


def _threshold(at: TurnThresholds, direction: str) -> np.ndarray:
    return at.left if direction == LEFT else at.right


def _largest(at: TurnThresholds, direction: str) -> int:
    """The index of the largest side torque |tau_0| + T* of a turn that way."""
    return int(np.argmax(np.abs(at.hold_torque) + _threshold(at, direction)))


def _sum(values: np.ndarray) -> np.ndarray:
    """The sum over the wheels (H,) of values (4, H): (front + front) + (rear + rear), the order BLAS adds a product
    (H, 4) @ (4,) in, so that the thresholds are those of either layout to the bit."""
    return (values[0] + values[2]) + (values[1] + values[3])
