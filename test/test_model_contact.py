"""Wheel-wall contact (docs/model.md 11): normal loads, friction use, Coulomb stick/slip, detachment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model_helpers import kinetic_energy, potential_energy, random_parameters, rotation, wheel_offsets
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, RobotParameters, Simulation
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.contact import DetachedError, unheld_slip
from wallbot_sim.model.normal_loads import normal_load_gain, normal_loads

DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)


@pytest.fixture(params=['python', pytest.param('numba', marks=pytest.mark.skipif(
    not kernel.available(), reason='numba is not installed'))])
def engine(request) -> str:
    """Each contact case on both engines: the Python model, and the compiled kernel's stick/slip."""
    return request.param


def at_rest(theta: float = 0.0, torque: tuple[float, float] = (0.0, 0.0), contact: str = 'coulomb',
            engine: str = 'python', **params) -> Simulation:
    simulation = Simulation(Robot(RobotParameters(**params)), None, DRIVEN,
                            np.array([0.0, 0.0, theta, 0, 0, 0, 0]), np.zeros(7), contact=contact, engine=engine)
    simulation.set_motor_torque(*torque)
    return simulation


def least_norm_loads(params: RobotParameters, adhesion: float, q, qd, qdd) -> np.ndarray:
    """9.1 solved as stated: the CoM acceleration, the inertial-gravity force in the body frame,
    then the minimum-norm solution of the 3 x 4 balance by numpy's lstsq."""
    m_t = params.body_mass + 4 * params.wheel_mass
    perp = np.array([[0.0, -1.0], [1.0, 0.0]])
    c = np.asarray(params.com_offset) * params.body_mass / m_t  # whole-robot CoM from the centre
    rot = rotation(q[2])
    com_acceleration = qdd[:2] + qdd[2] * rot @ perp @ c - qd[2] ** 2 * rot @ c
    body_force = rot.T @ (m_t * (np.array([0.0, -params.gravity]) - com_acceleration))
    d = wheel_offsets(params)
    system = np.vstack((np.ones(4), d[:, 0], d[:, 1]))
    rhs = np.array([adhesion, params.com_height * body_force[0], params.com_height * body_force[1]])
    return np.linalg.lstsq(system, rhs, rcond=None)[0]


def test_normal_loads_are_the_least_norm_balance():
    rng = np.random.default_rng(9)
    for _ in range(50):
        params = random_parameters(rng)
        robot = Robot(params)
        q = np.concatenate((rng.uniform(-1, 1, 2), [rng.uniform(-math.pi, math.pi)], np.zeros(4)))
        qd, qdd = rng.normal(size=7), rng.normal(size=7) * 5
        expected = least_norm_loads(params, robot.adsorption.applied_force, q, qd, qdd)
        assert np.allclose(normal_loads(robot, q, qd, qdd), expected, rtol=1e-12, atol=1e-10)


def test_the_loads_move_with_the_acceleration_through_the_body_forces():
    """N(qdd) = N(0) + U (B qdd[:3]) (the affine form the kinetic friction's fixed point is solved with)."""
    rng = np.random.default_rng(10)
    for _ in range(50):
        robot = Robot(random_parameters(rng))
        q = np.concatenate((rng.uniform(-1, 1, 2), [rng.uniform(-math.pi, math.pi)], np.zeros(4)))
        qd, qdd = rng.normal(size=7), rng.normal(size=7) * 5
        arms, body = normal_load_gain(robot, q)
        change = normal_loads(robot, q, qd, qdd) - normal_loads(robot, q, qd, np.zeros(7))
        assert np.allclose(arms @ (body @ qdd[:3]), change, rtol=1e-12, atol=1e-12 * robot.adsorption.applied_force)


def test_loads_at_rest_match_model_md():
    loads = at_rest(contact='ideal').outputs().contact.loads
    assert loads == pytest.approx([38.10, 38.10, 56.49, 56.49], abs=0.01)  # 56.495: the page rounds down
    robot = Robot(RobotParameters())
    facing_up = normal_loads(robot, np.array([0.0, 0.0, math.pi / 2, 0, 0, 0, 0]), np.zeros(7), np.zeros(7))
    adhesion = robot.adsorption.applied_force
    front = adhesion / 4 - 0.05 * 9.0 * 9.81 / (4 * 0.10)
    assert facing_up == pytest.approx([front, adhesion / 2 - front] * 2)


