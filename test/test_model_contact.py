"""Wheel-wall contact (docs/model.md 11): normal loads, friction use, Coulomb stick/slip per wheel, detachment.

The per-wheel analytic cases (turning threshold, wheel spin, spin momentum, the force split) are in
test_model_wheel_contact.py.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from model_helpers import (
    contact_jacobian, contact_velocity, kinetic_energy, least_norm_loads, potential_energy, random_parameters, rotation,
    wheel_offsets)
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, RobotParameters, Simulation
from wallbot_sim.model import contact as contact_module, kinetic_friction
from wallbot_sim.model.batch import kernel
from wallbot_sim.sweep import compute, load_spec
from wallbot_sim.model.contact import WHEEL_POSITIONS, DetachedError, unheld_slip
from wallbot_sim.model.normal_loads import load_acceleration_gain, normal_loads

REPO_ROOT = Path(__file__).resolve().parents[1]
DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)
ALL_SLIDING = (True, True, True, True)


@pytest.fixture(params=['python', pytest.param('numba', marks=pytest.mark.skipif(
    not kernel.available(), reason='numba is not installed'))])
def engine(request) -> str:
    """Each contact case on both engines: the Python model, and the compiled kernel's boundaries and steps."""
    return request.param


def at_rest(theta: float = 0.0, torque: tuple[float, float] = (0.0, 0.0), contact: str = 'coulomb',
            engine: str = 'python', **params) -> Simulation:
    simulation = Simulation(Robot(RobotParameters(**params)), None, DRIVEN,
                            np.array([0.0, 0.0, theta, 0, 0, 0, 0]), np.zeros(7), contact=contact, engine=engine)
    simulation.set_motor_torque(*torque)
    return simulation


def test_normal_loads_are_the_least_norm_balance():
    rng = np.random.default_rng(9)
    for _ in range(50):
        params = random_parameters(rng)
        robot = Robot(params)
        q = np.concatenate((rng.uniform(-1, 1, 2), [rng.uniform(-math.pi, math.pi)], np.zeros(4)))
        qd, qdd = rng.normal(size=7), rng.normal(size=7) * 5
        expected = least_norm_loads(params, robot.adsorption.applied_force, q, qd, qdd)
        assert np.allclose(normal_loads(robot, q, qd, qdd), expected, rtol=1e-12, atol=1e-10)


@pytest.mark.parametrize('spin_momentum', [False, True])
def test_the_loads_are_affine_in_the_acceleration(spin_momentum):
    """N(qdd) = N(0) + L qdd (the form kinetic friction and the loads are solved together with)."""
    rng = np.random.default_rng(10)
    for _ in range(50):
        robot = Robot(random_parameters(rng))
        q = np.concatenate((rng.uniform(-1, 1, 2), [rng.uniform(-math.pi, math.pi)], np.zeros(4)))
        qd, qdd = rng.normal(size=7) * 20, rng.normal(size=7) * 500
        gain = load_acceleration_gain(robot, q, spin_momentum)
        change = (normal_loads(robot, q, qd, qdd, spin_momentum)
                  - normal_loads(robot, q, qd, np.zeros(7), spin_momentum))
        assert np.allclose(gain @ qdd, change, rtol=1e-12, atol=1e-11 * robot.adsorption.applied_force)


def test_the_spin_momentum_loads_are_the_least_norm_balance_with_the_wheels_momentum_rate():
    """11.1 with the wheels' spin momentum, solved as stated: the moment balance less J_w (sum pdd_i, thd sum pd_i)."""
    rng = np.random.default_rng(11)
    for _ in range(50):
        params = random_parameters(rng)
        robot = Robot(params)
        q = np.concatenate((rng.uniform(-1, 1, 2), [rng.uniform(-math.pi, math.pi)], np.zeros(4)))
        qd, qdd = rng.normal(size=7) * 20, rng.normal(size=7) * 500
        rate = params.wheel_spin_inertia * np.array([np.sum(qdd[3:]), qd[2] * np.sum(qd[3:])])
        expected = least_norm_loads(params, robot.adsorption.applied_force, q, qd, qdd, moment_less=rate)
        assert np.allclose(normal_loads(robot, q, qd, qdd, spin_momentum=True), expected, rtol=1e-12, atol=1e-10)


