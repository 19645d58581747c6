"""Wheel-wall contact (docs/model.md 11): the ideal model, and Coulomb friction per wheel with stick and slip.

``ideal``: every constraint holds whatever force it needs; the normal loads and each wheel's share
of the contact force are reported. ``coulomb``: each wheel's contact point sticks to the wall while
its friction disc can hold it: its contact rows (the directions that nonslip and non-lateral motion
give friction) stay in the solve. A sliding wheel's rows leave the solve and its kinetic friction
(``kinetic_friction``) enters as a generalized force Q_f, held over the step with the loads it
holds. Transitions happen at step boundaries; a wheel whose normal load goes negative has lifted
off and ends the run.

The contact model knows constraint modules only through ContactConstraint: which direction of
the wheels' contact velocity a module's friction holds.
"""

from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.constraints import (
    LATERAL, LONGITUDINAL, BaumgarteGains, ConstraintModule, ContactConstraint, WheelContact)
from wallbot_sim.model.contact_kinematics import LATERAL_ROW, LONGITUDINAL_ROW, ContactKinematics
from wallbot_sim.model.errors import ModelError, ParameterError
from wallbot_sim.model.kinetic_friction import BoundaryResponse, consistent_friction
from wallbot_sim.model.normal_loads import load_acceleration_gain, normal_loads
from wallbot_sim.model.outputs import StepOutputs
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.solver import ConstrainedMotion, constrained_acceleration, solve_with_factor
from wallbot_sim.model.wheel_forces import split_contact_force, wheel_use

IDEAL, COULOMB = 'ideal', 'coulomb'
CONTACT_MODELS = (IDEAL, COULOMB)
WHEEL_POSITIONS = ('left front', 'left rear', 'right front', 'right rear')
"""Wheels 1..4 in the order of the generalized coordinates."""
WHEELS = frozenset(range(4))
_ROW_OF_DIRECTION = {LONGITUDINAL: LONGITUDINAL_ROW, LATERAL: LATERAL_ROW}
_SETTLE_PASSES = 8
"""Rounds of a boundary's transitions at most (each round stops a reversing wheel for good)."""
_AT_REST = 1e-12
"""Contact speed (m/s) up to which a wheel is at rest: the round-off a projection leaves, with no direction that a
step could reverse."""


def check_contact_model(name: str) -> str:
    """``name`` if it is a contact model, else a ParameterError naming it."""
    if name not in CONTACT_MODELS:
        raise ParameterError(f'unknown contact model {name!r} (use {" or ".join(CONTACT_MODELS)})')
    return name


class DetachedError(ModelError):
    """A wheel's normal load went negative: the robot peels off the wall."""

    def __init__(self, wheel: int, load: float, t: float) -> None:
        super().__init__(f'wheel {wheel} ({WHEEL_POSITIONS[wheel - 1]}) lifted off the wall: '
                         f'normal load {load:.2f} N at t = {t:.3f} s')
        self.wheel, self.load, self.t = wheel, load, t


def friction_directions(modules: Sequence[ConstraintModule]) -> tuple[int, ...]:
    """The rows of the contact velocity (0 along x_p, 1 along y_p) that the contact modules among ``modules`` give
    friction, in order."""
    return tuple(sorted({_ROW_OF_DIRECTION[module.direction] for module in modules
                         if isinstance(module, ContactConstraint)}))


class ContactLayout:
    """What coulomb contact derives from one list of modules: the others, the friction directions, and the
    modules the solver sees for each set of sticking wheels (built once per set)."""

    def __init__(self, modules: Sequence[ConstraintModule], kinematics: ContactKinematics,
                 gains: BaumgarteGains) -> None:
        self.modules, self.gains = modules, gains
        self.others: list[ConstraintModule] = [module for module in modules
                                               if not isinstance(module, ContactConstraint)]
        """The modules no friction holds (the belt, tasks, modules of your own)."""
        self.directions = friction_directions(modules)
        self.kinematics = kinematics
        self.wheels = WHEELS if self.directions else frozenset()
        """The wheels that have friction at all."""
        self._active: dict[frozenset[int], list[ConstraintModule]] = {}

    def active(self, sticking: frozenset[int]) -> list[ConstraintModule]:
        """The other modules, then the contact rows of the ``sticking`` wheels."""
        active = self._active.get(sticking)
        if active is None:
            active = list(self.others)
            if sticking and self.directions:
                active.append(WheelContact(self.kinematics, self.gains, sorted(sticking), self.directions))
            self._active[sticking] = active
        return active


