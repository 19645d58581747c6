"""cmd_vel_node's loop without ROS: diff_drive_controller's limiter and timeout, the wheel-speed PI on
the model (the driven plant at 1 kHz, the loop at cmd_vel_node's default rate), and the joint_commands side
mapping."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from wallbot_msgs_py import topics
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.joint_interface import side_torques
from wallbot_sim.control.sampling import ControlInstants, Rewind, steps_per_period
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.control.wheel_speed import (SPEED_LOOP_RATE_HZ, AxisLimits, WheelSpeedController, WheelSpeedSettings,
                                             wheel_speeds)
from wallbot_sim.model import Robot, Simulation

PARAMS = load_robot_parameters()
SEPARATION, RADIUS = 2.0 * PARAMS.half_track, PARAMS.wheel_radius
PERIOD_STEPS = steps_per_period(SPEED_LOOP_RATE_HZ)


def settings(**changes) -> WheelSpeedSettings:
    values = dict(wheel_separation=SEPARATION, wheel_radius=RADIUS, linear=AxisLimits(0.5, 1.0),
                  angular=AxisLimits(2.0, 4.0))
    values.update(changes)
    return WheelSpeedSettings(**values)


def test_the_limiter_ramps_at_the_acceleration_limit_and_stops_at_the_velocity_limit():
    controller = WheelSpeedController(settings())
    controller.command(2.0, -10.0, 0.0)
    seen = []
    for k in range(80):
        t = 0.01 * k
        controller.command(2.0, -10.0, t)
        out = controller.update(t, 0.0, 0.0)
        seen.append((out.linear, out.angular))
    linear, angular = np.array(seen).T
    # first update has no interval; then 0.01 m/s and 0.04 rad/s per 10 ms until the limits
    assert linear[:51] == pytest.approx(np.minimum(0.01 * np.arange(51), 0.5), abs=1e-12)
    assert linear[51:] == pytest.approx(0.5, abs=1e-12)
    assert angular[:51] == pytest.approx(-np.minimum(0.04 * np.arange(51), 2.0), abs=1e-12)
    assert angular[60:] == pytest.approx(-2.0, abs=1e-12)


def test_a_command_older_than_the_timeout_becomes_zero_through_the_limiter():
    controller = WheelSpeedController(settings(linear=AxisLimits(0.5, 10.0)))
    controller.command(0.3, 0.0, 0.0)
    for k in range(11):  # 0 .. 0.1 s: reaches 0.3
        controller.update(0.01 * k, 0.0, 0.0)
    assert controller.limited[0] == pytest.approx(0.3)
    held = controller.update(0.5, 0.0, 0.0)  # exactly the timeout: still live
    assert held.linear == pytest.approx(0.3) and not controller.timed_out
    ramp = controller.update(0.51, 0.0, 0.0)
    assert controller.timed_out and ramp.linear == pytest.approx(0.3 - 10.0 * 0.01)
    assert controller.update(0.6, 0.0, 0.0).linear == pytest.approx(0.0)


def test_refuses_a_command_that_is_not_finite_and_keeps_the_last():
    controller = WheelSpeedController(settings())
    controller.command(0.2, 0.1, 0.0)
    with pytest.raises(ValueError, match='finite'):
        controller.command(math.nan, 0.0, 0.1)
    assert controller.target == (0.2, 0.1)


def test_the_integral_does_not_wind_up_while_the_torque_is_saturated():
    s = settings(kp=0.1, ki=10.0, max_wheel_torque=1.0, linear=AxisLimits(0.5, 1e3))
    controller = WheelSpeedController(s)
    controller.update(0.0, 0.0, 0.0)  # the first update has no interval
    for k in range(1, 200):  # wheels held still: error 12.5 rad/s, kp alone already saturates
        controller.command(0.5, 0.0, 0.01 * k)
        out = controller.update(0.01 * k, 0.0, 0.0)
        assert (out.tau_left, out.tau_right) == (1.0, 1.0) and out.saturated
    assert max(abs(i) for i in controller.integral) < 10.0 * 12.5 * 0.02  # at most the first instants' share
    # once the wheels overshoot, the torque reverses within one period: no stored integral holds it up
    out = controller.update(2.0, 13.0, 13.0)
    assert out.tau_left < 0 and out.tau_right < 0


def drive(commands, heading: float = 0.0, duration: float = 3.0, **changes):
    """The driven plant (belt, non_lateral, nonslip; ideal contact) under the loop at its default rate.
    ``commands(t)`` -> (v, omega). Returns times, v_long, yaw rate and the torques."""
    plant = Simulation(Robot(PARAMS), None, DRIVEN, np.array([0.0, 0.0, heading, 0, 0, 0, 0]), np.zeros(7))
    controller = WheelSpeedController(settings(**changes))
    rows = []
    for k in range(round(duration / plant.dt)):
        if k % PERIOD_STEPS == 0:
            theta = plant.q[2]
            v_long = math.cos(theta) * plant.qd[0] + math.sin(theta) * plant.qd[1]
            measured = wheel_speeds(v_long, plant.qd[2], SEPARATION, RADIUS)
            controller.command(*commands(plant.t), plant.t)
            out = controller.update(plant.t, *measured)
            plant.set_motor_torque(out.tau_left, out.tau_right)
            rows.append((plant.t, v_long, plant.qd[2], out.tau_left, out.tau_right))
        plant.step()
    return np.array(rows).T


@pytest.mark.parametrize('heading', [0.0, math.pi / 2, -math.pi / 2])
def test_the_model_reaches_the_commanded_speed_along_and_up_and_down_the_wall(heading):
    t, v, omega, *_ = drive(lambda _t: (0.2, 0.0), heading)
    settled = t >= 1.5  # 0.2 s of ramp at 1 m/s^2, then the PI settles (integral against gravity)
    assert np.abs(v[settled] - 0.2).max() < 0.004
    assert np.abs(omega[settled]).max() < 1e-6


def test_the_default_gain_leaves_a_margin_at_the_default_rate():
    """Each torque is held for a whole period, so a gain too high for the rate oscillates and diverges:
    1.5 times the default kp still settles up the wall; 3 times (past the limit, 0.6-0.75 N m s/rad
    at 50 Hz) swings between the torque limits."""
    kp = WheelSpeedSettings.kp
    for factor, settles in ((1.5, True), (3.0, False)):
        t, v, _omega, tau_left, _ = drive(lambda _t: (0.2, 0.0), math.pi / 2, kp=factor * kp)
        settled = t >= 1.5
        assert bool(np.abs(v[settled] - 0.2).max() < 0.004) == settles, factor
        assert bool(np.ptp(tau_left[settled]) > 5.0) != settles, factor


def test_the_model_turns_at_the_commanded_rate():
    t, v, omega, *_ = drive(lambda _t: (0.1, 0.8), duration=8.0)  # a full turn on the vertical wall
    settled = t >= 1.5
    assert np.abs(omega[settled] - 0.8).max() < 0.8 * 0.002
    # gravity along the path changes as the robot turns: a disturbance the PI follows with a lag
    assert np.abs(v[settled] - 0.1).max() < 0.015  # 1.1 cm/s measured


def test_the_controller_follows_time_going_back():
    instants = ControlInstants(100)
    assert instants.due(0)
    instants.acted(0)
    instants.observe(5_000_000)
    assert not instants.due(5_000_000)
    instants.observe(10_000_000)
    assert instants.due(10_000_000)
    instants.acted(10_000_000)
    assert instants.observe(3_000_000) is Rewind.RESTART and instants.due(3_000_000)
    controller = WheelSpeedController(settings())
    controller.command(0.2, 0.0, 5.0)
    controller.update(5.0, 0.0, 0.0)
    controller.update(5.5, 0.0, 0.0)
    controller.reset()
    assert controller.expired(0.0) and controller.integral == [0.0, 0.0] and controller.limited == (0.0, 0.0)


def test_joint_commands_efforts_sum_per_side_in_any_order():
    lf, lr, rf, rr = topics.WHEEL_JOINTS
    assert side_torques([rr, lf, rf, lr], [0.5, 1.0, -0.25, 0.75], 5.0) == (1.75, 0.25)


@pytest.mark.parametrize('names, efforts, fragment', [
    (topics.WHEEL_JOINTS[:3], [0.0] * 3, 'must name each of'),
    ((*topics.WHEEL_JOINTS[:3], topics.WHEEL_JOINTS[0]), [0.0] * 4, 'must name each of'),
    ((*topics.WHEEL_JOINTS, 'arm'), [0.0] * 5, 'must name each of'),
    (topics.WHEEL_JOINTS, [0.0] * 3, '3 efforts for 4 joints'),
    (topics.WHEEL_JOINTS, [], '0 efforts for 4 joints'),
    (topics.WHEEL_JOINTS, [0.0, math.inf, 0.0, 0.0], 'wheel_left_rear is not finite'),
    (topics.WHEEL_JOINTS, [3.0, 2.5, 0.0, 0.0], 'left side total 5.5 N m exceeds +-5 N m'),
])
def test_malformed_joint_commands_are_refused_naming_what_is_wrong(names, efforts, fragment):
    with pytest.raises(ValueError, match=re.escape(fragment)) as error:
        side_torques(list(names), efforts, 5.0)
    assert '\n' not in str(error.value)
