"""Coulomb contact per wheel on the compiled engine (``Simulation(..., engine='numba', contact='coulomb')``) against the
Python model, step by step: the same stick/slip transitions at the same instants, every output within 1e-9.

The analytic cases, the energy balance and the loads-friction solution run on both engines in test_model_contact.py;
these runs add what only a comparison shows: turning slides whose loads move at every step, re-sticking (the switch
projection), every configuration call between steps, and the kernel's own solves against independent ones.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from batch_helpers import TOLERANCE, minimum_norm_motion, random_robots
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation, StepOutputs
from wallbot_sim.model import contact as python_contact
from wallbot_sim.model import kinetic_friction, wheel_forces
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.batch.kernel import dynamics, layout, row_space
from wallbot_sim.model.batch.robots import RobotBatch
from wallbot_sim.model.contact import CoulombContact, DetachedError
from wallbot_sim.model.robot import DOF

pytestmark = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')

DRIVEN = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False)


def reported(out: StepOutputs) -> dict[str, np.ndarray]:
    contact = out.contact
    friction = contact.friction_force
    return {'q': out.q, 'qd': out.qd, 'acceleration': out.acceleration, 'constraint_force': out.constraint_force,
            'residual': np.array([out.residual]), 'drive': np.array([out.drive.left, out.drive.right, out.drive.lateral]),
            'loads': contact.loads, 'use': np.array(contact.use), 'limits': np.array(contact.limits),
            'friction': np.zeros(DOF) if friction is None else friction, 'wheel_forces': contact.wheel_forces,
            'wheel_use': contact.wheel_use, 'slip_velocity': contact.slip_velocity}


class Pair:
    """One robot on both engines with coulomb contact, stepped together; their outputs at every instant."""

    def __init__(self, robot: Robot, q0: np.ndarray, selection: ConstraintSelection = DRIVEN, reference=None,
                 qd0: np.ndarray | None = None) -> None:
        qd0 = np.zeros(DOF) if qd0 is None else qd0
        self.sims = [Simulation(robot, reference, selection, q0, qd0, contact='coulomb', engine=engine)
                     for engine in ('python', 'numba')]
        self.outputs: list[list[dict[str, np.ndarray]]] = [[], []]
        self.sliding: list[tuple[bool, bool, bool, bool]] = []

    def call(self, action) -> None:
        for simulation in self.sims:
            action(simulation)

    def run(self, steps: int) -> None:
        for _ in range(steps):
            python, numba = (simulation.outputs() for simulation in self.sims)
            assert numba.contact.wheel_slipping == python.contact.wheel_slipping, f't = {python.t:.3f} s'
            assert numba.contact.slipping == python.contact.slipping, f't = {python.t:.3f} s'
            assert (numba.contact.friction_force is None) == (python.contact.friction_force is None)
            self.sliding.append(python.contact.wheel_slipping)
            for history, out in zip(self.outputs, (python, numba)):
                history.append(reported(out))
            self.call(Simulation.step)

    def assert_agree(self, label: str = '') -> None:
        """Every quantity within TOLERANCE of its largest magnitude over the run, or of 1 in its unit where
        that is round-off (a constraint force the sliding wheels leave at zero)."""
        python, numba = self.outputs
        assert len(python) == len(numba) > 0
        for key in python[0]:
            expected, got = np.array([o[key] for o in python]), np.array([o[key] for o in numba])
            error = np.max(np.abs(got - expected))
            assert error <= TOLERANCE * max(np.max(np.abs(expected)), 1.0), f'{label} {key}: differs by {error:.3g}'

    def transitions(self) -> int:
        return sum(a != b for a, b in zip(self.sliding[:-1], self.sliding[1:]))


@pytest.fixture
def python_settles(monkeypatch) -> list[int]:
    """How often the Python stick/slip settlement ran (counted, then passed on)."""
    calls = [0]

    def counted(self, *args, _settle=CoulombContact.settle):
        calls[0] += 1
        return _settle(self, *args)
    monkeypatch.setattr(CoulombContact, 'settle', counted)
    return calls


@pytest.mark.parametrize('heading, torque, adhesion, wheels', [
    (math.pi / 2, (3.5, 2.0), None, {0, 1}),           # the left wheels spin, the robot turns and scrubs
    (math.pi / 2, (3.0, 2.5), None, {0, 1}),           # the left wheels spin
    (0.0, (0.0, 0.0), 100.0, {0, 1, 2, 3}),            # every wheel slides down
    (2.0, (-2.5, 3.0), None, {0, 1, 2, 3}),            # turning on the spot at a slant, every wheel scrubbing
], ids=['turn', 'left-spins', 'slide', 'slant-spin'])
def test_slipping_runs_agree_with_the_python_model(heading, torque, adhesion, wheels, python_settles):
    robot = Robot(load_robot_parameters().replace(adhesion_force=adhesion))
    pair = Pair(robot, np.array([0.0, 0.0, heading, 0, 0, 0, 0]))
    pair.call(lambda simulation: simulation.set_motor_torque(*torque))
    pair.run(1500)
    pair.assert_agree()
    slid = {wheel for flags in pair.sliding for wheel in range(4) if flags[wheel]}
    assert slid == wheels
    assert python_settles[0] == len(pair.sliding)  # the Python engine's; the numba engine settles in the kernel


def test_random_robots_under_changing_torques_stick_and_slip_again_alike():
    """Torques drawn anew every 37 steps (mid-chunk), some zero: wheels slide, stop and stick again by the
    switch projection, on random robots with the CoM off the centre."""
    rng = np.random.default_rng(36)
    sticks_again = transitions = 0
    for i, robot in enumerate(random_robots(rng, 3)):
        weight_torque = robot.total_mass * robot.params.gravity * robot.params.wheel_radius
        pair = Pair(robot, np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi), 0, 0, 0, 0]))
        for change in range(12):
            torque = (0.0, 0.0) if change % 4 == 3 else tuple(rng.uniform(-1.2, 1.2, 2) * weight_torque)
            pair.call(lambda simulation: simulation.set_motor_torque(*torque))
            pair.run(37)
        pair.assert_agree(f'robot {i}')
        sticks_again += sum(any(a) and not any(b) for a, b in zip(pair.sliding[:-1], pair.sliding[1:]))
        transitions += pair.transitions()
    assert sticks_again >= 3 and transitions >= 10, (sticks_again, transitions)


def test_configuration_calls_between_steps_act_alike():
    """A suction loss and its recovery, the lateral constraint dropped and restored while sliding, ideal
    contact and back, a reset: both engines go on agreeing."""
    robot = Robot(load_robot_parameters())
    pair = Pair(robot, np.array([0.0, 0.0, 0.3, 0, 0, 0, 0]))
    pair.call(lambda simulation: simulation.set_motor_torque(1.0, 1.4))
    pair.run(100)
    pair.call(lambda simulation: simulation.set_adhesion_force(110.0))
    pair.run(150)
    assert all(pair.sliding[-1])  # every wheel sliding down after the suction loss
    without_lateral = ConstraintSelection.parse('belt,nonslip', trajectory=False)
    pair.call(lambda simulation: simulation.set_constraints(without_lateral))
    pair.run(40)
    pair.call(lambda simulation: simulation.set_constraints(DRIVEN))
    pair.run(40)
    pair.call(lambda simulation: simulation.set_adhesion_force(None))
    pair.run(150)
    pair.call(lambda simulation: simulation.set_contact_model('ideal'))
    pair.run(30)
    pair.call(lambda simulation: simulation.set_contact_model('coulomb'))
    pair.run(60)
    pair.call(lambda simulation: simulation.reset())
    pair.run(30)
    pair.assert_agree()
    assert pair.transitions() >= 2


def test_the_heading_task_beside_the_contact_rows_agrees():
    """Driven with the tangent-heading task on: a task row beside the contact rows (a least-squares compromise
    where the sticking wheels' lateral rows hold the heading too) while wheels slide."""
    robot = Robot(load_robot_parameters())
    circle = load_scenario('circle')
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False, tangent_heading=True)
    pair = Pair(robot, np.array([0.0, 0.0, 1.0, 0, 0, 0, 0]), selection, circle.reference)
    pair.call(lambda simulation: simulation.set_motor_torque(3.5, 1.0))
    pair.run(600)
    pair.assert_agree()
    assert any(any(flags) for flags in pair.sliding)


