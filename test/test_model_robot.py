"""The unconstrained robot against energies written body by body, and the adsorption analysis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from model_helpers import kinetic_energy, potential_energy, random_parameters, rotation, wheel_offsets
from wallbot_sim.model import Robot, RobotParameters, adsorption_analysis


def test_adsorption_of_the_defaults_matches_model_md():
    adsorption = adsorption_analysis(RobotParameters())
    assert adsorption.total_mass == pytest.approx(9.0)
    assert adsorption.minimum_force == pytest.approx(126.13, abs=0.005)
    assert adsorption.applied_force == pytest.approx(189.19, abs=0.005)
    assert adsorption.normal_force_per_wheel == pytest.approx(189.19 / 4, abs=0.002)
    assert adsorption.minimum_force == adsorption.sliding_limit


def test_tipping_governs_a_tall_robot():
    params = RobotParameters(com_height=0.5)  # m_t g h / min(a, b) = 88.29 * 0.5 / 0.1
    adsorption = adsorption_analysis(params)
    assert adsorption.minimum_force == pytest.approx(9.0 * 9.81 * 0.5 / 0.1)
    assert adsorption.applied_force == pytest.approx(1.5 * adsorption.minimum_force)


@pytest.mark.parametrize('seed', range(5))
def test_mass_matrix_gives_the_kinetic_energy_of_every_body(seed):
    rng = np.random.default_rng(seed)
    params = random_parameters(rng)
    robot = Robot(params)
    for _ in range(10):
        q, qd = rng.normal(size=7), rng.normal(size=7)
        mass = robot.mass_matrix(q)
        assert np.allclose(mass, mass.T)
        assert np.all(np.linalg.eigvalsh(mass) > 0)
        assert 0.5 * qd @ mass @ qd == pytest.approx(kinetic_energy(params, q, qd), rel=1e-12)
        assert np.allclose(robot.mass_matrix_inverse(q) @ mass, np.eye(7), atol=1e-10)
        factor = robot.mass_inverse_factor(q)
        assert np.allclose(factor @ factor.T @ mass, np.eye(7), atol=1e-10)
        assert np.allclose(factor, np.tril(factor))


def lagrange_force(params, robot, q, qd, h=1e-6):
    """-(dM/dt) qd + dT/dq - dV/dq by central differences: what Q must hold besides resistance."""
    def mass_at(theta):
        shifted = q.copy()
        shifted[2] = theta
        return robot.mass_matrix(shifted)
    d_mass = (mass_at(q[2] + h) - mass_at(q[2] - h)) / (2 * h)
    gradient_t = np.zeros(7)
    gradient_v = np.zeros(7)
    for i in range(7):
        step = np.zeros(7)
        step[i] = h
        gradient_t[i] = (kinetic_energy(params, q + step, qd) - kinetic_energy(params, q - step, qd)) / (2 * h)
        gradient_v[i] = (potential_energy(params, q + step) - potential_energy(params, q - step)) / (2 * h)
    return -(d_mass * qd[2]) @ qd + gradient_t - gradient_v


@pytest.mark.parametrize('seed', range(5))
def test_applied_force_without_resistance_follows_from_lagrange(seed):
    rng = np.random.default_rng(seed)
    params = random_parameters(rng).replace(rolling_resistance=0.0)
    robot = Robot(params)
    for _ in range(5):
        q, qd = rng.normal(size=7), rng.normal(size=7)
        tau = rng.normal(size=2)
        expected = lagrange_force(params, robot, q, qd)
        expected[3:] += [tau[0] / 2, tau[0] / 2, tau[1] / 2, tau[1] / 2]
        assert np.allclose(robot.applied_force(q, qd, tuple(tau)), expected, atol=1e-6)


def test_rolling_resistance_opposes_every_contact_velocity():
    rng = np.random.default_rng(2)
    params = random_parameters(rng, com_offset=False).replace(rolling_resistance=0.03)
    robot = Robot(params)
    normal = robot.adsorption.normal_force_per_wheel
    for _ in range(10):
        q, qd = rng.normal(size=7), rng.normal(size=7)
        force = robot.applied_force(q, qd)
        gravity = np.array([0.0, -robot.total_mass * params.gravity, 0.0])
        expected = gravity.copy()
        for d in wheel_offsets(params):
            arm = rotation(q[2]) @ np.array([-d[1], d[0]])
            v = qd[:2] + qd[2] * arm
            f = -params.rolling_resistance * normal * v / math.sqrt(v @ v + params.velocity_epsilon ** 2)
            expected += [f[0], f[1], arm @ f]
        assert np.allclose(force[:3], expected, atol=1e-12)
        assert (force[:3] - gravity) @ qd[:3] < 0  # dissipative


def test_rolling_spin_rates_roll_without_slip():
    robot = Robot(RobotParameters())
    theta, velocity, yaw_rate = 0.3, (0.2, -0.1), 0.5
    rates = robot.rolling_spin_rates(theta, velocity, yaw_rate)
    v_long = math.cos(theta) * velocity[0] + math.sin(theta) * velocity[1]
    for rate, lateral in zip(rates, [0.12, 0.12, -0.12, -0.12]):
        assert 0.04 * rate == pytest.approx(v_long - lateral * yaw_rate)
