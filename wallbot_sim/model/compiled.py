"""One robot's dynamics by the batch's compiled kernel (``Simulation(..., engine='numba')``).

With ideal contact the kernel's ``robot_run`` takes a chunk of one robot's RK4 steps in one call, with
the motion at each state: the batch's derivative and step, the same forces, the module rows in
stacking order and the same normal-equation solve as the numba batch engine (which agrees with the
Python model to 1e-9). The loads, friction use, drive forces and wheel outputs of a chunk's instants are
the kernel's too (``ideal_outputs``); the reference at the RK4 instants is sampled in Python for the chunk.

With coulomb contact the same is done by ``wallbot_sim.model.compiled_contact``.
"""

from __future__ import annotations

from typing import NamedTuple, Self

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.simulation import BatchSimulation
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.constraint_set import MODULES, ConstraintSelection
from wallbot_sim.model.constraints import BaumgarteGains
from wallbot_sim.model.constraints.look_ahead import PointReference
from wallbot_sim.model.contact import COULOMB, IDEAL
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.outputs import DriveForces, StepTable
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.simulation import NUMBA, Simulation
from wallbot_sim.model.solver import ConstrainedMotion
from wallbot_sim.model.trajectories import Circle, Reference
from wallbot_sim.model.wheel_forces import WheelOutputs

AHEAD_FIRST, AHEAD_MOST = 4, 64
"""Steps taken ahead per kernel call: the first after a change, and the most (doubling while used up)."""


def require_numba() -> None:
    """Raise ParameterError unless numba imported (the compiled engine can run)."""
    if not kernel.available():
        raise ParameterError("engine 'numba' needs the numba package (pip install numba)")


def compile_kernel() -> None:
    """Compile the kernel's runs and the tracking controller's inverse dynamics, or load them from numba's cache
    (which the first compilation on a machine writes, 20-60 s), so that no first numba step waits for them."""
    compile_run(COULOMB)
    compile_inverse_dynamics()


def compile_batch(contacts: tuple[str, ...] = (IDEAL, COULOMB)) -> None:
    """Compile the batch engine's kernel (``BatchSimulation(..., engine='numba')``, a sweep's robots) under
    ``contacts``: its fused steps and solve with ideal contact, its boundaries, steps and runs at held torques with
    coulomb contact; or load them from the cache."""
    robots, start = [Robot(RobotParameters())] * 2, np.zeros((2, DOF))
    selections = {IDEAL: ConstraintSelection.parse('belt'), COULOMB: ConstraintSelection.structural(trajectory=False)}
    for contact in contacts:
        batch = BatchSimulation(robots, Circle(1.0, 20.0), selections[contact], start, start, contact=contact,
                                engine=NUMBA)
        batch.step()
        batch.outputs()
        if batch.runs_held:
            batch.run_held(2)


def compile_ideal() -> None:
    """Compile (or load) what the trajectory task and ideal contact step by: the kernel's run, the tracking
    controller's inverse dynamics and the batch's fused steps."""
    compile_run(IDEAL)
    compile_inverse_dynamics()
    compile_batch((IDEAL,))


def compile_coulomb() -> None:
    """Compile (or load) what coulomb contact steps a driven robot by: the kernel's contact run and the batch's
    boundaries and steps. In one process, as they share the run (nearly all of it), which it compiles once;
    beside ``compile_ideal`` in another, the two take about as long."""
    still = np.zeros(DOF)
    Simulation(Robot(RobotParameters()), Circle(1.0, 20.0), ConstraintSelection.structural(trajectory=False),
               still, still, contact=COULOMB, engine=NUMBA).step()
    compile_batch((COULOMB,))


def compile_run(contact: str) -> None:
    """Compile what a numba ``Simulation`` under ``contact`` steps by, or load it from numba's cache: the kernel's
    run, which takes the steps under the trajectory task whatever the contact model, and its outputs, and with
    coulomb contact its contact run, which takes a driven robot's."""
    still = np.zeros(DOF)
    simulation = Simulation(Robot(RobotParameters()), Circle(1.0, 20.0), ConstraintSelection.parse('belt'),
                            still, still, contact=contact, engine=NUMBA)
    simulation.step()
    simulation.outputs()
    if contact == COULOMB:
        simulation.set_constraints(ConstraintSelection.structural(trajectory=False))
        simulation.step()