def test_detachment_mid_run_stops_both_engines_at_the_same_instant():
    """Facing +X at 3 N m per side the wheels spin and the robot slides down while turning, until a wheel's load
    goes negative (mid-chunk): the same wheel, load and time on both engines, the lift-off instant's outputs alike
    (the lifted wheel sliding with no force), and the state of that instant kept."""
    robot = Robot(load_robot_parameters())
    pair = Pair(robot, np.zeros(DOF))
    pair.call(lambda simulation: simulation.set_motor_torque(3.0, 3.0))
    errors = []
    for simulation, history in zip(pair.sims, pair.outputs):
        seen: list[StepOutputs] = []

        def record(out: StepOutputs, seen: list[StepOutputs] = seen, history: list = history) -> None:
            seen.append(out)
            history.append(reported(out))
        with pytest.raises(DetachedError) as error:
            simulation.run(2.0, record)
        errors.append((error.value, simulation.steps, simulation.q, seen[-1]))
    pair.assert_agree()
    (python, steps, q, python_out), (numba, numba_steps, numba_q, numba_out) = errors
    assert steps == numba_steps > 500
    assert (numba.wheel, numba.t) == (python.wheel, python.t)
    assert numba.load == pytest.approx(python.load, abs=TOLERANCE * 100.0)
    assert np.allclose(numba_q, q, rtol=0.0, atol=TOLERANCE)
    lifted = numba.wheel - 1
    for out in (python_out, numba_out):
        assert out.contact.wheel_slipping[lifted] and out.contact.wheel_use[lifted] == 0.0
        assert np.all(out.contact.wheel_forces[lifted] == 0.0)