def test_hold_sticks_at_two_thirds_of_the_lateral_limit(engine):
    simulation = at_rest(engine=engine)
    first = simulation.outputs()
    assert first.contact.use.lateral == pytest.approx(0.667, abs=5e-4)
    assert first.contact.use.lateral == pytest.approx(9.0 * 9.81 / (0.7 * 189.19), rel=1e-4)
    simulation.run(1.0, lambda out: assert_sticking(out))
    assert np.max(np.abs(simulation.q[:3])) < 1e-12


def assert_sticking(out) -> None:
    assert out.contact.slipping == (False, False, False)
    assert out.contact.friction_force is None


def test_slide_with_a_weak_adhesion_force(engine):
    simulation = at_rest(adhesion_force=100.0, engine=engine)
    trace = []
    final = simulation.run(1.0, lambda out: trace.append(out))
    assert all(out.contact.slipping == (False, False, True) for out in trace)
    assert final.acceleration[1] == pytest.approx(-9.81 + (0.6 + 0.03) * 100.0 / 9.0, abs=1e-5)
    assert final.acceleration[1] == pytest.approx(-2.81, abs=1e-5)
    assert final.q[1] == pytest.approx(-1.405, abs=3e-3)  # the eps-smoothing's millimetres
    assert abs(final.q[0]) < 1e-12 and abs(final.q[2]) < 1e-12
    assert final.contact.loads[:2] == pytest.approx([18.44, 18.44], abs=0.005)
    assert final.contact.use.lateral == pytest.approx(0.6 / 0.7, rel=1e-6)  # slipping: mu_k / mu_s


def test_spinning_climb(engine):
    simulation = at_rest(math.pi / 2, torque=(3.0, 3.0), engine=engine)
    first = simulation.outputs()
    assert first.contact.slipping == (True, True, False)
    final = simulation.run(1.0)
    assert final.contact.slipping == (True, True, False)
    assert final.acceleration[1] == pytest.approx((0.6 * 189.19 - 9.0 * 9.81 - 0.03 * 189.19) / 9.0, abs=1e-3)
    assert final.acceleration[1] == pytest.approx(2.172, abs=5e-4)
    assert abs(final.q[0]) < 1e-9 and final.q[2] == pytest.approx(math.pi / 2, abs=1e-9)


def test_traction_needed_to_climb_exceeds_the_side_limit():
    """The solve with every channel sticking asks more of each side than mu_s N_k = 66.2 N."""
    sticking = at_rest(math.pi / 2, torque=(3.0, 3.0), contact='ideal').outputs()
    side_load = sticking.contact.loads[0] + sticking.contact.loads[1]
    assert 0.7 * side_load == pytest.approx(66.2, abs=0.05)
    assert sticking.drive.left > 0.7 * side_load and sticking.contact.use.left > 1.0


def test_detachment_at_the_start_names_wheel_load_and_time(engine):
    simulation = at_rest(com_height=0.25, adhesion_force=130.0, engine=engine)
    first = simulation.outputs()
    assert first.contact.detached_wheel in (1, 2)  # the upper (left) wheels
    assert first.contact.loads[:2] == pytest.approx([32.5 - 45.98] * 2, abs=0.005)
    with pytest.raises(DetachedError, match=r'wheel [12] \(left (front|rear)\).*-13\.48 N at t = 0\.000 s') as error:
        simulation.step()
    assert error.value.t == 0.0 and error.value.load == pytest.approx(-13.48, abs=0.005)
    assert simulation.t == 0.0


def test_ideal_contact_reports_a_negative_load_and_goes_on():
    simulation = at_rest(com_height=0.25, adhesion_force=130.0, contact='ideal')
    final = simulation.run(0.1)
    assert final.contact.loads[0] < 0.0 and final.contact.slipping == (False, False, False)


def friction_power(params: RobotParameters, adhesion: float, q, qd, slipping, loads) -> float:
    """Power of the kinetic friction of 9.3 (computed here from the slip velocities)."""
    eps2 = params.velocity_epsilon ** 2
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    v_long, v_lat = cos_t * qd[0] + sin_t * qd[1], -sin_t * qd[0] + cos_t * qd[1]
    left, right, lateral = slipping
    power = 0.0
    if lateral:
        power -= params.kinetic_friction * adhesion * v_lat ** 2 / math.sqrt(v_lat ** 2 + eps2)
    for i, (_, dy) in enumerate(wheel_offsets(params)):
        if left if dy > 0 else right:
            slip = params.wheel_radius * qd[3 + i] - v_long + dy * qd[2]
            power -= params.kinetic_friction * loads[i] * slip ** 2 / math.sqrt(slip ** 2 + eps2)
    return power


