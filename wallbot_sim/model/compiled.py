"""One robot's dynamics by the batch's compiled kernel (``Simulation(..., engine='numba')``).

With ideal contact the kernel's ``robot_run`` takes a chunk of one robot's RK4 steps in one call, with
the motion at each state: the batch's derivative and step, the same forces, the module rows in
stacking order and the same normal-equation solve as the numba batch engine (which agrees with the
Python model to 1e-9). The loads, friction use and drive forces of a chunk are measured at once with
the batch's array functions; the reference at the RK4 instants is sampled in Python for the chunk.

With coulomb contact (per wheel) the kernel's ``robot_contact_run`` takes a chunk of boundaries and steps
the same way: each boundary settled as ``CoulombContact.settle`` settles it, then the step from it; the
chunk's outputs are derived at once (``coulomb_table``).
"""

from __future__ import annotations

from typing import NamedTuple, Self

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.contact import drive_forces, friction_use, normal_loads
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.constraints import BaumgarteGains
from wallbot_sim.model.constraints.look_ahead import PointReference
from wallbot_sim.model.contact import COULOMB, CoulombContact, HeldFriction, coulomb_table
from wallbot_sim.model.contact_kinematics import contact_velocities
from wallbot_sim.model.errors import ModelError, ParameterError
from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.outputs import ContactOutputs, DriveForces, StepTable
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.robot import DOF, Robot
from wallbot_sim.model.simulation import NUMBA, Simulation
from wallbot_sim.model.solver import ConstrainedMotion
from wallbot_sim.model.trajectories import Circle, Reference
from wallbot_sim.model.wheel_forces import WheelOutputs, ideal_wheel_outputs

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


def compile_run(contact: str) -> None:
    """Compile what a numba ``Simulation`` under ``contact`` steps by, or load it from numba's cache: the kernel's
    run, which takes the steps under the trajectory task whatever the contact model, and with coulomb contact
    its contact run, which takes a driven robot's."""
    still = np.zeros(DOF)
    simulation = Simulation(Robot(RobotParameters()), Circle(1.0, 20.0), ConstraintSelection.parse('belt'),
                            still, still, contact=contact, engine=NUMBA)
    simulation.step()
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
            flags, _ = kernel.module_flags(selection.active_names())
            if flags[0] or flags[1]:
                raise ParameterError('the look-ahead point task takes the place of the trajectory task: '
                                     'a selection without it is needed')
            self._selection, self._flags = selection, flags
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


class _Configured:
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
        self._constants = np.empty(0)
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


class CompiledDynamics(_Configured):
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
        self._batches: dict[int, RobotBatch] = {}
        """RobotBatch of that many copies of the robot, by size (the chunks' sizes are few)."""
        self._ahead: CompiledRun | None = None
        self._ahead_step, self._ahead_row = 0, 0
        """The simulation's step of the chunk's row 0, and the row whose state was handed out last."""
        self._ahead_state: np.ndarray | None = None
        self._ahead_torque: tuple[float, float] | None = None
        self._ahead_size = AHEAD_FIRST
        self._ahead_measured: tuple[np.ndarray, np.ndarray, np.ndarray, WheelOutputs] | None = None

    def _forget(self, robot_changed: bool = False) -> None:
        if robot_changed:
            self._batches = {}
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
        robots = self._batches.get(shown)
        if robots is None:  # built once per size: a driven run's chunks of 4 and 8 steps alternate
            robots = self._batches[shown] = RobotBatch([self._robot] * shown)
        q = run.states[:shown]
        loads = normal_loads(robots, q[:, :DOF], q[:, DOF:], run.motions[:shown, 0])
        drive = drive_forces(q[:, 2], run.motions[:shown, 2, :3], robots.half_track)
        wheels = ideal_wheel_outputs(self._robot, q[:, :DOF], q[:, DOF:], run.motions[:shown, 2, :3], loads)
        return loads, friction_use(robots, drive, loads), drive, wheels


class ContactRun(NamedTuple):
    """Consecutive boundaries and steps of one robot with coulomb contact (``kernel.robot_contact_run``)."""

    states: np.ndarray
    """(T + 1, 14): the state each step reached (row 0 the first instant's, before its boundary)."""
    settled: np.ndarray
    """(T, 14): each instant's state as its boundary left it (velocities projected where a wheel stopped or stuck)."""
    solutions: np.ndarray
    """(T, 8, 8): each boundary's solution (``kernel.SOLUTION_ROWS``)."""
    sliding: np.ndarray
    """(T, 4) bool: the wheels sliding over each step."""
    outcome: np.ndarray
    """The instants settled, the steps taken, how the run ended (``kernel.RAN``...), a boundary's error code."""


