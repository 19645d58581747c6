"""Classical fourth-order Runge-Kutta with a fixed step."""

from __future__ import annotations

from typing import Callable

import numpy as np

Derivative = Callable[[float, np.ndarray], np.ndarray]


def rk4_step(derivative: Derivative, t: float, y: np.ndarray, dt: float,
             k1: np.ndarray | None = None) -> np.ndarray:
    """y(t + dt) by one RK4 step; ``k1`` = derivative(t, y) when the caller already has it."""
    if k1 is None:
        k1 = derivative(t, y)
    half = 0.5 * dt
    k2 = derivative(t + half, y + half * k1)
    k3 = derivative(t + half, y + half * k2)
    k4 = derivative(t + dt, y + dt * k3)
    return y + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
