"""The constraint modules over a batch: each gives its rows A_k (N, k, 7) and b_k (N, k) at (t, q, qd).

Each reads like its single-robot module in wallbot_sim.model.constraints, with the robot index first.
They are chosen from a table by the names of ``ConstraintSelection.active_names()``, in that order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from wallbot_sim.model.constraint_set import MODULES, ConstraintSelection
from wallbot_sim.model.constraints import LATERAL, LEFT, RIGHT
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

    A wheel-wall contact module also has ``channels`` and ``row_wheels``: the friction channel of each row
    and the wheels bounding it (the batch's coulomb contact limits friction per channel).
    """

    name: str

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A_k (N, k, 7) and b_k (N, k) at time t and states (q, qd), each (N, 7)."""
        ...


_ALL_WHEELS = np.ones((1, 4))
"""Lateral friction is bounded by the whole adhesion force, the sum of the four loads."""
_OWN_WHEEL = np.eye(4)
"""Each nonslip row's friction is bounded by its own wheel's load."""
_ALL_WHEELS.flags.writeable = _OWN_WHEEL.flags.writeable = False


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
    channels = (LATERAL,)
    row_wheels = _ALL_WHEELS

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
    channels = (LEFT, LEFT, RIGHT, RIGHT)
    row_wheels = _OWN_WHEEL

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


def build_batch_modules(selection: ConstraintSelection, robots: RobotBatch, reference: Reference | None,
                        gains: BatchGains) -> list[BatchConstraint]:
    """The active modules over the batch, in the order of ``selection.active_names()``."""
    modules = []
    for name in selection.active_names():
        if MODULES[name].task and reference is None:
            raise ParameterError(f'the {name} task needs a reference')
        modules.append(BATCH_MODULES[name](robots, reference, gains))
    return modules
