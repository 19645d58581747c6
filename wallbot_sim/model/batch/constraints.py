"""The constraint modules over a batch: each gives its rows A_k (N, k, 7) and b_k (N, k) at (t, q, qd).

Each reads like its single-robot module in wallbot_sim.model.constraints, with the robot index first.
They are chosen from a table by the names of ``ConstraintSelection.active_names()``, in that order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from wallbot_sim.model.constraint_set import MODULES, ConstraintSelection
from wallbot_sim.model.constraints import LATERAL, LONGITUDINAL
from wallbot_sim.model.contact_kinematics import LATERAL_ROW, LONGITUDINAL_ROW
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.solver import stacked_product
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.trajectories import Reference, tangent_heading


@dataclass(frozen=True)
class BatchGains:
    """Baumgarte gains alpha and beta (1/s), one of each per robot (N,)."""

    alpha: np.ndarray
    beta: np.ndarray

    @classmethod
    def of(cls, robots: RobotBatch) -> BatchGains:
        """Each robot's own gains from its parameters (what ``Simulation`` uses by default)."""
        params = [robot.params for robot in robots.robots]
        return cls(np.array([p.baumgarte_alpha for p in params]), np.array([p.baumgarte_beta for p in params]))

    @property
    def velocity_gain(self) -> np.ndarray:
        """gam = 2 alpha (N,)."""
        return 2.0 * self.alpha


