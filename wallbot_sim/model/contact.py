"""Wheel-wall contact (docs/model.md 11): the ideal model, and Coulomb friction with stick and slip.

``ideal``: every constraint holds whatever force it needs; the normal loads and friction use are
reported. ``coulomb``: the friction channels (left and right traction, lateral) stick while
friction can supply their force; a slipping channel's rows leave the solve and kinetic friction
against its slip velocity enters as a generalized force Q_f. Transitions happen at step
boundaries; a wheel whose normal load goes negative has lifted off and ends the run.

The contact model knows constraint modules only through ContactConstraint: which channel each
row belongs to and which wheels' loads bound it.
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.constraints import CHANNELS, LATERAL, LEFT, RIGHT, ConstraintModule, ContactConstraint
from wallbot_sim.model.errors import ModelError, ParameterError
from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.normal_loads import normal_load_gain, normal_loads
from wallbot_sim.model.outputs import DriveForces, StepOutputs
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.solver import ConstrainedMotion, constrained_acceleration, motion_of, solve_with_factor

IDEAL, COULOMB = 'ideal', 'coulomb'
CONTACT_MODELS = (IDEAL, COULOMB)
WHEEL_POSITIONS = ('left front', 'left rear', 'right front', 'right rear')
"""Wheels 1..4 in the order of the generalized coordinates."""
_LOAD_TOLERANCE = 1e-9
"""Relative difference below which the loads the kinetic friction held are the loads it produced."""
_IDENTITY2 = np.eye(2)


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


class _RowSubset:
    """A contact module restricted to the rows of its sticking channels."""

    def __init__(self, module: ContactConstraint, keep: np.ndarray) -> None:
        self.module, self.keep = module, keep
        self.name = module.name
        self.channels = tuple(module.channels[i] for i in keep)
        self.row_wheels = module.row_wheels[keep]

    def rows(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rows, rhs = self.module.rows(t, q, qd)
        return rows[self.keep], rhs[self.keep]

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        return self.module.velocity_rows(q)[self.keep]

    def violation(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self.velocity_rows(q) @ qd


Problem = Callable[[Sequence[ConstraintModule], np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""(active modules, qd) -> Q and their rows A, b stacked in order, at the boundary's time and coordinates."""
Project = Callable[[Sequence[ConstraintModule], np.ndarray], np.ndarray]
"""(active modules, qd) -> qd projected onto their velocity constraints (the constraint-switch impulse)."""
Measure = Callable[[ConstrainedMotion, np.ndarray | None, np.ndarray], tuple[np.ndarray, FrictionUse, DriveForces]]
"""(motion, Q_f or None, qd) -> (normal loads, friction use, drive forces of the whole contact wrench)."""


class SlipVelocities(NamedTuple):
    """The slipping rows at one state: what the friction, its load response and the stopping test share."""

    rows: np.ndarray
    """a_k stacked (rows x 7)."""
    slip: np.ndarray
    """v_k = a_k qd."""
    direction: np.ndarray
    """v_k / sqrt(v_k^2 + eps^2): the smoothed sign kinetic friction opposes."""


