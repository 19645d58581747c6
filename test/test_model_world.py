"""The world file's surface (docs/model.md 13.1) against analytic cases: the floor's turning threshold with every
load (F_ad + m_t g) / 4, the ceiling holding or dropping the robot, the 45 degree slope at its friction limit, and a
robot climbing into a slippery patch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_sim.model import ConstraintSelection, ParameterError, Robot, RobotParameters, Simulation
from wallbot_sim.model.contact import DetachedError
from wallbot_sim.model.simulation import NUMBA
from wallbot_sim.model.world import Patch, Seam, World

DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)
PARAMS = RobotParameters()
MASS = PARAMS.body_mass + 4 * PARAMS.wheel_mass
WEIGHT = MASS * PARAMS.gravity


def at_rest(world: World, adhesion: float, theta: float = 0.0, torque: tuple[float, float] = (0.0, 0.0),
            y: float = 0.0) -> Simulation:
    robot = Robot(PARAMS.replace(adhesion_force=adhesion), world)
    simulation = Simulation(robot, None, DRIVEN, np.array([0.0, y, theta, 0, 0, 0, 0]), np.zeros(7), contact='coulomb')
    simulation.set_motor_torque(*torque)
    return simulation


def test_a_vertical_world_is_the_wall_without_a_world_file_to_the_bit():
    plain = Simulation(Robot(PARAMS), None, DRIVEN, np.zeros(7), np.zeros(7), contact='coulomb')
    walled = Simulation(Robot(PARAMS, World(90.0)), None, DRIVEN, np.zeros(7), np.zeros(7), contact='coulomb')
    for simulation in (plain, walled):
        simulation.set_motor_torque(3.0, 3.0)
        simulation.run(0.05)
    assert np.array_equal(plain.q, walled.q) and np.array_equal(plain.qd, walled.qd)


@pytest.mark.parametrize('fraction', [0.99, 1.01])
def test_on_the_floor_turning_in_place_holds_below_the_threshold_of_the_full_load(fraction):
    """Inclination 0: no in-plane gravity, every load (F_ad + m_t g) / 4, so the turn starts at
    T* = mu_s (F_ad + m_t g) r / (2 sqrt(1 + (b/a)^2)) (the wall's case with F_ad + m_t g for F_ad)."""
    adhesion = 40.0
    a, b, r = PARAMS.half_wheelbase, PARAMS.half_track, PARAMS.wheel_radius
    threshold = PARAMS.wall_friction * (adhesion + WEIGHT) * r / (2 * math.sqrt(1 + (b / a) ** 2))
    torque = fraction * threshold
    simulation = at_rest(World(0.0), adhesion, torque=(-torque, torque))
    first = simulation.outputs()
    assert first.contact.loads == pytest.approx([(adhesion + WEIGHT) / 4] * 4, rel=1e-12)
    if fraction < 1.0:
        assert first.contact.wheel_slipping == (False,) * 4
        assert first.contact.wheel_use == pytest.approx([fraction] * 4, rel=1e-6)
        simulation.run(0.2)
        assert abs(simulation.q[2]) < 1e-6
    else:
        assert first.contact.wheel_slipping == (True,) * 4
        simulation.run(0.2)
        assert simulation.q[2] > 1e-3


def test_on_the_ceiling_less_adhesion_than_weight_detaches_at_once():
    simulation = at_rest(World(180.0), 0.9 * WEIGHT)
    assert simulation.outputs().contact.loads == pytest.approx([-0.1 * WEIGHT / 4] * 4, rel=1e-9)
    with pytest.raises(DetachedError) as detached:
        simulation.step()
    assert detached.value.t == 0.0


def test_on_the_ceiling_more_adhesion_than_weight_holds():
    simulation = at_rest(World(180.0), 1.2 * WEIGHT)
    simulation.run(0.2)
    out = simulation.outputs()
    assert out.contact.loads == pytest.approx([0.2 * WEIGHT / 4] * 4, rel=1e-9)
    assert np.abs(simulation.q[:3]).max() < 1e-9 and out.contact.wheel_slipping == (False,) * 4


def slope_limit(inclination: float) -> float:
    """The adhesion at which a robot facing across the slope starts to slide:
    m_t g sin i = mu_s (F_ad + m_t g cos i)."""
    angle = math.radians(inclination)
    return WEIGHT * (math.sin(angle) - PARAMS.wall_friction * math.cos(angle)) / PARAMS.wall_friction


def test_at_45_degrees_just_above_the_friction_limit_the_robot_holds():
    adhesion = 1.03 * slope_limit(45.0)
    simulation = at_rest(World(45.0), adhesion)
    out = simulation.outputs()
    press = adhesion + WEIGHT * math.cos(math.radians(45.0))
    expected_use = WEIGHT * math.sin(math.radians(45.0)) / (PARAMS.wall_friction * press)
    assert out.contact.wheel_use == pytest.approx([expected_use] * 4, rel=1e-3)
    assert sum(out.contact.loads) == pytest.approx(press, rel=1e-12)
    simulation.run(0.3)
    assert np.abs(simulation.q[:2]).max() < 1e-6


def test_at_45_degrees_just_below_the_friction_limit_the_robot_slides_down_at_the_kinetic_rate():
    """ydd = -g sin i + (mu_k + f_r)(F_ad + m_t g cos i) / m_t: kinetic friction and rolling resistance both oppose
    the slide (the section 11 case with the slope's loads)."""
    adhesion = 0.97 * slope_limit(45.0)
    simulation = at_rest(World(45.0), adhesion)
    angle = math.radians(45.0)
    press = adhesion + WEIGHT * math.cos(angle)
    acceleration = (-PARAMS.gravity * math.sin(angle)
                    + (PARAMS.kinetic_friction + PARAMS.rolling_resistance) * press / MASS)
    assert simulation.outputs().contact.wheel_slipping == (True,) * 4
    simulation.run(0.5)
    assert simulation.q[1] == pytest.approx(0.5 * acceleration * 0.5 ** 2, abs=2e-3)
    assert abs(simulation.q[0]) < 1e-9


def test_a_robot_climbing_into_a_slippery_patch_slips_within_a_step_of_its_first_wheel_crossing():
    """Facing up under 2.2 N m per side the wheels use 83 % of mu_s 0.7; in the patch (mu_s 0.3) their discs are too
    small: the first wheel to cross its edge slides at that step boundary or the next."""
    edge = 0.3
    world = World(90.0, (Patch((-1.0, 1.0), (edge, 2.0), 0.3, 0.25),))
    simulation = at_rest(world, 189.19, theta=math.pi / 2, torque=(2.2, 2.2), y=edge - 0.15)
    robot = simulation.robot
    crossed_at = slipped_at = None
    crossed: set[int] = set()
    while slipped_at is None or crossed_at is None:
        out = simulation.outputs()
        inside = {wheel for wheel, point in enumerate(robot.wheel_points(out.q)) if point[1] >= edge}
        if inside and crossed_at is None:
            crossed_at, crossed = simulation.steps, inside
        if any(out.contact.wheel_slipping):
            slipped_at = simulation.steps
            slipping = {wheel for wheel, slips in enumerate(out.contact.wheel_slipping) if slips}
        assert simulation.t < 1.0, 'the robot never reached the patch'
        simulation.step()
    assert crossed == {0, 2}  # the front wheels
    assert crossed_at <= slipped_at <= crossed_at + 1
    assert slipping & crossed


def test_the_friction_at_a_point_is_the_first_patch_holding_it():
    world = World(patches=(Patch((0.0, 1.0), (0.0, 1.0), 0.3, 0.2), Patch((0.5, 2.0), (0.0, 1.0), 0.5, 0.4)))
    static, kinetic = world.friction_at(np.array([[0.5, 0.5], [1.5, 0.5], [3.0, 0.5]]), 0.7, 0.6)
    assert static.tolist() == [0.3, 0.5, 0.7] and kinetic.tolist() == [0.2, 0.4, 0.6]


@pytest.mark.parametrize('centre, length', [
    ((0.0, 1.0), 0.2),              # through the centre: the diameter
    ((0.0, 1.06), 2 * math.sqrt(0.1 ** 2 - 0.06 ** 2)),  # a chord
    ((0.0, 1.2), 0.0),              # beyond the disc
    ((1.0, 1.0), 0.1),              # the segment ends at the centre: half the diameter
])
def test_a_seams_length_under_a_disc_is_its_chord(centre, length):
    seam = Seam((-1.0, 1.0), (1.0, 1.0), 0.004)
    assert seam.length_within(np.array(centre), 0.1) == pytest.approx(length, abs=1e-12)


def test_the_numba_engine_refuses_a_world_naming_the_python_engine():
    with pytest.raises(ParameterError, match=r'python engine only: use --engine python'):
        Simulation(Robot(PARAMS, World(45.0)), None, DRIVEN, np.zeros(7), np.zeros(7), engine=NUMBA)
