"""What a constraint module is: rows A_k(q, qd, t) qdd = b_k(q, qd, t).

A wheel-wall contact constraint also says which friction channel each of its rows belongs to
(docs/model.md 11.3: ``left`` and ``right`` traction, ``lateral``), and which wheels' normal loads bound
that row's friction, so a contact model can drop a slipping channel's rows without knowing modules.
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


LEFT, RIGHT, LATERAL = 'left', 'right', 'lateral'
CHANNELS = (LEFT, RIGHT, LATERAL)
"""The friction channels of the wheel-wall contact, in output order."""


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
    """A velocity constraint held by wheel-wall friction: one channel per row."""

    channels: tuple[str, ...]
    """The friction channel (one of CHANNELS) of each row."""
    row_wheels: np.ndarray
    """(rows x 4) 0/1 weights: the normal load bounding a row's friction is row_wheels @ N."""
