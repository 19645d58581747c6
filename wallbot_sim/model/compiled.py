"""One robot's ideal-contact dynamics by the batch's compiled kernel (``Simulation(..., engine='numba')``).

The kernel's ``robot_motion`` and ``robot_step`` are the batch's derivative and RK4 step for a single
robot: the same forces, the module rows in stacking order and the same normal-equation solve as the
numba batch engine (which agrees with the Python model to 1e-9). What stays in Python is what the
simulation asks of the outputs besides the motion (loads, friction use, drive forces) and the
reference, sampled a chunk of steps ahead. ``robot_run`` takes a whole chunk of steps in one call, and
``CompiledDynamics.table`` measures their outputs with the batch's array functions (``Simulation.run_table``).
"""

from __future__ import annotations

import numpy as np

from typing import NamedTuple

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.contact import drive_forces, friction_use, normal_loads
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.constraint_set import MODULES, ConstraintSelection
from wallbot_sim.model.constraints import BaumgarteGains
from wallbot_sim.model.outputs import StepTable
from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.simulation import NUMBA, Simulation
from wallbot_sim.model.solver import ConstrainedMotion
from wallbot_sim.model.trajectories import Reference

REFERENCE_CHUNK = 256
"""Steps whose reference instants are sampled at once."""
_NO_REFERENCE = np.zeros((3, kernel.REFERENCE_FIELDS))
_UNKNOWN = np.empty(0)
"""``robot_step``'s "no first stage given"."""


def require_numba() -> None:
    """Raise ParameterError unless numba imported (the compiled engine can run)."""
    if not kernel.available():
        raise ParameterError("engine 'numba' needs the numba package (pip install numba)")


def compile_kernel() -> None:
    """Compile the kernel's motion, RK4 step and run, or load them from numba's cache (which the first
    compilation on a machine writes, 20-60 s), so that no simulation's first numba step waits for it."""
    still = np.zeros(DOF)
    simulation = Simulation(Robot(RobotParameters()), None, ConstraintSelection.parse('belt', trajectory=False), still,
                            still, engine=NUMBA)
    simulation.step()
    simulation.outputs()
    simulation.run_table(2 * simulation.dt, lambda _table: None)


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


class CompiledDynamics:
    """The motion at a state and the RK4 step of one robot, for what a ``Simulation`` has active now.

    ``configure`` is cheap when nothing changed (it compares identities), so the simulation calls it
    before each use.
    """

    def __init__(self, initial_time: float, dt: float) -> None:
        require_numba()
        self._initial_time, self._dt = initial_time, dt
        self._robot: Robot | None = None
        self._gains: BaumgarteGains | None = None
        self._selection: ConstraintSelection | None = None
        self._reference: Reference | None = None
        self._constants = np.empty(0)
        self._flags, self._rows = np.zeros(len(kernel.MODULE_ORDER), dtype=np.bool_), 0
        self._tasks = False
        """Whether an active module reads the reference (else its samples are not needed)."""
        self._chunk_start, self._chunk = 0, np.empty((0, 3, kernel.REFERENCE_FIELDS))
        self._torque_pair: tuple[float, float] | None = None
        self._batch: RobotBatch | None = None
        self._torque = np.zeros(2)

    def configure(self, robot: Robot, gains: BaumgarteGains, selection: ConstraintSelection,
                  reference: Reference | None, dt: float) -> CompiledDynamics:
        """Take the simulation's robot, gains, active set and reference (rebuilding what changed); returns self."""
        if robot is not self._robot or gains is not self._gains:
            self._robot, self._gains = robot, gains
            self._constants = kernel.robot_constants(RobotBatch([robot]), np.array([gains.alpha]),
                                                     np.array([gains.beta]))[0]
        if selection is not self._selection:
            self._selection = selection
            active = selection.active_names()
            self._flags, self._rows = kernel.module_flags(active)
            self._tasks = any(MODULES[name].task for name in active)
            self._chunk = self._chunk[:0]
        if reference is not self._reference or dt != self._dt:
            self._reference, self._dt = reference, dt
            self._chunk = self._chunk[:0]
        return self

    def motion(self, y: np.ndarray, step: int, torque: tuple[float, float]) -> ConstrainedMotion:
        """qdd, Q_c and the residual at state y (14,), the simulation's ``step``-th instant."""
        motion = np.empty((3, DOF))
        residual = kernel.robot_motion(y, self._references(step)[0], self._flags, self._rows, self._constants,
                                       self._torque_array(torque), motion)
        return ConstrainedMotion(motion[0], motion[2], residual)

    def step(self, y: np.ndarray, step: int, torque: tuple[float, float],
             acceleration: np.ndarray | None) -> np.ndarray | None:
        """The state one RK4 step after y, or None if it is not finite; ``acceleration``: qdd at y if known."""
        out = np.empty(2 * DOF)
        finite = kernel.robot_step(y, self._references(step), self._flags, self._constants, self._torque_array(torque),
                                   self._dt, _UNKNOWN if acceleration is None else acceleration, out)
        return out if finite else None

    def run(self, y: np.ndarray, step: int, torque: tuple[float, float], instants: int, steps: int) -> CompiledRun:
        """From y, the simulation's ``step``-th instant: the motion at ``instants`` consecutive instants and
        the ``steps`` (``instants`` or one fewer) RK4 steps between and after them, as ``motion`` and
        ``step`` would give them one by one."""
        references = kernel.reference_samples(self._reference, self._initial_time, step, instants, self._dt)
        states = np.empty((instants + 1, 2 * DOF))
        states[0] = y
        motions, residuals = np.empty((instants, 3, DOF)), np.empty(instants)
        taken = kernel.robot_run(states, references, self._flags, self._rows, self._constants,
                                 self._torque_array(torque), self._dt, steps, motions, residuals)
        return CompiledRun(states, motions, residuals, references, taken)

    def table(self, run: CompiledRun, first_time: float, first_step: int) -> StepTable:
        """The outputs at the instants of ``run`` (its first the ``first_step``-th, at ``first_time``)."""
        shown = run.instants
        robots = self._batch
        if robots is None or robots.robots[0] is not self._robot or robots.size != shown:
            robots = self._batch = RobotBatch([self._robot] * shown)  # every row this robot: a run's chunks share it
        q, qd = run.states[:shown, :DOF], run.states[:shown, DOF:]
        acceleration, constraint_force = run.motions[:shown, 0], run.motions[:shown, 2]
        loads = normal_loads(robots, q, qd, acceleration)
        drive = drive_forces(q[:, 2], constraint_force[:, :3], robots.half_track)
        return StepTable(first_time + (first_step + np.arange(shown)) * self._dt, q, qd, acceleration,
                         constraint_force, run.residuals[:shown], drive, loads, friction_use(robots, drive, loads),
                         np.zeros((shown, 3), dtype=bool),
                         run.references[:shown, 0, :2] if self._reference is not None else None)

    def _torque_array(self, torque: tuple[float, float]) -> np.ndarray:
        if torque is not self._torque_pair:
            self._torque_pair, self._torque = torque, np.array(torque, dtype=float)
        return self._torque

    def _references(self, step: int) -> np.ndarray:
        """(3, 10): the reference at the step's RK4 instants (zeros when no active module reads it)."""
        if not self._tasks or self._reference is None:
            return _NO_REFERENCE
        index = step - self._chunk_start
        if not 0 <= index < len(self._chunk):
            self._chunk_start, index = step, 0
            self._chunk = kernel.reference_samples(self._reference, self._initial_time, step, REFERENCE_CHUNK, self._dt)
        return self._chunk[index]
