"""One robot's coulomb contact (per wheel) by the batch's compiled kernel (``Simulation(..., engine='numba',
contact='coulomb')``).

The kernel's ``robot_contact_run`` takes a chunk of boundaries and steps the way ``robot_run`` takes a chunk of
ideal steps (``wallbot_sim.model.compiled``): each boundary settled as ``CoulombContact.settle`` settles it, then
the step from it; the chunk's outputs are derived at once (``coulomb_table``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from wallbot_sim.model.batch import kernel
from wallbot_sim.model.compiled import AHEAD_FIRST, AHEAD_MOST, Configured
from wallbot_sim.model.contact import CoulombContact, HeldFriction, coulomb_table
from wallbot_sim.model.contact_kinematics import contact_velocities
from wallbot_sim.model.errors import ModelError
from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.outputs import ContactOutputs, DriveForces
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.solver import ConstrainedMotion

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


class CompiledCoulomb(Configured):
    """The coulomb boundaries and RK4 steps of one robot, for what a ``Simulation`` has active now.

    The kernel settles boundaries and takes steps ahead, a chunk per call (``robot_contact_run``), from the
    state and the contact state (the ``CoulombContact``'s sliding wheels, held loads and friction) the simulation has;
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
        self._handed: tuple[CoulombContact | None, frozenset[int] | None, np.ndarray | None, np.ndarray | None] = (
            None, None, None, None)
        """The contact state the chunk wrote last (its ``CoulombContact``, sliding wheels, loads and friction
        objects)."""
        self._ahead_size = AHEAD_FIRST
        self._ahead_outputs: tuple | None = None
        self._directions: tuple[int, ...] = ()
        """The contact velocity's rows that have friction (0 along x_p with nonslip, 1 along y_p with non-lateral)."""
        self._components: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def _forget(self, robot_changed: bool = False) -> None:
        if robot_changed:
            self._contact = kernel.contact_constants(self._robot)
        self._directions = tuple(row for row, flag in enumerate(kernel.HELD_BY) if self._flags[flag])
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
        motion, drive, contact, masks, held = self._ahead_outputs
        mask = masks[row]
        coulomb.sliding, coulomb.loads, coulomb.friction = self._wheel_sets[mask], contact[0][row], held[row]
        self._handed = (coulomb, coulomb.sliding, coulomb.loads, coulomb.friction)
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
        held = (coulomb, coulomb.sliding, coulomb.loads, coulomb.friction)
        return (step == self._ahead_step + self._ahead_row and torque is self._ahead_torque
                and all(handed is now for handed, now in zip(self._handed, held)))

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
                                 sliding, np.array(coulomb.loads, dtype=float),
                                 np.array(coulomb.friction, dtype=float).reshape(8), solutions, slid, outcome, False)
        self._handed = (coulomb, coulomb.sliding, coulomb.loads, coulomb.friction)
        return ContactRun(states, settled, solutions, slid, outcome)

    def _outputs(self, run: ContactRun) -> tuple:
        """The motion, drive forces and contact outputs of every boundary the chunk settled, row by row, the bit
        masks of its sliding wheels and the friction each boundary holds (``CoulombContact.friction``)."""
        shown = run.outcome[0]
        solutions, settled = run.solutions[:shown], run.settled[:shown]
        loads, forces = solutions[:, kernel.LOADS, :4], solutions[:, kernel.FORCES].reshape(shown, 4, 2)
        sliding = run.sliding[:shown]
        robot = self._robot
        table = coulomb_table(loads, forces, sliding, self._directions, robot.params.wall_friction,
                              robot.wall_load)
        velocities = contact_velocities(settled[:, 2], settled[:, DOF:], robot.wheel_offsets, robot.params.wheel_radius)
        masks = (sliding @ (1 << np.arange(4))).tolist()
        motion = list(zip(solutions[:, kernel.QDD, :DOF], solutions[:, kernel.CONSTRAINT, :DOF],
                          solutions[:, kernel.STATUS, kernel.RESIDUAL].tolist()))
        contact = (loads, [tuple(row) for row in table.use.tolist()], [tuple(row) for row in table.limits.tolist()],
                   forces, [tuple(row) for row in table.slipping.tolist()], table.wheel_use,
                   [tuple(row) for row in sliding.tolist()], velocities)
        held = forces * sliding[:, :, None]
        return motion, [tuple(row) for row in table.drive.tolist()], contact, masks, held

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