@pytest.mark.parametrize('consistent', [True, False])
def test_the_rows_own_space_solve_keeps_independent_rows_and_refuses_disagreeing_ones(consistent):
    """``_prepare_rows`` then its solve (``_projected``): with rows that repeat others (as a side's contact rows
    repeat its belt row), each motion is the minimum-norm one numpy's SVD least squares gives (the rows' b for the
    first, 0 for the others); where a repeated row's b disagrees, the first is left to the least squares (False)."""
    rng = np.random.default_rng(5)
    factor = RobotBatch(random_robots(rng, 1)).mass_inverse_factor(rng.normal(size=(1, DOF)))[0]
    independent = rng.normal(size=(6, DOF))
    rows = np.vstack((independent, rng.normal(size=(4, 6)) @ independent))
    rhs = rows @ rng.normal(size=DOF)
    rhs[9] += 0.0 if consistent else 0.5
    count = len(rows)
    padded_rows, padded_rhs = np.zeros((kernel.MAX_ROWS, DOF)), np.zeros(kernel.MAX_ROWS)
    padded_rows[:count], padded_rhs[:count] = rows, rhs
    _, matrix, _, _, vectors, _ = dynamics._workspace()
    mats, _, ints, *_ = layout._contact_workspace()
    order, kept, lower = ints[layout.ROW_ORDER], ints[layout.ROW_KEPT], mats[layout.ROW_FACTOR]
    gram = mats[layout.FRAME_GRAM]
    rank = row_space._prepare_rows(padded_rows, factor, count, matrix, gram, mats[layout.ROW_SYSTEM], lower, order,
                                   kept)
    assert rank == 6
    for column, force in enumerate(rng.normal(size=(4, DOF))):
        out = np.full(DOF, np.nan)
        solved = row_space._projected(factor, force, padded_rhs, column == 0, matrix, gram, count, rank, order, kept,
                                      lower, vectors[1], vectors[2], vectors[3], out)
        assert solved == (consistent or column > 0)
        if solved:
            expected = minimum_norm_motion(factor, force, rows, rhs if column == 0 else np.zeros(count))
            scale = np.max(np.abs(factor @ (factor.T @ force)))  # the free motion (all rows held: qdd = 0 for b = 0)
            assert np.allclose(out, expected, rtol=0.0, atol=1e-9 * max(scale, np.max(np.abs(expected))))
        else:
            assert np.all(np.isnan(out))


def test_the_kernels_tolerances_are_the_python_models():
    """The kernel keeps its own copies (numba's cache sees changes to its own file only)."""
    assert layout.NEWTON_TOLERANCE == kinetic_friction._TOLERANCE
    assert layout.NEWTON_ITERATIONS == kinetic_friction._ITERATIONS
    assert layout.SETTLE_PASSES == python_contact._SETTLE_PASSES
    assert layout.AT_REST == python_contact._AT_REST
    assert layout.SPLIT_CUT == wheel_forces._SINGULAR


def test_contact_constants_are_in_the_order_the_kernel_reads_them():
    robot = Robot(load_robot_parameters().replace(com_height=0.07, kinetic_friction=0.5, adhesion_force=150.0,
                                                  rolling_resistance=0.02))
    constants = kernel.contact_constants(robot)
    params = robot.params
    assert constants[:7].tolist() == [150.0, params.wall_friction, 0.5, params.stick_velocity, 0.07,
                                      params.half_wheelbase, params.half_track]
    assert constants[7:11].tolist() == robot.wheel_offsets[:, 0].tolist()
    assert constants[11:15].tolist() == robot.wheel_offsets[:, 1].tolist()
    assert constants[layout.ROLLING] == 0.02
