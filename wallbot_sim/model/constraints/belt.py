"""The synchronous toothed belt: front and rear wheel of a side spin together.

Written on the wheel spins (pd1 = pd2, pd3 = pd4), not on the axle speeds as in the paper:
docs/model.md section 9 says why.
"""

from __future__ import annotations

import numpy as np

from wallbot_sim.model.constraints.base import BaumgarteGains

_ROWS = np.array([[0.0, 0.0, 0.0, 1.0, -1.0, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, -1.0]])


class SynchronousBelt:
    """pdd1 - pdd2 = -gam (pd1 - pd2) and pdd3 - pdd4 = -gam (pd3 - pd4)."""

    name = 'belt'

    def __init__(self, gains: BaumgarteGains) -> None:
        self.gains = gains

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _ROWS, -self.gains.velocity_gain * self.violation(q, qd)

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        return _ROWS

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return np.array([qd[3] - qd[4], qd[5] - qd[6]])