@pytest.mark.parametrize('theta, torque, adhesion, transitions', [
    (math.pi / 2, (3.0, 3.0), None, False),    # both sides slip throughout
    (math.pi / 2, (3.0, 2.5), None, False),    # the left side slips, the robot turns
    (0.0, (0.4, -0.2), 100.0, True),           # lateral slip, stick, slip again
])
def test_energy_is_dissipated_never_created_while_slipping(theta, torque, adhesion, transitions, engine):
    """d/dt (T + V) = motor + rolling resistance + kinetic friction power, the last never positive.

    Powers computed here (docs/model.md 4, 11.3) from the states and the loads of each step's start,
    which the friction holds over the step; trapezoidal rule per step. A re-stick's projection
    only removes kinetic energy, so with transitions the balance may only fall short."""
    simulation = at_rest(theta, torque, adhesion_force=adhesion, engine=engine)
    params = simulation.robot.params
    force = simulation.robot.adsorption.applied_force
    eps2 = params.velocity_epsilon ** 2
    states = []

    def other_power(q, qd) -> float:
        motor = 0.5 * torque[0] * (qd[3] + qd[4]) + 0.5 * torque[1] * (qd[5] + qd[6])
        for d in wheel_offsets(params):
            v = qd[:2] + qd[2] * rotation(q[2]) @ np.array([-d[1], d[0]])
            motor -= params.rolling_resistance * force / 4 * (v @ v) / math.sqrt(v @ v + eps2)
        return motor

    def record(out):
        power = friction_power(params, force, out.q, out.qd, out.contact.slipping, out.contact.loads)
        assert power <= 0.0
        if out.contact.friction_force is not None:
            assert out.contact.friction_force @ out.qd == pytest.approx(power, rel=1e-6, abs=1e-9)
        states.append((out.q, out.qd, out.contact.slipping, out.contact.loads,
                       kinetic_energy(params, out.q, out.qd) + potential_energy(params, out.q)))

    simulation.run(1.0, record)
    work, dissipated = [0.0], 0.0
    for (q0, qd0, slipping, loads, _), (q1, qd1, *_) in zip(states[:-1], states[1:]):
        friction = 0.5 * simulation.dt * (friction_power(params, force, q0, qd0, slipping, loads)
                                          + friction_power(params, force, q1, qd1, slipping, loads))
        work.append(work[-1] + 0.5 * simulation.dt * (other_power(q0, qd0) + other_power(q1, qd1)) + friction)
        dissipated -= friction
    change = np.array([state[4] for state in states]) - states[0][4]
    exchanged = sum(abs(other_power(q, qd)) for q, qd, *_ in states) * simulation.dt + dissipated
    assert dissipated > 1.0  # the run does slip
    assert np.max(change - np.array(work)) < 1e-5 * exchanged
    if not transitions:
        assert np.max(np.abs(change - np.array(work))) < 1e-5 * exchanged