class BatchConstraint(Protocol):
    """One constraint of every robot of the batch.

    A wheel-wall contact module also has ``direction``, the direction of the wheels' contact velocity its
    friction holds (``ContactConstraint.direction``): with coulomb contact its place goes to every wheel's
    contact row in that direction (``BatchWheelContact``).
    """

    name: str

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A_k (N, k, 7) and b_k (N, k) at time t and states (q, qd), each (N, 7)."""
        ...


def _unit_rows(size: int, columns: tuple[int, ...]) -> np.ndarray:
    rows = np.zeros((size, len(columns), DOF))
    rows[:, range(len(columns)), columns] = 1.0
    return rows


class BatchBelt:
    """pdd1 - pdd2 = -gam (pd1 - pd2) and pdd3 - pdd4 = -gam (pd3 - pd4)."""

    name = 'belt'

    def __init__(self, robots: RobotBatch, gains: BatchGains) -> None:
        self.gains = gains
        self._rows = np.zeros((robots.size, 2, DOF))
        self._rows[:, 0, 3:5] = self._rows[:, 1, 5:7] = (1.0, -1.0)

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        violation = np.stack((qd[:, 3] - qd[:, 4], qd[:, 5] - qd[:, 6]), axis=1)
        return self._rows, -self.gains.velocity_gain[:, None] * violation


class BatchNonLateral:
    """Row [-sin th, cos th, 0, ...], b = thd v_long - gam v_lat."""

    name = 'non_lateral'
    direction = LATERAL

    def __init__(self, robots: RobotBatch, gains: BatchGains) -> None:
        self.gains = gains
        self._size = robots.size

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cos_t, sin_t = np.cos(q[:, 2]), np.sin(q[:, 2])
        v_long = cos_t * qd[:, 0] + sin_t * qd[:, 1]
        v_lat = -sin_t * qd[:, 0] + cos_t * qd[:, 1]
        rows = np.zeros((self._size, 1, DOF))
        rows[:, 0, 0], rows[:, 0, 1] = -sin_t, cos_t
        return rows, (qd[:, 2] * v_long - self.gains.velocity_gain * v_lat)[:, None]


class BatchNonslip:
    """One row per wheel: [-cos th, -sin th, s_i, r at column 3+i], b = thd v_lat - gam h_i."""

    name = 'nonslip'
    direction = LONGITUDINAL

    def __init__(self, robots: RobotBatch, gains: BatchGains) -> None:
        self.gains = gains
        self._template = np.zeros((robots.size, 4, DOF))
        self._template[:, :, 2] = robots.lateral_offsets
        self._template[:, range(4), range(3, DOF)] = robots.wheel_radius[:, None]

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cos_t, sin_t = np.cos(q[:, 2]), np.sin(q[:, 2])
        rows = self._template.copy()
        rows[:, :, 0], rows[:, :, 1] = -cos_t[:, None], -sin_t[:, None]
        v_lat = -sin_t * qd[:, 0] + cos_t * qd[:, 1]
        return rows, (qd[:, 2] * v_lat)[:, None] - self.gains.velocity_gain[:, None] * stacked_product(rows, qd)


class BatchTrajectoryTask:
    """(x, y) = p_d(t), stabilized: xdd = pdd_d - 2 alpha ed - beta^2 e, every robot on the one reference."""

    name = 'trajectory'

    def __init__(self, robots: RobotBatch, reference: Reference, gains: BatchGains) -> None:
        self.reference = reference
        self.gains = gains
        self._rows = _unit_rows(robots.size, (0, 1))

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ref = self.reference.sample(t)
        two_alpha, beta2 = 2.0 * self.gains.alpha[:, None], self.gains.beta[:, None] ** 2
        rhs = (np.asarray(ref.acceleration) - two_alpha * (qd[:, :2] - np.asarray(ref.velocity))
               - beta2 * (q[:, :2] - np.asarray(ref.position)))
        return self._rows, rhs


class BatchTangentHeadingTask:
    """th = atan2(yd_d, xd_d); while the reference is at rest, thdd = -2 alpha thd."""

    name = 'tangent_heading'

    def __init__(self, robots: RobotBatch, reference: Reference, gains: BatchGains) -> None:
        self.reference = reference
        self.gains = gains
        self._rows = _unit_rows(robots.size, (2,))

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        heading = tangent_heading(self.reference.sample(t))
        two_alpha, rate = 2.0 * self.gains.alpha, qd[:, 2]
        if heading is None:
            return self._rows, (-two_alpha * rate)[:, None]
        error = wrap_angles(q[:, 2] - heading.angle)
        return self._rows, (heading.acceleration - two_alpha * (rate - heading.rate)
                            - self.gains.beta ** 2 * error)[:, None]


def wrap_angles(angles: np.ndarray) -> np.ndarray:
    """The angles in (-pi, pi] (``wrap_angle`` elementwise)."""
    turn = 2.0 * np.pi
    wrapped = angles - turn * np.round(angles / turn)
    return np.where(wrapped <= -np.pi, wrapped + turn, wrapped)


BatchBuilder = Callable[[RobotBatch, 'Reference | None', BatchGains], BatchConstraint]

BATCH_MODULES: dict[str, BatchBuilder] = {
    'trajectory': lambda robots, reference, gains: BatchTrajectoryTask(robots, reference, gains),
    'tangent_heading': lambda robots, reference, gains: BatchTangentHeadingTask(robots, reference, gains),
    'belt': lambda robots, reference, gains: BatchBelt(robots, gains),
    'non_lateral': lambda robots, reference, gains: BatchNonLateral(robots, gains),
    'nonslip': lambda robots, reference, gains: BatchNonslip(robots, gains),
}
"""The batched form of every module of ``wallbot_sim.model.constraint_set.MODULES``, by the same name."""


class BatchWheelContact:
    """The contact rows of every robot's sticking wheels (``WheelContact`` over a batch), and the held friction of
    its sliding ones: J_i qdd = -c - gam v_i per wheel and direction with friction, wheel by wheel; a wheel that
    does not stick has its rows zero (a zero row with a zero right side leaves the minimum-norm least-squares
    solution as removing it does)."""

    def __init__(self, robots: RobotBatch, gains: BatchGains, directions: tuple[int, ...]) -> None:
        """``directions``: the rows of the contact velocity that have friction (0 along x_p, 1 along y_p)."""
        self.gains = gains
        self.directions = directions
        self._template = np.zeros((robots.size, 4, 2, DOF))
        self._template[:, :, LONGITUDINAL_ROW, 2] = -robots.wheel_offsets[:, :, 1]
        self._template[:, :, LONGITUDINAL_ROW, 3:] = -robots.wheel_radius[:, None, None] * np.eye(4)
        self._template[:, :, LATERAL_ROW, 2] = robots.wheel_offsets[:, :, 0]

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """J (N, 4, 2, 7): each wheel's contact velocity v_i = J_i qd (``ContactKinematics.jacobian``)."""
        cos_t, sin_t = np.cos(theta)[:, None], np.sin(theta)[:, None]
        jacobian = self._template.copy()
        jacobian[:, :, LONGITUDINAL_ROW, 0], jacobian[:, :, LONGITUDINAL_ROW, 1] = cos_t, sin_t
        jacobian[:, :, LATERAL_ROW, 0], jacobian[:, :, LATERAL_ROW, 1] = -sin_t, cos_t
        return jacobian

    def rows(self, q: np.ndarray, qd: np.ndarray, sticking: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A (N, 4 d, 7) and b (N, 4 d) of the ``sticking`` (N, 4) wheels' rows, d the directions with friction."""
        jacobian = self.jacobian(q[:, 2])[:, :, self.directions]
        cos_t, sin_t = np.cos(q[:, 2]), np.sin(q[:, 2])
        xd, yd, thd = qd[:, 0], qd[:, 1], qd[:, 2]
        drift = np.stack((thd * (-sin_t * xd + cos_t * yd), -thd * (cos_t * xd + sin_t * yd)), axis=1)
        velocity = np.einsum('nwdc,nc->nwd', jacobian, qd)
        rhs = -drift[:, None, self.directions] - self.gains.velocity_gain[:, None, None] * velocity
        rows = jacobian * sticking[:, :, None, None]
        return rows.reshape(len(q), -1, DOF), (rhs * sticking[:, :, None]).reshape(len(q), -1)

    def friction(self, q: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """Q_f (N, 7) = sum_i J_i^T f_i of the wheels' forces (N, 4, 2) in body axes (``HeldFriction``)."""
        return np.einsum('nwd,nwdc->nc', forces, self.jacobian(q[:, 2]))


def build_batch_modules(selection: ConstraintSelection, robots: RobotBatch, reference: Reference | None,
                        gains: BatchGains) -> list[BatchConstraint]:
    """The active modules over the batch, in the order of ``selection.active_names()``."""
    modules = []
    for name in selection.active_names():
        if MODULES[name].task and reference is None:
            raise ParameterError(f'the {name} task needs a reference')
        modules.append(BATCH_MODULES[name](robots, reference, gains))
    return modules
