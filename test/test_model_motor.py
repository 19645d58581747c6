"""The motor block's torque-speed envelope (docs/model.md 13.2): its quadrants, and the steady climb on its line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_sim.model import ConstraintSelection, ParameterError, Robot, RobotParameters, Simulation
from wallbot_sim.model.motor import MotorParameters
from wallbot_sim.model.simulation import NUMBA

DRIVEN = ConstraintSelection(trajectory=False, belt=True, non_lateral=True, nonslip=True)
MOTOR = MotorParameters(stall_torque=4.0, no_load_speed=20.0)


@pytest.mark.parametrize('speed, command, applied', [
    (0.0, 10.0, 4.0),      # at rest: the stall torque either way
    (0.0, -10.0, -4.0),
    (10.0, 10.0, 2.0),     # driving at half the no-load speed: half the stall torque
    (-10.0, -10.0, -2.0),
    (10.0, 1.5, 1.5),      # within the envelope: the command
    (10.0, -10.0, -4.0),   # braking against the motion: the current limit, the full stall torque
    (-10.0, 10.0, 4.0),
    (25.0, 0.0, -1.0),     # above the no-load speed full voltage brakes: 4 (1 - 25/20)
])
def test_the_envelope_clips_each_quadrant(speed, command, applied):
    qd = np.array([0, 0, 0, speed, speed, speed, speed], dtype=float)
    assert MOTOR.applied((command, command), qd) == pytest.approx((applied, applied), abs=1e-12)


def test_a_sides_speed_is_the_mean_of_its_wheels():
    qd = np.array([0, 0, 0, 8.0, 12.0, 0.0, 0.0])
    assert MOTOR.applied((10.0, 10.0), qd) == pytest.approx((2.0, 4.0))


def climb(params: RobotParameters, command: float, duration: float) -> Simulation:
    simulation = Simulation(Robot(params), None, DRIVEN, np.array([0.0, 0.0, math.pi / 2, 0, 0, 0, 0]), np.zeros(7))
    simulation.set_motor_torque(command, command)
    simulation.run(duration)
    return simulation


def test_a_saturated_climb_settles_where_the_torque_speed_line_meets_the_load():
    """Facing up, commanding far more than the motors give: at the steady speed each side's torque
    T_s (1 - w/w_0) carries half of m_t g + f_r F_ad at the wheel's radius, so
    v = r w_0 (1 - r (m_t g + f_r F_ad) / (2 T_s)) (0.4164 m/s here)."""
    params = RobotParameters(motor=MOTOR)
    robot = Robot(params)
    r = params.wheel_radius
    load = robot.total_mass * params.gravity + params.rolling_resistance * robot.adsorption.applied_force
    expected = r * MOTOR.no_load_speed * (1 - r * load / (2 * MOTOR.stall_torque))
    simulation = climb(params, 50.0, 0.6)  # about 16 time constants of the approach (38 ms)
    assert simulation.qd[1] == pytest.approx(expected, rel=1e-5)
    out = simulation.outputs()
    assert out.motor_torque == pytest.approx((r * load / 2,) * 2, rel=1e-4)
    assert simulation.motor_torque == (50.0, 50.0)


def test_a_command_inside_the_envelope_is_applied_as_given_to_the_bit():
    unlimited, limited = climb(RobotParameters(), 2.5, 0.05), climb(RobotParameters(motor=MOTOR), 2.5, 0.05)
    assert np.array_equal(unlimited.q, limited.q) and np.array_equal(unlimited.qd, limited.qd)


def test_a_motor_block_is_read_and_refused_like_the_others():
    base = RobotParameters().replace(motor={'stall_torque': 2.0, 'no_load_speed': 20.0})
    assert base.motor == MotorParameters(2.0, 20.0) and base.replace(body_mass=9.0).motor == base.motor
    with pytest.raises(ParameterError, match=r"unknown motor key 'stall_torqe' \(did you mean 'stall_torque'\?\)"):
        RobotParameters(motor={'stall_torqe': 2.0, 'no_load_speed': 20.0})
    with pytest.raises(ParameterError, match='motor no_load_speed must be > 0'):
        RobotParameters(motor={'stall_torque': 2.0, 'no_load_speed': 0.0})


def test_the_numba_engine_refuses_a_motor_block_naming_the_python_engine():
    with pytest.raises(ParameterError, match=r'a motor block runs on the python engine only: use --engine python'):
        Simulation(Robot(RobotParameters(motor=MOTOR)), None, DRIVEN, np.zeros(7), np.zeros(7), engine=NUMBA)
