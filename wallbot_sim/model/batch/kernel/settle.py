"""Coulomb contact's step boundaries and the steps from them: one robot's transitions until its stick/slip set
holds (``CoulombContact.settle``), the RK4 step with the held friction and loads, a robot's chunk of instants
(``robot_contact_run``) and a batch's, robot by robot over the cores."""

from __future__ import annotations

import math

import numpy as np

from wallbot_sim.model.batch.kernel.boundary import _boundary, _inline_boundary, _project_onto
from wallbot_sim.model.batch.kernel.compiling import jit, prange, unowned
from wallbot_sim.model.batch.kernel.dynamics import _rk4, _workspace
from wallbot_sim.model.batch.kernel.layout import (
    AT_REST, CANDIDATES, DETACHED, DIVERGED, FAILED, FORCES, HOLDING, LOADS, MAX_ROWS, NON_LATERAL, NONSLIP, PREDICTED,
    PRESSED, PROJECTION, QDD, RAN, REVERSING, ROLLING, SETTLE_PASSES, SOLUTION_ROWS, SOLUTION_WIDTH, SOLVED, STATIC,
    STICK, STICKING, STOPPED, TOTAL, TRIAL_SLIDING, TRIAL_Y, VELOCITY, _contact_workspace)
from wallbot_sim.model.robot import DOF


def _speed(velocity: np.ndarray, wheel: int, flags: np.ndarray) -> float:
    """|v| of a wheel's velocity (interleaved) over the directions that have friction (``contact._speed``)."""
    along = velocity[2 * wheel] if flags[NONSLIP] else 0.0
    across = velocity[2 * wheel + 1] if flags[NON_LATERAL] else 0.0
    return math.sqrt(along * along + across * across)


def _reverses(solution: np.ndarray, wheel: int, flags: np.ndarray) -> bool:
    """Whether the step would reverse the wheel's slip, v_i . w_i < 0; never for a wheel at rest
    (``contact._reverses``)."""
    return ((solution[VELOCITY, 2 * wheel] * solution[PREDICTED, 2 * wheel]
             + solution[VELOCITY, 2 * wheel + 1] * solution[PREDICTED, 2 * wheel + 1]) < 0.0
            and _speed(solution[VELOCITY], wheel, flags) > AT_REST)


def _holds(solution: np.ndarray, wheel: int, static: float) -> bool:
    """Whether the wheel's force lies in its friction disc, |f_i| <= mu_s N_i (``contact._holds``)."""
    size = math.hypot(solution[FORCES, 2 * wheel], solution[FORCES, 2 * wheel + 1])
    return not size > static * solution[LOADS, wheel]