def test_loads_at_rest_match_model_md():
    loads = at_rest(contact='ideal').outputs().contact.loads
    assert loads == pytest.approx([38.10, 38.10, 56.49, 56.49], abs=0.01)  # 56.495: the page rounds down
    robot = Robot(RobotParameters())
    facing_up = normal_loads(robot, np.array([0.0, 0.0, math.pi / 2, 0, 0, 0, 0]), np.zeros(7), np.zeros(7))
    adhesion = robot.adsorption.applied_force
    front = adhesion / 4 - 0.05 * 9.0 * 9.81 / (4 * 0.10)
    assert facing_up == pytest.approx([front, adhesion / 2 - front] * 2)


def test_hold_sticks_at_two_thirds_of_every_wheels_disc(engine):
    """Facing +X with the default adhesion: every wheel's use m_t g / (mu_s F_ad) = 0.667 (the load-weighted
    split shares the weight in proportion to load), nothing moves."""
    simulation = at_rest(engine=engine)
    first = simulation.outputs()
    expected = 9.0 * 9.81 / (0.7 * 189.19)
    assert first.contact.wheel_use == pytest.approx([expected] * 4, rel=1e-4)
    assert first.contact.wheel_use == pytest.approx([0.667] * 4, abs=5e-4)
    assert first.contact.use.lateral == pytest.approx(expected, rel=1e-4)
    assert np.allclose(first.contact.wheel_forces[:, 0], 0.0, atol=1e-9)  # no torque: no longitudinal force
    simulation.run(1.0, assert_sticking)
    assert np.max(np.abs(simulation.q[:3])) < 1e-12


def assert_sticking(out) -> None:
    assert out.contact.wheel_slipping == (False, False, False, False)
    assert out.contact.slipping == (False, False, False)
    assert out.contact.friction_force is None


def test_slide_with_a_weak_adhesion_force(engine):
    """F_ad = 100 N: mu_s F_ad < m_t g, every wheel slides straight down with kinetic friction and rolling
    resistance on its own load: ydd = -g + (mu_k + f_r) F_ad / m_t."""
    simulation = at_rest(adhesion_force=100.0, engine=engine)
    trace = []
    final = simulation.run(1.0, trace.append)
    assert all(out.contact.wheel_slipping == ALL_SLIDING for out in trace)
    assert final.acceleration[1] == pytest.approx(-9.81 + (0.6 + 0.03) * 100.0 / 9.0, abs=1e-5)
    assert final.acceleration[1] == pytest.approx(-2.81, abs=1e-5)
    assert final.q[1] == pytest.approx(-1.405, abs=3e-3)  # the eps-smoothing's millimetres
    assert abs(final.q[0]) < 1e-12 and abs(final.q[2]) < 1e-12
    assert final.contact.loads[:2] == pytest.approx([18.44, 18.44], abs=0.005)
    assert final.contact.wheel_use == pytest.approx([0.6 / 0.7] * 4, rel=1e-6)  # sliding: mu_k / mu_s
    assert np.all(final.contact.wheel_forces[:, 1] > 0.0) and np.allclose(final.contact.wheel_forces[:, 0], 0.0,
                                                                           atol=1e-9)


