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

import functools
import math
from typing import Callable, NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.constraints import CHANNELS, LATERAL, LEFT, RIGHT, ConstraintModule, ContactConstraint
from wallbot_sim.model.errors import ModelError, ParameterError
from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.outputs import StepOutputs
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.model.robot import Robot
from wallbot_sim.model.solver import ConstrainedMotion

IDEAL, COULOMB = 'ideal', 'coulomb'
CONTACT_MODELS = (IDEAL, COULOMB)
WHEEL_POSITIONS = ('left front', 'left rear', 'right front', 'right rear')
"""Wheels 1..4 in the order of the generalized coordinates."""
_LOAD_TOLERANCE = 1e-9
"""Relative change of the held loads below which the loads-friction fixed point has converged."""
_LOAD_ITERATIONS = 50


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


Evaluate = Callable[[Sequence[ConstraintModule], np.ndarray | None, np.ndarray], ConstrainedMotion]
"""(active modules, Q_f or None, qd) -> the constrained motion at this instant."""
Project = Callable[[Sequence[ConstraintModule], np.ndarray], np.ndarray]
"""(active modules, qd) -> qd projected onto their velocity constraints (the constraint-switch impulse)."""
Measure = Callable[[ConstrainedMotion, np.ndarray | None, np.ndarray], tuple[np.ndarray, FrictionUse]]
"""(motion, Q_f or None, qd) -> (normal loads, friction use)."""


