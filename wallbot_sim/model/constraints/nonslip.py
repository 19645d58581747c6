"""Nonslip: every wheel rolls on the wall, h_i = r pd_i - v_long + s_i thd = 0."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from wallbot_sim.model.constraints.base import LONGITUDINAL, BaumgarteGains


class Nonslip:
    """One row per wheel: [-cos th, -sin th, s_i, r at column 3+i], b = thd v_lat - gam h_i."""

    name = 'nonslip'
    direction = LONGITUDINAL
    """Held by longitudinal friction: with coulomb contact, every wheel's longitudinal contact row."""

    def __init__(self, wheel_radius: float, lateral_offsets: Sequence[float], gains: BaumgarteGains) -> None:
        self.gains = gains
        self._template = np.zeros((4, 7))
        self._template[:, 2] = lateral_offsets
        self._template[:, 3:] = wheel_radius * np.eye(4)
        self._rows_theta, self._rows = math.nan, self._template

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        """A (read-only; the last one is kept: coulomb contact asks again at the same heading)."""
        theta = float(q[2])
        if theta != self._rows_theta:
            rows = self._template.copy()
            rows[:, :2] = (-math.cos(theta), -math.sin(theta))
            rows.flags.writeable = False
            self._rows_theta, self._rows = theta, rows
        return self._rows

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.velocity_rows(q) @ qd

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = float(q[2])
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        rows = self._template.copy()
        rows[:, :2] = (-cos_t, -sin_t)
        xd, yd, thd = qd[:3].tolist()
        v_lat = -sin_t * xd + cos_t * yd
        return rows, thd * v_lat - self.gains.velocity_gain * (rows @ qd)
