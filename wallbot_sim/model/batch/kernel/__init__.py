"""The batch compiled with numba: the RK4 steps robot by robot, ideal contact fused, coulomb contact settled.

The NumPy path (``BatchSimulation`` with ``engine='numpy'``) spends its time in whole-batch
array passes: every operation of a derivative reads and writes (N, k, 7) arrays, so a step is
bound by memory traffic and ~200 NumPy calls. This kernel computes the same derivative robot by
robot in registers and small scratch arrays, all the steps of a ``run`` at once (the reference
sampled beforehand, shared by all robots), the robots split over the cores. It is the same
computation as the NumPy path, operation for operation where it can be: the model's forces,
the rows of the modules of ``BATCH_MODULES`` in stacking order, the Udwadia-Kalaba solve by
normal equations with the pivoted (rank-revealing) fallback per robot, and RK4's sums. The
agreement tests run both.

``constrained_accelerations`` is the solve alone (the NumPy engine's ``batch_constrained_acceleration``
robot by robot), for what the fused step does not cover: the outputs step hooks see with ideal contact.

``robot_run`` takes one robot's RK4 steps a chunk at a time, with the motion (qdd, Q, Q_c, residual) at
each state, for ``Simulation(..., engine='numba')`` (``wallbot_sim.model.compiled``): the same
derivative and RK4 step as the batch's fused loop.

Coulomb contact per wheel (docs/model.md 11.3): ``_settle`` is one robot's step boundary, ``CoulombContact.settle``
of the Python model (its transitions, the solve of each stick/slip set with the friction and loads found by
Newton's method, the split of the sticking wheels' force), and ``_held_step`` the RK4 step from it.
``robot_contact_run`` takes one robot's boundaries and steps a chunk at a time (``Simulation(..., engine='numba',
contact='coulomb')``), ``batch_contact_settle`` and ``batch_contact_step`` a batch's, robot by robot over the
cores, and ``batch_contact_run`` a batch's chunk of steps at held torques. They agree with the Python model to
1e-9 (``test/test_compiled_contact.py``, ``test/test_batch_contact.py``).

The package is split by concern: ``problem`` (a robot's Q, W and constraint rows at a state), ``dynamics`` (the
derivative and RK4 step, ``robot_run``, ``tracking_force`` and a batch's ``batch_tracking_forces``), ``outputs`` (the
outputs of a run's instants with ideal contact), ``linalg`` (the solves), ``row_space`` (the solve in the rows' own
space), ``frame`` (coulomb's solves in the body axes: a stick/slip set's rows, responses and Newton's blocks kept
while it holds), ``layout`` (the contact arrays' layout and tolerances), ``friction`` (the contact rows, loads and
Newton's kinetic friction), ``boundary`` (one stick/slip set's solve and split) and ``settle`` (the transitions, the
steps from a boundary, the runs); ``compiling`` compiles them into numba's cache under one stamp of the whole
package. numba is optional: ``available()`` says whether it imported.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from wallbot_sim.model.batch.kernel.compiling import available, numba
from wallbot_sim.model.batch.kernel.dynamics import (
    REFERENCE_FIELDS, _steps, batch_tracking_forces, reference_samples, robot_run, tracking_force)
from wallbot_sim.model.batch.kernel.layout import (
    CONSTRAINT, CONTACT_ERRORS, DETACHED, DIVERGED, FAILED, FORCES, FRICTION, HELD_BY, LOADS, MAX_ROWS, MODULE_ORDER,
    MODULE_ROWS, NEWTON_RESIDUAL, PREDICTED, QDD, RAN, RESIDUAL, SOLUTION_ROWS, SOLUTION_WIDTH, STATUS, VELOCITY,
    contact_constants)
from wallbot_sim.model.batch.kernel.linalg import _accelerations
from wallbot_sim.model.batch.kernel.outputs import ideal_outputs
from wallbot_sim.model.batch.kernel.settle import _batch_contact_run, contact_workspaces, robot_contact_run
from wallbot_sim.model.batch.robots import RobotBatch

__all__ = [
    'available', 'numba', 'HELD_BY', 'MAX_ROWS', 'MODULE_ORDER', 'MODULE_ROWS', 'REFERENCE_FIELDS', 'reference_samples',
    'robot_run', 'tracking_force', 'batch_tracking_forces', 'CONSTRAINT', 'CONTACT_ERRORS', 'FAILED', 'FORCES',
    'FRICTION', 'LOADS',
    'NEWTON_RESIDUAL', 'PREDICTED', 'QDD', 'RAN', 'RESIDUAL', 'SOLUTION_ROWS', 'SOLUTION_WIDTH', 'STATUS', 'VELOCITY',
    'contact_constants', 'robot_contact_run', 'constrained_accelerations', 'robot_constants', 'module_flags', 'advance',
    'batch_contact_settle', 'batch_contact_step', 'batch_contact_run', 'contact_workspaces', 'ideal_outputs',
    'DETACHED', 'DIVERGED']


def constrained_accelerations(factor: np.ndarray, force: np.ndarray, rows: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``batch_constrained_acceleration`` compiled robot by robot, for the robots' own factors W (N, 7, 7)."""
    out = np.empty(force.shape)
    _accelerations(np.ascontiguousarray(factor), np.ascontiguousarray(force), np.ascontiguousarray(rows),
                   np.ascontiguousarray(rhs), out)
    return out