class ContactSolution(NamedTuple):
    """The motion at a step boundary under a stick/slip state, and what the step integrates."""

    motion: ConstrainedMotion
    friction: np.ndarray | None
    """Q_f at the boundary, None while no channel slips."""
    loads: np.ndarray
    use: FrictionUse
    held: np.ndarray
    """The loads the kinetic friction holds over the step."""
    active: Sequence[ConstraintModule]
    """The modules the solver sees over the step."""
    function: Callable[[np.ndarray, np.ndarray], np.ndarray] | None
    """Q_f(q, qd) over the step."""


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

    # --- the problem the solver sees ---------------------------------------------------------
    def active_modules(self, modules: Sequence[ConstraintModule],
                       slipping: frozenset[str] | None = None) -> list[ConstraintModule]:
        """``modules`` without the rows of slipping channels (the same list while none slips)."""
        slipping = self.slipping if slipping is None else slipping
        if not slipping:
            return modules  # type: ignore[return-value]
        return self._layout_of(modules).active(frozenset(slipping))

    def friction_function(self, modules: Sequence[ConstraintModule], loads: np.ndarray,
                          slipping: frozenset[str] | None = None
                          ) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
        """Q_f(q, qd) of the slipping rows with ``loads`` held; None while none slips.

        Each slipping row k with velocity row a_k and slip velocity v_k = a_k qd adds
        Q_f -= mu_k N_k v_k / sqrt(v_k^2 + eps^2) a_k, N_k its bounding load: the traction of
        wheel i (N_i, nonslip row) and the lateral friction (F_ad, non-lateral row) of 9.3.
        """
        slipping = self.slipping if slipping is None else slipping
        if not slipping:
            return None
        parts = [(module.velocity_rows, rows, -self.kinetic_friction * (wheels @ loads))
                 for module, rows, wheels in self._layout_of(modules).slipping_rows(frozenset(slipping))]
        if not parts:
            return None
        epsilon = self.epsilon

        def part_friction(velocity_rows_of: Callable[[np.ndarray], np.ndarray], rows: np.ndarray | None,
                          bound: np.ndarray, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            velocity_rows = velocity_rows_of(q) if rows is None else velocity_rows_of(q)[rows]
            slip = velocity_rows @ qd
            return (bound * slip / np.hypot(slip, epsilon)) @ velocity_rows

        if len(parts) == 1:  # one slipping module (the usual case): no sum to form
            return functools.partial(part_friction, *parts[0])

        def friction(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            return sum(part_friction(*part, q, qd) for part in parts)
        return friction

    def slip_speed(self, modules: Sequence[ConstraintModule], channel: str, q: np.ndarray, qd: np.ndarray) -> float:
        """The largest |slip velocity| of the channel's rows (|h_i| of a side's wheels, |v_lat|)."""
        speed = 0.0
        for module, rows in self._layout_of(modules).channel_rows(frozenset((channel,))):
            slips = (module.velocity_rows(q) @ qd).tolist()
            speed = max([speed] + [abs(slips[row]) for row, _channel in rows])
        return speed

    def _stopping(self, modules: Sequence[ConstraintModule], channels: frozenset[str], q: np.ndarray, qd: np.ndarray,
                  predicted: np.ndarray) -> set[str]:
        """The channels whose every slip velocity a_k qd is below v_st or changes sign within the step.

        The second test catches a slip that the regularized kinetic friction would reverse in one
        step: near zero slip its stiffness mu_k N / (m eps) makes fixed-step RK4 overshoot into a
        cycle of slip speeds that straddles v_st without ever falling below it.
        """
        stopping = set(channels)
        for module, rows in self._layout_of(modules).channel_rows(channels):
            velocity_rows = module.velocity_rows(q)
            now, then = (velocity_rows @ qd).tolist(), (velocity_rows @ predicted).tolist()
            for row, channel in rows:
                if not (abs(now[row]) < self.stick_velocity or now[row] * then[row] < 0.0):
                    stopping.discard(channel)
        return stopping

    # --- transitions at a step boundary ------------------------------------------------------
    def settle(self, modules: Sequence[ConstraintModule], q: np.ndarray, qd: np.ndarray, dt: float,
               evaluate: Evaluate, project: Project, measure: Measure) -> tuple[np.ndarray, ContactSolution]:
        """Stick/slip transitions at this boundary, then the motion of the step.

        Slipping channels that are stopping (slower than v_st, or reversing within the step ``dt``)
        stick again when the solve with their rows restored keeps their force within the limit
        (their remaining slip removed by the switch projection); then every sticking channel
        whose force exceeds its limit slips. Returns the velocities (projected if a channel
        stuck again) and the solution the step integrates.
        """
        present = self._layout_of(modules).present
        self.slipping = self.slipping & present
        result = self._solve(modules, self.slipping, q, qd, evaluate, measure)
        candidates = (self._stopping(modules, self.slipping, q, qd, qd + dt * result.motion.acceleration)
                      if self.slipping else None)
        while candidates:
            trial = self.slipping - candidates
            trial_qd = project(self.active_modules(modules, trial), qd)
            trial_result = self._solve(modules, trial, q, trial_qd, evaluate, measure)
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
            result = self._solve(modules, self.slipping, q, qd, evaluate, measure)
        self.loads = result.held
        return qd, result

    def _solve(self, modules: Sequence[ConstraintModule], slipping: frozenset[str], q: np.ndarray, qd: np.ndarray,
               evaluate: Evaluate, measure: Measure) -> ContactSolution:
        """The motion with ``slipping`` channels slipping, and the loads their friction holds.

        Traction friction depends on the normal loads, which depend on the acceleration: the two
        are iterated to their fixed point (a lateral slip is bounded by sum N_i = F_ad, which needs none).
        """
        active = self.active_modules(modules, slipping)
        held = self.loads
        for _ in range(_LOAD_ITERATIONS):
            function = self.friction_function(modules, held, slipping)
            friction = None if function is None else function(q, qd)
            motion = evaluate(active, friction, qd)
            loads, use = measure(motion, friction, qd)
            if function is None or not self._layout_of(modules).load_dependent(frozenset(slipping)) \
                    or _converged(loads.tolist(), held.tolist()):
                return ContactSolution(motion, friction, loads, use, held, active, function)
            held = loads
        raise ModelError('normal loads and kinetic friction found no consistent value in '
                         f'{_LOAD_ITERATIONS} iterations (loads {np.round(loads, 3).tolist()} N)')


def _converged(loads: list[float], held: list[float]) -> bool:
    """Whether the loads the friction held are the loads it produced, to _LOAD_TOLERANCE."""
    return (max(abs(new - old) for new, old in zip(loads, held))
            <= _LOAD_TOLERANCE * sum(abs(load) for load in loads))


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
