"""The constrained robot in time: state, fixed-step RK4, constraint switching, outputs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from wallbot_sim.model.constraint_set import ConstraintSelection, build_modules
from wallbot_sim.model.constrained_problem import (constrained_motion, constrained_rows, impulsive_projection, row_keys,
                                                   stack_problem)
from wallbot_sim.model.constraints import BaumgarteGains, ConstraintModule, VelocityConstraint, WheelContact
from wallbot_sim.model.contact import (
    IDEAL, CoulombContact, CoulombState, DetachedError, HeldFriction, check_contact_model)
from wallbot_sim.model.contact_outputs import coulomb_contact, ideal_contact, ideal_measures
from wallbot_sim.model.errors import DivergedError, ParameterError
from wallbot_sim.model.integrator import rk4_step
from wallbot_sim.model.numbers import POSITIVE, NumberRange
from wallbot_sim.model.outputs import StepOutputs
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.solver import ConstrainedMotion, constrained_acceleration, solve_with_factor
from wallbot_sim.model.trajectories import LastSample, Reference
from wallbot_sim.model.python_only import refuse_compiled
from wallbot_sim.model.tabulated import CompiledSteps, compiled_dynamics
from wallbot_sim.model.vacuum import PUMP_COMMAND, Chamber

if TYPE_CHECKING:
    from wallbot_sim.model.compiled_contact import CompiledCoulomb

DEFAULT_STEP = 1e-3
"""The paper's fixed RK4 step (s)."""
TIME_STEP = NumberRange(0.0, 0.1, low_open=True)
"""The RK4 steps the tools accept (s): simulate's --dt and a sweep's dt."""
PYTHON, NUMBA = 'python', 'numba'
ENGINES = (PYTHON, NUMBA)
"""How the motion and steps are computed: the model's Python, or the batch's compiled kernel."""


@dataclass(frozen=True)
class SwitchReport:
    """What a constraint switch did to the velocities."""

    previous: ConstraintSelection
    current: ConstraintSelection
    violation_before: float
    """|A_v qd| of the newly active velocity constraints (rows) before projection."""
    violation_after: float
    """The same after the impulsive projection."""


