"""Friction use of the paper's three force channels (docs/model.md 11.2).

The channel forces are the drive forces of section 8 (with coulomb contact, the sums of the wheels'
forces); each is set against mu_s times the load bounding it: left and right traction their side's
load, lateral the sum of the loads (F_ad on a vertical wall). The wheels' own use is ``wheel_forces.wheel_use``.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np


class FrictionUse(NamedTuple):
    """|force| / (mu_s N) per channel, in the order of CHANNELS: above 1 the channel would slip."""

    left: float
    right: float
    lateral: float


def channel_loads(loads: np.ndarray, wall_load: float) -> tuple[float, float, float]:
    """The normal load bounding each channel: N_1 + N_2, N_3 + N_4, and ``wall_load``, F_ad + m_t g cos i (N)."""
    return float(loads[0] + loads[1]), float(loads[2] + loads[3]), wall_load


def friction_use(forces: Sequence[float], loads: np.ndarray, wall_load: float,
                 static_friction: float) -> FrictionUse:
    """u_L = |F_L| / (mu_s N_L), u_R = |F_R| / (mu_s N_R), u_lat = |F_lat| / (mu_s (F_ad + m_t g cos i)).

    ``forces``: the channel forces (F_L, F_R, F_lat).

    A channel whose load is not positive can transmit nothing: its use is infinite unless its force is 0.
    """
    return FrictionUse(*(_ratio(abs(force), static_friction * load)
                         for force, load in zip(forces, channel_loads(loads, wall_load))))


def _ratio(force: float, limit: float) -> float:
    if limit > 0.0:
        return float(force / limit)
    return 0.0 if force == 0.0 else math.inf
