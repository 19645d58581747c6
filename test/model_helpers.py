"""Independent computations the model tests compare against (written from docs/model.md, not the code)."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model import RobotParameters


def random_parameters(rng: np.random.Generator, com_offset: bool = True) -> RobotParameters:
    """Plausible random robot parameters, with the body CoM off the centre when asked."""
    values = dict(
        body_mass=rng.uniform(3, 15), wheel_mass=rng.uniform(0.1, 0.5),
        body_yaw_inertia=rng.uniform(0.05, 0.3), wheel_yaw_inertia=rng.uniform(5e-5, 5e-4),
        wheel_spin_inertia=rng.uniform(1e-4, 1e-3), wheel_radius=rng.uniform(0.02, 0.08),
        half_wheelbase=rng.uniform(0.06, 0.2), half_track=rng.uniform(0.06, 0.2),
        com_offset=tuple(rng.uniform(-0.03, 0.03, 2)) if com_offset else (0.0, 0.0),
        com_height=rng.uniform(0.02, 0.08), wall_friction=rng.uniform(0.4, 0.9),
        rolling_resistance=rng.uniform(0.0, 0.05), baumgarte_alpha=rng.uniform(2, 8),
        baumgarte_beta=rng.uniform(2, 8))
    return RobotParameters(**values, kinetic_friction=0.85 * values['wall_friction'])


def wheel_offsets(p: RobotParameters) -> np.ndarray:
    a, b = p.half_wheelbase, p.half_track
    return np.array([[a, b], [-a, b], [a, -b], [-a, -b]])


def rotation(theta: float) -> np.ndarray:
    return np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])


def kinetic_energy(p: RobotParameters, q: np.ndarray, qd: np.ndarray) -> float:
    """T summed body by body: chassis about its own CoM, each wheel translating, yawing, spinning."""
    perp = np.array([[0.0, -1.0], [1.0, 0.0]])
    rot = rotation(q[2])
    v, thd = qd[:2], qd[2]
    body_v = v + thd * rot @ perp @ np.asarray(p.com_offset)
    energy = 0.5 * p.body_mass * body_v @ body_v + 0.5 * p.body_yaw_inertia * thd ** 2
    for i, d in enumerate(wheel_offsets(p)):
        wheel_v = v + thd * rot @ perp @ d
        energy += 0.5 * p.wheel_mass * wheel_v @ wheel_v + 0.5 * p.wheel_yaw_inertia * thd ** 2
        energy += 0.5 * p.wheel_spin_inertia * qd[3 + i] ** 2
    return float(energy)


def potential_energy(p: RobotParameters, q: np.ndarray) -> float:
    """Height of every mass times its weight (the wheels' centres sum to the geometric centre)."""
    body_y = q[1] + (rotation(q[2]) @ np.asarray(p.com_offset))[1]
    return p.gravity * (p.body_mass * body_y + 4.0 * p.wheel_mass * q[1])


def kkt_acceleration(mass: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """qdd from the Lagrange-multiplier system [[M, A^T], [A, 0]] [qdd, -lam] = [Q, b] (least squares)."""
    n, m = mass.shape[0], rows.shape[0]
    kkt = np.block([[mass, rows.T], [rows, np.zeros((m, m))]])
    solution = np.linalg.lstsq(kkt, np.concatenate((force, rhs)), rcond=None)[0]
    return solution[:n]


def udwadia_kalaba_acceleration(mass: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """qdd = a + M^-1/2 (A M^-1/2)+ (b - A a), M^-1/2 from an eigen-decomposition of M."""
    values, vectors = np.linalg.eigh(mass)
    inv_sqrt = vectors @ np.diag(values ** -0.5) @ vectors.T
    free = np.linalg.solve(mass, force)
    return free + inv_sqrt @ np.linalg.pinv(rows @ inv_sqrt) @ (rhs - rows @ free)


def is_consistent(rows: np.ndarray, rhs: np.ndarray) -> bool:
    """Whether A x = b has a solution (rank test)."""
    rank = np.linalg.matrix_rank(rows, tol=1e-9)
    return rank == np.linalg.matrix_rank(np.column_stack((rows, rhs)), tol=1e-9)
