"""The least adhesion force of a run's samples (``rundata.least_adhesion``) against a scan of the adhesion force F
whose every step shares the samples' forces again by a KKT solve of the weighted least-norm problem."""

from __future__ import annotations

import numpy as np
import pytest

from model_helpers import random_parameters
from wallbot_sim.model import Robot
from wallbot_sim.model.wheel_forces import split_chassis_wrench
from wallbot_sim.rundata.least_adhesion import least_adhesion, needed_adhesion

SCAN = 400
"""Adhesion forces of a sample's scan, from its lift-off to where every wheel holds."""


def kept_rows(robot: Robot, held: str) -> np.ndarray:
    """The rows (k, 8) of what the split keeps of the forces (fx1..fx4, fy1..fy4): 'chassis', the wrench on the
    chassis (F_bx, F_by, M_Z); 'sides', each side's traction, the lateral force and its moment."""
    along, across = robot.wheel_offsets[:, 0], robot.wheel_offsets[:, 1]
    left = across > 0.0
    if held == 'chassis':
        return np.array([np.r_[np.ones(4), np.zeros(4)], np.r_[np.zeros(4), np.ones(4)], np.r_[-across, along]])
    return np.array([np.r_[left, np.zeros(4)], np.r_[~left, np.zeros(4)], np.r_[np.zeros(4), np.ones(4)],
                     np.r_[np.zeros(4), along]], dtype=float)


def use_at(loads: np.ndarray, forces: np.ndarray, adhesion: np.ndarray, rows: np.ndarray, static: float) -> np.ndarray:
    """|f_i| / (mu_s N_i) (K, 4) of one sample's forces shared again by the loads of each adhesion force (K,): the
    least sum of |f_i|^2 / N_i keeping rows @ f, by the KKT system [[diag(1 / w), C^T], [C, 0]] of each."""
    shifted = loads + (adhesion[:, None] - loads.sum()) / 4.0  # (K, 4)
    weights = np.concatenate((shifted, shifted), axis=1)
    count = len(rows)
    system = np.zeros((len(adhesion), 8 + count, 8 + count))
    system[:, np.arange(8), np.arange(8)] = 1.0 / np.maximum(weights, 1e-300)
    system[:, :8, 8:], system[:, 8:, :8] = rows.T, rows
    target = rows @ np.concatenate((forces[:, 0], forces[:, 1]))
    right = np.zeros((len(adhesion), 8 + count))
    right[:, 8:] = target
    with np.errstate(divide='ignore', invalid='ignore'):  # at its lift-off a wheel has no load
        solution = np.linalg.solve(system, right[..., None])[..., 0]
        magnitude = np.hypot(solution[:, :4], solution[:, 4:8])
        return np.where(shifted > 0.0, magnitude / (static * shifted), np.inf)


def scanned_least_adhesion(loads: np.ndarray, forces: np.ndarray, rows: np.ndarray, static: float) -> float:
    """The least F holding the sample: a scan up from its lift-off to the first F held with every F above it held,
    then halvings between it and the step below."""
    lift_off = loads.sum() + np.max(-4.0 * loads)
    top = lift_off + 2.0 * (abs(loads.sum()) + 1.0)
    while not np.all(use_at(loads, forces, np.array([top]), rows, static) <= 1.0):
        top = lift_off + 2.0 * (top - lift_off)
    scan = lift_off + (top - lift_off) * np.arange(1, SCAN + 1) / SCAN
    held = np.all(use_at(loads, forces, scan, rows, static) <= 1.0, axis=1)
    first = SCAN - int(np.argmin(held[::-1])) if not held.all() else 0  # held from here on
    low, high = (scan[first - 1] if first else lift_off), scan[first]
    for _ in range(60):
        middle = 0.5 * (low + high)
        if np.all(use_at(loads, forces, np.array([middle]), rows, static) <= 1.0):
            high = middle
        else:
            low = middle
    return high


def test_the_least_adhesion_of_each_sample_is_that_of_a_scan_of_the_adhesion_force():
    """Samples of three robots, their loads some negative (in one sample their sum), some light: forces that are their chassis wrench's
    split (ideal contact's), re-shared by that split, and forces that are not, re-shared as coulomb contact shares
    them (each side's traction by load, the lateral force and moment by the least-norm split); some held as soon
    as every wheel is on the wall (lift-off binds). Each sample's figure is the scan's, and least_adhesion gives the
    largest, its sample and the wheel that binds there."""
    rng = np.random.default_rng(11)
    binding = set()  # (whether by coulomb contact's split, whether by lift-off) of what binds
    for case in range(3):
        robot = Robot(random_parameters(rng))
        static = robot.params.wall_friction
        samples = 12
        loads = rng.uniform(-10.0, 80.0, size=(samples, 4))
        wrench = rng.normal(scale=20.0, size=(samples, 3))
        wrench[:3] *= 1e-3  # lift-off binds
        loads[-1] = (-9.0, 3.0, -6.0, 2.0)  # F_run < 0
        forces = split_chassis_wrench(np.zeros(samples), wrench, loads, robot.wheel_offsets)
        coulomb = np.arange(samples) % 2 == case % 2
        forces[coulomb] += rng.normal(scale=4.0, size=forces[coulomb].shape)
        chassis_rows, side_rows = kept_rows(robot, 'chassis'), kept_rows(robot, 'sides')
        want = np.array([scanned_least_adhesion(loads[k], forces[k], side_rows if coulomb[k] else chassis_rows,
                                                static) for k in range(samples)])
        got = needed_adhesion(loads, forces, robot)
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
        lift_off = loads.sum(axis=1) + np.max(-4.0 * loads, axis=1)
        assert np.any(np.isclose(want, lift_off, rtol=1e-9)) and not np.all(np.isclose(want, lift_off, rtol=1e-9))
        for part in (np.arange(samples), np.flatnonzero(~coulomb), np.arange(3)):  # all, the chassis', lift-offs
            needed, sample, wheel, lifts = least_adhesion(loads[part], forces[part], robot)
            assert (needed, sample) == (pytest.approx(np.max(want[part]), rel=1e-9), int(np.argmax(want[part])))
            k = part[sample]
            if lifts:
                assert needed == pytest.approx(lift_off[k], rel=1e-12) and wheel == int(np.argmin(loads[k]))
            else:
                rows = side_rows if coulomb[k] else chassis_rows
                use = use_at(loads[k], forces[k], np.array([needed * (1.0 + 1e-9)]), rows, static)[0]
                assert int(np.argmax(use)) == wheel and 1.0 - 1e-6 < use[wheel] <= 1.0
            binding.add((bool(coulomb[k]), lifts))
    assert {(True, False), (False, False)} < binding and any(lifts for _coulomb, lifts in binding), binding