class KineticFriction:
    """Q_f(q, qd) of the slipping rows with their bounding loads held over a step (9.3).

    Each slipping row k with velocity row a_k and slip velocity v_k = a_k qd adds
    Q_f -= mu_k N_k v_k / sqrt(v_k^2 + eps^2) a_k, N_k its bounding load: the traction of
    wheel i (N_i, nonslip row) and the lateral friction (F_ad, non-lateral row).
    """

    def __init__(self, parts: Sequence[tuple[Callable[[np.ndarray], np.ndarray], np.ndarray | None]],
                 channels: Sequence[str], per_load: np.ndarray, loads: np.ndarray, epsilon: float) -> None:
        self.parts = parts
        """(a module's velocity_rows, its slipping rows or None for all of them)."""
        self.channels = channels
        """The channel of each slipping row, in the order of the parts."""
        self.per_load = per_load
        """-mu_k times the wheels bounding each row (rows x 4): the bounds are per_load @ N."""
        self.loads = loads
        self.bounds = per_load @ loads
        self.epsilon = epsilon

    def holding(self, loads: np.ndarray) -> KineticFriction:
        """The same rows with other loads held."""
        return KineticFriction(self.parts, self.channels, self.per_load, loads, self.epsilon)

    def velocity_rows(self, q: np.ndarray) -> np.ndarray:
        """The slipping rows a_k at q, stacked."""
        rows = [velocity_rows(q) if selected is None else velocity_rows(q)[selected]
                for velocity_rows, selected in self.parts]
        return rows[0] if len(rows) == 1 else np.concatenate(rows)

    def at(self, q: np.ndarray, qd: np.ndarray) -> SlipVelocities:
        """The slipping rows, their slip velocities and directions at (q, qd)."""
        rows = self.velocity_rows(q)
        slip = rows @ qd
        return SlipVelocities(rows, slip, slip / np.hypot(slip, self.epsilon))

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        rows = self.velocity_rows(q)
        slip = rows @ qd
        return (self.bounds * slip / np.hypot(slip, self.epsilon)) @ rows

    def force(self, slip: SlipVelocities) -> np.ndarray:
        """Q_f at the state ``slip`` was taken at."""
        return (self.bounds * slip.direction) @ slip.rows

    def force_per_load(self, slip: SlipVelocities) -> np.ndarray:
        """dQ_f/dN (7 x 4) at the state ``slip`` was taken at: Q_f = force_per_load @ N."""
        return slip.rows.T @ (slip.direction[:, None] * self.per_load)

    def stopping(self, slip: SlipVelocities, predicted: np.ndarray, stick_velocity: float) -> set[str]:
        """The channels whose every slip velocity a_k qd is below v_st or changes sign by ``predicted``.

        The second test catches a slip that the regularized kinetic friction would reverse in one
        step: near zero slip its stiffness mu_k N / (m eps) makes fixed-step RK4 overshoot into a
        cycle of slip speeds that straddles v_st without ever falling below it.
        """
        stopping = set(self.channels)
        for channel, now, then in zip(self.channels, slip.slip.tolist(), (slip.rows @ predicted).tolist()):
            if not (abs(now) < stick_velocity or now * then < 0.0):
                stopping.discard(channel)
        return stopping


class ContactSolution(NamedTuple):
    """The motion at a step boundary under a stick/slip state, and what the step integrates."""

    motion: ConstrainedMotion
    friction: np.ndarray | None
    """Q_f at the boundary, None while no channel slips."""
    loads: np.ndarray
    use: FrictionUse
    drive: DriveForces
    held: np.ndarray
    """The loads the kinetic friction holds over the step."""
    active: Sequence[ConstraintModule]
    """The modules the solver sees over the step."""
    function: KineticFriction | None
    """Q_f(q, qd) over the step."""
    slip: SlipVelocities | None
    """The slipping rows at the boundary."""