def test_spinning_climb(engine):
    """Facing up at 3 N m per side the traction needed exceeds every disc: the wheels spin and slide along x_p,
    a = (mu_k F_ad - m_t g - f_r F_ad) / m_t, and the spin-up (J_w sum pdd_i) moves load from the front wheels
    to the rear ones (docs/model.md 11.1)."""
    simulation = at_rest(math.pi / 2, torque=(3.0, 3.0), engine=engine)
    first = simulation.outputs()
    assert first.contact.wheel_slipping == ALL_SLIDING
    final = simulation.run(1.0)
    assert final.contact.wheel_slipping == ALL_SLIDING
    assert final.acceleration[1] == pytest.approx((0.6 * 189.19 - 9.0 * 9.81 - 0.03 * 189.19) / 9.0, abs=1e-3)
    assert final.acceleration[1] == pytest.approx(2.172, abs=5e-4)
    assert abs(final.q[0]) < 1e-9 and final.q[2] == pytest.approx(math.pi / 2, abs=1e-9)
    params = simulation.robot.params
    spin_up = params.wheel_spin_inertia * np.sum(final.acceleration[3:])
    assert spin_up > 1.0  # N m: the wheels spin up at about 1800 rad/s^2
    adhesion = simulation.robot.adsorption.applied_force
    weight_shift = 0.05 * 9.0 * (9.81 + final.acceleration[1]) / (4 * 0.10)
    front = adhesion / 4 - weight_shift - spin_up / (4 * 0.10)
    assert final.contact.loads == pytest.approx([front, adhesion / 2 - front] * 2, abs=1e-6)


def test_traction_needed_to_climb_exceeds_the_side_limit():
    """The solve with every channel sticking asks more of each side than mu_s N_k = 66.2 N."""
    sticking = at_rest(math.pi / 2, torque=(3.0, 3.0), contact='ideal').outputs()
    side_load = sticking.contact.loads[0] + sticking.contact.loads[1]
    assert 0.7 * side_load == pytest.approx(66.2, abs=0.05)
    assert sticking.drive.left > 0.7 * side_load and sticking.contact.use.left > 1.0


def test_detachment_at_the_start_names_wheel_load_and_time(engine):
    """The lift-off instant's outputs: the lifted wheel's disc is empty, so it slides with no force (use 0), the
    others settle as at any instant; then the run ends there."""
    simulation = at_rest(com_height=0.25, adhesion_force=130.0, engine=engine)
    first = simulation.outputs()
    assert first.contact.detached_wheel in (1, 2)  # the upper (left) wheels
    assert first.contact.loads[:2] == pytest.approx([32.5 - 45.98] * 2, abs=0.005)
    lifted = first.contact.loads < 0.0
    assert np.array_equal(lifted, [True, True, False, False])
    assert all(first.contact.wheel_slipping[i] for i in (0, 1))
    assert np.all(first.contact.wheel_forces[lifted] == 0.0) and np.all(first.contact.wheel_use[lifted] == 0.0)
    with pytest.raises(DetachedError, match=r'wheel [12] \(left (front|rear)\).*-13\.48 N at t = 0\.000 s') as error:
        simulation.step()
    assert error.value.t == 0.0 and error.value.load == pytest.approx(-13.48, abs=0.005)
    assert simulation.t == 0.0


def test_ideal_contact_reports_a_negative_load_and_goes_on():
    simulation = at_rest(com_height=0.25, adhesion_force=130.0, contact='ideal')
    final = simulation.run(0.1)
    assert final.contact.loads[0] < 0.0 and final.contact.slipping == (False, False, False)
    assert final.contact.wheel_slipping == (False, False, False, False)
    assert final.contact.wheel_use[0] == 0.0 and np.all(final.contact.wheel_forces[0] == 0.0)  # a lifted wheel


def other_power(params: RobotParameters, torque, q, qd, loads) -> float:
    """Motor power and rolling resistance with each wheel's own load (docs/model.md 4, 11.3), written out here."""
    eps2 = params.velocity_epsilon ** 2
    power = 0.5 * torque[0] * (qd[3] + qd[4]) + 0.5 * torque[1] * (qd[5] + qd[6])
    for load, d in zip(loads, wheel_offsets(params)):
        v = qd[:2] + qd[2] * rotation(q[2]) @ np.array([-d[1], d[0]])
        power -= params.rolling_resistance * max(load, 0.0) * (v @ v) / math.sqrt(v @ v + eps2)
    return power


