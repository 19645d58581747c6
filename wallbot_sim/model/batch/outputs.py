"""The solution of N robots at one instant (``BatchOutputs``), and a step hook that records them over time."""

from __future__ import annotations

from typing import Callable, NamedTuple, Sequence

import numpy as np

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.trajectories import ReferenceSample, Vec2


class BatchOutputs(NamedTuple):
    """The solution of every robot at one instant (``StepOutputs`` with the robot index first)."""

    t: float
    q: np.ndarray
    """(N, 7)."""
    qd: np.ndarray
    """(N, 7)."""
    acceleration: np.ndarray
    """qdd (N, 7)."""
    constraint_force: np.ndarray
    """Q_c = M qdd - Q (N, 7) (Q_f, the kinetic friction, apart: ``friction_force``)."""
    residual: np.ndarray
    """|A qdd - b| (N,) over the rows in the solve."""
    motor_torque: np.ndarray
    """(tau_L, tau_R) held over the next step (N, 2)."""
    drive: np.ndarray
    """(F_L, F_R, F_lat) (N, 3): the channel forces of the whole contact wrench (constraint force plus Q_f)."""
    loads: np.ndarray
    """Normal loads N_1..N_4 (N, 4)."""
    use: np.ndarray
    """Friction use of the channels (left, right, lateral) (N, 3)."""
    slipping: np.ndarray
    """(N, 3) bool: the channels a sliding wheel belongs to (never with ideal contact)."""
    friction_force: np.ndarray
    """Q_f (N, 7): the sliding wheels' kinetic friction, zero while none of a robot's wheels slides."""
    detached: np.ndarray
    """(N,) bool: the robots stopped by a lifted wheel (their state and outputs the ones they detached at)."""
    reference: ReferenceSample | None
    wheel_forces: np.ndarray
    """f_i (N, 4, 2): each wheel's tangential contact force in body axes (``ContactOutputs.wheel_forces``)."""
    wheel_use: np.ndarray
    """|f_i| / (mu_s N_i) (N, 4)."""
    wheel_slipping: np.ndarray
    """(N, 4) bool: the sliding wheels (never with ideal contact)."""
    slip_velocity: np.ndarray
    """v_i (N, 4, 2): each wheel's contact-point velocity in body axes."""

    @property
    def size(self) -> int:
        return self.q.shape[0]

    @property
    def wheel_torques(self) -> np.ndarray:
        """Total torque on each wheel (N, 4): constraint torque, kinetic friction and its share of the motor."""
        return _wheel_torques(self.constraint_force, self.motor_torque, self.friction_force)

    @property
    def reference_position(self) -> Vec2 | None:
        """The reference point (the same for every robot), None without a reference."""
        return self.reference.position if self.reference is not None else None

    @property
    def tracking_error(self) -> np.ndarray:
        """Distance of each centre from the reference point (N,) (m); NaN without a reference."""
        return _tracking_error(self.q, self.reference_position)



class BatchTable(NamedTuple):
    """The outputs of every robot at T consecutive instants (``BatchOutputs`` with the instant second), the motor
    torques held over them: ``BatchSimulation.run_held``'s."""

    t: np.ndarray
    """(T,)."""
    q: np.ndarray
    """(N, T, 7)."""
    qd: np.ndarray
    """(N, T, 7)."""
    constraint_force: np.ndarray
    """(N, T, 7)."""
    friction_force: np.ndarray
    """(N, T, 7)."""
    residual: np.ndarray
    """(N, T)."""
    motor_torque: np.ndarray
    """(N, 2), held over every instant."""
    drive: np.ndarray
    """(N, T, 3)."""
    loads: np.ndarray
    """(N, T, 4)."""
    wheel_forces: np.ndarray
    """(N, T, 4, 2)."""
    wheel_use: np.ndarray
    """(N, T, 4)."""
    wheel_slipping: np.ndarray
    """(N, T, 4) bool."""
    reference_position: np.ndarray | None
    """(T, 2): the reference point at each instant, None without a reference."""
    on_wall: np.ndarray
    """(N, T) bool: the instants each robot reached on the wall (up to its lift-off instant, included); its values
    after them are not outputs."""

    @property
    def tracking_error(self) -> np.ndarray:
        """(N, T) (m); NaN without a reference."""
        return _tracking_error(self.q, self.reference_position)

    @property
    def wheel_torques(self) -> np.ndarray:
        """(N, T, 4): ``BatchOutputs.wheel_torques`` at every instant."""
        return _wheel_torques(self.constraint_force, self.motor_torque[:, None], self.friction_force)


def _tracking_error(q: np.ndarray, position: Vec2 | np.ndarray | None) -> np.ndarray:
    """Distance of each centre in ``q`` (..., 7) from the reference point ``position`` ((2,), or (..., 2) an instant
    each) (m); NaN without a reference."""
    if position is None:
        return np.full(q.shape[:-1], np.nan)
    offset = q[..., :2] - np.asarray(position)
    return np.hypot(offset[..., 0], offset[..., 1])


def _wheel_torques(constraint_force: np.ndarray, motor_torque: np.ndarray, friction_force: np.ndarray) -> np.ndarray:
    """Total torque on each wheel (..., 4) from Q_c and Q_f (..., 7) and the side torques (..., 2): constraint torque,
    kinetic friction and its share of the motor."""
    motor = 0.5 * np.repeat(motor_torque, 2, axis=-1)
    return constraint_force[..., 3:] + motor + friction_force[..., 3:]


StepHook = Callable[[BatchOutputs], None]
"""Called with the outputs of every instant (``Simulation.run``'s ``on_step`` over a batch)."""


class BatchRecorder:
    """A step hook keeping chosen fields of ``BatchOutputs`` every ``every`` instants: per-robot time series.

    ``series()`` gives 't' (T,) and each field stacked over time, robot index second: q (T, N, 7),
    tracking_error (T, N), ... (any field or property of ``BatchOutputs``).
    """

    def __init__(self, fields: Sequence[str], every: int = 1) -> None:
        unknown = [name for name in fields if not hasattr(BatchOutputs, name)]
        if unknown:
            raise ParameterError(f'BatchOutputs has no field {unknown[0]!r}')
        if every < 1:
            raise ParameterError(f'every must be >= 1, got {every}')
        self.fields, self.every = tuple(fields), every
        self._count = 0
        self._times: list[float] = []
        self._values: dict[str, list[np.ndarray]] = {name: [] for name in self.fields}

    def __call__(self, out: BatchOutputs) -> None:
        if self._count % self.every == 0:
            self._times.append(out.t)
            for name in self.fields:
                self._values[name].append(np.array(getattr(out, name)))
        self._count += 1

    def series(self) -> dict[str, np.ndarray]:
        """'t' and every recorded field, stacked over the recorded instants."""
        return {'t': np.array(self._times), **{name: np.array(values) for name, values in self._values.items()}}
