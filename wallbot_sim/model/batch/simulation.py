"""N robots in time: one RK4 step advances them all (``Simulation`` with the ideal contact, over a batch)."""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.batch.constraints import BatchConstraint, BatchGains, build_batch_modules
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.solver import batch_constrained_acceleration, stacked_product
from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.integrator import rk4_step
from wallbot_sim.model.numbers import POSITIVE
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.scenario import Scenario
from wallbot_sim.model.simulation import DEFAULT_STEP, DivergedError
from wallbot_sim.model.trajectories import LastSample, Reference


class BatchOutputs(NamedTuple):
    """The solution of every robot at one instant."""

    t: float
    q: np.ndarray
    """(N, 7)."""
    qd: np.ndarray
    """(N, 7)."""
    acceleration: np.ndarray
    """qdd (N, 7)."""
    constraint_force: np.ndarray
    """Q_c = M qdd - Q (N, 7)."""
    residual: np.ndarray
    """|A qdd - b| (N,)."""


class BatchSimulation:
    """N robots, one reference and one set of active constraints, advanced together by RK4 at a fixed step.

    The contact is ideal (every constraint held, whatever force it takes).
    """

    def __init__(self, robots: Sequence[Robot], reference: Reference | None, selection: ConstraintSelection,
                 q0: np.ndarray, qd0: np.ndarray, dt: float = DEFAULT_STEP, t0: float = 0.0,
                 gains: BatchGains | None = None) -> None:
        """``q0``, ``qd0``: (N, 7), row i the initial state of ``robots[i]``; ``gains``: default each robot's own."""
        POSITIVE.check('time step', dt)
        self.robots = RobotBatch(robots)
        self.dt = dt
        self.gains = gains or BatchGains.of(self.robots)
        shared = LastSample(reference) if reference is not None else None
        self.modules: list[BatchConstraint] = build_batch_modules(selection, self.robots, shared, self.gains)
        self.selection = selection
        self.initial_time = t0
        self._y = _state_matrix(self.robots.size, q0, qd0)
        self.motor_torque = np.zeros((self.robots.size, 2))
        self.steps = 0

    @classmethod
    def from_scenario(cls, robots: Sequence[Robot], scenario: Scenario, selection: ConstraintSelection,
                      dt: float = DEFAULT_STEP) -> BatchSimulation:
        """Every robot at the scenario's initial state (each with its own rolling spin rates)."""
        states = [scenario.initial_state(robot) for robot in robots]
        return cls(robots, scenario.reference, selection, np.array([q for q, _ in states]),
                   np.array([qd for _, qd in states]), dt)

    @property
    def size(self) -> int:
        """N, the number of robots."""
        return self.robots.size

    @property
    def t(self) -> float:
        """Simulation time (s), the same for every robot."""
        return self.initial_time + self.steps * self.dt

    @property
    def q(self) -> np.ndarray:
        """(N, 7) generalized coordinates (copy)."""
        return self._y[:, :DOF].copy()

    @property
    def qd(self) -> np.ndarray:
        """(N, 7) generalized velocities (copy)."""
        return self._y[:, DOF:].copy()

    def set_motor_torque(self, torques: np.ndarray) -> None:
        """Side motor torques (N m), (N, 2) or one (2,) pair for all, held from the next step on."""
        torques = np.broadcast_to(np.asarray(torques, dtype=float), (self.size, 2))
        if not np.all(np.isfinite(torques)):
            raise ParameterError('motor torques must be finite')
        self.motor_torque = torques.copy()

    def _problem(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Q (N, 7) and the rows A (N, k, 7), b (N, k) of every module, stacked in order."""
        force = self.robots.applied_force(q, qd, self.motor_torque)
        if not self.modules:
            return force, np.empty((self.size, 0, DOF)), np.empty((self.size, 0))
        parts = [module.rows(t, q, qd) for module in self.modules]
        return (force, np.concatenate([part[0] for part in parts], axis=1),
                np.concatenate([part[1] for part in parts], axis=1))

    def _derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[:, :DOF], y[:, DOF:]
        force, rows, rhs = self._problem(t, q, qd)
        acceleration = batch_constrained_acceleration(self.robots.mass_inverse_factor(q), force, rows, rhs)
        return np.concatenate((qd, acceleration), axis=1)

    def outputs(self) -> BatchOutputs:
        """Accelerations, constraint forces and residuals of every robot at the current state."""
        q, qd = self.q, self.qd
        force, rows, rhs = self._problem(self.t, q, qd)
        acceleration = batch_constrained_acceleration(self.robots.mass_inverse_factor(q), force, rows, rhs)
        misfit = stacked_product(rows, acceleration) - rhs
        return BatchOutputs(self.t, q, qd, acceleration,
                            stacked_product(self.robots.mass_matrix(q), acceleration) - force,
                            np.sqrt(np.sum(misfit * misfit, axis=1)))

    def step(self) -> None:
        """Advance every robot one RK4 step; DivergedError (states unchanged) if one stops being finite."""
        with np.errstate(over='ignore', invalid='ignore'):  # divergence is checked just below
            y = rk4_step(self._derivative, self.t, self._y, self.dt)
        finite = np.all(np.isfinite(y), axis=1)
        if not finite.all():
            robots = np.flatnonzero(~finite)
            raise DivergedError(f'state of robot(s) {robots[:5].tolist()} is no longer finite '
                                f'at t = {self.t + self.dt:.3f} s')
        self.steps += 1
        self._y = y

    def run(self, steps: int) -> None:
        """Advance ``steps`` steps."""
        for _ in range(steps):
            self.step()


def _state_matrix(size: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
    if q.shape != (size, DOF) or qd.shape != (size, DOF):
        raise ParameterError(f'states of {size} robots need q and qd of shape ({size}, {DOF}), '
                             f'got {q.shape} and {qd.shape}')
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        raise ParameterError('initial states must be finite')
    return np.concatenate((q, qd), axis=1)