def friction_power(params: RobotParameters, q, qd, forces) -> float:
    """sum_i f_i . v_i: the sliding wheels' friction (body axes) on their contact velocities."""
    return float(np.sum(forces * contact_velocity(params, q, qd)))


@pytest.mark.parametrize('theta, torque, adhesion, restick', [
    (math.pi / 2, (3.0, 3.0), None, False),      # every wheel spins and slides along x_p
    (math.pi / 2, (3.0, 1.0), None, False),      # the left side spins, the robot turns and scrubs
    (0.0, (-2.2, 2.2), None, False),             # a turn in place above the threshold
    (0.0, (3.0, 3.0), None, False),              # spinning wheels facing +X: sliding down
    (0.0, (0.4, -0.2), 100.0, True),             # sliding down, a little torque
])
def test_friction_never_adds_energy(theta, torque, adhesion, restick, engine):
    """f_i . v_i <= 0 at every instant for every sliding wheel (its held friction against its contact velocity),
    and d/dt (T + V) = motor + rolling resistance + friction power, the friction's work never positive.

    Powers computed here (contact velocities written from docs/model.md 11.3) with the forces and loads each
    instant reports, which the step holds; trapezoidal rule per step. A stop or re-stick's projection only
    removes kinetic energy, so where wheels stop the balance may only fall short."""
    simulation = at_rest(theta, torque, adhesion_force=adhesion, engine=engine)
    params = simulation.robot.params
    states = []

    def record(out):
        sliding = np.array(out.contact.wheel_slipping)
        forces = out.contact.wheel_forces * sliding[:, None]
        powers = np.sum(forces * contact_velocity(params, out.q, out.qd), axis=1)
        assert np.all(powers <= 1e-12 * (1.0 + np.abs(forces).sum())), f't = {out.t:.3f} s: {powers}'
        if out.contact.friction_force is not None:  # Q_f = sum J_i^T f_i, the Jacobian written here
            expected = np.einsum('ij,ijk->k', forces, contact_jacobian(params, out.q))
            assert np.allclose(out.contact.friction_force, expected, rtol=0, atol=1e-9 * max(1.0, np.abs(expected).max()))
        states.append((out.q, out.qd, forces, out.contact.loads,
                       kinetic_energy(params, out.q, out.qd) + potential_energy(params, out.q)))

    try:
        simulation.run(1.0, record)
    except DetachedError:  # the spinning robot may peel off before 1 s; the balance holds up to there
        pass
    work, dissipated = [0.0], 0.0
    for (q0, qd0, forces, loads, _), (q1, qd1, *_) in zip(states[:-1], states[1:]):
        friction = 0.5 * simulation.dt * (friction_power(params, q0, qd0, forces) + friction_power(params, q1, qd1, forces))
        assert friction <= 1e-12
        other = 0.5 * simulation.dt * (other_power(params, torque, q0, qd0, loads) + other_power(params, torque, q1, qd1, loads))
        work.append(work[-1] + other + friction)
        dissipated -= friction
    change = np.array([state[4] for state in states]) - states[0][4]
    exchanged = sum(abs(other_power(params, torque, q, qd, loads)) for q, qd, _, loads, _ in states) * simulation.dt
    assert dissipated > 1.0  # the run does slide
    assert np.max(change - np.array(work)) < 1e-4 * (exchanged + dissipated)
    if not restick:
        assert np.max(np.abs(change - np.array(work))) < 1e-4 * (exchanged + dissipated)


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_the_loads_kinetic_friction_holds_are_the_loads_it_produces(seed, engine):
    """At every boundary of a turning slide (loads shifting step by step, CoM off the centre): the reported loads
    are 11.1's balance (with the spin momentum) of the reported acceleration, every sliding wheel's friction has
    the magnitude mu_k N_i |w| / sqrt(|w|^2 + eps^2) of those loads, and opposes the slip the step ends with."""
    rng = np.random.default_rng(seed)
    params = random_parameters(rng)
    simulation = Simulation(Robot(params), None, DRIVEN, np.array([0.0, 0.0, math.pi / 2, 0, 0, 0, 0]),
                            np.zeros(7), contact='coulomb', engine=engine)
    weight = (params.body_mass + 4 * params.wheel_mass) * params.gravity
    simulation.set_motor_torque(1.2 * weight * params.wheel_radius, 0.5 * weight * params.wheel_radius)
    adhesion = simulation.robot.adsorption.applied_force
    outputs = []
    simulation.run(0.3, outputs.append)
    checked = 0
    for out, after in zip(outputs[:-1], outputs[1:]):
        rate = params.wheel_spin_inertia * np.array([np.sum(out.acceleration[3:]), out.qd[2] * np.sum(out.qd[3:])])
        balance = least_norm_loads(params, adhesion, out.q, out.qd, out.acceleration, moment_less=rate)
        assert np.allclose(out.contact.loads, balance, rtol=0, atol=1e-9 * adhesion)
        end = contact_velocity(params, after.q, after.qd)
        for wheel in np.flatnonzero(out.contact.wheel_slipping):
            force, slip = out.contact.wheel_forces[wheel], end[wheel]
            if np.linalg.norm(slip) < 0.05:
                continue
            expected = params.kinetic_friction * out.contact.loads[wheel]
            assert np.linalg.norm(force) == pytest.approx(expected, rel=1e-3)  # |w| >> eps
            assert force @ slip < -0.99 * np.linalg.norm(force) * np.linalg.norm(slip)
            checked += 1
    assert checked > 200