class Boundary(NamedTuple):
    """What ``Simulation.outputs`` takes from a settled boundary."""

    y: np.ndarray
    """The state (14,) with its velocities as the boundary left them."""
    motion: ConstrainedMotion
    drive: DriveForces
    contact: ContactOutputs
    friction: HeldFriction | None
    """Q_f(q, qd) of the sliding wheels over the step (``Simulation.solve``'s), None while none slides."""


class CompiledCoulomb(_Configured):
    """The coulomb boundaries and RK4 steps of one robot, for what a ``Simulation`` has active now.

    The kernel settles boundaries and takes steps ahead, a chunk per call (``robot_contact_run``), from the
    state and the contact state (the ``CoulombContact``'s sliding wheels and held loads) the simulation has;
    ``boundary`` and ``step`` answer from the chunk while the simulation goes on from what was handed out last
    (the state, the contact state written into its ``CoulombContact``), under the same configuration and motor
    torque (the same objects). Anything else starts a new chunk there, settling the boundary again as the
    Python model does. A chunk's outputs are derived at once; its sizes follow ``CompiledDynamics``'.
    """

    def __init__(self, initial_time: float, dt: float) -> None:
        super().__init__(initial_time, dt)
        self._contact = np.empty(0)
        self._wheel_sets = tuple(frozenset(wheel for wheel in range(4) if mask >> wheel & 1) for mask in range(16))
        """The sets of wheels, by bit mask (wheel i: bit i)."""
        self._ahead: ContactRun | None = None
        self._ahead_step, self._ahead_row = 0, 0
        self._ahead_state: np.ndarray | None = None
        """The state handed out last: the settled state of row ``_ahead_row`` if ``_at_boundary``, else its state
        before the boundary."""
        self._at_boundary = False
        self._ahead_torque: tuple[float, float] | None = None
        self._handed: tuple[CoulombContact | None, frozenset[int] | None, np.ndarray | None] = (None, None, None)
        """The contact state the chunk wrote last (its ``CoulombContact``, sliding wheels and loads objects)."""
        self._ahead_size = AHEAD_FIRST
        self._ahead_outputs: tuple | None = None
        self._directions: tuple[int, ...] = ()
        """The contact velocity's rows that have friction (0 along x_p with nonslip, 1 along y_p with non-lateral)."""
        self._components: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def _forget(self, robot_changed: bool = False) -> None:
        if robot_changed:
            self._contact = kernel.contact_constants(self._robot)
        nonslip, non_lateral = self._flags[kernel.MODULE_ORDER.index('nonslip')], self._flags[
            kernel.MODULE_ORDER.index('non_lateral')]
        self._directions = tuple(row for row, friction in ((0, nonslip), (1, non_lateral)) if friction)
        self._components = {}
        self._ahead = None

    def boundary(self, y: np.ndarray, step: int, torque: tuple[float, float], coulomb: CoulombContact) -> Boundary:
        """The settled boundary of y (14,), the simulation's ``step``-th instant, under ``coulomb``'s contact state,
        which it updates (``CoulombContact.settle``); ModelError where friction and loads have no solution."""
        run = self._ahead
        if (run is not None and y is self._ahead_state and not self._at_boundary and self._same(step, torque, coulomb)
                and self._ahead_row < run.outcome[0]):
            row = self._ahead_row
        else:
            used_up = run is not None and y is self._ahead_state and self._ahead_row == len(run.solutions)
            self._ahead_size = min(2 * self._ahead_size, AHEAD_MOST) if used_up else AHEAD_FIRST
            run = self._ahead = self._run(y, step, torque, coulomb, self._ahead_size)
            self._ahead_step, self._ahead_torque, self._ahead_outputs = step, torque, None
            row = 0
        instants, _, ended, error = run.outcome.tolist()
        if row == instants and ended == kernel.FAILED:
            self._ahead = None
            raise ModelError(kernel.CONTACT_ERRORS[error].format(run.solutions[row, kernel.STATUS,
                                                                               kernel.NEWTON_RESIDUAL]))
        if self._ahead_outputs is None:
            self._ahead_outputs = self._outputs(run)
        motion, drive, contact, masks = self._ahead_outputs
        mask = masks[row]
        coulomb.sliding, coulomb.loads = self._wheel_sets[mask], contact[0][row]
        self._handed = (coulomb, coulomb.sliding, coulomb.loads)
        self._ahead_row, self._ahead_state, self._at_boundary = row, run.settled[row], True
        friction = None
        if mask:
            wheel_of, direction_of = self._sliding_components(mask)
            friction = HeldFriction(coulomb.kinematics, wheel_of, direction_of,
                                    contact[3][row].reshape(8)[2 * wheel_of + direction_of])
        return Boundary(self._ahead_state, ConstrainedMotion(*motion[row]), DriveForces(*drive[row]),
                        ContactOutputs(contact[0][row], FrictionUse(*contact[1][row]), contact[2][row],
                                       contact[4][row], run.solutions[row, kernel.FRICTION, :DOF] if mask else None,
                                       contact[3][row], contact[5][row], contact[6][row], contact[7][row]),
                        friction)

    def step(self, y: np.ndarray, step: int, torque: tuple[float, float]) -> np.ndarray | None:
        """The state one RK4 step after the boundary ``boundary`` handed out last (y), or None if it is not
        finite."""
        run = self._ahead
        if run is None or y is not self._ahead_state or not self._at_boundary or step != self._ahead_step + self._ahead_row:
            raise ModelError('a coulomb step needs the boundary of its state first (Simulation.outputs)')
        row = self._ahead_row
        if row >= run.outcome[1]:  # the next state is not finite
            self._ahead = None
            return None
        self._ahead_row, self._ahead_state, self._at_boundary = row + 1, run.states[row + 1], False
        return self._ahead_state

    def _same(self, step: int, torque: tuple[float, float], coulomb: CoulombContact) -> bool:
        """Whether the simulation goes on as the chunk did: its step, torque and the contact state handed out."""
        return (step == self._ahead_step + self._ahead_row and torque is self._ahead_torque
                and self._handed == (coulomb, coulomb.sliding, coulomb.loads))

    def _run(self, y: np.ndarray, step: int, torque: tuple[float, float], coulomb: CoulombContact,
             instants: int) -> ContactRun:
        """``instants`` boundaries from y, the simulation's ``step``-th instant, and the steps after them."""
        states = np.empty((instants + 1, 2 * DOF))
        states[0] = y
        settled, solutions = np.empty((instants, 2 * DOF)), np.empty((instants, kernel.SOLUTION_ROWS,
                                                                          kernel.SOLUTION_WIDTH))
        sliding = np.array([wheel in coulomb.sliding for wheel in range(4)], dtype=np.bool_)
        slid, outcome = np.empty((instants, 4), dtype=np.bool_), np.zeros(4, dtype=np.int64)
        kernel.robot_contact_run(states, settled, self.reference_rows(step, instants).rows, self._flags,
                                 self._constants, self._contact, self._torque_array(torque), self._dt, instants,
                                 sliding, np.array(coulomb.loads, dtype=float), solutions, slid, outcome)
        self._handed = (coulomb, coulomb.sliding, coulomb.loads)
        return ContactRun(states, settled, solutions, slid, outcome)

    def _outputs(self, run: ContactRun) -> tuple:
        """The motion, drive forces and contact outputs of every boundary the chunk settled, row by row, and the bit
        masks of its sliding wheels."""
        shown = run.outcome[0]
        solutions, settled = run.solutions[:shown], run.settled[:shown]
        loads, forces = solutions[:, kernel.LOADS, :4], solutions[:, kernel.FORCES].reshape(shown, 4, 2)
        sliding = run.sliding[:shown]
        robot = self._robot
        table = coulomb_table(loads, forces, sliding, self._directions, robot.params.wall_friction,
                              robot.adsorption.applied_force)
        velocities = contact_velocities(settled[:, 2], settled[:, DOF:], robot.wheel_offsets, robot.params.wheel_radius)
        masks = (sliding @ (1 << np.arange(4))).tolist()
        motion = list(zip(solutions[:, kernel.QDD, :DOF], solutions[:, kernel.CONSTRAINT, :DOF],
                          solutions[:, kernel.STATUS, kernel.RESIDUAL].tolist()))
        contact = (loads, [tuple(row) for row in table.use.tolist()], [tuple(row) for row in table.limits.tolist()],
                   forces, [tuple(row) for row in table.slipping.tolist()], table.wheel_use,
                   [tuple(row) for row in sliding.tolist()], velocities)
        return motion, [tuple(row) for row in table.drive.tolist()], contact, masks

    def _sliding_components(self, mask: int) -> tuple[np.ndarray, np.ndarray]:
        """Each sliding component's wheel and direction, wheel by wheel (``CoulombContact._solve``'s), for the
        sliding set ``mask``."""
        components = self._components.get(mask)
        if components is None:
            directions = np.array(self._directions, dtype=int)
            wheels = np.array(sorted(self._wheel_sets[mask]), dtype=int)
            components = self._components[mask] = (np.repeat(wheels, len(directions)),
                                                   np.tile(directions, len(wheels)))
        return components