class Simulation(CompiledSteps):
    """A robot, a reference and a set of active constraints, advanced by RK4 at a fixed step.

    With ``contact`` 'coulomb' (docs/model.md 11.3) and no trajectory task, each wheel sticks or
    slides: the transitions of a step boundary are made when its outputs are computed (``step``
    computes them), and a wheel lifting off raises DetachedError from ``step`` after the outputs
    of that instant were available.

    ``engine`` 'numba' computes the motion, the coulomb boundaries and the RK4 steps by the batch's compiled
    kernel (``model.compiled``) while no ``extra_modules`` are active; modules of your own stay on the Python path.
    """

    def __init__(self, robot: Robot, reference: Reference | None, selection: ConstraintSelection,
                 q0: np.ndarray, qd0: np.ndarray, dt: float = DEFAULT_STEP, t0: float = 0.0,
                 gains: BaumgarteGains | None = None, extra_modules: Sequence[ConstraintModule] = (),
                 contact: str = IDEAL, engine: str = PYTHON) -> None:
        """``extra_modules``: constraint modules of your own, active beside the selected ones."""
        POSITIVE.check('time step', dt)
        if engine not in ENGINES:
            raise ParameterError(f'unknown engine {engine!r} (use {" or ".join(ENGINES)})')
        self.engine = engine
        self.robot = robot
        self.dt = dt
        self.gains = gains or BaumgarteGains(robot.params.baumgarte_alpha, robot.params.baumgarte_beta)
        self._reference = reference
        self._selection = selection
        self._extra_modules = list(extra_modules)
        self._modules = self._build(selection, reference, self.gains)
        self._coulomb: CoulombContact | None = None
        self._active: list[ConstraintModule] = self._modules
        """The modules the solver sees: with coulomb contact, the contact rows of the sticking wheels."""
        self._friction: HeldFriction | None = None
        """Q_f of the sliding wheels over this step, or None."""
        self._held_loads: np.ndarray | None = None
        """The loads coulomb contact's rolling resistance holds over this step; None: section 4's F_ad / 4."""
        self.set_contact_model(contact)
        self._initial = (t0, _state_vector(q0, qd0))
        if engine == NUMBA:
            refuse_compiled(robot)
        self._compiled = None if engine == PYTHON else compiled_dynamics(t0, dt)
        self._compiled_coulomb: CompiledCoulomb | None = None
        """The kernel's coulomb boundaries and steps (engine 'numba'), made at their first use."""
        self.motor_torque: tuple[float, float] = (0.0, 0.0)
        """The commanded side torques (N m); ``applied_torque`` is what acts."""
        self._held_torque: tuple[np.ndarray | None, tuple[float, float]] = (None, self.motor_torque)
        """The state the applied torque was found at, and that torque (held over the step from there)."""
        vacuum = robot.params.adhesion
        self._chamber = None if vacuum is None else Chamber(vacuum, robot.world)
        self.pump_command = 1.0
        """u in [0, 1], the vacuum pump's command (``set_pump_command``)."""
        self.pressure = 0.0
        """dp (Pa) of the vacuum chamber, a state integrated with the robot's; 0 without a chamber."""
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
        if self._chamber is not None:  # the chamber starts balanced where the robot starts
            self._set_pressure(self._chamber.steady_pressure(y0[:2], self.pump_command))
        if self._coulomb is not None:
            self._coulomb.reset(self.robot.wall_load)
        self._active, self._friction, self._held_loads = self._modules, None, None

    @property
    def contact_model(self) -> str:
        """'ideal' or 'coulomb'."""
        return IDEAL if self._coulomb is None else 'coulomb'

    @property
    def coulomb_applies(self) -> bool:
        """Whether friction limits the contact now: coulomb contact and no trajectory task (9.3)."""
        return self._coulomb is not None and not self._selection.trajectory

    @property
    def contact_state(self) -> CoulombState | None:
        """Coulomb contact's state at the current boundary (after ``outputs`` settled it); None with ideal contact."""
        return None if self._coulomb is None else self._coulomb.state

    def restore(self, steps: int, q: np.ndarray, qd: np.ndarray, contact: CoulombState | None = None) -> None:
        """Continue from the state (q, qd) a run reached after ``steps`` steps from the initial time, and with
        coulomb contact from its ``contact_state`` there (None: as it stands).

        Time is computed as ``step`` computes it (from the initial time and the step count), so a
        run restored from a saved state continues bit for bit.
        """
        if steps < 0:
            raise ParameterError(f'steps must be >= 0, got {steps}')
        if contact is not None and self._coulomb is not None:
            self._coulomb.take_up(contact)
        self._y = _state_vector(q, qd)
        self.steps = int(steps)
        self._t = self._initial[0] + self.steps * self.dt
        self._cached = None

    # --- configuration -------------------------------------------------------------------
    def set_motor_torque(self, tau_left: float, tau_right: float) -> None:
        """Motor torques (N m) commanded from the next step on."""
        self.motor_torque = (float(tau_left), float(tau_right))
        self._held_torque = (None, self.motor_torque)
        self._cached = None

    @property
    def applied_torque(self) -> tuple[float, float]:
        """The side torques acting over the step from the current state: the command, clipped to the robot file's
        motor envelope at the wheels' speeds of this state where it has a ``motor`` block (docs/model.md 13.2)."""
        state, torque = self._held_torque
        if state is not self._y:
            motor = self.robot.params.motor
            torque = self.motor_torque if motor is None else motor.applied(self.motor_torque, self._y[DOF:])
            self._held_torque = (self._y, torque)
        return torque

    def set_pump_command(self, command: float) -> None:
        """The vacuum pump's command u in [0, 1] from this step boundary on."""
        self.pump_command = PUMP_COMMAND.check('pump command', command)
        self._cached = None

    def _set_pressure(self, pressure: float) -> None:
        """dp, and the robot pressed by the chamber's dp x area from here (held over the next step)."""
        self.pressure = pressure
        self.robot = self.robot.with_adhesion_force(max(pressure, 0.0) * self.robot.params.adhesion.chamber_area)

    def set_contact_model(self, name: str) -> None:
        """'ideal' or 'coulomb' from this step boundary on.

        Going ideal imposes the ideal rows (by the switch projection); going coulomb starts with every
        wheel sticking.
        """
        if check_contact_model(name) == IDEAL:
            self._coulomb = None
            if self._active is not self._modules:
                self._y = np.concatenate((self._y[:DOF], self._project(self._modules, self._y[DOF:])))
            self._active, self._friction, self._held_loads = self._modules, None, None
        elif self._coulomb is None:
            self._coulomb = CoulombContact(self.robot, self.gains)
        self._cached = None

    def set_adhesion_force(self, force: float | None) -> None:
        """F_ad (N; None = k_ad F_min) from this step boundary on: loads, friction limits, rolling resistance.

        Sliding wheels keep sliding; the loads their friction holds are found again at the next boundary.
        """
        self.robot = Robot(self.robot.params.replace(adhesion_force=force), self.robot.world)
        self._cached = None

    def set_reference(self, reference: Reference | None) -> None:
        """A new reference for the trajectory and heading tasks, from the next step on."""
        self._reference = reference
        self._modules = self._build(self._selection, reference, self.gains)
        self._active = self._coulomb.active_modules(self._modules) if self.coulomb_applies else self._modules
        self._friction = self._held_loads = None  # rebuilt on the new modules by the next outputs()
        self._cached = None

    def set_constraints(self, selection: ConstraintSelection, gains: BaumgarteGains | None = None) -> SwitchReport:
        """Switch the active set at this step boundary.

        Velocity constraints that become active are imposed on the velocities at once by the
        impulsive, mass-weighted projection qd+ = qd - M^-1 A^T (A M^-1 A^T)+ A qd.
        With coulomb contact a wheel that has been moving at v_st or faster in a direction that gets
        friction slides instead: its rows are not imposed.
        """
        previous, was_constrained = self._selection, constrained_rows(self._active)
        new_modules = self._build(selection, self._reference, gains or self.gains)
        if gains is not None:
            self.gains = gains
        self._selection, self._modules = selection, new_modules
        q, qd = self._y[:DOF], self._y[DOF:]
        if self.coulomb_applies:
            self._coulomb.gains = self.gains
            held = {key for name, key in was_constrained if name == WheelContact.name}
            self._coulomb.slide_where_fast(new_modules, held, q, qd, self.robot.params.stick_velocity)
            self._active = self._coulomb.active_modules(new_modules)
        else:
            if self._coulomb is not None:
                self._coulomb.reset(self.robot.wall_load)
            self._active = new_modules
        self._friction = self._held_loads = None
        velocity_rows = [row for module in self._active if isinstance(module, VelocityConstraint)
                         for row, key in zip(module.velocity_rows(q), row_keys(module)) if key not in was_constrained]
        before = after = 0.0
        if velocity_rows:
            new_rows = np.vstack(velocity_rows)
            before = float(np.linalg.norm(new_rows @ qd))
            qd = self._project(self._active, qd)
            after = float(np.linalg.norm(new_rows @ qd))
            self._y = np.concatenate((q, qd))
        self._cached = None
        return SwitchReport(previous, selection, before, after)

    def _project(self, modules: Sequence[ConstraintModule], qd: np.ndarray) -> np.ndarray:
        """``impulsive_projection`` of ``qd`` at the current q."""
        return impulsive_projection(self.robot, modules, self._y[:DOF], qd)

    def _build(self, selection: ConstraintSelection, reference: Reference | None,
               gains: BaumgarteGains) -> list[ConstraintModule]:
        shared = LastSample(reference) if reference is not None else None
        return build_modules(selection, self.robot, shared, gains) + self._extra_modules

    # --- dynamics ------------------------------------------------------------------------
    def solve(self, t: float, q: np.ndarray, qd: np.ndarray) -> ConstrainedMotion:
        """The constrained motion at (t, q, qd) with the held motor torques (and contact state)."""
        if self._friction is None and self._held_loads is None:
            return constrained_motion(self.robot, self._active, t, q, qd, self.applied_torque)
        force, rows, rhs = self._problem(t, q, qd)
        return solve_with_factor(self.robot.mass_matrix(q), self.robot.mass_inverse_factor(q), force, rows, rhs)

    def _problem(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        force, rows, rhs = stack_problem(self.robot, self._active, t, q, qd, self.applied_torque, self._held_loads)
        if self._friction is not None:
            force = force + self._friction(q, qd)
        return force, rows, rhs

    def _derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[:DOF], y[DOF:]
        force, rows, rhs = self._problem(t, q, qd)
        return np.concatenate((qd, constrained_acceleration(self.robot.mass_inverse_factor(q), force, rows, rhs)))

    def outputs(self) -> StepOutputs:
        """The outputs at the current state (computed once; the next step reuses their solve).

        With coulomb contact this is where the stick/slip transitions of the boundary are made.
        """
        if self._cached is None:
            q = self._y[:DOF]
            compiled_contact = self._compiled_contact()
            if compiled_contact is not None:
                boundary = compiled_contact.boundary(self._y, self.steps, self.motor_torque, self._coulomb)
                self._y, q, qd = boundary.y, boundary.y[:DOF], boundary.y[DOF:]
                layout = self._coulomb.layout(self._modules)
                self._active = layout.active(layout.wheels - self._coulomb.sliding)
                self._friction, self._held_loads = boundary.friction, self._coulomb.loads
                motion, drive, contact = boundary.motion, boundary.drive, boundary.contact
            elif self.coulomb_applies:
                velocities = self._y[DOF:]
                qd, solution = self._coulomb.settle(self.robot, self._modules, self._t, q, velocities, self.dt,
                                                    self.applied_torque, self._project)
                if qd is not velocities:  # a wheel stopped or stuck again: its slip was projected away
                    torque = self.applied_torque  # the boundary's, which the settled contact holds
                    self._y = np.concatenate((q, qd))
                    self._held_torque = (self._y, torque)
                    q = self._y[:DOF]
                self._active, self._friction, self._held_loads = solution.active, solution.friction, solution.loads
                directions = self._coulomb.layout(self._modules).directions
                motion, drive, contact = solution.motion, *coulomb_contact(self.robot, directions, q, qd, solution)
            else:
                qd = self._y[DOF:]
                compiled = self._compiled_now()
                if compiled is not None:
                    motion, loads, use, drive, wheels = compiled.measured(self._y, self.steps, self.motor_torque)
                else:
                    motion = self.solve(self._t, q, qd)
                    loads, use, drive, wheels = ideal_measures(self.robot, q, qd, motion)
                contact = ideal_contact(self.robot, loads, use, wheels)
            reference = self._reference.sample(self._t) if self._reference is not None else None
            self._cached = StepOutputs(
                self._t, q.copy(), qd.copy(), motion.acceleration, motion.constraint_force, motion.residual,
                self.applied_torque, drive, reference, contact,
                None if self._chamber is None else (self.pressure, self.robot.adsorption.applied_force),
                None if self.robot.params.motor is None else self.motor_torque)
        return self._cached

    def step(self) -> None:
        """Advance one RK4 step; raises DivergedError (state unchanged) if it stops being finite, and
        DetachedError (state unchanged) if coulomb contact finds a wheel lifted off at this instant."""
        if self.coulomb_applies:
            contact = self.outputs().contact
            wheel = contact.detached_wheel
            if wheel is not None:
                raise DetachedError(wheel, float(contact.loads[wheel - 1]), self._t)
        compiled = self._compiled_now() or self._compiled_contact()
        if compiled is not None:
            y = compiled.step(self._y, self.steps, self.motor_torque)
        else:
            cached = self._cached  # outputs already asked for at this state: their solve is RK4's first stage
            with np.errstate(over='ignore', invalid='ignore'):  # divergence is checked just below
                k1 = None if cached is None else np.concatenate((self._y[DOF:], cached.acceleration))
                if self._chamber is None:
                    y = rk4_step(self._derivative, self._t, self._y, self.dt, k1)
                else:
                    y, pressure = self._chamber.step(self._derivative, self._t, self._y, self.pressure, self.dt,
                                                     self.pump_command, k1)
            y = y if np.all(np.isfinite(y)) else None
        if y is None:
            raise DivergedError(f'state is no longer finite at t = {self._t + self.dt:.3f} s')
        self.steps += 1
        self._t = self._initial[0] + self.steps * self.dt
        self._y = y
        self._cached = None
        if self._chamber is not None:
            self._set_pressure(pressure)

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

def _state_vector(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
    if q.shape != (DOF,) or qd.shape != (DOF,):
        raise ParameterError(f'state needs q and qd of length {DOF}, got {q.shape} and {qd.shape}')
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        raise ParameterError('initial state must be finite')
    return np.concatenate((q, qd))