def test_a_straight_sticking_climb_is_the_ideal_climb(engine):
    """Climbing straight below the traction limit no wheel slides and nothing scrubs: the per-wheel rows hold the
    same motion as the paper's ideal rows (to round-off), and the lateral rows carry no force."""
    runs = []
    for contact in ('ideal', 'coulomb'):
        simulation = at_rest(math.pi / 2, (2.0, 2.0), contact=contact, engine=engine)
        trace = []
        simulation.run(1.0, lambda out: trace.append(np.concatenate((out.q, out.qd, out.acceleration))))
        if contact == 'coulomb':
            assert max(simulation.outputs().contact.wheel_use) < 1.0
            assert np.allclose(simulation.outputs().contact.wheel_forces[:, 1], 0.0, atol=1e-9)
        runs.append(np.array(trace))
    assert np.allclose(runs[0], runs[1], rtol=0, atol=1e-9 * np.abs(runs[0]).max())
    assert runs[0][-1, 1] > 0.3  # it does climb


def test_the_numba_engine_computes_coulomb_contact_as_the_python_model():
    """A turn in place above the threshold (every wheel scrubbing, the loads moving): the kernel's boundaries and
    steps give the Python model's states and outputs per wheel to 1e-9 (test_compiled_contact.py has more)."""
    if not kernel.available():
        pytest.skip('numba is not installed')
    traces = []
    for engine in ('python', 'numba'):
        simulation = at_rest(0.0, (-2.2, 2.2), engine=engine)
        assert not simulation.tabulates
        trace = []
        simulation.run(0.2, lambda out: trace.append(np.concatenate((
            out.q, out.qd, out.acceleration, out.contact.loads, out.contact.wheel_forces.ravel(),
            out.contact.wheel_use, out.contact.slip_velocity.ravel(), out.contact.wheel_slipping))))
        traces.append(np.array(trace))
    python, numba = traces
    assert np.all(python[:, -4:] == 1.0) and np.array_equal(python[:, -4:], numba[:, -4:])  # every wheel slides
    scale = np.maximum(np.max(np.abs(python), axis=0), 1.0)
    assert np.max(np.abs(numba - python) / scale) < 1e-9


def test_coulomb_with_the_trajectory_task_stays_ideal():
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip')
    ends = [Simulation(robot, scenario.reference, selection, q0, qd0, contact=contact).run(0.5)
            for contact in ('ideal', 'coulomb')]
    assert np.array_equal(ends[0].q, ends[1].q) and np.array_equal(ends[0].qd, ends[1].qd)
    assert np.array_equal(ends[0].contact.wheel_forces, ends[1].contact.wheel_forces)


