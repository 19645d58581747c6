"""Steps per second of the model core, against a straightforward section-6 solver in the same process.

For each scenario and constraint set, the same simulation is stepped with
  * the core (Udwadia-Kalaba form with a factor W of M^-1, one small LAPACK least-squares call), and
  * a straightforward Udwadia-Phohomsiri evaluation: two numpy.linalg.pinv per evaluation, no
    structure exploited (wallbot_sim.model.solve),
and the ratio is printed. Both must end in the same state (a check that the comparison is fair).
Both share the model's evaluation (Q, the constraint rows, RK4); "solve ratio" compares the two
solvers alone on the same inputs (A, b, M, Q at the final state).

Then the wheel-wall contact: the driven robot from rest (docs/model.md 11.4's cases: belt, non-lateral,
nonslip, no trajectory task) stepped with its outputs at every step, as ``simulate`` and the
dynamics node do, with ideal and with coulomb contact. "cost" is the coulomb step's extra time
relative to the ideal step; in the sticking cases it is the stick/slip bookkeeping alone.

    python bench/bench_core.py [--seconds 2.0]
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import numpy as np

from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import ConstraintSelection, Robot, Simulation, solve
from wallbot_sim.model.robot import DOF
from wallbot_sim.model.solver import constrained_acceleration

SETS = ('none', 'belt', 'belt,non_lateral', 'belt,non_lateral,nonslip')


class StraightforwardSimulation(Simulation):
    """The same model, each RK4 stage solved by the general two-pinv formula."""

    def _derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[:DOF], y[DOF:]
        force, rows, rhs = self._problem(t, q, qd)
        return np.concatenate((qd, solve(self.robot.mass_matrix(q), force, rows, rhs).acceleration))


def solves_per_second(simulation: Simulation, count: int = 3000) -> tuple[float, float]:
    """Solves per second at the simulation's state: the core's solver, then the two-pinv formula."""
    q, qd = simulation.q, simulation.qd
    force, rows, rhs = simulation._problem(simulation.t, q, qd)
    mass, factor = simulation.robot.mass_matrix(q), simulation.robot.mass_inverse_factor(q)
    rates = []
    for solve_once in (lambda: constrained_acceleration(factor, force, rows, rhs),
                       lambda: solve(mass, force, rows, rhs)):
        started = time.perf_counter()
        for _ in range(count):
            solve_once()
        rates.append(count / (time.perf_counter() - started))
    return rates[0], rates[1]


def steps_per_second(simulation: Simulation, steps: int) -> float:
    started = time.perf_counter()
    for _ in range(steps):
        simulation.step()
    return steps / (time.perf_counter() - started)


CONTACT_CASES = (  # name, heading, side torques, adhesion force (None: the robot file's), what happens
    ('hold', 0.0, (0.0, 0.0), None, 'sticks'),
    ('climb', math.pi / 2, (2.0, 1.95), None, 'sticks, turning'),
    ('slide', 0.0, (0.0, 0.0), 100.0, 'lateral slip'),
    ('spin', math.pi / 2, (3.0, 3.0), None, 'both sides slip'),
    ('turn', math.pi / 2, (3.5, 2.0), None, 'slips, turning'),
)


def steps_with_outputs_per_second(simulation: Simulation, steps: int) -> float:
    """Steps per second of CPU time, the outputs computed at every step."""
    started = time.process_time()
    for _ in range(steps):
        simulation.outputs()
        simulation.step()
    return steps / (time.process_time() - started)


def contact_table(steps: int) -> None:
    print(f'\n{"contact case":13s} {"":17s} {"ideal steps/s":>13s} {"coulomb steps/s":>15s} {"cost":>7s}')
    driven = ConstraintSelection.parse('belt,non_lateral,nonslip', trajectory=False)
    for name, heading, torque, adhesion, what in CONTACT_CASES:
        robot = Robot(load_robot_parameters().replace(adhesion_force=adhesion))
        rates = [0.0, 0.0]
        for _ in range(5):  # alternating, best of five: load from other processes hits both alike
            for k, contact in enumerate(('ideal', 'coulomb')):
                simulation = Simulation(robot, None, driven, np.array([0.0, 0.0, heading, 0, 0, 0, 0]),
                                        np.zeros(DOF), contact=contact)
                simulation.set_motor_torque(*torque)
                rates[k] = max(rates[k], steps_with_outputs_per_second(simulation, steps))
        print(f'{name:13s} {what:17s} {rates[0]:13.0f} {rates[1]:15.0f} {rates[0] / rates[1] - 1:7.1%}')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=2.0, help='simulated seconds per measurement')
    args = parser.parse_args()
    steps = round(args.seconds / 1e-3)
    robot = Robot(load_robot_parameters())
    print(f'# {platform.processor() or platform.machine()}, Python {platform.python_version()}, '
          f'numpy {np.__version__}; {steps} steps of 1 ms per measurement, single thread')
    print(f'{"scenario":9s} {"constraint set":48s} {"core steps/s":>12s} {"pinv steps/s":>12s} {"ratio":>6s} '
          f'{"x real time":>11s} {"solve ratio":>11s}')
    for name in ('circle', 'figure8'):
        scenario = load_scenario(name)
        q0, qd0 = scenario.initial_state(robot)
        for constraints in SETS:
            selection = ConstraintSelection.parse(constraints)
            core = Simulation(robot, scenario.reference, selection, q0, qd0)
            plain = StraightforwardSimulation(robot, scenario.reference, selection, q0, qd0)
            fast, slow = steps_per_second(core, steps), steps_per_second(plain, steps)
            if not np.allclose(core.q, plain.q, rtol=1e-9, atol=1e-9):
                raise SystemExit(f'{name} {constraints}: the two solvers disagree: {core.q} vs {plain.q}')
            fast_solve, slow_solve = solves_per_second(core)
            print(f'{name:9s} {selection.label():48s} {fast:12.0f} {slow:12.0f} {fast / slow:6.2f} {fast / 1000:11.1f} '
                  f'{fast_solve / slow_solve:11.2f}')
    contact_table(steps)


if __name__ == '__main__':
    main()