def kinetic_friction_force(params: RobotParameters, adhesion: float, q, qd, slipping, loads) -> np.ndarray:
    """Q_f of 9.3 written out row by row (nonslip rows of the slipping sides, the non-lateral row)."""
    eps2 = params.velocity_epsilon ** 2
    cos_t, sin_t = math.cos(q[2]), math.sin(q[2])
    v_long, v_lat = cos_t * qd[0] + sin_t * qd[1], -sin_t * qd[0] + cos_t * qd[1]
    left, right, lateral = slipping
    force = np.zeros(7)
    if lateral:
        force += -params.kinetic_friction * adhesion * v_lat / math.sqrt(v_lat ** 2 + eps2) * np.array(
            [-sin_t, cos_t, 0, 0, 0, 0, 0])
    for i, (_, dy) in enumerate(wheel_offsets(params)):
        if left if dy > 0 else right:
            slip = params.wheel_radius * qd[3 + i] - v_long + dy * qd[2]
            row = np.array([-cos_t, -sin_t, dy, 0, 0, 0, 0])
            row[3 + i] = params.wheel_radius
            force -= params.kinetic_friction * loads[i] * slip / math.sqrt(slip ** 2 + eps2) * row
    return force


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_the_loads_kinetic_friction_holds_are_the_loads_it_produces(seed, engine):
    """At every boundary of a turning slip (loads shifting step by step, CoM off the centre), Q_f
    equals 9.3's friction of the very loads the solution reports (the loads-friction fixed point)."""
    rng = np.random.default_rng(seed)
    params = random_parameters(rng)
    simulation = Simulation(Robot(params), None, DRIVEN, np.array([0.0, 0.0, math.pi / 2, 0, 0, 0, 0]),
                            np.zeros(7), contact='coulomb', engine=engine)
    weight = (params.body_mass + 4 * params.wheel_mass) * params.gravity
    simulation.set_motor_torque(1.2 * weight * params.wheel_radius, 0.5 * weight * params.wheel_radius)
    adhesion = simulation.robot.adsorption.applied_force
    checked = 0

    def check(out):
        nonlocal checked
        if out.contact.friction_force is None or not any(out.contact.slipping[:2]):
            return
        expected = kinetic_friction_force(params, adhesion, out.q, out.qd, out.contact.slipping, out.contact.loads)
        assert np.allclose(out.contact.friction_force, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
        checked += 1

    simulation.run(0.3, check)
    assert checked > 200


def test_a_sticking_coulomb_run_equals_the_ideal_run_bit_for_bit(engine):
    runs = []
    for contact in ('ideal', 'coulomb'):
        simulation = at_rest(math.pi / 2, (2.0, 1.95), contact=contact, engine=engine)
        trace = []
        simulation.run(1.0, lambda out: trace.append(np.concatenate((out.q, out.qd, out.constraint_force,
                                                                       out.contact.loads, out.contact.use))))
        simulation.set_motor_torque(1.95, 2.0)
        simulation.run(0.5, lambda out: trace.append(np.concatenate((out.q, out.qd, out.constraint_force,
                                                                       out.contact.loads, out.contact.use))))
        runs.append(trace)
    assert len(runs[0]) == len(runs[1])
    assert max(max(row[-3:]) for row in runs[0]) < 1.0  # every channel within its limit
    assert all(np.array_equal(a, b) for a, b in zip(*runs))
    assert np.max(np.abs(runs[0][-1][:2])) > 0.01  # it does move


def test_coulomb_with_the_trajectory_task_stays_ideal():
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    q0, qd0 = scenario.initial_state(robot)
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip')
    ends = [Simulation(robot, scenario.reference, selection, q0, qd0, contact=contact).run(0.5)
            for contact in ('ideal', 'coulomb')]
    assert np.array_equal(ends[0].q, ends[1].q) and np.array_equal(ends[0].qd, ends[1].qd)


def test_a_slide_stopped_by_more_adhesion_sticks_again(engine):
    simulation = at_rest(adhesion_force=100.0, engine=engine)
    simulation.run(0.2)
    assert simulation.outputs().contact.slipping[2]
    simulation.set_adhesion_force(200.0)  # mu_k F_ad + f_r F_ad = 126 N > m_t g: decelerates
    for _ in range(2000):
        if not simulation.outputs().contact.slipping[2]:
            break
        simulation.step()
    out = simulation.outputs()
    assert out.contact.slipping == (False, False, False)
    assert abs(out.qd[1]) < 1e-9  # the remaining slip removed by the projection
    stopped_at = out.q[1]
    simulation.run(0.5)
    assert simulation.q[1] == pytest.approx(stopped_at, abs=1e-9)


def test_switching_contact_model_and_adhesion_between_steps(engine):
    simulation = at_rest(adhesion_force=100.0, engine=engine)
    simulation.run(0.1)
    simulation.set_contact_model('ideal')  # the slipped lateral row is imposed again
    out = simulation.outputs()
    assert out.contact.slipping == (False, False, False) and abs(out.qd[1]) < 1e-9
    assert simulation.contact_model == 'ideal'
    simulation.set_contact_model('coulomb')
    assert simulation.outputs().contact.slipping == (False, False, True)
    with pytest.raises(ValueError, match="unknown contact model 'sticky'"):
        simulation.set_contact_model('sticky')


def test_a_robot_falling_without_the_lateral_constraint_is_reported_sliding():
    """The driven robot without non-lateral motion falls sideways; ideal or not, that is never silent."""
    robot = Robot(RobotParameters())
    falling = Simulation(robot, None, ConstraintSelection(trajectory=False, belt=True, nonslip=True),
                         np.zeros(7), np.zeros(7))
    assert unheld_slip(robot, falling.selection, falling.outputs()) == {}
    falling.run(0.1)
    sliding = unheld_slip(robot, falling.selection, falling.outputs())
    assert list(sliding) == ['lateral'] and sliding['lateral'] > 0.5
    holding = at_rest()
    holding.run(0.1)
    assert unheld_slip(holding.robot, holding.selection, holding.outputs()) == {}
    slide = at_rest(adhesion_force=100.0)
    slide.run(0.1)
    assert list(unheld_slip(slide.robot, slide.selection, slide.outputs())) == ['lateral']


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