# Long on purpose (numba): a round of transitions keeps its state, the stick/slip sets, in one compiled frame.
def _settle(y: np.ndarray, reference: np.ndarray, flags: np.ndarray, constants: np.ndarray, contact: np.ndarray,
            torque: np.ndarray, dt: float, sliding: np.ndarray, loads: np.ndarray, friction: np.ndarray,
            rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
            lower: np.ndarray, vectors: np.ndarray,
            scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray, marks: np.ndarray,
            columns: np.ndarray, responses: np.ndarray, solution: np.ndarray, trial: np.ndarray) -> int:
    """The stick/slip transitions at y's boundary, then the solution the step integrates (``CoulombContact.settle``,
    one long function as numba compiles it best: a round of transitions shares its state, the sets, in registers).

    In turn, until nothing changes: a sliding wheel the step would reverse is stopped by the switch projection and
    slides on from rest; sliding wheels that are stopping stick again when the solve with their rows restored
    holds them in their discs (their slip projected away); every sticking wheel whose force leaves its disc
    slides. ``sliding`` (4,), ``loads`` (4,) and ``friction`` (8,: the sliding wheels' (f_x, f_y), zero for the
    others) are the contact state held over the last step (the loads and friction Newton's start), updated in
    place, and y's velocities are projected in place, unless an error code is returned (``CONTACT_ERRORS``).
    """
    frictional = flags[NON_LATERAL] or flags[NONSLIP]
    static, stick = contact[STATIC], contact[STICK]
    for wheel in range(4):
        sliding[wheel] = sliding[wheel] and frictional
    error = _inline_boundary(y, reference, flags, constants, contact, torque, dt, sliding, loads, friction, rows, rhs,
                             factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns,
                             responses, solution)
    if error != SOLVED:
        return error
    sticking, trial_sliding, stopped = marks[STICKING], marks[TRIAL_SLIDING], marks[STOPPED]
    reversing, candidates, holding = marks[REVERSING], marks[CANDIDATES], marks[HOLDING]
    trial_y, projection = vecs[TRIAL_Y, :2 * DOF], mats[PROJECTION]
    for wheel in range(4):
        stopped[wheel] = False
    for _ in range(SETTLE_PASSES):
        any_reversing = False
        for wheel in range(4):
            reversing[wheel] = sliding[wheel] and not stopped[wheel] and _reverses(solution, wheel, flags)
            any_reversing = any_reversing or reversing[wheel]
        if any_reversing:
            for wheel in range(4):
                stopped[wheel] = stopped[wheel] or reversing[wheel]
                sticking[wheel] = frictional and (not sliding[wheel] or reversing[wheel])
            _project_onto(y, flags, constants, sticking, projection, factor, matrix, gram, lower, vectors, scratch)
            error = _boundary(y, reference, flags, constants, contact, torque, dt, sliding, loads, friction, rows, rhs,
                              factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns,
                              responses, solution)
            if error != SOLVED:
                return error
        searching = False
        for wheel in range(4):
            candidates[wheel] = sliding[wheel] and (_speed(solution[VELOCITY], wheel, flags) < stick
                                                    or _speed(solution[PREDICTED], wheel, flags) < stick)
            searching = searching or candidates[wheel]
        while searching:
            for wheel in range(4):
                trial_sliding[wheel] = sliding[wheel] and not candidates[wheel]
                sticking[wheel] = frictional and not trial_sliding[wheel]
            for i in range(2 * DOF):
                trial_y[i] = y[i]
            _project_onto(trial_y, flags, constants, sticking, projection, factor, matrix, gram, lower, vectors,
                          scratch)
            error = _boundary(trial_y, reference, flags, constants, contact, torque, dt, trial_sliding,
                              loads, friction, rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs,
                              ints, marks, columns, responses, trial)
            if error != SOLVED:
                return error
            same, searching = True, False
            for wheel in range(4):
                holding[wheel] = candidates[wheel] and _holds(trial, wheel, static)
                same = same and holding[wheel] == candidates[wheel]
                searching = searching or holding[wheel]
            if same:
                for wheel in range(4):
                    sliding[wheel] = trial_sliding[wheel]
                for i in range(2 * DOF):
                    y[i] = trial_y[i]
                solution[:, :] = trial
                break
            for wheel in range(4):
                candidates[wheel] = holding[wheel]
        while True:
            exceeded = False
            for wheel in range(4):
                if frictional and not sliding[wheel] and not _holds(solution, wheel, static):
                    sliding[wheel] = exceeded = True
            if not exceeded:
                break
            error = _boundary(y, reference, flags, constants, contact, torque, dt, sliding, loads, friction, rows, rhs,
                              factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns,
                              responses, solution)
            if error != SOLVED:
                return error
        reversed_again = False
        for wheel in range(4):
            reversed_again = reversed_again or (sliding[wheel] and not stopped[wheel]
                                                and _reverses(solution, wheel, flags))
        if not reversed_again:
            break
    for wheel in range(4):
        loads[wheel] = solution[LOADS, wheel]
        for direction in range(2):
            friction[2 * wheel + direction] = solution[FORCES, 2 * wheel + direction] if sliding[wheel] else 0.0
    return SOLVED


def _hold(solution: np.ndarray, sliding: np.ndarray, flags: np.ndarray, contact: np.ndarray, gains: np.ndarray,
          sticking: np.ndarray, held: np.ndarray) -> None:
    """What a step holds from its settled boundary (``_problem``'s gains, sticking and held): each wheel's rolling
    resistance f_r max(N_i, 0), the sticking wheels, the sliding wheels' friction."""
    frictional = flags[NON_LATERAL] or flags[NONSLIP]
    for wheel in range(4):
        load = solution[LOADS, wheel]
        gains[wheel] = contact[ROLLING] * (load if load > 0.0 else 0.0)
        sticking[wheel] = frictional and not sliding[wheel]
        for direction in range(2):
            held[2 * wheel + direction] = solution[FORCES, 2 * wheel + direction] if sliding[wheel] else 0.0