def robot_constants(robots: RobotBatch, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """(N, 24) per robot, in ``_acceleration``'s order, from a ``RobotBatch`` and the Baumgarte gains."""
    return np.ascontiguousarray(np.column_stack((
        robots.total_mass, robots.yaw_inertia, robots.spin_inertia, robots.first_moment, robots.gravity,
        robots.weight, robots.wheel_radius, robots.resistance_gain, robots.velocity_epsilon2, alpha, beta,
        robots.lateral_offsets, robots.perpendicular_offsets.reshape(len(alpha), 8))))


def module_flags(active: Sequence[str]) -> tuple[np.ndarray, int]:
    """The kernel's flags (in MODULE_ORDER) of the modules named ``active``, and their row count."""
    flags = np.array([name in active for name in MODULE_ORDER], dtype=np.bool_)
    return flags, sum(rows for name, rows in zip(MODULE_ORDER, MODULE_ROWS) if name in active)


def advance(y: np.ndarray, steps: int, dt: float, references: np.ndarray, active: tuple[str, ...],
            constants: np.ndarray, torques: np.ndarray, chunk: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """y after ``steps`` steps (a new array), and (N,) the step each robot diverged at (-1: none)."""
    flags, _ = module_flags(active)
    advanced = np.array(y, dtype=float, order='C')
    diverged = np.full(len(y), -1, dtype=np.int64)
    _steps(advanced, steps, dt, references, flags, constants, np.ascontiguousarray(torques), chunk, diverged)
    return advanced, diverged


def batch_contact_settle(states: np.ndarray, reference: np.ndarray, active: tuple[str, ...], constants: np.ndarray,
                         contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, loads: np.ndarray,
                         friction: np.ndarray, live: np.ndarray, solutions: np.ndarray,
                         workspaces: tuple) -> np.ndarray:
    """Every live robot's coulomb boundary, robot by robot over the cores: ``states`` (velocities projected),
    ``sliding``, ``loads``, ``friction`` (N, 8) and ``solutions`` (N, 8, 8) change in place; returns each robot's
    error code (``CONTACT_ERRORS``). ``workspaces``: the robots' own (``contact_workspaces``), for the batch's calls
    under one configuration (active modules, constants, dt). A run of one instant and no step (``_runs``)."""
    references = np.zeros((1, 3, REFERENCE_FIELDS))
    references[0, 0] = reference
    _, settled, run_solutions, _, outcomes = _runs(states, references, 0, False, active, constants, contact, torques,
                                                   dt, sliding, loads, friction, live, solutions, workspaces)
    states[live], solutions[live] = settled[live, 0], run_solutions[live, 0]
    return outcomes[:, 3]


def batch_contact_step(states: np.ndarray, references: np.ndarray, active: tuple[str, ...], constants: np.ndarray,
                       contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, live: np.ndarray,
                       solutions: np.ndarray, workspaces: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Every live robot's RK4 step from its settled boundary: the new states (the others' as they were) and which
    are finite. ``workspaces`` as ``batch_contact_settle``'s. A run of one step from a settled boundary (``_runs``),
    which settles nothing: the contact state it is handed (zero loads and friction) only passes its lift-off check."""
    size = states.shape[0]
    run_states, _, _, _, outcomes = _runs(states, references[None], 1, True, active, constants, contact, torques, dt,
                                          sliding, np.zeros((size, 4)), np.zeros((size, 8)), live, solutions,
                                          workspaces)
    out = np.where(live[:, None], run_states[:, 1], states)
    return out, ~live | (outcomes[:, 2] != DIVERGED)


def batch_contact_run(states: np.ndarray, references: np.ndarray, active: tuple[str, ...], constants: np.ndarray,
                      contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray, loads: np.ndarray,
                      friction: np.ndarray, live: np.ndarray, solutions: np.ndarray, workspaces: tuple
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """T steps of every live robot from its settled boundary (``_batch_contact_run``), T = len(references), at
    the held ``torques``: ``states`` (N, 14) the boundaries, ``solutions`` (N, 8, 8) theirs; the contact state
    (``sliding``, ``loads``, ``friction``) updated in place. Returns the states (N, T + 1, 14), the settled states
    (N, T, 14), the solutions (N, T, 8, 8), the sliding wheels (N, T, 4) of each instant, and each robot's
    ``robot_contact_run`` outcome (N, 4). ``workspaces`` as ``batch_contact_settle``'s."""
    return _runs(states, references, references.shape[0], True, active, constants, contact, torques, dt, sliding,
                 loads, friction, live, solutions, workspaces)


def _runs(states: np.ndarray, references: np.ndarray, steps: int, settled_first: bool, active: tuple[str, ...],
          constants: np.ndarray, contact: np.ndarray, torques: np.ndarray, dt: float, sliding: np.ndarray,
          loads: np.ndarray, friction: np.ndarray, live: np.ndarray, solutions: np.ndarray, workspaces: tuple
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``_batch_contact_run`` of the robots at ``states`` (N, 14) over T = len(references) instants, taking ``steps``
    steps, from settled boundaries (their ``solutions``) if ``settled_first``: its states, settled states,
    solutions, sliding wheels and outcomes (``batch_contact_run``'s). The one compiled run serves a batch's
    boundaries, steps and held runs."""
    flags, _ = module_flags(active)
    size, instants = states.shape[0], references.shape[0]
    run_states = np.zeros((size, instants + 1, states.shape[1]))
    run_states[:, 0] = states
    settled = np.zeros((size, instants, states.shape[1]))
    run_solutions = np.zeros((size, instants, SOLUTION_ROWS, SOLUTION_WIDTH))
    run_solutions[:, 0] = solutions
    slid = np.zeros((size, instants, 4), dtype=np.bool_)
    outcomes = np.zeros((size, 4), dtype=np.int64)
    _batch_contact_run(run_states, settled, np.ascontiguousarray(references), flags, constants, contact,
                       np.ascontiguousarray(torques), dt, steps, sliding, loads, friction, live, run_solutions,
                       slid, outcomes, settled_first, workspaces)
    return run_states, settled, run_solutions, slid, outcomes
