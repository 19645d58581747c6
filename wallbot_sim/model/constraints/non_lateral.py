"""Non-lateral motion: the centre does not move sideways, v_lat = -sin th xd + cos th yd = 0."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.constraints.base import BaumgarteGains


class NonLateral:
    """Row [-sin th, cos th, 0, ...], b = thd v_long - gam v_lat."""

    name = 'non_lateral'

    def __init__(self, gains: BaumgarteGains) -> None:
        self.gains = gains

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
        v_long = cos_t * qd[0] + sin_t * qd[1]
        v_lat = -sin_t * qd[0] + cos_t * qd[1]
        return (np.array([[-sin_t, cos_t, 0.0, 0.0, 0.0, 0.0, 0.0]]),
                np.array([qd[2] * v_long - self.gains.velocity_gain * v_lat]))

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        return np.array([[-math.sin(q[2]), math.cos(q[2]), 0.0, 0.0, 0.0, 0.0, 0.0]])

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.velocity_rows(q) @ qd
