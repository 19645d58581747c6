"""A vacuum chamber's adhesion (docs/model.md 13.3): the pressure difference dp under the chamber is a state.

Isothermal chamber of volume V at the pressure p_atm - dp, evacuated by a pump with a linear curve
and filled by the leak through the gap under its skirt (and the seams under it):

    d(dp)/dt = (p_atm / V) (Q_pump(dp) u - Q_leak(dp)),
    Q_pump = Q_max max(0, 1 - dp / P_max),   Q_leak = C_d A_gap sqrt(2 dp / rho_air),

u in [0, 1] the pump command, A_gap = leak_area plus the seams' area under the chamber (a disc of
``chamber_area`` about the robot's centre). The chamber pulls the robot to the wall with
F_ad = dp ``chamber_area``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from wallbot_sim.model.integrator import Derivative, rk4_step
from wallbot_sim.model.keys import check_block
from wallbot_sim.model.numbers import NON_NEGATIVE, POSITIVE, NumberRange
from wallbot_sim.model.world import World

ATMOSPHERE = 101325.0
"""p_atm (Pa)."""
AIR_DENSITY = 1.204
"""rho_air (kg/m^3, 20 degrees C)."""
DISCHARGE_COEFFICIENT = 0.61
"""C_d of a sharp-edged gap."""
PUMP_COMMAND = NumberRange(0.0, 1.0)
_KEYS = ('chamber_area', 'chamber_volume', 'pump_max_pressure', 'pump_max_flow', 'leak_area')


@dataclass(frozen=True)
class VacuumParameters:
    """The robot file's ``adhesion`` block: a vacuum chamber instead of the constant adhesion force."""

    chamber_area: float
    """m^2: F_ad = dp x area; the chamber is a disc of this area about the centre."""
    chamber_volume: float
    """V, m^3."""
    pump_max_pressure: float
    """P_max, Pa at zero flow."""
    pump_max_flow: float
    """Q_max, m^3/s at zero pressure difference."""
    leak_area: float
    """m^2 of gap under the skirt on a smooth wall."""

    def __post_init__(self) -> None:
        for name in _KEYS:
            allowed = NON_NEGATIVE if name == 'leak_area' else POSITIVE
            object.__setattr__(self, name, allowed.check(f'adhesion {name}', getattr(self, name)))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> VacuumParameters:
        check_block(values, _KEYS, 'adhesion')
        return cls(**values)

    @property
    def chamber_radius(self) -> float:
        """The radius of the chamber's disc (m)."""
        return math.sqrt(self.chamber_area / math.pi)

    def rate(self, pressure: float, gap_area: float, command: float) -> float:
        """d(dp)/dt (Pa/s) at the pressure difference ``pressure`` through the gap ``gap_area`` (m^2)."""
        pumped = self.pump_max_flow * max(0.0, 1.0 - pressure / self.pump_max_pressure) * command
        leaked = DISCHARGE_COEFFICIENT * gap_area * math.sqrt(2.0 * max(pressure, 0.0) / AIR_DENSITY)
        return ATMOSPHERE / self.chamber_volume * (pumped - leaked)

    def steady_pressure(self, gap_area: float, command: float) -> float:
        """The dp (Pa) at which pump and leak balance: with s = sqrt(dp), (Q u / P) s^2 + k s - Q u = 0,
        k = C_d A_gap sqrt(2 / rho)."""
        flow = self.pump_max_flow * command
        if flow == 0.0:
            return 0.0
        gain = DISCHARGE_COEFFICIENT * gap_area * math.sqrt(2.0 / AIR_DENSITY)
        curve = flow / self.pump_max_pressure
        root = 2.0 * flow / (gain + math.sqrt(gain * gain + 4.0 * curve * flow))  # the positive root, stably
        return root * root


class Chamber:
    """The chamber of ``params`` on the surface ``world``: its rate and steady state where the robot's centre is."""

    def __init__(self, params: VacuumParameters, world: World) -> None:
        self.params, self.world = params, world

    def gap_area(self, centre: np.ndarray) -> float:
        """A_gap (m^2): the skirt's leak and the seams' area under the chamber's disc about ``centre``."""
        return self.params.leak_area + self.world.seam_area(centre, self.params.chamber_radius)

    def rate(self, pressure: float, centre: np.ndarray, command: float) -> float:
        """d(dp)/dt (Pa/s) with the robot's centre at ``centre``."""
        return self.params.rate(pressure, self.gap_area(centre), command)

    def steady_pressure(self, centre: np.ndarray, command: float) -> float:
        """The balanced dp (Pa) with the robot's centre at ``centre``."""
        return self.params.steady_pressure(self.gap_area(centre), command)

    def step(self, derivative: Derivative, t: float, y: np.ndarray, pressure: float, dt: float, command: float,
             k1: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """One RK4 step of the robot's state y (``derivative``, under the F_ad held from the boundary) and dp
        together: dp's rate at each stage's centre (the seams under it). ``k1``: the robot's derivative at (t, y)."""
        def joint(time: float, state: np.ndarray) -> np.ndarray:
            return np.append(derivative(time, state[:-1]), self.rate(float(state[-1]), state[:2], command))
        first = None if k1 is None else np.append(k1, self.rate(pressure, y[:2], command))
        end = rk4_step(joint, t, np.append(y, pressure), dt, first)
        return end[:-1], float(end[-1])
