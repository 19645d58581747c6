"""The Udwadia-Phohomsiri problem of a robot under a list of constraint modules: the applied force Q and the
rows A qdd = b stacked in the modules' order, its solution, and the impulse of a switch to new velocity rows."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model.constraints import ConstraintModule, VelocityConstraint, WheelContact
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.solver import ConstrainedMotion, solve_with_factor


def stack_problem(robot: Robot, modules: Sequence[ConstraintModule], t: float, q: np.ndarray, qd: np.ndarray,
                  motor_torque: tuple[float, float] = (0.0, 0.0),
                  loads: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q and the rows A, b of ``modules`` stacked in order, at (t, q, qd) (``loads``: ``Robot.applied_force``'s)."""
    force = robot.applied_force(q, qd, motor_torque, loads)
    if not modules:
        return force, np.empty((0, DOF)), np.empty(0)
    parts = [module.rows(t, q, qd) for module in modules]
    return force, np.concatenate([part[0] for part in parts]), np.concatenate([part[1] for part in parts])


def impulsive_projection(robot: Robot, modules: Sequence[ConstraintModule], q: np.ndarray,
                         qd: np.ndarray) -> np.ndarray:
    """qd+ = qd - M^-1 A^T (A M^-1 A^T)+ A qd over the velocity constraints of ``modules`` at q: the impulse of a
    constraint switch, the least kinetic energy change that imposes them."""
    rows = [module.velocity_rows(q) for module in modules if isinstance(module, VelocityConstraint)]
    if not rows:
        return qd
    rows = np.vstack(rows)
    weighted = robot.mass_matrix_inverse(q) @ rows.T
    return qd - weighted @ (np.linalg.pinv(rows @ weighted) @ (rows @ qd))


def constrained_motion(robot: Robot, modules: Sequence[ConstraintModule], t: float, q: np.ndarray,
                       qd: np.ndarray, motor_torque: tuple[float, float] = (0.0, 0.0)) -> ConstrainedMotion:
    """qdd, Q_c and residual of ``robot`` under ``modules`` at (t, q, qd)."""
    force, rows, rhs = stack_problem(robot, modules, t, q, qd, motor_torque)
    return solve_with_factor(robot.mass_matrix(q), robot.mass_inverse_factor(q), force, rows, rhs)


RowKey = tuple[str, tuple[int, int] | None]


def row_keys(module: ConstraintModule) -> list[RowKey]:
    if isinstance(module, WheelContact):
        return [(module.name, (wheel, row)) for wheel in module.wheels for row in module.directions]
    return [(module.name, None)] * len(module.velocity_rows(np.zeros(DOF)))


def constrained_rows(modules: Sequence[ConstraintModule]) -> set[RowKey]:
    """(module name, (wheel, contact row) or None) of every velocity-constraint row ``modules`` impose."""
    return {key for module in modules if isinstance(module, VelocityConstraint) for key in row_keys(module)}