class HeldFriction:
    """Q_f(q) = sum_i J_i(q)^T f_i of the sliding wheels, their forces held in body axes over a step."""

    def __init__(self, kinematics: ContactKinematics, wheels: np.ndarray, directions: np.ndarray,
                 forces: np.ndarray) -> None:
        self.kinematics, self.wheels, self.directions, self.forces = kinematics, wheels, directions, forces

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.forces @ self.kinematics.jacobian(float(q[2]))[self.wheels, self.directions]


class ContactSolution(NamedTuple):
    """The contact at a step boundary under a stick/slip state, and what the step holds."""

    motion: ConstrainedMotion
    sliding: frozenset[int]
    """The sliding wheels (0..3)."""
    loads: np.ndarray
    """N (4,): the loads the step holds, those of ``motion`` (docs/model.md 11.1 with the spin momentum)."""
    wheel_forces: np.ndarray
    """f (4, 2), body axes: the sticking wheels' split of the contact force, the sliding ones' kinetic friction."""
    velocities: np.ndarray
    """v (4, 2): the contact velocities at the boundary."""
    predicted: np.ndarray
    """(4, 2): the sliding wheels' contact velocities predicted for the step's end (zero for the others)."""
    friction_force: np.ndarray | None
    """Q_f (7,) at the boundary, None while no wheel slides."""
    friction: HeldFriction | None
    """Q_f(q, qd) over the step, None while no wheel slides."""
    active: list[ConstraintModule]
    """The modules the solver sees over the step."""


Project = Callable[[Sequence[ConstraintModule], np.ndarray], np.ndarray]
"""(modules, qd) -> qd projected onto their velocity constraints (the constraint-switch impulse)."""


class CoulombState(NamedTuple):
    """What coulomb contact holds over the step from a settled boundary: a restarted run takes it up again."""

    sliding: frozenset[int]
    """The sliding wheels (0..3)."""
    loads: np.ndarray
    """(4,): the loads held over the step (N)."""
    friction: np.ndarray
    """(4, 2): the sliding wheels' forces (body axes), zero for the others (N)."""