def test_a_slide_stopped_by_more_adhesion_sticks_again(engine):
    simulation = at_rest(adhesion_force=100.0, engine=engine)
    simulation.run(0.2)
    assert simulation.outputs().contact.wheel_slipping == ALL_SLIDING
    simulation.set_adhesion_force(200.0)  # mu_k F_ad + f_r F_ad = 126 N > m_t g: decelerates
    for _ in range(2000):
        if not any(simulation.outputs().contact.wheel_slipping):
            break
        simulation.step()
    out = simulation.outputs()
    assert out.contact.wheel_slipping == (False, False, False, False)
    assert abs(out.qd[1]) < 1e-9  # the remaining slip removed by the projection
    stopped_at = out.q[1]
    simulation.run(0.5)
    assert simulation.q[1] == pytest.approx(stopped_at, abs=1e-9)


def test_a_reversing_wheel_is_stopped_at_the_boundary(engine):
    """A wheel sliding backwards that its motor's torque turns forward within a step: its slip is projected away at
    the boundary (it stops there), then it slides on from rest, its friction opposing the new slip."""
    simulation = at_rest(math.pi / 2, (3.0, 3.0), engine=engine)
    simulation.reset(qd0=np.array([0.0, 0.0, 0.0, -0.2, -0.2, -0.2, -0.2]) / 0.04 * 0.01)  # wheels spinning back
    first = simulation.outputs()
    assert first.contact.wheel_slipping == ALL_SLIDING
    assert np.allclose(first.contact.slip_velocity, 0.0, atol=1e-12)  # stopped at the boundary
    assert np.all(first.contact.wheel_forces[:, 0] > 0.0)  # slides on forward: friction pushes the robot up
    simulation.step()
    assert np.all(simulation.outputs().contact.slip_velocity[:, 0] < 0.0)


def test_switching_contact_model_and_adhesion_between_steps(engine):
    simulation = at_rest(adhesion_force=100.0, engine=engine)
    simulation.run(0.1)
    simulation.set_contact_model('ideal')  # the slid rows are imposed again
    out = simulation.outputs()
    assert out.contact.wheel_slipping == (False, False, False, False) and abs(out.qd[1]) < 1e-9
    assert simulation.contact_model == 'ideal'
    simulation.set_contact_model('coulomb')
    assert simulation.outputs().contact.wheel_slipping == ALL_SLIDING
    with pytest.raises(ValueError, match="unknown contact model 'sticky'"):
        simulation.set_contact_model('sticky')


def test_switching_on_lateral_friction_while_sliding_keeps_the_wheels_sliding(engine):
    """Without non-lateral motion the driven robot falls; switching it on with coulomb contact, wheels moving
    faster than v_st across slide on (no projection stops them), and friction brakes them."""
    simulation = Simulation(Robot(RobotParameters()), None,
                            ConstraintSelection(trajectory=False, belt=True, nonslip=True), np.zeros(7), np.zeros(7),
                            contact='coulomb', engine=engine)
    simulation.run(0.1)
    falling = simulation.qd[1]
    assert falling < -0.5
    report = simulation.set_constraints(DRIVEN)
    assert report.violation_after == pytest.approx(report.violation_before)  # nothing imposed
    out = simulation.outputs()
    assert out.contact.wheel_slipping == ALL_SLIDING and out.qd[1] == falling
    simulation.run(0.05)
    assert falling < simulation.qd[1] < 0.0


