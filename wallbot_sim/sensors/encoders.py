"""Incremental wheel encoders (``sensors.encoders``): each wheel's angle known to one count.

An encoder of N counts per revolution reports the whole counts the wheel has turned since the start, so the angle
read is floor(phi N / 2 pi) 2 pi / N (rounding towards minus infinity, as a counter that counts down does). The
speed is the count's change over the time since the previous sample (0 at the first sample, and after the time
went back: a reset).
"""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.sensors import EncoderParameters


def quantized(angles: np.ndarray, counts_per_rev: int) -> np.ndarray:
    """The angles (rad) an encoder of ``counts_per_rev`` reads for the wheel ``angles``."""
    step = 2.0 * math.pi / counts_per_rev
    return np.floor(angles / step) * step


class Encoders:
    """The four wheels' encoders of ``params``."""

    def __init__(self, params: EncoderParameters) -> None:
        self.params = params
        self._previous: tuple[float, np.ndarray] | None = None

    def measure(self, t: float, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(angles, speeds) read at time ``t`` (s) of the wheel ``angles`` (rad)."""
        read = quantized(np.asarray(angles, dtype=float), self.params.counts_per_rev)
        previous, self._previous = self._previous, (t, read)
        if previous is None or t <= previous[0]:
            return read, np.zeros_like(read)
        return read, (read - previous[1]) / (t - previous[0])
