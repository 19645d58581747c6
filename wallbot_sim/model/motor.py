"""The side motors' torque-speed envelope (docs/model.md 13.2): a command is clipped to what a DC motor can apply.

One DC motor per side, seen at the wheels (after the gear), with a voltage limit and a current limit.
At full voltage its torque falls linearly with speed from the stall torque T_s at rest to 0 at the
no-load speed w_0; reversing the voltage gives the line T_s (-1 - w/w_0). The current limit (the stall
current) bounds |tau| <= T_s. So at the wheels' speed w of the side

    T_s max(-1, -1 - w/w_0) <= tau <= T_s min(1, 1 - w/w_0):

in the driving quadrant (tau along w) |tau| <= T_s (1 - |w|/w_0); braking (tau against w, the
regenerative quadrant) the back EMF helps the current, so the full T_s is available at any speed;
above the no-load speed the motor at full voltage brakes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from wallbot_sim.model.keys import check_block
from wallbot_sim.model.numbers import POSITIVE

_KEYS = ('stall_torque', 'no_load_speed')


@dataclass(frozen=True)
class MotorParameters:
    """The robot file's ``motor`` block: one DC motor per side at the wheels."""

    stall_torque: float
    """T_s, N m per side at zero wheel speed."""
    no_load_speed: float
    """w_0, rad/s of the wheels at zero torque."""

    def __post_init__(self) -> None:
        for name in _KEYS:
            object.__setattr__(self, name, POSITIVE.check(f'motor {name}', getattr(self, name)))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> MotorParameters:
        check_block(values, _KEYS, 'motor')
        return cls(**values)

    def limits(self, speed: float) -> tuple[float, float]:
        """(lowest, highest) torque (N m) the side can apply at the wheels' ``speed`` (rad/s)."""
        ratio = speed / self.no_load_speed
        return self.stall_torque * max(-1.0, -1.0 - ratio), self.stall_torque * min(1.0, 1.0 - ratio)

    def applied(self, command: tuple[float, float], qd: np.ndarray) -> tuple[float, float]:
        """The side torques (tau_L, tau_R) applied for ``command`` at the velocities ``qd``: each clipped to its
        envelope at its side's wheel speed, the mean of its two wheels' (left 1, 2; right 3, 4)."""
        speeds = (0.5 * float(qd[3] + qd[4]), 0.5 * float(qd[5] + qd[6]))
        return tuple(min(max(torque, low), high)  # type: ignore[return-value]
                     for torque, (low, high) in zip(command, map(self.limits, speeds)))