def test_a_robot_falling_without_the_lateral_constraint_is_reported_sliding():
    """The driven robot without non-lateral motion falls sideways; ideal or not, that is never silent."""
    robot = Robot(RobotParameters())
    falling = Simulation(robot, None, ConstraintSelection(trajectory=False, belt=True, nonslip=True),
                         np.zeros(7), np.zeros(7))
    assert unheld_slip(robot, falling.selection, falling.outputs()) == {}
    falling.run(0.1)
    sliding = unheld_slip(robot, falling.selection, falling.outputs())
    assert list(sliding) == list(WHEEL_POSITIONS) and min(sliding.values()) > 0.5  # every wheel, sideways
    holding = at_rest()
    holding.run(0.1)
    assert unheld_slip(holding.robot, holding.selection, holding.outputs()) == {}
    slide = at_rest(adhesion_force=100.0)
    slide.run(0.1)
    sliding = unheld_slip(slide.robot, slide.selection, slide.outputs())
    assert list(sliding) == list(WHEEL_POSITIONS)
    assert list(sliding.values()) == pytest.approx([abs(slide.qd[1])] * 4)  # each wheel slides down with the robot
    turning = at_rest(0.4, (-0.9, 1.2))  # turning in place hard enough to slide the rear wheels, not the front
    turning.run(0.1)
    out = turning.outputs()
    assert out.contact.wheel_slipping == (False, True, False, True)
    rear = out.contact.slip_velocity[[1, 3]]
    assert unheld_slip(turning.robot, turning.selection, out) == {'left rear': math.hypot(*rear[0]),
                                                                 'right rear': math.hypot(*rear[1])}


def test_a_new_reference_reaches_the_solver():
    """set_reference rebuilds the modules the solver sees (the active list follows them)."""
    from wallbot_sim.model import Circle
    robot = Robot(RobotParameters())
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip')
    q0 = np.array([0.8, 0.0, 0.0, 0, 0, 0, 0])
    direct = Simulation(robot, Circle(1.0, 20.0), selection, q0, np.zeros(7))
    switched = Simulation(robot, Circle(2.0, 10.0), selection, q0, np.zeros(7))
    switched.set_reference(Circle(1.0, 20.0))
    direct.run(0.2)
    switched.run(0.2)
    assert np.array_equal(direct.q, switched.q)


def test_newton_from_the_held_friction_takes_fewer_iterations_to_the_cold_starts_solution(monkeypatch):
    """Kinetic friction and loads at every boundary of a sweep's robot under the example controller (slips near eps,
    where the friction's direction turns fast with the slip): from the friction each wheel held over the last step,
    Newton's method evaluates its equations about 3 times (the start and two iterations); from the friction opposing
    the frictionless slip, the cold start, about 10. Both reach the same friction and loads to Newton's tolerance
    (1e-12 of F_ad, checked at 1e-10)."""
    calls = {'evaluations': 0}
    equations, solve = kinetic_friction._equations, kinetic_friction.consistent_friction

    def counted(*args):
        calls['evaluations'] += 1
        return equations(*args)

    counts: dict[str, list[int]] = {'warm': [], 'cold': []}

    def both(response, mu, epsilon, dt, loads, held, adhesion):
        calls['evaluations'] = 0
        cold = solve(response, mu, epsilon, dt, loads, np.zeros_like(held), adhesion)
        cold_count, calls['evaluations'] = calls['evaluations'], 0
        warm = solve(response, mu, epsilon, dt, loads, held, adhesion)
        if len(held) and np.all(held != 0.0):  # every component has a held friction
            counts['cold'].append(cold_count)
            counts['warm'].append(calls['evaluations'])
            assert np.allclose(warm.friction, cold.friction, rtol=0, atol=1e-10 * adhesion)
            assert np.allclose(warm.loads, cold.loads, rtol=0, atol=1e-10 * adhesion)
        return warm

    monkeypatch.setattr(kinetic_friction, '_equations', counted)
    monkeypatch.setattr(contact_module, 'consistent_friction', both)
    spec = load_spec(REPO_ROOT / 'bench' / 'sweep_coulomb_controller.yaml')
    compute.single_robot_run(dataclasses.replace(spec.settings, duration=1.5), spec.parameters(0))
    assert len(counts['warm']) > 200
    assert np.mean(counts['warm']) < 3.5 and np.mean(counts['cold']) > 6.0