class CoulombContact:
    """Which wheels slide, and the loads their friction and rolling resistance hold over a step."""

    def __init__(self, robot: Robot, gains: BaumgarteGains) -> None:
        self.kinematics = ContactKinematics(robot)
        self.gains = gains
        self.sliding: frozenset[int] = frozenset()
        self.loads = np.full(4, 0.25 * robot.wall_load)
        """The loads held over the step (Newton's start at the next boundary)."""
        self.friction = np.zeros((4, 2))
        """The sliding wheels' forces held over the step (body axes), zero for the others (Newton's start too)."""
        self._layout = ContactLayout([], self.kinematics, gains)

    def reset(self, wall_load: float) -> None:
        """Every wheel sticking, loads at rest on a level share of ``wall_load`` (``Robot.wall_load``)."""
        self.sliding = frozenset()
        self.loads = np.full(4, 0.25 * wall_load)
        self.friction = np.zeros((4, 2))

    @property
    def state(self) -> CoulombState:
        """The sliding wheels, loads and friction held now (copies)."""
        return CoulombState(self.sliding, self.loads.copy(), self.friction.copy())

    def take_up(self, state: CoulombState) -> None:
        """Hold ``state`` (a run's, at the boundary it is restored at) as if this contact had settled it."""
        loads, friction = np.array(state.loads, dtype=float), np.array(state.friction, dtype=float)
        if loads.shape != (4,) or friction.shape != (4, 2) or not set(state.sliding) <= set(range(4)):
            raise ParameterError('a coulomb contact state has 4 loads, 4 x 2 friction components and wheels 0..3')
        self.sliding, self.loads, self.friction = frozenset(state.sliding), loads, friction

    def layout(self, modules: Sequence[ConstraintModule]) -> ContactLayout:
        """The layout of ``modules`` (remembered for the last list and gains)."""
        if modules is not self._layout.modules or self.gains is not self._layout.gains:
            self._layout = ContactLayout(modules, self.kinematics, self.gains)
        return self._layout

    def active_modules(self, modules: Sequence[ConstraintModule]) -> list[ConstraintModule]:
        """What the solver sees of ``modules``: the others, and the contact rows of the sticking wheels."""
        layout = self.layout(modules)
        return layout.active(layout.wheels - self.sliding)

    def slide_where_fast(self, modules: Sequence[ConstraintModule], held: set[tuple[int, int]], q: np.ndarray,
                         qd: np.ndarray, stick_velocity: float) -> None:
        """After a switch to ``modules``: a wheel moving at v_st or faster in the directions that get friction and
        were not ``held`` ((wheel, contact row) pairs) slides on, rather than being stopped by the switch's
        projection."""
        velocities = self.kinematics.velocities(q, qd)
        fast = set()
        for wheel in range(4):
            added = [row for row in friction_directions(modules) if (wheel, row) not in held]
            if added and float(np.linalg.norm(velocities[wheel, added])) >= stick_velocity:
                fast.add(wheel)
        self.sliding = self.sliding | frozenset(fast)

    # --- a step boundary ---------------------------------------------------------------------
    def settle(self, robot: Robot, modules: Sequence[ConstraintModule], t: float, q: np.ndarray, qd: np.ndarray,
               dt: float, motor_torque: tuple[float, float], project: Project) -> tuple[np.ndarray, ContactSolution]:
        """Stick/slip transitions at this boundary, then what the step holds (docs/model.md 11.3).

        In turn, until nothing changes: a sliding wheel whose slip the step would reverse (v_i . w_i < 0,
        w_i its predicted end-of-step slip) is stopped by the switch projection and slides on from rest;
        sliding wheels that are stopping (|v_i| or |w_i| below v_st) stick again when the solve with their
        rows restored holds them in their friction discs (their slip projected away); then every sticking
        wheel whose force leaves its disc (|f_i| > mu_s N_i) slides. Returns the velocities (projected
        where a wheel stopped or stuck) and the solution the step integrates.
        """
        layout = self.layout(modules)
        params = robot.params
        static, kinetic = robot.wheel_friction(q)  # each wheel's patch's, held over the step
        sliding = self.sliding & layout.wheels
        solution = self._solve(robot, layout, sliding, t, q, qd, dt, motor_torque, kinetic)
        stopped: set[int] = set()
        for _ in range(_SETTLE_PASSES):
            reversing = {wheel for wheel in solution.sliding - stopped
                         if _reverses(solution, wheel, layout.directions)}
            if reversing:
                stopped |= reversing
                qd = project(layout.active(layout.wheels - sliding | frozenset(reversing)), qd)
                solution = self._solve(robot, layout, sliding, t, q, qd, dt, motor_torque, kinetic)
            candidates = {wheel for wheel in sliding
                          if _speed(solution.velocities[wheel], layout.directions) < params.stick_velocity
                          or _speed(solution.predicted[wheel], layout.directions) < params.stick_velocity}
            while candidates:
                trial = sliding - candidates
                trial_qd = project(layout.active(layout.wheels - trial), qd)
                trial_solution = self._solve(robot, layout, trial, t, q, trial_qd, dt, motor_torque, kinetic)
                holding = {wheel for wheel in candidates if _holds(trial_solution, wheel, static[wheel])}
                if holding == candidates:
                    sliding, qd, solution = trial, trial_qd, trial_solution
                    break
                candidates = holding
            while exceeded := {wheel for wheel in layout.wheels - sliding
                               if not _holds(solution, wheel, static[wheel])}:
                sliding = sliding | exceeded
                solution = self._solve(robot, layout, sliding, t, q, qd, dt, motor_torque, kinetic)
            if not any(_reverses(solution, wheel, layout.directions) for wheel in solution.sliding - stopped):
                break
        self.sliding, self.loads = sliding, solution.loads
        self.friction = np.where(np.isin(np.arange(4), list(sliding))[:, None], solution.wheel_forces, 0.0)
        return qd, solution

    def _solve(self, robot: Robot, layout: ContactLayout, sliding: frozenset[int], t: float, q: np.ndarray,
               qd: np.ndarray, dt: float, motor_torque: tuple[float, float], kinetic: np.ndarray) -> ContactSolution:
        """The motion with the ``sliding`` wheels sliding: their friction (``kinetic``: mu_k per wheel) and every
        wheel's load solved together (``consistent_friction``), then the sticking wheels' share of the constraint
        force."""
        params = robot.params
        active = layout.active(layout.wheels - sliding)
        directions = np.array(layout.directions, dtype=int)
        wheel_of = np.repeat(np.array(sorted(sliding), dtype=int), len(directions))
        direction_of = np.tile(directions, len(sliding))
        jacobian = self.kinematics.jacobian(float(q[2]))
        slip_rows = jacobian[wheel_of, direction_of]
        parts = [module.rows(t, q, qd) for module in active]
        rows = np.concatenate([part[0] for part in parts]) if parts else np.empty((0, 7))
        rhs = np.concatenate([part[1] for part in parts]) if parts else np.empty(0)
        unloaded = robot.applied_force(q, qd, motor_torque, np.zeros(4))
        forces = np.column_stack((unloaded, slip_rows.T, robot.rolling_resistance_per_load(q, qd)))
        right_sides = np.zeros((len(rhs), forces.shape[1]))
        right_sides[:, 0] = rhs
        factor = robot.mass_inverse_factor(q)
        response = constrained_acceleration(factor, forces, rows, right_sides)
        count = len(wheel_of)
        solved = consistent_friction(
            BoundaryResponse(response[:, 0], response[:, 1:1 + count], response[:, 1 + count:],
                             normal_loads(robot, q, qd, np.zeros(7), spin_momentum=True),
                             load_acceleration_gain(robot, q, spin_momentum=True), slip_rows, slip_rows @ qd,
                             self.kinematics.drift(q, qd)[direction_of], wheel_of),
            kinetic[wheel_of], params.velocity_epsilon, dt, self.loads, self.friction[wheel_of, direction_of],
            robot.adsorption.applied_force or robot.total_mass * params.gravity)  # the residual's scale
        held = HeldFriction(self.kinematics, wheel_of, direction_of, solved.friction) if count else None
        friction = solved.friction @ slip_rows if count else None
        force = robot.applied_force(q, qd, motor_torque, solved.loads)
        motion = solve_with_factor(robot.mass_matrix(q), factor, force if friction is None else force + friction,
                                   rows, rhs)
        wheel_forces = np.zeros((4, 2))
        wheel_forces[wheel_of, direction_of] = solved.friction
        predicted = np.zeros((4, 2))
        predicted[wheel_of, direction_of] = solved.predicted
        sticking = sorted(layout.wheels - sliding)
        if sticking:
            stuck_wheels = np.repeat(np.array(sticking, dtype=int), len(directions))
            stuck_directions = np.tile(directions, len(sticking))
            other_rows = [module.rows(t, q, qd)[0] for module in layout.others]
            wheel_forces[stuck_wheels, stuck_directions] = split_contact_force(
                jacobian[stuck_wheels, stuck_directions], solved.loads[stuck_wheels],
                np.concatenate(other_rows) if other_rows else np.empty((0, 7)), motion.constraint_force)
        return ContactSolution(motion, sliding, solved.loads, wheel_forces, jacobian @ qd, predicted, friction, held,
                               active)


