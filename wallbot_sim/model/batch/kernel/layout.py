"""The layout of the kernel's arrays: the constraint modules' flags and rows, each robot's contact constants, a
boundary's solution, the workspace's rows, and the tolerances and error codes the kernel shares with the Python
model."""

from __future__ import annotations

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import jit
from wallbot_sim.model.constraint_set import MODULES
from wallbot_sim.model.robot import DOF, Robot


MODULE_ORDER = tuple(MODULES)
"""The modules the kernel knows, in ``MODULES``' stacking order: a problem's flags follow it (``module_flags``)."""
MODULE_ROWS = tuple(kind.rows for kind in MODULES.values())
"""Each module's row count, in MODULE_ORDER."""
TRAJECTORY, TANGENT_HEADING, BELT, NON_LATERAL, NONSLIP = (
    MODULE_ORDER.index(name) for name in ('trajectory', 'tangent_heading', 'belt', 'non_lateral', 'nonslip'))
"""Each module's flag (its place in MODULE_ORDER); numba compiles these module-level ints in as constants."""
HELD_BY = (NONSLIP, NON_LATERAL)
"""The flag of the module whose friction holds each direction of a wheel's contact velocity (x_p, y_p): with coulomb
contact its rows give way to each sticking wheel's contact row in that direction."""
MAX_ROWS = sum(MODULE_ROWS) - sum(MODULE_ROWS[flag] for flag in HELD_BY) + 2 * 4
"""The rows of the other modules with every wheel's two contact rows (more than every module's at once)."""

ADHESION, STATIC, KINETIC, STICK, HEIGHT, HALF_BASE, HALF_TRACK = range(7)
ROLLING = 15
"""``contact_constants``' fields: F_ad, mu_s, mu_k, v_st, h, a, b; then the wheels' x_i (7-10) and y_i (11-14),
then f_r."""
NEWTON_TOLERANCE = 1e-12
"""Residual, relative to F_ad, at which the friction and loads are solved (``kinetic_friction._TOLERANCE``)."""
NEWTON_ITERATIONS = 60
"""``kinetic_friction._ITERATIONS``."""
SETTLE_PASSES = 8
"""Rounds of a boundary's transitions at most (``contact._SETTLE_PASSES``)."""
AT_REST = 1e-12
"""Contact speed (m/s) up to which a wheel is at rest (``contact._AT_REST``)."""
SPLIT_CUT = 1e-12
"""Relative pivot below which the split's weighted system has no more directions (``wheel_forces._SINGULAR``)."""
SOLUTION_ROWS, SOLUTION_WIDTH = 8, 8
QDD, CONSTRAINT, FRICTION, LOADS, FORCES, PREDICTED, VELOCITY, STATUS = range(SOLUTION_ROWS)
"""A boundary's solution (8, 8), by row: qdd, Q_c = M qdd - Q, Q_f (the sliding wheels' friction), N_1..N_4,
f_i (interleaved x, y, wheel by wheel: reshaped (4, 2)), the predicted slip w_i and the contact velocities v_i
(likewise), then STATUS."""
RESIDUAL, ERROR, NEWTON_RESIDUAL = range(3)
"""The STATUS row: |A qdd - b|, an error code (``CONTACT_ERRORS``), the Newton residual it stopped at (N)."""
SOLVED, SINGULAR, UNCONVERGED = range(3)
CONTACT_ERRORS = ('', 'kinetic friction and normal loads have no consistent value (singular system)',
                  'kinetic friction and normal loads did not converge (residual {:.3g} N)')
