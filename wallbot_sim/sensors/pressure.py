"""A pressure sensor in the vacuum chamber (``sensors.pressure``): the chamber's absolute pressure.

The chamber is dp below the atmosphere (docs/model.md 13.3), so the sensor reads p_atm - dp plus its constant
``bias`` and Gaussian noise of standard deviation ``noise`` (Pa), drawn from a generator seeded with ``seed``.
"""

from __future__ import annotations

import numpy as np

from wallbot_sim.model.sensors import PressureParameters
from wallbot_sim.model.vacuum import ATMOSPHERE


class PressureSensor:
    def __init__(self, params: PressureParameters) -> None:
        self.params = params
        self._rng = np.random.default_rng(params.seed)

    def measure(self, pressure_difference: float) -> float:
        """The absolute pressure (Pa) read in a chamber ``pressure_difference`` (Pa) below the atmosphere."""
        params = self.params
        return ATMOSPHERE - pressure_difference + params.bias + params.noise * float(self._rng.standard_normal())