def _speed(velocity: np.ndarray, directions: Sequence[int]) -> float:
    """|v| over the directions that have friction."""
    return float(np.linalg.norm(velocity[list(directions)]))


def _reverses(solution: ContactSolution, wheel: int, directions: Sequence[int]) -> bool:
    """Whether the step would reverse the wheel's slip, v_i . w_i < 0; never for a wheel at rest (|v_i| up to
    _AT_REST), whose velocity's direction is round-off."""
    velocity = solution.velocities[wheel]
    return float(velocity @ solution.predicted[wheel]) < 0.0 and _speed(velocity, directions) > _AT_REST


def _holds(solution: ContactSolution, wheel: int, static_friction: np.floating) -> bool:
    """Whether the wheel's force lies in its friction disc, |f_i| <= mu_s N_i."""
    force = solution.wheel_forces[wheel]
    return not float(np.hypot(force[0], force[1])) > static_friction * float(solution.loads[wheel])


class CoulombTable(NamedTuple):
    """What coulomb contact's outputs derive from settled boundaries, at consecutive instants or robots (rows)."""

    drive: np.ndarray
    """(F_L, F_R, F_lat) (T, 3): the channels as sums of the wheels' forces (each side's longitudinal forces, every
    lateral one)."""
    use: np.ndarray
    """The channels' friction use (T, 3) (``friction_use``)."""
    limits: np.ndarray
    """mu_s (N_1 + N_2), mu_s (N_3 + N_4), mu_s F_ad (T, 3)."""
    slipping: np.ndarray
    """(T, 3) bool: the channels a sliding wheel belongs to (a side's traction when a wheel of that side slides with
    longitudinal friction, the lateral channel when any wheel slides with lateral friction)."""
    wheel_use: np.ndarray
    """|f_i| / (mu_s N_i) (T, 4) (``wheel_use``)."""