"""What a boundary's error code means (``consistent_friction``'s ModelError messages)."""
RAN, DETACHED, DIVERGED, FAILED = range(4)
"""How a contact run ended (``robot_contact_run``'s outcome): as asked, a wheel lifted off, a state stopped being
finite, a boundary had no solution."""
COLUMNS = 1 + 8 + 4
"""A boundary's right-hand sides at most: the forces, each sliding component's unit force, each wheel's unit load."""
(JACOBIAN, TRIAL_JACOBIAN, LU, SLIP_ROWS, GAIN, SLIP_BY_FRICTION, SLIP_BY_LOAD, LOAD_BY_FRICTION, LOAD_BY_LOAD,
 BY_SLIP, STUCK_ROWS, MADE, SPLIT, SPLIT_LOWER, ROW_SYSTEM, ROW_FACTOR, PROJECTION, FRAME_ROWS, FRAME_FACTOR,
 FRAME_MATRIX, FRAME_GRAM, FRAME_PROJECTION, FRAME_SCRATCH, SLIDING_MOTION, LOAD_RESPONSE, SLIP_RESPONSE) = range(26)
"""``_contact_workspace``'s matrices (16 x 16 each): the Newton Jacobian, its trial and LU factors; J_S, L, the
constant blocks dt J_S D, dt J_S R, -L D, L R and the Newton step's d(f mu N w / s)/dw; the sticking rows, the
split's U^T J^T, its weighted system and factor; the scratch of B B^T's pivoted factorization and that factor
(``_prepare_rows``); the rows of a projection; the rows the solves use, in the body axes (``frame``), their
factor W of M^-1, B = A W, B B^T, the motion's response to a force W (I - B+ B) W^T, scratch rows, and the
sliding components' responses P J_S^T in the body axes (``_sliding_responses``); the loads'
and the predicted slip's responses to the friction with the loads eliminated, G and H (``_pressed_kinetic``)."""
(STATE, TRIAL_STATE, NEWTON_STEP, RESIDUALS, TRIAL_RESIDUALS, NEWTON_PREDICTED, TRIAL_PREDICTED, SIZES,
 DIRECTIONS, PRESSED, SQUARES, SLIP, DRIFT, ORIGIN, ACCELERATION, TOTAL, REDUCED, SPLIT_X, ROW_LOADS, ZERO,
 NEGATIVE, TRIAL_Y, FREE_LOADS, FREE_SLIP, NEWTON_START) = range(25)
"""``_contact_workspace``'s vectors (16 each)."""
WHEEL_OF, DIRECTION_OF, BLOCK_FIRST, BLOCK_END, PIVOTS, SPLIT_PIVOTS, SPLIT_KEPT, ROW_ORDER, ROW_KEPT, FRAME = range(10)
"""``_contact_workspace``'s integer rows (16 each): each sliding component's wheel and direction, and the first and
one past the last component of its wheel; LU's pivots, the split's pivots (in pivot order, and 1 on each), the rows
``_prepare_rows`` keeps (likewise); which rows ``frame`` has factored."""
STICKING, TRIAL_SLIDING, STOPPED, REVERSING, CANDIDATES, HOLDING = range(6)
"""``_contact_workspace``'s wheel sets (4 each)."""
MATRICES, VECTORS, INTEGERS, SETS = SLIP_RESPONSE + 1, NEWTON_START + 1, FRAME + 1, HOLDING + 1


def contact_constants(robot: Robot) -> np.ndarray:
    """(16,) in the fields' order: F_ad, mu_s, mu_k, v_st, h, a, b, x_1..x_4, y_1..y_4, f_r."""
    params = robot.params
    return np.array([robot.adsorption.applied_force, params.wall_friction, params.kinetic_friction,
                     params.stick_velocity, params.com_height, params.half_wheelbase, params.half_track,
                     *robot.wheel_offsets[:, 0], *robot.wheel_offsets[:, 1], params.rolling_resistance], dtype=float)


def _contact_workspace() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One robot's scratch for its boundaries beside ``_workspace``'s: matrices, vectors, integers, wheel sets, and
    the columns and responses of a boundary's solve (COLUMNS x 7 each)."""
    return (np.zeros((MATRICES, 16, 16)), np.zeros((VECTORS, 16)), np.zeros((INTEGERS, 16), dtype=np.int64),
            np.zeros((SETS, 4), dtype=np.bool_), np.zeros((COLUMNS, DOF)), np.zeros((COLUMNS, DOF)))


_contact_workspace = jit(_contact_workspace, inline="always")
