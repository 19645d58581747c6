"""N robots in time: one RK4 step advances them all (``Simulation`` over a batch)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.constraints import BatchConstraint, BatchGains, BatchWheelContact, build_batch_modules
from wallbot_sim.model.batch.contact import (
    BatchCoulomb, BatchMotion, diverged_error, drive_forces, friction_use, normal_loads)
from wallbot_sim.model.batch.outputs import BatchOutputs, BatchTable, StepHook
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.batch.solver import batch_constrained_acceleration, stacked_product
from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.contact import COULOMB, IDEAL, DetachedError, check_contact_model, coulomb_table
from wallbot_sim.model.contact_kinematics import contact_velocities
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.integrator import rk4_step
from wallbot_sim.model.numbers import POSITIVE
from wallbot_sim.model.outputs import lifted_wheels
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.scenario import Scenario
from wallbot_sim.model.simulation import DEFAULT_STEP
from wallbot_sim.model.trajectories import LastSample, Reference
from wallbot_sim.model.wheel_forces import split_chassis_wrench, wheel_use


NUMPY, NUMBA = 'numpy', 'numba'
ENGINES = (NUMPY, NUMBA)
"""How the ideal-contact steps are computed: whole-batch NumPy array passes, or the compiled kernel."""


class BatchSimulation:
    """N robots, one reference and one set of active constraints, advanced together by RK4 at a fixed step.

    ``contact`` 'ideal': every constraint held, whatever force it takes. 'coulomb' (without the
    trajectory task, as ``Simulation``): each robot's wheels stick or slide on their own (``BatchCoulomb``);
    a robot one of whose wheels lifts off stops where it detached (``detached``, ``t_detached``,
    ``detached_wheel``; its outputs stay those of that instant) while the others go on.
    """

    def __init__(self, robots: Sequence[Robot], reference: Reference | None, selection: ConstraintSelection,
                 q0: np.ndarray, qd0: np.ndarray, dt: float = DEFAULT_STEP, t0: float = 0.0,
                 gains: BatchGains | None = None, contact: str = IDEAL, engine: str = NUMPY) -> None:
        """``q0``, ``qd0``: (N, 7), row i the initial state of ``robots[i]``; ``gains``: default each robot's own.

        ``engine``: 'numpy', or 'numba' for the compiled step (``kernel``): fused over the steps with ideal
        contact, a step per call with coulomb contact (each robot's boundary settled and stepped in the kernel),
        and the compiled solve for the outputs step hooks see with ideal contact. With coulomb contact the
        NumPy engine settles each robot's boundary by the model's ``CoulombContact``, one robot at a time, and
        takes the batch's RK4 step from them.
        """
        POSITIVE.check('time step', dt)
        check_contact_model(contact)
        if engine not in ENGINES:
            raise ParameterError(f'unknown engine {engine!r} (use {" or ".join(ENGINES)})')
        if engine == NUMBA and not kernel.available():
            raise ParameterError("engine 'numba' needs the numba package (pip install numba)")
        self.engine = engine
        compiled = engine == NUMBA
        self._accelerations = kernel.constrained_accelerations if compiled else batch_constrained_acceleration
        """The batch's solve: the compiled one robot by robot for engine 'numba' (the outputs of ideal contact)."""
        self.robots = RobotBatch(robots)
        self.dt = dt
        self.gains = gains or BatchGains.of(self.robots)
        self.reference = reference
        shared = LastSample(reference) if reference is not None else None
        self.modules: list[BatchConstraint] = build_batch_modules(selection, self.robots, shared, self.gains)
        self.selection = selection
        self.contact = contact
        self.initial_time = t0
        self._y = _state_matrix(self.robots.size, q0, qd0)
        self.motor_torque = np.zeros((self.robots.size, 2))
        self.steps = 0
        self._coulomb = (BatchCoulomb(self.robots, selection, reference, self.gains) if contact == COULOMB
                         else None)
        self._others = [module for module in self.modules if not hasattr(module, 'direction')]
        """The modules no friction holds (coulomb contact puts the wheels' contact rows in the others' place)."""
        self._wheels = BatchWheelContact(self.robots, self.gains, self._coulomb.directions) if self._coulomb else None
        self._held: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        """What the NumPy engine's coulomb step holds (``BatchCoulomb.held``)."""
        self.detached = np.zeros(self.size, dtype=bool)
        self.t_detached = np.full(self.size, np.nan)
        """When each detached robot's wheel lifted off (s); NaN for the others."""
        self.detached_wheel = np.zeros(self.size, dtype=int)
        """The wheel (1..4) that lifted off, 0 for a robot still on the wall."""
        self._lift_off_load = np.full(self.size, np.nan)
        """The lifted wheel's load at each detached robot's lift-off instant (N)."""
        self._cached: BatchOutputs | None = None
        self._constants: np.ndarray | None = None
        """The compiled engine's per-robot constants, made on its first step."""
        self._step_references = np.zeros((3, kernel.REFERENCE_FIELDS))
        """The reference at the RK4 instants of the step from the coulomb outputs (``kernel.reference_samples``)."""

    @classmethod
    def from_scenario(cls, robots: Sequence[Robot], scenario: Scenario, selection: ConstraintSelection,
                      dt: float = DEFAULT_STEP, contact: str = IDEAL, engine: str = NUMPY) -> BatchSimulation:
        """Every robot at the scenario's initial state (each with its own rolling spin rates)."""
        states = [scenario.initial_state(robot) for robot in robots]
        return cls(robots, scenario.reference, selection, np.array([q for q, _ in states]),
                   np.array([qd for _, qd in states]), dt, contact=contact, engine=engine)

    @property
    def size(self) -> int:
        """N, the number of robots."""
        return self.robots.size

    @property
    def t(self) -> float:
        """Simulation time (s), the same for every robot."""
        return self.time_at(self.steps)

    def time_at(self, steps: int | np.ndarray) -> float | np.ndarray:
        """The time after ``steps`` steps from the initial time (each of an array of step counts), as ``t`` is
        computed."""
        return self.initial_time + steps * self.dt

    @property
    def q(self) -> np.ndarray:
        """(N, 7) generalized coordinates (copy)."""
        return self._y[:, :DOF].copy()

    @property
    def qd(self) -> np.ndarray:
        """(N, 7) generalized velocities (copy)."""
        return self._y[:, DOF:].copy()

    @property
    def coulomb_applies(self) -> bool:
        """Whether friction limits the contact: coulomb contact and no trajectory task."""
        return self._coulomb is not None and not self.selection.trajectory

    def set_motor_torque(self, torques: np.ndarray) -> None:
        """Side motor torques (N m), (N, 2) or one (2,) pair for all, held from the next step on."""
        torques = np.broadcast_to(np.asarray(torques, dtype=float), (self.size, 2))
        if not np.all(np.isfinite(torques)):
            raise ParameterError('motor torques must be finite')
        self.motor_torque = torques.copy()
        self._cached = None

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
        if self._held is None:
            force, rows, rhs = self._problem(t, q, qd)
        else:
            force, rows, rhs = self._held_problem(t, q, qd)
        acceleration = self._accelerations(self.robots.mass_inverse_factor(q), force, rows, rhs)
        return np.concatenate((qd, acceleration), axis=1)

    def _held_problem(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Q + Q_f, A and b of coulomb contact over a step (``Simulation._problem``): the rolling resistance of the
        held loads and the held friction of the sliding wheels; the others' rows, then the sticking wheels'."""
        assert self._held is not None and self._wheels is not None
        sticking, loads, forces = self._held
        force = self.robots.applied_force(q, qd, self.motor_torque, loads) + self._wheels.friction(q, forces)
        parts = [module.rows(t, q, qd) for module in self._others] + [self._wheels.rows(q, qd, sticking)]
        return (force, np.concatenate([part[0] for part in parts], axis=1),
                np.concatenate([part[1] for part in parts], axis=1))

    def _motion(self, t: float, q: np.ndarray, qd: np.ndarray) -> BatchMotion:
        """qdd, Q_c and residual at (t, q, qd) with ideal contact."""
        force, rows, rhs = self._problem(t, q, qd)
        acceleration = self._accelerations(self.robots.mass_inverse_factor(q), force, rows, rhs)
        misfit = stacked_product(rows, acceleration) - rhs
        return BatchMotion(acceleration, stacked_product(self.robots.mass_matrix(q), acceleration) - force,
                           np.sqrt(np.sum(misfit * misfit, axis=1)))

    def outputs(self) -> BatchOutputs:
        """Every robot's outputs at the current state (computed once; the next step reuses their solve).

        With coulomb contact this is where each robot's stick/slip transitions of the boundary are made.
        """
        if self._cached is None:
            self._cached = self._coulomb_outputs() if self.coulomb_applies else self._ideal_outputs()
        return self._cached

    def _ideal_outputs(self) -> BatchOutputs:
        t, q, qd = self.t, self._y[:, :DOF], self._y[:, DOF:]
        motion = self._motion(t, q, qd)
        loads = normal_loads(self.robots, q, qd, motion.acceleration)
        wrench = motion.constraint_force[:, :3]
        drive = drive_forces(q[:, 2], wrench, self.robots.half_track)
        forces = split_chassis_wrench(q[:, 2], wrench, loads, self.robots.wheel_offsets)
        return BatchOutputs(t, q.copy(), qd.copy(), motion.acceleration, motion.constraint_force, motion.residual,
                            self.motor_torque.copy(), drive, loads, friction_use(self.robots, drive, loads),
                            np.zeros((self.size, 3), dtype=bool), np.zeros_like(qd), self.detached.copy(),
                            self.reference.sample(t) if self.reference is not None else None, forces,
                            wheel_use(forces, loads, self.robots.static_friction[:, None]),
                            np.zeros((self.size, 4), dtype=bool), self._slip_velocities(q, qd))

    def _coulomb_outputs(self) -> BatchOutputs:
        """Every live robot's boundary settled (``BatchCoulomb``), and the outputs of all (``coulomb_table``)."""
        coulomb = self._coulomb
        assert coulomb is not None
        live = ~self.detached
        if self.engine == NUMBA:
            self._step_references = kernel.reference_samples(self.reference, self.initial_time, self.steps, 1,
                                                             self.dt)[0]
            coulomb.settle_compiled(self._y, self._step_references, self._kernel_constants(), self.motor_torque,
                                    self.dt, live)
        else:
            coulomb.settle_each(self.t, self._y, self.motor_torque, self.dt, live)
            self._held = coulomb.held()
        q, qd = self._y[:, :DOF], self._y[:, DOF:]
        solutions, loads = coulomb.solutions, coulomb.solutions[:, kernel.LOADS, :4]
        forces = solutions[:, kernel.FORCES].reshape(self.size, 4, 2)
        table = coulomb_table(loads, forces, coulomb.sliding, coulomb.directions, self.robots.static_friction,
                              self.robots.adhesion_force)
        return BatchOutputs(
            self.t, q.copy(), qd.copy(), solutions[:, kernel.QDD, :DOF].copy(),
            solutions[:, kernel.CONSTRAINT, :DOF].copy(), solutions[:, kernel.STATUS, kernel.RESIDUAL].copy(),
            self.motor_torque.copy(), table.drive, loads.copy(), table.use, table.slipping,
            solutions[:, kernel.FRICTION, :DOF].copy(), self.detached.copy(),
            self.reference.sample(self.t) if self.reference is not None else None, forces.copy(), table.wheel_use,
            coulomb.sliding.copy(), self._slip_velocities(q, qd))

    def _slip_velocities(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return contact_velocities(q[:, 2], qd, self.robots.wheel_offsets, self.robots.wheel_radius[:, None])

    def _kernel_constants(self) -> np.ndarray:
        if self._constants is None:
            self._constants = kernel.robot_constants(self.robots, self.gains.alpha, self.gains.beta)
        return self._constants

    @property
    def compiled(self) -> bool:
        """Whether the steps go through the compiled kernel (engine 'numba' and the contact ideal)."""
        return self.engine == NUMBA and not self.coulomb_applies

    def _compiled_steps(self, steps: int) -> None:
        """``steps`` steps by the kernel; on divergence, the batch at the step before it and DivergedError."""
        references = kernel.reference_samples(self.reference, self.initial_time, self.steps, steps, self.dt)
        active = tuple(self.selection.active_names())
        y, diverged = kernel.advance(self._y, steps, self.dt, references, active, self._kernel_constants(),
                                     self.motor_torque)
        if np.any(diverged >= 0):
            first = int(np.min(diverged[diverged >= 0]))
            if first > 0:
                self._compiled_steps(first)
            raise diverged_error(np.flatnonzero(diverged == first), self.t + self.dt)
        self._y = y
        self.steps += steps
        self._cached = None

    def step(self) -> None:
        """Advance every robot one RK4 step; DivergedError (states unchanged) if one stops being finite.

        With coulomb contact a robot with a wheel lifted off at this instant is detached first: it
        keeps its state from here on.
        """
        if self.compiled:
            self._compiled_steps(1)
            return
        k1 = None
        if self.coulomb_applies:
            out = self._boundary_now()
            if self.engine == NUMBA:
                self._compiled_contact_step()
                return
            k1 = np.concatenate((out.qd, out.acceleration), axis=1)
        elif self._cached is not None:
            k1 = np.concatenate((self._cached.qd, self._cached.acceleration), axis=1)
        with np.errstate(over='ignore', invalid='ignore'):  # divergence is checked just below
            y = rk4_step(self._derivative, self.t, self._y, self.dt, k1)
        if self.detached.any():
            y[self.detached] = self._y[self.detached]
        self._advance(y, np.all(np.isfinite(y), axis=1))

    def _boundary_now(self) -> BatchOutputs:
        """The outputs now (coulomb contact: the settled boundary a step starts from), each robot a wheel of which
        lifts off at them detached."""
        out = self.outputs()
        self._detach(lifted_wheels(out.loads), out.loads, self.t)
        return out

    def _detach(self, wheel: np.ndarray, loads: np.ndarray, t: float | np.ndarray) -> None:
        """Detach the robots on the wall whose ``wheel`` (1..4, 0: none) (N,) lifted off at ``t``, ``loads`` (N, 4)
        their loads then."""
        newly = (wheel > 0) & ~self.detached
        self.detached_wheel[newly] = wheel[newly]
        self.t_detached[newly] = t if np.isscalar(t) else t[newly]
        self._lift_off_load[newly] = loads[newly, wheel[newly] - 1]
        self.detached |= newly

    @property
    def runs_held(self) -> bool:
        """Whether ``run_held`` can run: the compiled engine with coulomb contact."""
        return self.engine == NUMBA and self.coulomb_applies

    def run_held(self, steps: int, references: np.ndarray | None = None) -> BatchTable:
        """``steps`` steps at the motor torques held now, as ``steps`` calls of ``step`` take them, in one call of
        the kernel (``kernel.batch_contact_run``; ``runs_held`` only): the outputs of the ``steps - 1`` instants
        between now and then (``outputs`` gives those at both ends). A robot that lifts off at one of them is
        detached there. DivergedError or ModelError, with the message ``step`` or ``outputs`` would raise at the
        first instant they would, leave the robots' states and time where the call began (its boundary settled).
        ``references``: the reference at the steps' RK4 instants from now (``kernel.reference_samples``), where the
        caller sampled them already (sampling costs about 20 us a step)."""
        coulomb = self._coulomb
        assert coulomb is not None and self.runs_held and steps >= 1
        self._boundary_now()
        live = ~self.detached
        if references is None:
            references = kernel.reference_samples(self.reference, self.initial_time, self.steps, steps, self.dt)
        run = coulomb.run_compiled(self._y, references, self._kernel_constants(), self.motor_torque, self.dt, live)
        times = self.time_at(self.steps + np.arange(steps))
        error = run.first_error(live, times, self.dt)
        if error is not None:
            raise error
        table = coulomb.table(run, self.robots, times, self.motor_torque, self.reference)
        ended = np.flatnonzero(live & (run.outcomes[:, 2] == kernel.DETACHED))
        at = run.outcomes[ended, 0] - 1  # the lift-off instant
        moved = live.copy()
        moved[ended] = False
        self._y[moved] = run.states[moved, steps]
        self._y[ended] = run.settled[ended, at]
        coulomb.solutions[ended] = run.solutions[ended, at]
        loads = np.zeros((self.size, 4))
        loads[ended] = run.solutions[ended, at, kernel.LOADS, :4]
        wheel = np.zeros(self.size, dtype=int)
        wheel[ended] = lifted_wheels(loads[ended])
        lifted_at = np.zeros(self.size)
        lifted_at[ended] = times[at]
        self._detach(wheel, loads, lifted_at)
        self.steps += steps
        self._cached = None
        return table

    def lift_off(self, robot: int) -> DetachedError | None:
        """The lift-off that stopped robot ``robot`` (``Simulation.step``'s DetachedError for it alone), None while
        it is on the wall."""
        if not self.detached[robot]:
            return None
        return DetachedError(int(self.detached_wheel[robot]), float(self._lift_off_load[robot]),
                             float(self.t_detached[robot]))

    def _advance(self, y: np.ndarray, finite: np.ndarray) -> None:
        """One step taken: the new states y, or DivergedError (states unchanged) if a robot's is not ``finite``."""
        if not finite.all():
            raise diverged_error(np.flatnonzero(~finite), self.t + self.dt)
        self.steps += 1
        self._y = y
        self._cached = None

    def _compiled_contact_step(self) -> None:
        """Every live robot's RK4 step from its settled boundary by the kernel (``kernel.batch_contact_step``)."""
        coulomb = self._coulomb
        assert coulomb is not None
        y, finite = kernel.batch_contact_step(self._y, self._step_references, tuple(self.selection.active_names()),
                                              self._kernel_constants(), coulomb.contact, self.motor_torque,
                                              self.dt, coulomb.sliding, ~self.detached, coulomb.solutions,
                                              coulomb.workspaces)
        self._advance(y, finite)

    def run(self, steps: int, on_step: StepHook | None = None) -> BatchOutputs | None:
        """Advance ``steps`` steps; ``on_step`` sees the outputs at every instant, both ends included.

        Returns the final outputs when there is an ``on_step`` (without one, none are computed).
        """
        if on_step is None and self.compiled:
            self._compiled_steps(steps)
            return None
        for _ in range(steps):
            if on_step is not None:
                on_step(self.outputs())
            self.step()
        if on_step is None:
            return None
        on_step(self.outputs())
        return self.outputs()


def _state_matrix(size: int, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
    if q.shape != (size, DOF) or qd.shape != (size, DOF):
        raise ParameterError(f'states of {size} robots need q and qd of shape ({size}, {DOF}), '
                             f'got {q.shape} and {qd.shape}')
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(qd))):
        raise ParameterError('initial states must be finite')
    return np.concatenate((q, qd), axis=1)