class _Layout:
    """What the contact model derives from one list of modules, for each set of slipping channels.

    Built once per list and slipping set (a step boundary asks for the same ones again and again),
    so a slipping step pays for its friction, not for finding its rows.
    """

    def __init__(self, modules: Sequence[ConstraintModule]) -> None:
        self.modules = modules
        self.contacts: list[ContactConstraint] = [module for module in modules if isinstance(module, ContactConstraint)]
        """The contact modules (found once: a Protocol check is slow)."""
        self.present = frozenset(channel for module in self.contacts for channel in module.channels)
        self._active: dict[frozenset[str], list[ConstraintModule]] = {}
        self._slipping_rows: dict[frozenset[str], list[tuple[ContactConstraint, np.ndarray | None, np.ndarray]]] = {}
        self._load_dependent: dict[frozenset[str], bool] = {}
        self._slipping_channels: dict[frozenset[str], tuple[tuple[str, ...], np.ndarray]] = {}
        self._channel_rows: dict[frozenset[str], list[tuple[ContactConstraint, list[tuple[int, str]]]]] = {}

    def active(self, slipping: frozenset[str]) -> list[ConstraintModule]:
        """The modules without the rows of ``slipping`` channels."""
        active = self._active.get(slipping)
        if active is None:
            contacts = {id(module) for module in self.contacts}
            active = []
            for module in self.modules:
                if id(module) in contacts:
                    keep = np.array([i for i, channel in enumerate(module.channels) if channel not in slipping],
                                    dtype=int)
                    if len(keep) == len(module.channels):
                        active.append(module)
                    elif len(keep):
                        active.append(_RowSubset(module, keep))
                else:
                    active.append(module)
            self._active[slipping] = active
        return active

    def load_dependent(self, slipping: frozenset[str]) -> bool:
        """Whether a slipping row's friction depends on how the load is shared among the wheels."""
        dependent = self._load_dependent.get(slipping)
        if dependent is None:
            dependent = any(not wheels.all() for _module, _rows, wheels in self.slipping_rows(slipping))
            self._load_dependent[slipping] = dependent
        return dependent

    def channel_rows(self, channels: frozenset[str]) -> list[tuple[ContactConstraint, list[tuple[int, str]]]]:
        """(module, its (row, channel) pairs of ``channels``) for the modules that have such rows."""
        found = self._channel_rows.get(channels)
        if found is None:
            found = [(module, rows) for module in self.contacts
                     if (rows := [(row, channel) for row, channel in enumerate(module.channels) if channel in channels])]
            self._channel_rows[channels] = found
        return found

    def slipping_channels(self, slipping: frozenset[str]) -> tuple[tuple[str, ...], np.ndarray]:
        """The channel and the bounding wheels (rows x 4) of each slipping row, in the order of ``slipping_rows``."""
        found = self._slipping_channels.get(slipping)
        if found is None:
            parts = self.slipping_rows(slipping)
            channels = tuple(module.channels[row] for module, rows, _wheels in parts
                             for row in (range(len(module.channels)) if rows is None else rows))
            found = channels, np.concatenate([part_wheels for _module, _rows, part_wheels in parts])
            self._slipping_channels[slipping] = found
        return found

    def slipping_rows(self, slipping: frozenset[str]) -> list[tuple[ContactConstraint, np.ndarray | None, np.ndarray]]:
        """(module, its rows of ``slipping`` channels or None for all of them, the wheels bounding each row)."""
        parts = self._slipping_rows.get(slipping)
        if parts is None:
            parts = []
            for module in self.contacts:
                rows = [i for i, channel in enumerate(module.channels) if channel in slipping]
                if rows:
                    selected = None if len(rows) == len(module.channels) else np.array(rows, dtype=int)
                    parts.append((module, selected, module.row_wheels[rows]))
            self._slipping_rows[slipping] = parts
        return parts