def _held_step(state: np.ndarray, references: np.ndarray, flags: np.ndarray, constants: np.ndarray,
               contact: np.ndarray, torque: np.ndarray, dt: float, solution: np.ndarray, sliding: np.ndarray,
               rows: np.ndarray, rhs: np.ndarray, factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray,
               lower: np.ndarray, vectors: np.ndarray, scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray,
               ints: np.ndarray, marks: np.ndarray, out: np.ndarray, slopes: np.ndarray) -> bool:
    """The RK4 step from a settled boundary (``Simulation.step``): the solution's qdd its first stage, the sticking
    set, loads and sliding wheels' friction held; whether the state it gives (``out``) is finite."""
    gains, held, sticking = vecs[PRESSED], vecs[TOTAL], marks[STICKING]
    _hold(solution, sliding, flags, contact, gains, sticking, held)
    for i in range(DOF):
        slopes[0, DOF + i] = solution[QDD, i]
    return _rk4(state, references, flags, constants, torque, gains, True, sticking, held, dt, True, rows, rhs, factor,
                matrix, gram, lower, vectors, scratch, mats, ints, out, slopes)


def _robot_workspace() -> tuple[np.ndarray, ...]:
    """One robot's scratch for its boundaries and steps, in ``_contact_run``'s order: rows, rhs, ``_workspace``'s
    six arrays, ``_contact_workspace``'s six, the trial solution and the RK4 slopes."""
    return ((np.zeros((MAX_ROWS, DOF)), np.zeros(MAX_ROWS)) + _workspace() + _contact_workspace()
            + (np.zeros((SOLUTION_ROWS, SOLUTION_WIDTH)), np.zeros((4, 2 * DOF))))


def robot_contact_run(states: np.ndarray, settled: np.ndarray, references: np.ndarray, flags: np.ndarray,
                      constants: np.ndarray, contact: np.ndarray, torque: np.ndarray, dt: float, steps: int,
                      sliding: np.ndarray, loads: np.ndarray, friction: np.ndarray, solutions: np.ndarray,
                      slid: np.ndarray, outcome: np.ndarray, settled_first: bool) -> None:
    """One robot with coulomb contact over consecutive instants: each boundary settled (``_settle``), then the
    step from it (``_held_step``).

    ``states`` (T + 1, 14): row 0 the state at the first instant; ``settled`` (T, 14) gets each instant's state
    with its velocities projected where a wheel stopped or stuck, ``solutions`` (T, 8, 8) its solution, ``slid``
    (T, 4) its sliding wheels, and ``states`` row k + 1 the state one step later, for k < ``steps`` (at most T).
    ``sliding`` (4,), ``loads`` (4,) and ``friction`` (8,): the contact state at the start (``_settle``'s), updated
    instant by instant.
    ``outcome`` (4,): the instants settled, the steps taken, how the run ended (RAN, DETACHED at the last instant
    settled, DIVERGED after it, FAILED at the next: its error code in outcome[3]). ``settled_first``: row 0 of
    ``states`` is settled already, ``solutions[0]`` its solution and the contact state the one after it (a
    boundary the caller settled): the run steps from it.
    """
    (rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns, responses, trial,
     slopes) = _robot_workspace()
    _contact_run(states, settled, references, flags, constants, contact, torque, dt, steps, sliding, loads, friction,
                 solutions, slid, outcome, settled_first, rows, rhs, factor, matrix, gram, lower, vectors, scratch,
                 mats, vecs, ints, marks, columns, responses, trial, slopes)


def _contact_run(states: np.ndarray, settled: np.ndarray, references: np.ndarray, flags: np.ndarray,
                 constants: np.ndarray, contact: np.ndarray, torque: np.ndarray, dt: float, steps: int,
                 sliding: np.ndarray, loads: np.ndarray, friction: np.ndarray, solutions: np.ndarray,
                 slid: np.ndarray, outcome: np.ndarray, settled_first: bool, rows: np.ndarray, rhs: np.ndarray,
                 factor: np.ndarray, matrix: np.ndarray, gram: np.ndarray, lower: np.ndarray, vectors: np.ndarray,
                 scratch: np.ndarray, mats: np.ndarray, vecs: np.ndarray, ints: np.ndarray, marks: np.ndarray,
                 columns: np.ndarray, responses: np.ndarray, trial: np.ndarray, slopes: np.ndarray) -> None:
    """``robot_contact_run`` in its workspace (``_settle``'s and ``_held_step``'s scratch), every array taken
    ``unowned``: the caller holds them all for the run."""
    states, settled, references, flags = unowned(states), unowned(settled), unowned(references), unowned(flags)
    constants, contact, torque = unowned(constants), unowned(contact), unowned(torque)
    sliding, loads, friction = unowned(sliding), unowned(loads), unowned(friction)
    solutions, slid, outcome = unowned(solutions), unowned(slid), unowned(outcome)
    rows, rhs, factor, matrix, gram = unowned(rows), unowned(rhs), unowned(factor), unowned(matrix), unowned(gram)
    lower, vectors, scratch = unowned(lower), unowned(vectors), unowned(scratch)
    mats, vecs, ints, marks = unowned(mats), unowned(vecs), unowned(ints), unowned(marks)
    columns, responses = unowned(columns), unowned(responses)
    trial, slopes = unowned(trial), unowned(slopes)
    outcome[0], outcome[1], outcome[2], outcome[3] = 0, 0, RAN, SOLVED
    for k in range(solutions.shape[0]):
        for i in range(2 * DOF):
            settled[k, i] = states[k, i]
        if k > 0 or not settled_first:
            error = _settle(settled[k], references[k, 0], flags, constants, contact, torque, dt, sliding, loads,
                            friction, rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints,
                            marks, columns, responses, solutions[k], trial)
            if error != SOLVED:
                outcome[2], outcome[3] = FAILED, error
                return
        outcome[0] = k + 1
        for wheel in range(4):
            slid[k, wheel] = sliding[wheel]
        if min(loads[0], loads[1], loads[2], loads[3]) < 0.0:
            outcome[2] = DETACHED
            return
        if k == steps:
            return
        if not _held_step(settled[k], references[k], flags, constants, contact, torque, dt, solutions[k], sliding,
                          rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks,
                          states[k + 1], slopes):
            outcome[2] = DIVERGED
            return
        outcome[1] = k + 1


