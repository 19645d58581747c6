"""Coulomb contact per wheel (docs/model.md 11.2-11.4): the turning threshold, spinning wheels, the spin momentum in
the loads, and the load-weighted least-norm force split against an independent optimizer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import lstsq

from model_helpers import contact_jacobian, random_parameters, rotation, wheel_offsets
from wallbot_sim.model import ConstraintSelection, Robot, RobotParameters, Simulation
from wallbot_sim.model.constraints import BaumgarteGains, SynchronousBelt
from wallbot_sim.model.contact import DetachedError
from wallbot_sim.model.wheel_forces import split_chassis_wrench, split_contact_force

DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)
ADHESION = 189.19
FLAT = dict(gravity=0.01, adhesion_force=ADHESION)
"""In-plane gravity negligible: every wheel carries F_ad / 4."""


def at_rest(theta: float = 0.0, torque: tuple[float, float] = (0.0, 0.0), **params) -> Simulation:
    simulation = Simulation(Robot(RobotParameters(**params)), None, DRIVEN, np.array([0.0, 0.0, theta, 0, 0, 0, 0]),
                            np.zeros(7), contact='coulomb')
    simulation.set_motor_torque(*torque)
    return simulation


def turning_threshold(params: RobotParameters, adhesion: float) -> float:
    """T* = mu_s F_ad r / (2 sqrt(1 + (b/a)^2)): each wheel holds T/(2r) along x_p and b T/(2 a r) across."""
    a, b = params.half_wheelbase, params.half_track
    return params.wall_friction * adhesion * params.wheel_radius / (2 * math.sqrt(1 + (b / a) ** 2))


def test_the_turning_threshold_is_1_696_n_m():
    assert turning_threshold(RobotParameters(), ADHESION) == pytest.approx(1.696, abs=5e-4)


@pytest.mark.parametrize('fraction', [0.99, 1.01])
def test_turning_in_place_sticks_below_the_threshold_and_slides_above(fraction):
    """-T, +T on the sides with in-plane gravity negligible: below T* every wheel holds (use T/T*), above it all four
    slide at once (they reach their discs together)."""
    torque = fraction * turning_threshold(RobotParameters(), ADHESION)
    first = at_rest(torque=(-torque, torque), **FLAT).outputs()
    if fraction < 1.0:
        assert first.contact.wheel_slipping == (False, False, False, False)
        assert first.contact.wheel_use == pytest.approx([fraction] * 4, rel=2e-3)  # gravity's 0.09 N aside
    else:
        assert first.contact.wheel_slipping == (True, True, True, True)


def test_below_the_threshold_each_wheel_holds_the_analytic_forces_and_nothing_moves():
    """At 1.54 N m (91 % of T*): f_x = -+T/(2r) (each wheel's torque balance, the belt sharing a side's by load),
    lateral forces -+ b T/(2 a r) front and rear making the yaw moment 2 b T / r; over 1 s nothing moves."""
    torque, r, a, b = 1.54, 0.04, 0.10, 0.12
    simulation = at_rest(torque=(-torque, torque), **FLAT)
    first = simulation.outputs()
    along = torque / (2 * r)
    across = b * torque / (2 * a * r)
    expected = np.array([[-along, -across], [-along, across], [along, -across], [along, across]])
    assert np.allclose(first.contact.wheel_forces, expected, rtol=0, atol=2e-3 * along)  # 0.09 N of gravity
    final = simulation.run(1.0, lambda out: None)
    assert not any(final.contact.wheel_slipping)
    assert np.max(np.abs(final.q[:3])) < 1e-9 and abs(final.qd[2]) < 1e-9


def test_above_the_threshold_all_four_wheels_slide_and_scrub_resists_the_turn():
    """At 1.85 N m it turns with all four wheels sliding; the front and rear wheels scrub sideways, their friction
    resisting the yaw."""
    simulation = at_rest(torque=(-1.85, 1.85), **FLAT)
    trace = []
    final = simulation.run(1.0, trace.append)
    assert all(out.contact.wheel_slipping == (True, True, True, True) for out in trace[1:])
    assert final.qd[2] > 1.0 and final.q[2] > 0.5
    assert np.hypot(*final.q[:2]) < 0.01  # in place
    lateral = final.contact.slip_velocity[:, 1]
    assert lateral[0] * lateral[1] < 0.0 and lateral[2] * lateral[3] < 0.0  # front and rear scrub opposite ways
    scrub = final.contact.wheel_forces[:, 1] @ wheel_offsets(simulation.robot.params)[:, 0]  # their yaw moment
    assert scrub < -1.0  # N m, against the turn


def test_spinning_wheels_facing_x_lose_their_grip_and_slide_down():
    """3 N m per side facing +X: the wheels spin and slide along x_p, keep little lateral grip, and the robot slides
    down more than 3 m within 1 s (it may peel off before: the run ends there)."""
    simulation = at_rest(0.0, (3.0, 3.0))
    lowest = [0.0]
    try:
        simulation.run(1.0, lambda out: lowest.__setitem__(0, min(lowest[0], out.q[1])))
    except DetachedError as detached:
        assert detached.t > 0.9
    assert lowest[0] < -3.0
    held = 9.0 * 9.81 * 1.0 ** 2 / 2
    assert lowest[0] > -held  # short of a free fall


def momentum_rate(params: RobotParameters, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """The wheels' spin angular momentum J_w sum pd_i y_p in the wall frame (in-plane)."""
    axle = rotation(q[2]) @ np.array([0.0, 1.0])
    return params.wheel_spin_inertia * np.sum(qd[3:]) * axle