class CoulombContact:
    """The stick/slip state of the channels and the kinetic friction of the slipping ones."""

    def __init__(self, params: RobotParameters, adhesion_force: float) -> None:
        self.kinetic_friction = params.kinetic_friction
        self.epsilon = params.velocity_epsilon
        self.stick_velocity = params.stick_velocity
        self.slipping: frozenset[str] = frozenset()
        self.loads = np.full(4, 0.25 * adhesion_force)
        """The loads bounding kinetic friction, held over a step like the motor torques."""
        self.loads_moving = False
        """Whether the held loads changed at the last boundary (the next one solves for them at once)."""
        self._layout = _Layout([])

    def _layout_of(self, modules: Sequence[ConstraintModule]) -> _Layout:
        """The layout of ``modules`` (remembered for the last list)."""
        if modules is not self._layout.modules:
            self._layout = _Layout(modules)
        return self._layout

    def contacts(self, modules: Sequence[ConstraintModule]) -> list[ContactConstraint]:
        """The contact modules among ``modules``."""
        return self._layout_of(modules).contacts

    def reset(self, adhesion_force: float) -> None:
        """Every channel sticking, loads at rest on a level share."""
        self.slipping = frozenset()
        self.loads = np.full(4, 0.25 * adhesion_force)
        self.loads_moving = False

    # --- the problem the solver sees ---------------------------------------------------------
    def active_modules(self, modules: Sequence[ConstraintModule],
                       slipping: frozenset[str] | None = None) -> list[ConstraintModule]:
        """``modules`` without the rows of slipping channels (the same list while none slips)."""
        slipping = self.slipping if slipping is None else slipping
        if not slipping:
            return modules  # type: ignore[return-value]
        return self._layout_of(modules).active(frozenset(slipping))

    def friction_function(self, modules: Sequence[ConstraintModule], loads: np.ndarray,
                          slipping: frozenset[str] | None = None) -> KineticFriction | None:
        """Q_f(q, qd) of the slipping rows with ``loads`` held; None while none slips."""
        slipping = self.slipping if slipping is None else slipping
        if not slipping:
            return None
        layout = self._layout_of(modules)
        parts = layout.slipping_rows(frozenset(slipping))
        if not parts:
            return None
        channels, wheels = layout.slipping_channels(frozenset(slipping))
        return KineticFriction([(module.velocity_rows, rows) for module, rows, _wheels in parts], channels,
                               -self.kinetic_friction * wheels, loads, self.epsilon)

    def slip_speed(self, modules: Sequence[ConstraintModule], channel: str, q: np.ndarray, qd: np.ndarray) -> float:
        """The largest |slip velocity| of the channel's rows (|h_i| of a side's wheels, |v_lat|)."""
        speed = 0.0
        for module, rows in self._layout_of(modules).channel_rows(frozenset((channel,))):
            slips = (module.velocity_rows(q) @ qd).tolist()
            speed = max([speed] + [abs(slips[row]) for row, _channel in rows])
        return speed

    # --- transitions at a step boundary ------------------------------------------------------
    def settle(self, modules: Sequence[ConstraintModule], robot: Robot, q: np.ndarray, qd: np.ndarray, dt: float,
               problem: Problem, project: Project, measure: Measure) -> tuple[np.ndarray, ContactSolution]:
        """Stick/slip transitions at this boundary, then the motion of the step.

        Slipping channels that are stopping (slower than v_st, or reversing within the step ``dt``)
        stick again when the solve with their rows restored keeps their force within the limit
        (their remaining slip removed by the switch projection); then every sticking channel
        whose force exceeds its limit slips. Returns the velocities (projected if a channel
        stuck again) and the solution the step integrates.
        """
        present = self._layout_of(modules).present
        self.slipping = self.slipping & present
        result = self._solve(modules, robot, self.slipping, q, qd, problem, measure)
        candidates = (result.function.stopping(result.slip, qd + dt * result.motion.acceleration, self.stick_velocity)
                      if result.function is not None else None)
        while candidates:
            trial = self.slipping - candidates
            trial_qd = project(self.active_modules(modules, trial), qd)
            trial_result = self._solve(modules, robot, trial, q, trial_qd, problem, measure)
            holding = {channel for channel in candidates if _within_limit(trial_result.use, channel)}
            if holding == candidates:
                self.slipping, qd, result = trial, trial_qd, trial_result
                break
            candidates = holding
        while True:
            exceeded = {channel for channel in present - self.slipping if not _within_limit(result.use, channel)}
            if not exceeded:
                break
            self.slipping = self.slipping | exceeded
            result = self._solve(modules, robot, self.slipping, q, qd, problem, measure)
        self.loads_moving = bool(self.slipping) and not _converged(result.held.tolist(), self.loads.tolist())
        self.loads = result.held
        return qd, result

    def _solve(self, modules: Sequence[ConstraintModule], robot: Robot, slipping: frozenset[str], q: np.ndarray,
               qd: np.ndarray, problem: Problem, measure: Measure) -> ContactSolution:
        """The motion with ``slipping`` channels slipping, and the loads their friction holds.

        Traction friction depends on the normal loads, which depend on the acceleration: the loads
        the friction holds must be the loads it produces. In a steady slip the loads held over the
        last step still are (one solve checks them); when they moved, ``_consistent_loads`` finds
        them exactly, and while they keep moving from step to step it is used at once. A lateral
        slip alone is bounded by sum N_i = F_ad, which needs neither.
        """
        active = self.active_modules(modules, slipping)
        force, rows, rhs = problem(active, qd)
        mass, factor = robot.mass_matrix(q), robot.mass_inverse_factor(q)
        held = self.loads
        function = self.friction_function(modules, held, slipping)
        if function is None:
            motion = solve_with_factor(mass, factor, force, rows, rhs)
            loads, use, drive = measure(motion, None, qd)
            return ContactSolution(motion, None, loads, use, drive, held, active, None, None)
        slip = function.at(q, qd)
        dependent = self._layout_of(modules).load_dependent(frozenset(slipping))
        if not (dependent and self.loads_moving):
            friction = function.force(slip)
            motion = solve_with_factor(mass, factor, force + friction, rows, rhs)
            loads, use, drive = measure(motion, friction, qd)
            if not dependent or _converged(loads.tolist(), held.tolist()):
                return ContactSolution(motion, friction, loads, use, drive, held, active, function, slip)
        per_load = function.force_per_load(slip)
        held, acceleration = _consistent_loads(robot, q, qd, factor, force, rows, rhs, per_load)
        function = function.holding(held)
        friction = per_load @ held
        motion = motion_of(mass, force + friction, rows, rhs, acceleration)
        loads, use, drive = measure(motion, friction, qd)
        return ContactSolution(motion, friction, loads, use, drive, held, active, function, slip)


