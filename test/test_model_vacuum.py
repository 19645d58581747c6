"""The vacuum block (docs/model.md 13.3) against its analytic cases: the chamber's steady pressure difference, the
time constant of the linearized chamber, and a seam that drops dp under the chamber and detaches the robot."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from wallbot_sim.model import ConstraintSelection, ParameterError, Robot, RobotParameters, Simulation
from wallbot_sim.model.contact import DetachedError
from wallbot_sim.model.simulation import NUMBA
from wallbot_sim.model.world import Seam, World

DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)
BLOCK = dict(chamber_area=0.02, chamber_volume=0.002, pump_max_pressure=12000.0, pump_max_flow=0.01,
             leak_area=2.0e-5)
P_ATM, RHO, C_D = 101325.0, 1.204, 0.61


def pump_minus_leak(dp: float, command: float, gap: float = BLOCK['leak_area']) -> float:
    """Q_pump(dp) u - Q_leak(dp) (m^3/s), written from docs/model.md 13.3."""
    return (BLOCK['pump_max_flow'] * (1 - dp / BLOCK['pump_max_pressure']) * command
            - C_D * gap * math.sqrt(2 * dp / RHO))


def balanced(command: float, gap: float = BLOCK['leak_area']) -> float:
    return brentq(pump_minus_leak, 1e-9, BLOCK['pump_max_pressure'], args=(command, gap), xtol=1e-12)


def at_rest(world: World | None = None, theta: float = 0.0, torque=(0.0, 0.0), y: float = 0.0) -> Simulation:
    robot = Robot(RobotParameters(adhesion=BLOCK), world)
    simulation = Simulation(robot, None, DRIVEN, np.array([0.0, y, theta, 0, 0, 0, 0]), np.zeros(7), contact='coulomb')
    simulation.set_motor_torque(*torque)
    return simulation


def test_the_chamber_starts_and_stays_where_pump_and_leak_balance():
    simulation = at_rest()
    expected = balanced(1.0)
    assert simulation.pressure == pytest.approx(expected, rel=1e-9)
    assert simulation.outputs().vacuum == pytest.approx((expected, expected * BLOCK['chamber_area']), rel=1e-9)
    assert sum(simulation.outputs().contact.loads) == pytest.approx(expected * BLOCK['chamber_area'], rel=1e-9)
    simulation.run(0.05)
    assert simulation.pressure == pytest.approx(expected, rel=1e-9)


def test_a_seam_under_the_chamber_leaks_through_its_width_times_its_chord():
    """A 4 mm seam through the centre of the chamber's disc (area A: diameter 2 sqrt(A / pi)) adds width x diameter
    to the gap: the chamber starts where the pump balances that leak; a seam beside the disc changes nothing."""
    diameter = 2 * math.sqrt(BLOCK['chamber_area'] / math.pi)
    through = at_rest(World(seams=(Seam((-5.0, 0.0), (5.0, 0.0), 0.004),)))
    expected = balanced(1.0, BLOCK['leak_area'] + 0.004 * diameter)
    assert through.pressure == pytest.approx(expected, rel=1e-9) and expected < 0.2 * balanced(1.0)
    assert through.outputs().vacuum[1] == pytest.approx(expected * BLOCK['chamber_area'], rel=1e-9)
    beside = at_rest(World(seams=(Seam((-5.0, 0.5 * diameter + 1e-3), (5.0, 0.5 * diameter + 1e-3), 0.004),)))
    assert beside.pressure == pytest.approx(balanced(1.0), rel=1e-9)


def test_a_small_pump_step_relaxes_with_the_linearized_time_constant():
    """From the balance at u = 1 to u = 0.95: dp moves to the new balance as exp(-t / tau) with
    1 / tau = -(p_atm / V) d(Q_pump u - Q_leak)/d(dp) at the new balance."""
    simulation = at_rest()
    start, end = balanced(1.0), balanced(0.95)
    slope = (pump_minus_leak(end + 1e-3, 0.95) - pump_minus_leak(end - 1e-3, 0.95)) / 2e-3
    tau = -BLOCK['chamber_volume'] / (P_ATM * slope)
    simulation.set_pump_command(0.95)
    simulation.run(round(tau, 3))
    fraction = (simulation.pressure - end) / (start - end)
    assert fraction == pytest.approx(math.exp(-round(tau, 3) / tau), abs=0.01)  # 0.368, the step's nonlinearity
    simulation.run(10 * tau)
    assert simulation.pressure == pytest.approx(end, rel=1e-4)


def test_crossing_a_seam_drops_the_pressure_and_detaches_the_robot():
    """Climbing facing up under 2.2 N m per side with a 202 N chamber (1.6 times section 3's F_min): on a smooth
    wall it climbs on; with a 4 mm seam across its way the chamber's disc reaches the seam, its leak grows, dp
    falls and the robot peels off before its centre is past the seam."""
    seam = 0.35
    smooth, seamed = (at_rest(world, math.pi / 2, (2.2, 2.2)) for world in
                      (None, World(seams=(Seam((-5.0, seam), (5.0, seam), 0.004),))))
    smooth.run(0.8)
    assert smooth.q[1] > seam + 0.1 and smooth.pressure == pytest.approx(balanced(1.0), rel=1e-9)
    radius = math.sqrt(BLOCK['chamber_area'] / math.pi)
    with pytest.raises(DetachedError):
        while True:
            out = seamed.outputs()
            if out.q[1] < seam - radius:
                assert seamed.pressure == pytest.approx(balanced(1.0), rel=1e-9)  # the seam not yet under it
            assert out.q[1] < seam + radius, 'crossed the seam on the wall'
            seamed.step()
    assert seamed.pressure < 0.5 * balanced(1.0)


def test_the_numba_engine_refuses_a_vacuum_block_naming_the_python_engine():
    with pytest.raises(ParameterError, match=r'a vacuum block runs on the python engine only: use --engine python'):
        Simulation(Robot(RobotParameters(adhesion=BLOCK)), None, DRIVEN, np.zeros(7), np.zeros(7), engine=NUMBA)


def test_a_vacuum_block_is_read_and_refused_like_the_others():
    with pytest.raises(ParameterError, match=r"unknown adhesion key 'leak' \(did you mean 'leak_area'\?\)"):
        RobotParameters(adhesion={**BLOCK, 'leak': 1.0})
    with pytest.raises(ParameterError, match='adhesion chamber_volume must be > 0'):
        RobotParameters(adhesion={**BLOCK, 'chamber_volume': 0.0})