def compile_inverse_dynamics() -> None:
    """Compile the tracking controller's inverse dynamics (``kernel.tracking_force``) or load it from the cache."""
    still, at_rest = np.zeros(DOF), PointReference((0.0, 0.0), (0.0, 0.0), (0.0, 0.0), 0.0)
    CompiledInverseDynamics().constraint_force(Robot(RobotParameters()), BaumgarteGains(1.0, 1.0),
                                               ConstraintSelection.structural(trajectory=False), at_rest, 0.05,
                                               still, still)



class CompiledInverseDynamics:
    """Q_c of an unpowered robot under a constraint set and the look-ahead point task, by the kernel
    (``kernel.tracking_force``): ``constrained_motion``'s constraint force with those modules, to round-off.

    The robot's constants are rebuilt only when the robot, gains or set are other objects.
    """

    def __init__(self) -> None:
        require_numba()
        self._robot: Robot | None = None
        self._gains: BaumgarteGains | None = None
        self._selection: ConstraintSelection | None = None
        self._constants = np.empty(0)
        self._flags = np.zeros(len(kernel.MODULE_ORDER), dtype=np.bool_)
        self._state = np.zeros(2 * DOF)

    def constraint_force(self, robot: Robot, gains: BaumgarteGains, selection: ConstraintSelection,
                         point: PointReference, distance: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Q_c (7,) at (q, qd): ``selection``'s modules, then the task steering the point ``distance`` ahead
        of the centre onto ``point``."""
        if robot is not self._robot or gains is not self._gains:
            self._robot, self._gains = robot, gains
            self._constants = kernel.robot_constants(RobotBatch([robot]), np.array([gains.alpha]),
                                                     np.array([gains.beta]))[0]
        if selection is not self._selection:
            if any(MODULES[name].task for name in selection.active_names()):
                raise ParameterError('the look-ahead point task takes the place of the trajectory task: '
                                     'a selection without it is needed')
            self._selection, self._flags = selection, kernel.module_flags(selection.active_names())[0]
        self._state[:DOF], self._state[DOF:] = q, qd
        out = np.empty(DOF)
        kernel.tracking_force(self._state, np.array(point[:3]), self._flags, self._constants, float(distance), out)
        return out


class ReferenceRows(NamedTuple):
    """The reference at the RK4 instants of consecutive steps (``kernel.reference_samples``), sampled ahead of
    the run that uses them (``CompiledDynamics.reference_rows``); a run uses them only for what they were
    sampled for."""

    sampled_for: tuple[Reference | None, float, float, int]
    """The reference, the simulation's initial time and dt, and the first step."""
    rows: np.ndarray
    """(instants, 3, 10)."""


class Measured(NamedTuple):
    """What a simulation's outputs derive at one state: the motion, normal loads, friction use, drive forces and
    the outputs per wheel (one row)."""

    motion: ConstrainedMotion
    loads: np.ndarray
    use: FrictionUse
    drive: DriveForces
    wheels: WheelOutputs


class CompiledRun(NamedTuple):
    """Consecutive instants of one robot from ``CompiledDynamics.run`` (``kernel.robot_run``)."""

    states: np.ndarray
    """(T + 1, 14): the state at each instant, and after the last (where ``taken`` reaches it)."""
    motions: np.ndarray
    """(T, 3, 7): qdd, Q and Q_c at each instant reached."""
    residuals: np.ndarray
    """(T,)."""
    references: np.ndarray
    """(T, 3, 10): the reference at each step's RK4 instants (zeros without a reference)."""
    taken: int
    """Steps taken: fewer than asked where a state stopped being finite."""

    @property
    def instants(self) -> int:
        """The instants whose motion was computed."""
        return min(self.taken + 1, len(self.residuals))


class Configured:
    """The kernel's constants for what a ``Simulation`` has active now: the robot's, the module flags, the reference.

    ``configure`` is cheap when nothing changed (it compares identities), so the simulation calls it
    before each use; what changed drops the steps taken ahead (``_forget``).
    """

    def __init__(self, initial_time: float, dt: float) -> None:
        require_numba()
        self._initial_time, self._dt = initial_time, dt
        self._robot: Robot | None = None
        self._gains: BaumgarteGains | None = None
        self._selection: ConstraintSelection | None = None
        self._reference: Reference | None = None
        self._constants, self._contact = np.empty(0), np.empty(0)
        self._flags, self._rows = np.zeros(len(kernel.MODULE_ORDER), dtype=np.bool_), 0
        self._torque_pair: tuple[float, float] | None = None
        self._torque = np.zeros(2)

    def configure(self, robot: Robot, gains: BaumgarteGains, selection: ConstraintSelection,
                  reference: Reference | None, dt: float) -> Self:
        """Take the simulation's robot, gains, active set and reference (rebuilding what changed); returns self."""
        if robot is not self._robot or gains is not self._gains:
            self._robot, self._gains = robot, gains
            self._constants = kernel.robot_constants(RobotBatch([robot]), np.array([gains.alpha]),
                                                     np.array([gains.beta]))[0]
            self._contact = kernel.contact_constants(robot)
            self._forget(robot_changed=True)
        if selection is not self._selection:
            self._selection = selection
            self._flags, self._rows = kernel.module_flags(selection.active_names())
            self._forget()
        if reference is not self._reference or dt != self._dt:
            self._reference, self._dt = reference, dt
            self._forget()
        return self

    def _forget(self, robot_changed: bool = False) -> None:
        """Drop what was computed for the configuration before."""

    def reference_rows(self, step: int, instants: int) -> ReferenceRows:
        """The reference at the RK4 instants of ``instants`` steps from the simulation's ``step``-th: the Python
        part of a ``run``, which can be done beforehand."""
        return ReferenceRows((self._reference, self._initial_time, self._dt, step),
                             kernel.reference_samples(self._reference, self._initial_time, step, instants, self._dt))

    def _torque_array(self, torque: tuple[float, float]) -> np.ndarray:
        if torque is not self._torque_pair:
            self._torque_pair, self._torque = torque, np.array(torque, dtype=float)
        return self._torque


class CompiledDynamics(Configured):
    """The motion, outputs and RK4 steps of one robot with ideal contact, for what a ``Simulation`` has active now.

    The kernel takes steps ahead, a chunk per call (``robot_run``), and ``measured`` and ``step``
    answer from the chunk while the simulation goes on from the state handed out last, under the
    same configuration and motor torque (the same objects): the states and motions one kernel step
    at a time gives, to the bit, with the chunk's loads, friction use and drive forces measured at
    once. Any other state starts a new chunk there. A chunk used to its end doubles the next, up to
    AHEAD_MOST; a change starts again at AHEAD_FIRST (a driven run's commands change the torque
    every control period).
    """

    def __init__(self, initial_time: float, dt: float) -> None:
        super().__init__(initial_time, dt)
        self._ahead: CompiledRun | None = None
        self._ahead_step, self._ahead_row = 0, 0
        """The simulation's step of the chunk's row 0, and the row whose state was handed out last."""
        self._ahead_state: np.ndarray | None = None
        self._ahead_torque: tuple[float, float] | None = None
        self._ahead_size = AHEAD_FIRST
        self._ahead_measured: tuple[np.ndarray, np.ndarray, np.ndarray, WheelOutputs] | None = None

    def _forget(self, robot_changed: bool = False) -> None:
        self._ahead = None

    def measured(self, y: np.ndarray, step: int, torque: tuple[float, float]) -> Measured:
        """The motion, normal loads, friction use, drive forces and outputs per wheel at y (14,), the simulation's
        ``step``-th instant."""
        row = self._row(y, step, torque)
        run = self._ahead
        if self._ahead_measured is None:
            self._ahead_measured = self._measured(run)
        loads, use, drive, wheels = self._ahead_measured
        return Measured(ConstrainedMotion(run.motions[row, 0], run.motions[row, 2], float(run.residuals[row])),
                        loads[row], FrictionUse(*use[row].tolist()), DriveForces(*drive[row].tolist()),
                        WheelOutputs(*(column[row:row + 1] for column in wheels)))

    def step(self, y: np.ndarray, step: int, torque: tuple[float, float]) -> np.ndarray | None:
        """The state one RK4 step after y, the simulation's ``step``-th instant, or None if it is not finite."""
        row = self._row(y, step, torque)
        run = self._ahead
        if row >= run.taken:  # the next state is not finite
            self._ahead = None
            return None
        self._ahead_row, self._ahead_state = row + 1, run.states[row + 1]
        return self._ahead_state

    def _row(self, y: np.ndarray, step: int, torque: tuple[float, float]) -> int:
        """The row of y in the steps ahead: the state handed out last, under the same torque; else a new chunk."""
        ahead = self._ahead
        same = ahead is not None and y is self._ahead_state
        if (same and torque is self._ahead_torque and step == self._ahead_step + self._ahead_row
                and self._ahead_row < len(ahead.residuals)):
            return self._ahead_row
        used_up = same and self._ahead_row == len(ahead.residuals)
        self._ahead_size = min(2 * self._ahead_size, AHEAD_MOST) if used_up else AHEAD_FIRST
        self._ahead = self.run(y, step, torque, self._ahead_size, self._ahead_size)
        self._ahead_state = y
        self._ahead_step, self._ahead_row, self._ahead_torque = step, 0, torque
        self._ahead_measured = None
        return 0

    def run(self, y: np.ndarray, step: int, torque: tuple[float, float], instants: int, steps: int,
            sampled: ReferenceRows | None = None) -> CompiledRun:
        """From y, the simulation's ``step``-th instant: the motion at ``instants`` consecutive instants and
        the ``steps`` (``instants`` or one fewer) RK4 steps between and after them (``kernel.robot_run``).
        ``sampled``: ``reference_rows`` of at least ``instants`` from ``step``, if sampled for what is configured
        now (else they are sampled here)."""
        if (sampled is not None and sampled.sampled_for == (self._reference, self._initial_time, self._dt, step)
                and len(sampled.rows) >= instants):
            references = sampled.rows[:instants]
        else:
            references = self.reference_rows(step, instants).rows
        states = np.empty((instants + 1, 2 * DOF))
        states[0] = y
        motions, residuals = np.empty((instants, 3, DOF)), np.empty(instants)
        taken = kernel.robot_run(states, references, self._flags, self._rows, self._constants,
                                 self._torque_array(torque), self._dt, steps, motions, residuals)
        return CompiledRun(states, motions, residuals, references, taken)

    def table(self, run: CompiledRun, first_time: float, first_step: int) -> StepTable:
        """The outputs at the instants of ``run`` (its first the ``first_step``-th, at ``first_time``)."""
        shown = run.instants
        loads, use, drive, wheels = self._measured(run)
        return StepTable(first_time + (first_step + np.arange(shown)) * self._dt, run.states[:shown, :DOF],
                         run.states[:shown, DOF:], run.motions[:shown, 0], run.motions[:shown, 2],
                         run.residuals[:shown], drive, loads, use, np.zeros((shown, 3), dtype=bool), wheels.forces,
                         wheels.use, np.zeros((shown, 4), dtype=bool), wheels.velocities,
                         run.references[:shown, 0, :2] if self._reference is not None else None)

    def _measured(self, run: CompiledRun) -> tuple[np.ndarray, np.ndarray, np.ndarray, WheelOutputs]:
        """Normal loads (T, 4), friction use (T, 3), drive forces (T, 3) and the outputs per wheel at the instants
        of ``run``."""
        shown = run.instants
        loads, drive, use = np.empty((shown, 4)), np.empty((shown, 3)), np.empty((shown, 3))
        forces, wheel_use, velocities = np.empty((shown, 4, 2)), np.empty((shown, 4)), np.empty((shown, 4, 2))
        kernel.ideal_outputs(run.states, run.motions, shown, self._constants, self._contact, loads, drive, use, forces,
                             wheel_use, velocities)
        return loads, use, drive, WheelOutputs(forces, wheel_use, velocities)