def _consistent_loads(robot: Robot, q: np.ndarray, qd: np.ndarray, factor: np.ndarray, force: np.ndarray,
                      rows: np.ndarray, rhs: np.ndarray, per_load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The loads h the kinetic friction Q_f = F h holds that are also the loads it produces, and qdd.

    At a boundary everything is affine in h: qdd = qdd_0 + D h, D the solver's response to F (the
    same solve with four more right-hand sides), and N = N(qdd_0) + U C h with C = B D[:3] (2 x 4;
    ``normal_load_gain``: the loads move only through the two body-frame inertia forces). So the
    fixed point h = N solves (I - U C) h = N(qdd_0), a rank-2 update of I:
    h = N(qdd_0) + U (I_2 - C U)^-1 C N(qdd_0).
    """
    columns = constrained_acceleration(factor, np.concatenate((force[:, None], per_load), axis=1), rows,
                                       np.concatenate((rhs[:, None], np.zeros((len(rhs), 4))), axis=1))
    free, response = columns[:, 0], columns[:, 1:]
    arms, body = normal_load_gain(robot, q)
    coupling = body @ response[:3]  # the body-frame force per unit of each held load (2 x 4)
    unheld = normal_loads(robot, q, qd, free)
    held = unheld + arms @ _solve_2x2(_IDENTITY2 - coupling @ arms, coupling @ unheld)
    return held, free + response @ held


def _converged(loads: list[float], held: list[float]) -> bool:
    """Whether the loads the friction held are the loads it produced, to _LOAD_TOLERANCE."""
    return (max(abs(new - old) for new, old in zip(loads, held))
            <= _LOAD_TOLERANCE * sum(abs(load) for load in loads))


def _solve_2x2(matrix: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """matrix^-1 vector by Cramer's rule (a general solver costs more than the rest of the fixed point)."""
    (a, b), (c, d) = matrix.tolist()
    x, y = vector.tolist()
    determinant = a * d - b * c
    if determinant == 0.0:
        raise ModelError('normal loads and kinetic friction have no consistent value (singular coupling)')
    return np.array([(d * x - b * y) / determinant, (a * y - c * x) / determinant])


def _within_limit(use: FrictionUse, channel: str) -> bool:
    return not use[CHANNELS.index(channel)] > 1.0


def slip_flags(slipping: frozenset[str]) -> tuple[bool, bool, bool]:
    """(left, right, lateral) slipping flags."""
    return tuple(channel in slipping for channel in CHANNELS)  # type: ignore[return-value]


def unheld_slip(robot: Robot, selection: ConstraintSelection, out: StepOutputs) -> dict[str, float]:
    """Channels moving faster than v_st with no friction holding them, and their slip speed (m/s).

    A channel is held while its rows are active and it sticks; otherwise it slides when its slip
    velocity (|h_i| of a side's wheels, |v_lat|) exceeds v_st: a slipping channel, or a robot
    without the non-lateral or nonslip constraint sliding down the wall. None with the
    trajectory task on: the task holds the robot.
    """
    if selection.trajectory:
        return {}
    theta = float(out.q[2])
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    xd, yd, thd = out.qd[:3].tolist()
    v_long, v_lat = cos_t * xd + sin_t * yd, -sin_t * xd + cos_t * yd
    wheel_slip = np.abs(robot.params.wheel_radius * out.qd[3:] - v_long + robot.lateral_offsets * thd)
    speeds = {LEFT: float(max(wheel_slip[:2])), RIGHT: float(max(wheel_slip[2:])), LATERAL: abs(v_lat)}
    rows = {LEFT: selection.nonslip, RIGHT: selection.nonslip, LATERAL: selection.non_lateral}
    slipping = dict(zip(CHANNELS, out.contact.slipping))
    return {channel: speed for channel, speed in speeds.items()
            if speed > robot.params.stick_velocity and (slipping[channel] or not rows[channel])}
