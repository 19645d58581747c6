"""Non-lateral motion: the centre does not move sideways, v_lat = -sin th xd + cos th yd = 0."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.constraints.base import LATERAL, BaumgarteGains


class NonLateral:
    """Row [-sin th, cos th, 0, ...], b = thd v_long - gam v_lat."""

    name = 'non_lateral'
    direction = LATERAL
    """Held by lateral friction: with coulomb contact, every wheel's lateral contact row (docs/model.md 11.3)."""

    def __init__(self, gains: BaumgarteGains) -> None:
        self.gains = gains
        self._rows_theta, self._rows = math.nan, np.zeros((1, 7))

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = float(q[2])
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        xd, yd, thd = qd[:3].tolist()
        v_long = cos_t * xd + sin_t * yd
        v_lat = -sin_t * xd + cos_t * yd
        return (np.array([[-sin_t, cos_t, 0.0, 0.0, 0.0, 0.0, 0.0]]),
                np.array([thd * v_long - self.gains.velocity_gain * v_lat]))

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        """A (read-only; the last one is kept: coulomb contact asks again at the same heading)."""
        theta = float(q[2])
        if theta != self._rows_theta:
            rows = np.array([[-math.sin(theta), math.cos(theta), 0.0, 0.0, 0.0, 0.0, 0.0]])
            rows.flags.writeable = False
            self._rows_theta, self._rows = theta, rows
        return self._rows

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.velocity_rows(q) @ qd
