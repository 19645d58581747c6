"""The Udwadia-Phohomsiri solver against a KKT solve and the Udwadia-Kalaba form."""

from __future__ import annotations

import itertools
import zlib

import numpy as np
import pytest

from model_helpers import is_consistent, kkt_acceleration, random_parameters, udwadia_kalaba_acceleration
from wallbot_sim.model import (
    BaumgarteGains, Circle, FigureEight, Robot, SmoothStop, solve, solve_with_factor)
from wallbot_sim.model.constraint_set import MODULES, make_module
from wallbot_sim.model.constraints import TangentHeadingTask
from wallbot_sim.model.solver import constrained_acceleration

def make_modules(names, robot, reference, gains):
    return [make_module(name, robot, reference, gains) for name in names]


def stacked(modules, t, q, qd):
    parts = [m.rows(t, q, qd) for m in modules]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def random_problem(rng, names):
    params = random_parameters(rng)
    robot = Robot(params)
    reference = Circle(rng.uniform(0.5, 2), rng.uniform(5, 30), tuple(rng.uniform(-1, 1, 2)))
    gains = BaumgarteGains(params.baumgarte_alpha, params.baumgarte_beta)
    q = np.concatenate((rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi, 1), rng.uniform(-10, 10, 4)))
    qd = np.concatenate((rng.uniform(-0.5, 0.5, 3), rng.uniform(-20, 20, 4)))
    t = rng.uniform(0, 20)
    rows, rhs = stacked(make_modules(names, robot, reference, gains), t, q, qd)
    tau = tuple(rng.uniform(-2, 2, 2))
    return robot, q, qd, rows, rhs, robot.applied_force(q, qd, tau)


ALL_COMBINATIONS = [names for k in range(1, 6) for names in itertools.combinations(MODULES, k)]


def relative_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))


@pytest.mark.parametrize('names', ALL_COMBINATIONS, ids='+'.join)
def test_solver_matches_kkt_and_udwadia_kalaba_on_consistent_sets(names):
    rng = np.random.default_rng(zlib.crc32('+'.join(names).encode()))  # str hash() varies per process
    checked = 0
    for _ in range(20):
        robot, q, qd, rows, rhs, force = random_problem(rng, names)
        if not is_consistent(rows, rhs):
            continue
        checked += 1
        mass = robot.mass_matrix(q)
        reference = kkt_acceleration(mass, force, rows, rhs)
        assert relative_error(udwadia_kalaba_acceleration(mass, force, rows, rhs), reference) < 1e-9
        general = solve(mass, force, rows, rhs)
        fast = solve_with_factor(mass, robot.mass_inverse_factor(q), force, rows, rhs)
        for motion in (general, fast):
            assert relative_error(motion.acceleration, reference) < 1e-9
            assert relative_error(motion.constraint_force, mass @ reference - force) < 1e-9
            assert motion.residual < 1e-9 * max(1.0, np.linalg.norm(rhs))
    if 'trajectory' in names and 'non_lateral' in names:
        return  # non-lateral repeats a combination of the x, y task rows: consistent only by chance
    assert checked == 20


@pytest.mark.parametrize('names', [('belt', 'non_lateral', 'nonslip'), ('trajectory', 'non_lateral', 'nonslip')],
                         ids='+'.join)
def test_several_forces_on_the_same_rows_are_solved_as_one_at_a_time(names):
    """Force (7, m) with rhs (k, m): each column the motion of that force and right-hand side."""
    rng = np.random.default_rng(5)
    for _ in range(10):
        robot, q, qd, rows, rhs, force = random_problem(rng, names)
        factor = robot.mass_inverse_factor(q)
        forces = np.column_stack((force, rng.normal(size=(7, 4))))
        rhs_columns = np.column_stack((rhs, np.zeros((len(rhs), 4))))
        together = constrained_acceleration(factor, forces, rows, rhs_columns)
        for column in range(5):
            alone = constrained_acceleration(factor, forces[:, column], rows, rhs_columns[:, column])
            assert relative_error(together[:, column], alone) < 1e-12


@pytest.mark.parametrize('names', [n for n in ALL_COMBINATIONS if 'trajectory' in n and 'non_lateral' in n], ids='+'.join)
def test_inconsistent_sets_get_the_same_least_squares_compromise(names):
    rng = np.random.default_rng(7)
    for _ in range(10):
        robot, q, qd, rows, rhs, force = random_problem(rng, names)
        assert not is_consistent(rows, rhs)
        mass = robot.mass_matrix(q)
        general = solve(mass, force, rows, rhs)
        fast = solve_with_factor(mass, robot.mass_inverse_factor(q), force, rows, rhs)
        assert relative_error(fast.acceleration, general.acceleration) < 1e-9
        # the compromise satisfies the constraints in the least-squares sense: A qdd = A A+ b
        assert np.allclose(rows @ general.acceleration, rows @ np.linalg.pinv(rows) @ rhs, atol=1e-9)
        assert general.residual > 1e-6
        # and the constraint force is ideal: it does no work on motions the rows allow
        null_space = np.eye(7) - np.linalg.pinv(rows) @ rows
        assert np.linalg.norm(null_space @ general.constraint_force) < 1e-8 * np.linalg.norm(general.constraint_force)


def test_no_constraint_is_the_free_robot():
    rng = np.random.default_rng(3)
    robot, q, qd, _, _, force = random_problem(rng, ('belt',))
    empty_rows, empty_rhs = np.empty((0, 7)), np.empty(0)
    mass = robot.mass_matrix(q)
    for motion in (solve(mass, force, empty_rows, empty_rhs),
                   solve_with_factor(mass, robot.mass_inverse_factor(q), force, empty_rows, empty_rhs)):
        assert relative_error(motion.acceleration, np.linalg.solve(mass, force)) < 1e-12
        assert np.allclose(motion.constraint_force, 0.0, atol=1e-12)


@pytest.mark.parametrize('names', [('trajectory', 'tangent_heading', 'nonslip'), ('trajectory', 'nonslip'),
                                   ('trajectory', 'tangent_heading', 'belt', 'nonslip')], ids='+'.join)
def test_singular_mass_matrix_with_zero_wheel_spin_inertia(names):
    """Massless wheel spins: M is singular, yet the rolling rows fix the wheel accelerations."""
    rng = np.random.default_rng(11)
    for _ in range(10):
        robot, q, qd, rows, rhs, force = random_problem(rng, names)
        mass = robot.mass_matrix(q).copy()
        mass[3:, 3:] = 0.0
        assert np.linalg.matrix_rank(mass) == 3
        reference = kkt_acceleration(mass, force, rows, rhs)
        motion = solve(mass, force, rows, rhs)
        assert relative_error(motion.acceleration, reference) < 1e-9
        assert motion.residual < 1e-9


def test_heading_task_holds_heading_when_reference_is_at_rest():
    rng = np.random.default_rng(5)
    params = random_parameters(rng)
    gains = BaumgarteGains(params.baumgarte_alpha, params.baumgarte_beta)
    reference = SmoothStop(FigureEight(), duration=3.0, stop_time=1.0)
    task = TangentHeadingTask(reference, gains)
    q, qd = np.zeros(7), np.zeros(7)
    qd[2] = 0.4
    rows, rhs = task.rows(10.0, q, qd)
    assert rows.tolist() == [[0, 0, 1, 0, 0, 0, 0]]
    assert rhs[0] == pytest.approx(-2 * params.baumgarte_alpha * 0.4)
