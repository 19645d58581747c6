"""Coulomb contact on the compiled engine (``Simulation(..., engine='numba', contact='coulomb')``) against the
Python model, step by step: the same stick/slip transitions at the same instants, every output within 1e-9.

The analytic cases, the energy balance and the loads-friction fixed point run on both engines in
test_model_contact.py; these runs add what only a comparison shows: turning slips whose loads move at
every step, re-sticking (the switch projection) and every configuration call between steps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from batch_helpers import TOLERANCE, random_robots
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation, StepOutputs
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.contact import CoulombContact, DetachedError
from wallbot_sim.model.robot import DOF

pytestmark = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')

DRIVEN = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False)


def reported(out: StepOutputs) -> dict[str, np.ndarray]:
    friction = out.contact.friction_force
    return {'q': out.q, 'qd': out.qd, 'acceleration': out.acceleration, 'constraint_force': out.constraint_force,
            'drive': np.array([out.drive.left, out.drive.right, out.drive.lateral]), 'loads': out.contact.loads,
            'use': np.array(out.contact.use), 'friction': np.zeros(DOF) if friction is None else friction}


class Pair:
    """One robot on both engines with coulomb contact, stepped together; their outputs at every instant."""

    def __init__(self, robot: Robot, q0: np.ndarray, selection: ConstraintSelection = DRIVEN, reference=None,
                 qd0: np.ndarray | None = None) -> None:
        qd0 = np.zeros(DOF) if qd0 is None else qd0
        self.sims = [Simulation(robot, reference, selection, q0, qd0, contact='coulomb', engine=engine)
                     for engine in ('python', 'numba')]
        self.outputs: list[list[dict[str, np.ndarray]]] = [[], []]
        self.slipping: list[tuple[bool, bool, bool]] = []

    def call(self, action) -> None:
        for simulation in self.sims:
            action(simulation)

    def run(self, steps: int) -> None:
        for _ in range(steps):
            python, numba = (simulation.outputs() for simulation in self.sims)
            assert numba.contact.slipping == python.contact.slipping, f't = {python.t:.3f} s'
            self.slipping.append(python.contact.slipping)
            for history, out in zip(self.outputs, (python, numba)):
                history.append(reported(out))
            self.call(Simulation.step)

    def assert_agree(self, label: str = '') -> None:
        """Every quantity within TOLERANCE of its largest magnitude over the run, or of 1 in its unit where
        that is round-off (a constraint force the slipping channels leave at zero)."""
        python, numba = self.outputs
        assert len(python) == len(numba) > 0
        for key in python[0]:
            expected, got = np.array([o[key] for o in python]), np.array([o[key] for o in numba])
            error = np.max(np.abs(got - expected))
            assert error <= TOLERANCE * max(np.max(np.abs(expected)), 1.0), f'{label} {key}: differs by {error:.3g}'

    def transitions(self) -> int:
        return sum(a != b for a, b in zip(self.slipping[:-1], self.slipping[1:]))


@pytest.fixture
def python_settles(monkeypatch) -> list[int]:
    """How often the Python stick/slip settlement ran (counted, then passed on)."""
    calls = [0]

    def counted(self, *args, _settle=CoulombContact.settle):
        calls[0] += 1
        return _settle(self, *args)
    monkeypatch.setattr(CoulombContact, 'settle', counted)
    return calls


@pytest.mark.parametrize('heading, torque, adhesion', [
    (math.pi / 2, (3.5, 2.0), None),   # both sides slip while turning, then sideways too: the loads move
    (math.pi / 2, (3.0, 2.5), None),   # the left side slips, the robot turns
    (0.0, (0.0, 0.0), 100.0),          # lateral slip
    (2.0, (-2.5, 3.0), None),          # spinning on the spot at a slant
], ids=['turn', 'left-slips', 'slide', 'slant-spin'])
def test_slipping_runs_agree_with_the_python_model(heading, torque, adhesion, python_settles):
    robot = Robot(load_robot_parameters().replace(adhesion_force=adhesion))
    pair = Pair(robot, np.array([0.0, 0.0, heading, 0, 0, 0, 0]))
    pair.call(lambda simulation: simulation.set_motor_torque(*torque))
    pair.run(1500)
    pair.assert_agree()
    assert any(any(flags) for flags in pair.slipping)
    assert python_settles[0] == len(pair.slipping)  # the Python engine's; the numba engine settles in the kernel


def test_random_robots_under_changing_torques_stick_and_slip_again_alike():
    """Torques drawn anew every 37 steps (mid-chunk), some zero: channels slip, stop and stick again by the
    switch projection, on random robots with the CoM off the centre."""
    rng = np.random.default_rng(31)
    sticks_again = transitions = 0
    for i, robot in enumerate(random_robots(rng, 3)):
        weight_torque = robot.total_mass * robot.params.gravity * robot.params.wheel_radius
        pair = Pair(robot, np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi), 0, 0, 0, 0]))
        for change in range(12):
            torque = (0.0, 0.0) if change % 4 == 3 else tuple(rng.uniform(-2.0, 2.0, 2) * weight_torque)
            pair.call(lambda simulation: simulation.set_motor_torque(*torque))
            pair.run(37)
        pair.assert_agree(f'robot {i}')
        sticks_again += sum(any(a) and not any(b) for a, b in zip(pair.slipping[:-1], pair.slipping[1:]))
        transitions += pair.transitions()
    print(f'{transitions} transitions, {sticks_again} back to sticking everywhere')
    assert sticks_again >= 3 and transitions >= 10


def test_configuration_calls_between_steps_act_alike():
    """A suction loss and its recovery, the lateral constraint dropped and restored while sliding, ideal
    contact and back, a reset: both engines go on agreeing."""
    robot = Robot(load_robot_parameters())
    pair = Pair(robot, np.array([0.0, 0.0, 0.3, 0, 0, 0, 0]))
    pair.call(lambda simulation: simulation.set_motor_torque(1.0, 1.4))
    pair.run(100)
    pair.call(lambda simulation: simulation.set_adhesion_force(110.0))
    pair.run(150)
    assert pair.slipping[-1][2]  # sliding sideways after the suction loss
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
    """Driven with the tangent-heading task on: a task row beside the contact rows while a side slips."""
    robot = Robot(load_robot_parameters())
    circle = load_scenario('circle')
    selection = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False, tangent_heading=True)
    pair = Pair(robot, np.array([0.0, 0.0, 1.0, 0, 0, 0, 0]), selection, circle.reference)
    pair.call(lambda simulation: simulation.set_motor_torque(3.5, 1.0))
    pair.run(600)
    pair.assert_agree()
    assert any(flags[0] or flags[1] for flags in pair.slipping)


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


def test_detachment_mid_run_stops_both_engines_at_the_same_instant():
    """A high CoM, spun on the spot from facing +X: as the heading turns, a wheel's load goes negative
    (0.29 s in, mid-chunk): the same wheel, load and time on both engines, and the state of that instant kept."""
    robot = Robot(load_robot_parameters().replace(com_height=0.12, adhesion_force=130.0))
    errors = []
    for engine in ('python', 'numba'):
        simulation = Simulation(robot, None, DRIVEN, np.zeros(DOF), np.zeros(DOF), contact='coulomb', engine=engine)
        simulation.set_motor_torque(-1.0, 1.0)
        with pytest.raises(DetachedError) as error:
            simulation.run(2.0)
        errors.append((error.value, simulation.steps, simulation.q))
    (python, steps, q), (numba, numba_steps, numba_q) = errors
    assert steps == numba_steps > 100
    assert (numba.wheel, numba.t) == (python.wheel, python.t)
    assert numba.load == pytest.approx(python.load, abs=TOLERANCE * 100.0)
    assert np.allclose(numba_q, q, rtol=0.0, atol=TOLERANCE)


def test_contact_constants_are_in_the_order_the_kernel_reads_them():
    robot = Robot(load_robot_parameters().replace(com_height=0.07, kinetic_friction=0.5, adhesion_force=150.0))
    constants = kernel.contact_constants(robot)
    params = robot.params
    assert constants[:7].tolist() == [150.0, params.wall_friction, 0.5, params.stick_velocity, 0.07,
                                      params.half_wheelbase, params.half_track]
    assert constants[7:11].tolist() == robot.wheel_offsets[:, 0].tolist()
    assert constants[11:].tolist() == robot.wheel_offsets[:, 1].tolist()
