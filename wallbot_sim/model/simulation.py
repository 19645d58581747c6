"""The constrained robot in time: state, fixed-step RK4, constraint switching, outputs."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from wallbot_sim.model.constraint_set import ConstraintSelection, build_modules
from wallbot_sim.model.constraints import BaumgarteGains, ConstraintModule, VelocityConstraint
from wallbot_sim.model.errors import ModelError, ParameterError
from wallbot_sim.model.integrator import rk4_step
from wallbot_sim.model.outputs import StepOutputs, drive_forces
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.solver import ConstrainedMotion, constrained_acceleration, solve_with_factor
from wallbot_sim.model.trajectories import LastSample, Reference

DEFAULT_STEP = 1e-3
"""The paper's fixed RK4 step (s)."""


class DivergedError(ModelError):
    """The state stopped being finite."""


@dataclass(frozen=True)
class SwitchReport:
    """What a constraint switch did to the velocities."""

    previous: ConstraintSelection
    current: ConstraintSelection
    violation_before: float
    """|A_v qd| of the newly active velocity constraints before projection."""
    violation_after: float
    """The same after the impulsive projection."""


class Simulation:
    """A robot, a reference and a set of active constraints, advanced by RK4 at a fixed step."""

    def __init__(self, robot: Robot, reference: Reference | None, selection: ConstraintSelection,
                 q0: np.ndarray, qd0: np.ndarray, dt: float = DEFAULT_STEP, t0: float = 0.0,
                 gains: BaumgarteGains | None = None, extra_modules: Sequence[ConstraintModule] = ()) -> None:
        """``extra_modules``: constraint modules of your own, active beside the selected ones."""
        if not (math.isfinite(dt) and dt > 0.0):
            raise ParameterError(f'time step must be a finite number > 0, got {dt!r}')
        self.robot = robot
        self.dt = dt
        self.gains = gains or BaumgarteGains(robot.params.baumgarte_alpha, robot.params.baumgarte_beta)
        self._reference = reference
        self._selection = selection
        self._extra_modules = list(extra_modules)
        self._modules = self._build(selection, reference, self.gains)
        self._initial = (t0, _state_vector(q0, qd0))
        self.motor_torque: tuple[float, float] = (0.0, 0.0)
        self.steps = 0
        self.reset()

    # --- state ---------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Simulation time (s)."""
        return self._t

    @property
    def initial_time(self) -> float:
        """Simulation time of step 0 (s); t = initial_time + steps * dt."""
        return self._initial[0]

    @property
    def q(self) -> np.ndarray:
        """Generalized coordinates [x, y, th, p1..p4] (copy)."""
        return self._y[:DOF].copy()

    @property
    def qd(self) -> np.ndarray:
        """Generalized velocities (copy)."""
        return self._y[DOF:].copy()

    @property
    def selection(self) -> ConstraintSelection:
        """The active constraint switches."""
        return self._selection

    @property
    def reference(self) -> Reference | None:
        """The reference the trajectory task follows."""
        return self._reference

    def reset(self, q0: np.ndarray | None = None, qd0: np.ndarray | None = None) -> None:
        """Back to the initial state (or a new one) at the initial time."""
        t0, y0 = self._initial
        if q0 is not None or qd0 is not None:
            y0 = _state_vector(y0[:DOF] if q0 is None else q0, y0[DOF:] if qd0 is None else qd0)
            self._initial = (t0, y0)
        self._t, self._y = t0, y0.copy()
        self.steps = 0
        self._cached: StepOutputs | None = None

    def restore(self, steps: int, q: np.ndarray, qd: np.ndarray) -> None:
        """Continue from the state (q, qd) a run reached after ``steps`` steps from the initial time.

        Time is computed as ``step`` computes it (from the initial time and the step count), so a
        run restored from a saved state continues bit for bit.
        """
        if steps < 0:
            raise ParameterError(f'steps must be >= 0, got {steps}')
        self._y = _state_vector(q, qd)
        self.steps = int(steps)
        self._t = self._initial[0] + self.steps * self.dt
        self._cached = None

    # --- configuration -------------------------------------------------------------------
    def set_motor_torque(self, tau_left: float, tau_right: float) -> None:
        """Motor torques (N m) held from the next step on."""
        self.motor_torque = (float(tau_left), float(tau_right))
        self._cached = None

    def set_reference(self, reference: Reference | None) -> None:
        """A new reference for the trajectory and heading tasks, from the next step on."""
        self._reference = reference
        self._modules = self._build(self._selection, reference, self.gains)
        self._cached = None

    def set_constraints(self, selection: ConstraintSelection, gains: BaumgarteGains | None = None) -> SwitchReport:
        """Switch the active set at this step boundary.

        Velocity constraints that become active are imposed on the velocities at once by the
        impulsive, mass-weighted projection qd+ = qd - M^-1 A^T (A M^-1 A^T)+ A qd.
        """
        previous = self._selection
        new_modules = self._build(selection, self._reference, gains or self.gains)
        added = set(selection.active_names()) - set(previous.active_names())
        velocity_rows = [m.velocity_rows(self._y[:DOF]) for m in new_modules
                         if m.name in added and isinstance(m, VelocityConstraint)]
        before = after = 0.0
        if velocity_rows:
            q, qd = self._y[:DOF], self._y[DOF:]
            rows = np.vstack([m.velocity_rows(q) for m in new_modules if isinstance(m, VelocityConstraint)])
            new_rows = np.vstack(velocity_rows)
            before = float(np.linalg.norm(new_rows @ qd))
            mass_inverse = self.robot.mass_matrix_inverse(q)
            weighted = mass_inverse @ rows.T
            qd = qd - weighted @ (np.linalg.pinv(rows @ weighted) @ (rows @ qd))
            after = float(np.linalg.norm(new_rows @ qd))
            self._y = np.concatenate((q, qd))
        if gains is not None:
            self.gains = gains
        self._selection, self._modules = selection, new_modules
        self._cached = None
        return SwitchReport(previous, selection, before, after)

    def _build(self, selection: ConstraintSelection, reference: Reference | None,
               gains: BaumgarteGains) -> list[ConstraintModule]:
        shared = LastSample(reference) if reference is not None else None
        return build_modules(selection, self.robot, shared, gains) + self._extra_modules

    # --- dynamics ------------------------------------------------------------------------
    def solve(self, t: float, q: np.ndarray, qd: np.ndarray) -> ConstrainedMotion:
        """The constrained motion at (t, q, qd) with the held motor torques."""
        return constrained_motion(self.robot, self._modules, t, q, qd, self.motor_torque)

    def _problem(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return stack_problem(self.robot, self._modules, t, q, qd, self.motor_torque)

    def _derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[:DOF], y[DOF:]
        force, rows, rhs = self._problem(t, q, qd)
        return np.concatenate((qd, constrained_acceleration(self.robot.mass_inverse_factor(q), force, rows, rhs)))

    def outputs(self) -> StepOutputs:
        """The outputs at the current state (computed once; the next step reuses their solve)."""
        if self._cached is None:
            q, qd = self._y[:DOF], self._y[DOF:]
            motion = self.solve(self._t, q, qd)
            reference = self._reference.sample(self._t) if self._reference is not None else None
            self._cached = StepOutputs(
                self._t, q.copy(), qd.copy(), motion.acceleration, motion.constraint_force, motion.residual,
                self.motor_torque, drive_forces(q[2], motion.constraint_force[:3], self.robot.params.half_track),
                reference)
        return self._cached

    def step(self) -> None:
        """Advance one RK4 step; raises DivergedError (state unchanged) if it stops being finite."""
        with np.errstate(over='ignore', invalid='ignore'):  # divergence is checked just below
            cached = self._cached  # outputs already asked for at this state: their solve is RK4's first stage
            k1 = None if cached is None else np.concatenate((self._y[DOF:], cached.acceleration))
            y = rk4_step(self._derivative, self._t, self._y, self.dt, k1)
        if not np.all(np.isfinite(y)):
            raise DivergedError(f'state is no longer finite at t = {self._t + self.dt:.3f} s')
        self.steps += 1
        self._t = self._initial[0] + self.steps * self.dt
        self._y = y
        self._cached = None

    def run(self, duration: float, on_step: Callable[[StepOutputs], None] | None = None) -> StepOutputs:
        """Step for ``duration`` seconds; ``on_step`` sees the outputs at every instant, both ends included."""
        count = round(duration / self.dt)
        for _ in range(count):
            if on_step is not None:
                on_step(self.outputs())
            self.step()
        if on_step is not None:
            on_step(self.outputs())
        return self.outputs()


def stack_problem(robot: Robot, modules: Sequence[ConstraintModule], t: float, q: np.ndarray, qd: np.ndarray,
                  motor_torque: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Q and the rows A, b of ``modules`` stacked in order, at (t, q, qd)."""
    force = robot.applied_force(q, qd, motor_torque)
    if not modules:
        return force, np.empty((0, DOF)), np.empty(0)
    parts = [module.rows(t, q, qd) for module in modules]
    return force, np.concatenate([part[0] for part in parts]), np.concatenate([part[1] for part in parts])


def constrained_motion(robot: Robot, modules: Sequence[ConstraintModule], t: float, q: np.ndarray,
                       qd: np.ndarray, motor_torque: tuple[float, float] = (0.0, 0.0)) -> ConstrainedMotion:
    """qdd, Q_c and residual of ``robot`` under ``modules`` at (t, q, qd)."""
    force, rows, rhs = stack_problem(robot, modules, t, q, qd, motor_torque)
    return solve_with_factor(robot.mass_matrix(q), robot.mass_inverse_factor(q), force, rows, rhs)


def _state_vector(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
    if q.shape != (DOF,) or qd.shape != (DOF,):
        raise ParameterError(f'state needs q and qd of length {DOF}, got {q.shape} and {qd.shape}')
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        raise ParameterError('initial state must be finite')
    return np.concatenate((q, qd))

