"""What a constraint module is: rows A_k(q, qd, t) qdd = b_k(q, qd, t).

A wheel-wall contact constraint also says which direction of the wheels' contact velocity its
friction holds (docs/model.md 11.3: ``longitudinal`` for nonslip, ``lateral`` for non-lateral motion),
so that coulomb contact can put each wheel's own contact rows in its place without knowing modules.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from wallbot_sim.model.numbers import POSITIVE


@dataclass(frozen=True)
class BaumgarteGains:
    """Baumgarte stabilization gains alpha and beta (1/s)."""

    alpha: float = 5.0
    beta: float = 5.0

    def __post_init__(self) -> None:
        for name in ('alpha', 'beta'):
            POSITIVE.check(f'baumgarte_{name}', getattr(self, name))

    @property
    def velocity_gain(self) -> float:
        """gam = 2 alpha, the gain on velocity-level violations."""
        return 2.0 * self.alpha


@runtime_checkable
class ConstraintModule(Protocol):
    """One constraint of the robot: its rows of A qdd = b at a state."""

    name: str

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A_k (k x 7) and b_k (k,) at time t and state (q, qd)."""
        ...


LONGITUDINAL, LATERAL = 'longitudinal', 'lateral'
WHEEL_DIRECTIONS = (LONGITUDINAL, LATERAL)
"""The directions of a wheel's contact velocity, along the body axes x_p and y_p, in the order of its rows."""
LEFT, RIGHT = 'left', 'right'
CHANNELS = (LEFT, RIGHT, LATERAL)
"""The paper's force channels (docs/model.md 8: left and right traction, lateral force), in output order."""


@runtime_checkable
class VelocityConstraint(Protocol):
    """A constraint on velocities, A_v(q) qd = 0 (nonholonomic or a belt)."""

    name: str

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        """A_v (k x 7) such that the constraint is A_v qd = 0."""
        ...

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """A_v qd: how far the velocities are from satisfying the constraint."""
        ...


@runtime_checkable
class ContactConstraint(VelocityConstraint, Protocol):
    """A velocity constraint held by wheel-wall friction in one direction of the wheels' contact velocity."""

    direction: str
    """LONGITUDINAL or LATERAL: with coulomb contact the constraint is every wheel's contact row in that direction."""
