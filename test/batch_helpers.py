"""What the batch agreement tests share: its engines, the agreement asked, random robots and starts, and the
minimum-norm motion by numpy's least squares the kernel's solves are held to."""

from __future__ import annotations

import numpy as np
import pytest

from model_helpers import random_parameters
from wallbot_sim.model import Robot
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.robot import DOF

ENGINES = ['numpy', pytest.param('numba', marks=pytest.mark.skipif(not kernel.available(),
                                                                  reason='numba is not installed'))]
"""The batch's engines, each held to the same agreement."""
TOLERANCE = 1e-9
"""Relative agreement asked of the batch, states and forces, robot by robot."""


def random_robots(rng: np.random.Generator, count: int) -> list[Robot]:
    """Robots of random parameters (CoM off the centre), half with an adhesion force of their own."""
    robots = []
    for i in range(count):
        params = random_parameters(rng)
        if i % 2:
            params = params.replace(adhesion_force=float(rng.uniform(1.0, 3.0)) * params.gravity * 10.0)
        robots.append(Robot(params))
    return robots


def perturbed_starts(rng: np.random.Generator, robots: list[Robot], scenario) -> tuple[np.ndarray, np.ndarray]:
    """Each robot at the scenario's start, moved and set moving a little differently."""
    states = [scenario.initial_state(robot) for robot in robots]
    q0 = np.array([q for q, _ in states]) + rng.normal(0.0, [0.02, 0.02, 0.1, 0.5, 0.5, 0.5, 0.5], (len(robots), DOF))
    qd0 = np.array([qd for _, qd in states]) + rng.normal(0.0, [0.02, 0.02, 0.1, 0.5, 0.5, 0.5, 0.5],
                                                            (len(robots), DOF))
    return q0, qd0


def assert_agree(name: str, batch_values: np.ndarray, single_values: np.ndarray, floor: float = 0.0) -> None:
    """|batch - single| within TOLERANCE of the single robot's largest magnitude of that quantity, or of ``floor`` in
    its unit where that is larger (a quantity that is round-off, such as a sticking wheel's slip velocity)."""
    scale = max(float(np.max(np.abs(single_values))), floor)
    error = np.max(np.abs(batch_values - single_values))
    assert error <= TOLERANCE * scale, f'{name}: batch differs by {error:.3g}, {error / scale:.3g} relative'


def minimum_norm_motion(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """qdd = W (s + B+ (b - B s)), s = W^T Q, B = A W, by numpy's least squares (SVD)."""
    scaled = factor.T @ force
    matrix = rows @ factor
    return factor @ (scaled + np.linalg.lstsq(matrix, rhs - matrix @ scaled, rcond=None)[0])