def contact_workspaces(size: int) -> tuple[np.ndarray, ...]:
    """Each of ``size`` robots' own scratch for its boundaries and steps (``_contact_run``'s workspace, 16 arrays
    with the robot first, ~60 kB a robot), kept over a batch's calls: a robot's stick/slip set stays factored
    (``frame``) from one call to the next instead of being factored again at the start of each (three times a
    controller period: its two boundaries and its run)."""
    return tuple(np.zeros((size, *array.shape), dtype=array.dtype) for array in _robot_workspace())


def _batch_contact_run(states: np.ndarray, settled: np.ndarray, references: np.ndarray, flags: np.ndarray,
                       constants: np.ndarray, contact: np.ndarray, torques: np.ndarray, dt: float, steps: int,
                       sliding: np.ndarray, loads: np.ndarray, friction: np.ndarray, live: np.ndarray,
                       solutions: np.ndarray, slid: np.ndarray, outcomes: np.ndarray, settled_first: bool,
                       workspaces: tuple) -> None:
    """``robot_contact_run`` of every ``live`` robot (``settled_first``: from its settled boundary) over the
    same instants, robot by robot over the cores, each in its own workspace (``contact_workspaces``): ``states``
    (N, T + 1, 14), ``settled`` (N, T, 14), ``solutions`` (N, T, 8, 8), ``slid`` (N, T, 4), ``outcomes`` (N, 4) each
    robot's ``robot_contact_run``'s, ``references`` (T, 3, 10) theirs; ``sliding``, ``loads`` and ``friction``
    (N, ...) each robot's contact state, updated."""
    (rows, rhs, factor, matrix, gram, lower, vectors, scratch, mats, vecs, ints, marks, columns, responses, trial,
     slopes) = workspaces
    for robot in prange(states.shape[0]):
        if live[robot]:
            _contact_run(states[robot], settled[robot], references, flags, constants[robot], contact[robot],
                         torques[robot], dt, steps, sliding[robot], loads[robot], friction[robot], solutions[robot],
                         slid[robot], outcomes[robot], settled_first, rows[robot], rhs[robot], factor[robot],
                         matrix[robot], gram[robot], lower[robot], vectors[robot], scratch[robot], mats[robot],
                         vecs[robot], ints[robot], marks[robot], columns[robot], responses[robot], trial[robot],
                         slopes[robot])


_speed = jit(_speed, inline="always")
_reverses = jit(_reverses, inline="always")
_holds = jit(_holds, inline="always")
# A step's boundary and RK4 step compile into the run's own frame (inline): numba passes an array argument as its
# seven to nine fields, so a call with the ~25 arrays of a boundary moves some 200 values, and the optimizer sees
# no further than a call; inlined, a coulomb step takes ~40% less time (docs/performance.md)
_settle = jit(_settle, inline="always")
_hold = jit(_hold, inline="always")
_held_step = jit(_held_step, inline="always")
_robot_workspace = jit(_robot_workspace, inline="always")
robot_contact_run = jit(robot_contact_run)
_contact_run = jit(_contact_run)
_batch_contact_run = jit(_batch_contact_run, parallel=True)
