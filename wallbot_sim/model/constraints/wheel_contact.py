"""Wheel contact rows: the contact points of some wheels do not move on the wall (coulomb contact's sticking wheels).

Each row is one direction of one wheel's contact velocity v_i = J_i(th) qd (``contact_kinematics``),
held at zero with the Baumgarte term of the nonholonomic modules: J_i qdd = -c_i - gam v_i.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model.constraints.base import BaumgarteGains
from wallbot_sim.model.contact_kinematics import ContactKinematics


class WheelContact:
    """The contact rows of ``wheels`` (0..3) in ``directions`` (rows of v_i: 0 along x_p, 1 along y_p), wheel by wheel."""

    name = 'wheel_contact'

    def __init__(self, kinematics: ContactKinematics, gains: BaumgarteGains, wheels: Sequence[int],
                 directions: Sequence[int]) -> None:
        self.kinematics = kinematics
        self.gains = gains
        self.wheels = tuple(wheels)
        self.directions = tuple(directions)
        self._wheel_index = np.repeat(np.array(self.wheels, dtype=int), len(self.directions))
        self._direction_index = np.tile(np.array(self.directions, dtype=int), len(self.wheels))

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        """J of the rows (k x 7)."""
        return self.kinematics.jacobian(float(q[2]))[self._wheel_index, self._direction_index]

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.velocity_rows(q) @ qd

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rows = self.velocity_rows(q)
        drift = self.kinematics.drift(q, qd)[self._direction_index]
        return rows, -drift - self.gains.velocity_gain * (rows @ qd)
