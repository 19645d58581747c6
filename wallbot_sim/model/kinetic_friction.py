"""Kinetic friction of the sliding wheels over one step, with the loads it holds (docs/model.md 11.3).

A sliding wheel i's friction opposes its slip velocity at the end of the step, predicted from the
motion at the step's start, and is held over the step (body axes) like the motor torques:

    f_i = -mu_k max(N_i, 0) w_i / sqrt(|w_i|^2 + eps^2),   w = v_S + dt (J_S qdd + c_S)

(the implicit, backward-Euler direction: a wheel's spin can follow its friction within far less
than a step, and only the end of the step's direction keeps that stable). At a step boundary the
acceleration is affine in the sliding wheels' forces and in the loads (through rolling resistance,
f_r N_i), and the loads are affine in the acceleration (``normal_loads``):

    qdd = a + D f + R max(N, 0),   N = N_0 + L qdd.

``consistent_friction`` solves those equations for (f, N) together by Newton's method, so that the
friction and rolling resistance hold the very loads they produce.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from wallbot_sim.model.errors import ModelError

_TOLERANCE = 1e-12
"""Residual, relative to the adhesion force, at which the friction and loads are solved."""
_ITERATIONS = 60


class BoundaryResponse(NamedTuple):
    """What is affine at a step boundary: the motion's response to the sliding wheels' forces and the loads."""

    free: np.ndarray
    """a (7,): qdd with no friction of sliding wheels and no rolling resistance."""
    per_friction: np.ndarray
    """D (7 x m): qdd per newton of each sliding component's force."""
    per_load: np.ndarray
    """R (7 x 4): qdd per newton of each wheel's load, through its rolling resistance."""
    load_origin: np.ndarray
    """N_0 (4,): the loads at qdd = 0."""
    load_gain: np.ndarray
    """L (4 x 7)."""
    slip_rows: np.ndarray
    """J_S (m x 7): the contact rows of the sliding wheels' enabled directions."""
    slip: np.ndarray
    """v_S (m,) = J_S qd."""
    drift: np.ndarray
    """c_S (m,)."""
    wheel_of: np.ndarray
    """(m,) the wheel (0..3) of each sliding component."""


class KineticSolution(NamedTuple):
    """The friction held over the step and the loads it holds."""

    friction: np.ndarray
    """f (m,) per sliding component (N)."""
    loads: np.ndarray
    """N (4,)."""
    predicted: np.ndarray
    """w (m,): the sliding components' slip velocities predicted for the step's end."""


def consistent_friction(response: BoundaryResponse, kinetic_friction: np.ndarray, epsilon: float, dt: float,
                        loads: np.ndarray, held: np.ndarray, adhesion_force: float) -> KineticSolution:
    """(f, N) solving the boundary's equations (Newton's method with a halving line search from ``loads`` and the
    ``held`` friction).

    ``kinetic_friction``: mu_k of each sliding component's wheel (m,); ``held`` (m,): each component's friction held
    over the last step, zero where its wheel did not slide; ``adhesion_force`` scales the tolerance. Newton starts
    from the held friction where there is one (a step changes it little: two iterations, where the cold start below
    takes about eight), else from the friction opposing the slip predicted with none."""
    count = len(response.slip)
    state = np.concatenate((np.zeros(count), loads))
    state[:count] = np.where(held != 0.0, held, _friction_of(response, kinetic_friction, epsilon, dt, state))
    residual, jacobian, predicted = _equations(response, kinetic_friction, epsilon, dt, state)
    size = _norm(residual)
    for _ in range(_ITERATIONS):
        if size <= _TOLERANCE * adhesion_force:
            friction, loads = state[:count], state[count:]
            # a lifted wheel (N_i <= 0) has no friction at all, not a remainder within the tolerance
            return KineticSolution(np.where(loads[response.wheel_of] > 0.0, friction, 0.0), loads.copy(), predicted)
        try:
            step = np.linalg.solve(jacobian, -residual)
        except np.linalg.LinAlgError as error:
            raise ModelError('kinetic friction and normal loads have no consistent value (singular system)') from error
        scale = 1.0
        while True:
            trial = state + scale * step
            trial_residual, trial_jacobian, trial_predicted = _equations(response, kinetic_friction, epsilon, dt,
                                                                         trial)
            trial_size = _norm(trial_residual)
            if trial_size < size or scale < 1e-6:
                break
            scale *= 0.5
        state, residual, jacobian, predicted, size = trial, trial_residual, trial_jacobian, trial_predicted, trial_size
    raise ModelError(f'kinetic friction and normal loads did not converge (residual {size:.3g} N)')