def coulomb_table(loads: np.ndarray, wheel_forces: np.ndarray, sliding: np.ndarray, directions: Sequence[int],
                  static_friction: float | np.ndarray, wall_load: float | np.ndarray,
                  wheel_static_friction: np.ndarray | None = None) -> CoulombTable:
    """The outputs of settled boundaries from their loads (T, 4), wheel forces (T, 4, 2) and sliding wheels (T, 4):
    one definition for the single robot's engines and the batch's, the lift-off instant's (a lifted wheel slides
    with no force) included. ``static_friction`` (the channels') and ``wall_load`` (F_ad + m_t g cos i, bounding
    the lateral channel): one value, or one per row; ``wheel_static_friction`` (T, 4) each wheel's mu_s where it
    is on a patch of its own (None: ``static_friction``)."""
    static, adhesion = np.asarray(static_friction, dtype=float), np.asarray(wall_load, dtype=float)
    along, across = wheel_forces[..., 0], wheel_forces[..., 1]
    drive = np.stack((along[:, 0] + along[:, 1], along[:, 2] + along[:, 3],
                      across[:, 0] + across[:, 1] + across[:, 2] + across[:, 3]), axis=1)
    bounding = np.stack((loads[:, 0] + loads[:, 1], loads[:, 2] + loads[:, 3],
                         np.broadcast_to(adhesion, loads[:, 0].shape)), axis=1)
    limits = static[..., None] * bounding
    magnitude = np.abs(drive)
    with np.errstate(divide='ignore', invalid='ignore'):
        ratio = magnitude / limits
    use = np.where(limits > 0.0, ratio, np.where(magnitude == 0.0, 0.0, np.inf))
    longitudinal, lateral = LONGITUDINAL_ROW in directions, LATERAL_ROW in directions
    slipping = np.stack((longitudinal & (sliding[:, 0] | sliding[:, 1]), longitudinal & (sliding[:, 2] | sliding[:, 3]),
                         lateral & np.any(sliding, axis=1)), axis=1)
    wheel_static = static[..., None] if wheel_static_friction is None else wheel_static_friction
    return CoulombTable(drive, use, limits, slipping, wheel_use(wheel_forces, loads, wheel_static))


def unheld_slip(robot: Robot, selection: ConstraintSelection, out: StepOutputs) -> dict[str, float]:
    """Wheels (by position) whose contact point moves faster than v_st with no friction holding it, and that
    speed (m/s).

    A sticking wheel is held in the directions whose friction row is active (x_p with nonslip, y_p with
    non-lateral motion); a sliding wheel in none. A wheel's unheld speed is |v_i| over the directions not held:
    so a sliding wheel, or a robot without the non-lateral or nonslip constraint sliding down the wall. None
    with the trajectory task on: the task holds the robot.
    """
    if selection.trajectory:
        return {}
    free = [row for row, held in ((LONGITUDINAL_ROW, selection.nonslip), (LATERAL_ROW, selection.non_lateral))
            if not held]
    speeds = {}
    for name, velocity, sliding in zip(WHEEL_POSITIONS, out.contact.slip_velocity, out.contact.wheel_slipping):
        speed = float(np.hypot(velocity[0], velocity[1])) if sliding else _speed(velocity, free)
        if speed > robot.params.stick_velocity:
            speeds[name] = speed
    return speeds