def test_the_loads_balance_the_rate_of_the_wheels_spin_momentum():
    """The reported loads, with gravity and inertia at the CoM height, make the in-plane moment that turns the
    wheels' spin momentum, its rate taken by central differences of the momentum along a simulated turning slide
    (wheels spinning up while the robot yaws)."""
    simulation = at_rest(math.pi / 2, (3.0, 1.2))
    params, adhesion = simulation.robot.params, simulation.robot.adsorption.applied_force
    outputs = []
    simulation.run(0.3, outputs.append)
    dt, h, m_t = simulation.dt, params.com_height, simulation.robot.total_mass
    checked = 0
    for before, out, after in zip(outputs[:-2], outputs[1:-1], outputs[2:]):
        if before.contact.wheel_slipping != after.contact.wheel_slipping:
            continue
        rate = (momentum_rate(params, after.q, after.qd) - momentum_rate(params, before.q, before.qd)) / (2 * dt)
        force = m_t * (np.array([0.0, -params.gravity]) - out.acceleration[:2])  # CoM at the centre (c = 0)
        points = (rotation(out.q[2]) @ wheel_offsets(params).T).T
        moment = np.array([points[:, 1] @ out.contact.loads - h * force[1], -points[:, 0] @ out.contact.loads + h * force[0]])
        assert np.allclose(moment, rate, rtol=0, atol=2e-3), f't = {out.t:.3f} s'
        assert np.sum(out.contact.loads) == pytest.approx(adhesion)
        checked += 1
    assert checked > 250
    assert np.linalg.norm(rate) > 0.5  # N m: the term the loads take account of is not small


def kkt_split(weights: np.ndarray, matrix: np.ndarray, target: np.ndarray, free: int = 0) -> np.ndarray:
    """argmin sum f_k^2 / w_k subject to matrix [f, mu] = target (mu: ``free`` unweighted unknowns), from the
    Lagrange conditions [[H, C^T], [C, 0]] [x, l] = [0, target], H = diag(2 / w, 0), solved by SciPy's lstsq."""
    count, size = len(weights), matrix.shape[1]
    hessian = np.diag(np.concatenate((2.0 / weights, np.zeros(free))))
    system = np.block([[hessian, matrix.T], [matrix, np.zeros((len(target), len(target)))]])
    solution = lstsq(system, np.concatenate((np.zeros(size), target)), cond=1e-13)[0]
    return solution[:count]


