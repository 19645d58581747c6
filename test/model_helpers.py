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


def least_norm_loads(p: RobotParameters, adhesion: float, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                     moment_less: np.ndarray = np.zeros(2)) -> np.ndarray:
    """11.1 solved as stated: the CoM acceleration, the inertial-gravity force in the body frame, then the
    minimum-norm solution of the 3 x 4 balance by numpy's lstsq; ``moment_less`` (2,) is taken from the two moment
    rows h F_bx, h F_by (the wheels' spin momentum rate)."""
    m_t = p.body_mass + 4 * p.wheel_mass
    perp = np.array([[0.0, -1.0], [1.0, 0.0]])
    c = np.asarray(p.com_offset) * p.body_mass / m_t  # whole-robot CoM from the centre
    rot = rotation(q[2])
    com_acceleration = qdd[:2] + qdd[2] * rot @ perp @ c - qd[2] ** 2 * rot @ c
    body_force = rot.T @ (m_t * (np.array([0.0, -p.gravity]) - com_acceleration))
    d = wheel_offsets(p)
    system = np.vstack((np.ones(4), d[:, 0], d[:, 1]))
    rhs = np.array([adhesion, p.com_height * body_force[0] - moment_less[0],
                    p.com_height * body_force[1] - moment_less[1]])
    return np.linalg.lstsq(system, rhs, rcond=None)[0]


def contact_velocity(p: RobotParameters, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """(4, 2): each wheel's contact point on the wall, body axes: the chassis point d_i moving with the centre and
    the yaw, less the wheel's rolling r pd_i along x_p (a wheel spinning forward at pd pushes its contact point back)."""
    rot = rotation(q[2])
    velocities = np.zeros((4, 2))
    for i, d in enumerate(wheel_offsets(p)):
        point = qd[:2] + qd[2] * rot @ np.array([-d[1], d[0]])  # wall frame
        velocities[i] = rot.T @ point - np.array([p.wheel_radius * qd[3 + i], 0.0])
    return velocities


def contact_jacobian(p: RobotParameters, q: np.ndarray) -> np.ndarray:
    """(4, 2, 7): contact_velocity's derivative by qd, column by column."""
    return np.stack([contact_velocity(p, q, unit) for unit in np.eye(7)], axis=-1)