def _norm(vector: np.ndarray) -> float:
    return float(np.max(np.abs(vector))) if len(vector) else 0.0


def _friction_of(response: BoundaryResponse, kinetic_friction: np.ndarray, epsilon: float, dt: float,
                 state: np.ndarray) -> np.ndarray:
    """The friction opposing the slip predicted with no friction, at the loads of ``state`` (Newton's start)."""
    count = len(response.slip)
    if not count:
        return np.zeros(0)
    loads = np.maximum(state[count:], 0.0)
    acceleration = response.free + response.per_load @ loads
    predicted = response.slip + dt * (response.slip_rows @ acceleration + response.drift)
    size = _wheel_speeds(predicted, response.wheel_of, epsilon)
    return -kinetic_friction * loads[response.wheel_of] * predicted / size


def _wheel_speeds(predicted: np.ndarray, wheel_of: np.ndarray, epsilon: float) -> np.ndarray:
    """sqrt(|w_i|^2 + eps^2) of each component's wheel (m,)."""
    squares = np.zeros(4)
    np.add.at(squares, wheel_of, predicted * predicted)
    return np.sqrt(squares + epsilon * epsilon)[wheel_of]


def _equations(response: BoundaryResponse, kinetic_friction: np.ndarray, epsilon: float, dt: float,
               state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residual (m + 4,) of z = (f, N), its Jacobian, and the predicted slip velocities w (m,).

    r_f = f + mu_k max(N_i, 0) w / s,  r_N = N - N_0 - L qdd,  s = sqrt(|w_i|^2 + eps^2) per wheel.
    """
    count = len(response.slip)
    friction, loads = state[:count], state[count:]
    positive = loads > 0.0
    pressed = np.where(positive, loads, 0.0)
    acceleration = response.free + response.per_friction @ friction + response.per_load @ pressed
    by_load = response.per_load * positive  # dqdd/dN
    jacobian = np.zeros((count + 4, count + 4))
    load_residual = loads - response.load_origin - response.load_gain @ acceleration
    jacobian[count:, :count] = -response.load_gain @ response.per_friction
    jacobian[count:, count:] = np.eye(4) - response.load_gain @ by_load
    if not count:
        return load_residual, jacobian, np.zeros(0)
    wheel = response.wheel_of
    predicted = response.slip + dt * (response.slip_rows @ acceleration + response.drift)
    size = _wheel_speeds(predicted, wheel, epsilon)
    direction = predicted / size
    force = kinetic_friction * pressed[wheel]
    friction_residual = friction + force * direction
    # d(w/s)/dw within each wheel: I/s - w w^T/s^3
    same_wheel = wheel[:, None] == wheel[None, :]
    turning = same_wheel * (np.eye(count) - np.outer(direction, direction)) / size[:, None]
    by_slip = force[:, None] * turning  # d(force w/s)/dw
    slip_by_friction = dt * response.slip_rows @ response.per_friction
    slip_by_load = dt * response.slip_rows @ by_load
    jacobian[:count, :count] = np.eye(count) + by_slip @ slip_by_friction
    jacobian[:count, count:] = by_slip @ slip_by_load
    jacobian[np.arange(count), count + wheel] += kinetic_friction * positive[wheel] * direction
    return np.concatenate((friction_residual, load_residual)), jacobian, predicted