def test_the_chassis_wrench_split_is_the_weighted_least_norm_one():
    """Ideal contact's split of (F_X, F_Y, M_Z) over the four wheels, against the stated problem's Lagrange conditions."""
    rng = np.random.default_rng(21)
    for _ in range(20):
        params = random_parameters(rng)
        theta = rng.uniform(-math.pi, math.pi)
        loads = rng.uniform(5.0, 80.0, 4)
        wrench = rng.normal(0.0, 30.0, 3)
        got = split_chassis_wrench(np.array([theta]), wrench[None], loads[None], wheel_offsets(params))[0]
        # unknowns f_x1, f_y1, ..., f_y4 in body axes; the wrench they make, wall frame, about the centre
        matrix = np.zeros((3, 8))
        for i, (a, s) in enumerate(wheel_offsets(params)):
            matrix[:2, 2 * i:2 * i + 2] = rotation(theta)
            matrix[2, 2 * i:2 * i + 2] = (-s, a)
        expected = kkt_split(np.repeat(loads, 2), matrix, wrench).reshape(4, 2)
        assert np.allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())


def test_the_contact_split_leaves_the_belt_force_free():
    """Coulomb contact's split over the sticking wheels' contact rows, the belt's force free, against the Lagrange
    conditions with the belt's two multipliers as unweighted unknowns; the contact force is made from random wheel
    and belt forces."""
    rng = np.random.default_rng(22)
    for _ in range(20):
        params = random_parameters(rng)
        q = np.concatenate((rng.uniform(-1, 1, 2), [rng.uniform(-math.pi, math.pi)], np.zeros(4)))
        wheels = sorted(rng.choice(4, size=int(rng.integers(2, 5)), replace=False).tolist())
        jacobian = contact_jacobian(params, q)[wheels].reshape(-1, 7)
        belt = SynchronousBelt(BaumgarteGains()).velocity_rows(q)
        loads = rng.uniform(5.0, 80.0, 4)
        force = jacobian.T @ rng.normal(0.0, 20.0, len(jacobian)) + belt.T @ rng.normal(0.0, 1.0, 2)
        got = split_contact_force(jacobian, np.repeat(loads[wheels], 2), belt, force)
        expected = kkt_split(np.repeat(loads[wheels], 2), np.hstack((jacobian.T, belt.T)), force, free=2)
        assert np.allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
        belt_part = force - jacobian.T @ got  # what the split leaves to the belt: a belt force
        assert np.allclose(belt_part, belt.T @ np.linalg.lstsq(belt.T, belt_part, rcond=None)[0], atol=1e-9)


@pytest.mark.parametrize('theta, torque, params', [
    (math.pi / 2, (-3.0, 3.0), {}),        # fast slips: wheels spinning at hundreds of rad/s while scrubbing
    (0.0, (-1.85, 1.85), FLAT),            # slow slips: the turn starts from rest just above the threshold
    (0.0, (3.0, 3.0), {}),                 # spinning wheels sliding down, their slip turning as the robot yaws
])
def test_a_1_ms_step_is_as_accurate_as_a_quarter_of_it(theta, torque, params):
    """The sliding wheels' friction held over a step in the direction the step ends with stays stable and accurate
    at 1 ms where a wheel's spin follows its friction in microseconds: the run at 0.25 ms ends within 0.5 %."""
    ends = []
    for dt in (1e-3, 2.5e-4):
        simulation = Simulation(Robot(RobotParameters(**params)), None, DRIVEN,
                                np.array([0.0, 0.0, theta, 0, 0, 0, 0]), np.zeros(7), dt=dt, contact='coulomb')
        simulation.set_motor_torque(*torque)
        final = simulation.run(0.5)
        assert all(final.contact.wheel_slipping)
        ends.append(np.concatenate((final.q[:3], final.qd[:3])))
    scale = np.abs(ends[1]).max()
    assert np.allclose(ends[0], ends[1], rtol=0, atol=5e-3 * scale)
    assert scale > 1.0
