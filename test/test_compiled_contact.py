"""The batch kernel's coulomb functions that the comparisons of whole runs do not isolate.

The kernel's coulomb contact is the batch's (per channel; ``test_batch_contact.py`` runs it against the NumPy
engine). A single ``Simulation`` runs coulomb contact on the Python model on either engine
(``test_model_contact.py::test_the_numba_engine_runs_coulomb_contact_on_the_python_model``).
"""

from __future__ import annotations

import numpy as np
import pytest

from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import Robot
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.robot import DOF

pytestmark = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')


def minimum_norm_motion(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """qdd = W (s + B+ (b - B s)), s = W^T Q, B = A W, by numpy's least squares (SVD)."""
    scaled = factor.T @ force
    matrix = rows @ factor
    return factor @ (scaled + np.linalg.lstsq(matrix, rhs - matrix @ scaled, rcond=None)[0])


@pytest.mark.parametrize('consistent', [True, False])
def test_the_one_factorization_solve_keeps_independent_rows_and_refuses_disagreeing_ones(consistent):
    """``_responses``: with a row that repeats another (as a side's nonslip rows repeat its belt row) the
    five motions are the minimum-norm ones; where the repeated row's b disagrees it leaves the work to the
    least-squares solve (returns False)."""
    rng = np.random.default_rng(5)
    factor = np.tril(rng.normal(0.0, 1.0, (DOF, DOF)))
    factor[3:, :] = 0.0
    factor[np.arange(DOF), np.arange(DOF)] = rng.uniform(1.0, 2.0, DOF)
    rows = rng.normal(0.0, 1.0, (4, DOF))
    rows[3] = 2.0 * rows[1] - rows[0]
    rhs = rng.normal(0.0, 1.0, 4)
    rhs[3] = 2.0 * rhs[1] - rhs[0] + (0.0 if consistent else 0.5)
    force, per_load = rng.normal(0.0, 1.0, DOF), rng.normal(0.0, 1.0, (4, DOF))
    padded_rows, padded_rhs = np.zeros((kernel.MAX_ROWS, DOF)), np.zeros(kernel.MAX_ROWS)
    padded_rows[:4], padded_rhs[:4] = rows, rhs
    free, responses = np.zeros(DOF), np.zeros((4, DOF))
    done = kernel._responses(factor, force, padded_rhs, np.zeros(kernel.MAX_ROWS), per_load, padded_rows, 4,
                                     np.zeros((kernel.MAX_ROWS, DOF)), np.zeros((DOF, DOF)), np.zeros((DOF, DOF)),
                                     np.zeros(kernel.MAX_ROWS), np.zeros((kernel.WORK_ROWS, DOF)), free,
                                     responses)
    assert done == consistent
    if consistent:
        assert np.allclose(free, minimum_norm_motion(factor, force, rows, rhs), rtol=0.0, atol=1e-12)
        for wheel in range(4):
            assert np.allclose(responses[wheel], minimum_norm_motion(factor, per_load[wheel], rows, np.zeros(4)),
                               rtol=0.0, atol=1e-12)


def test_contact_constants_are_in_the_order_the_kernel_reads_them():
    robot = Robot(load_robot_parameters().replace(com_height=0.07, kinetic_friction=0.5, adhesion_force=150.0))
    constants = kernel.contact_constants(robot)
    params = robot.params
    assert constants[:7].tolist() == [150.0, params.wall_friction, 0.5, params.stick_velocity, 0.07,
                                      params.half_wheelbase, params.half_track]
    assert constants[7:11].tolist() == robot.wheel_offsets[:, 0].tolist()
    assert constants[11:].tolist() == robot.wheel_offsets[:, 1].tolist()
