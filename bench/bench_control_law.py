"""CPU time of the tracking controller's control law, back to back and at its control instants (a measurement).

The tracking controller node spends most of each control instant in ``SampledController.command``
(the inverse-dynamics solve of its robot copy, on the plan as the node interpolates it). Measured
back to back, in a loop, that call runs with warm caches; in the node it runs once per control
period, after the process slept, and other processes (the dynamics, the recorder) have had the
core meanwhile. For each engine of the law (python, the baseline: the model's modules and
least-squares solve; numba: the compiled kernel) this calls it --calls times back to back, then
--calls times with a sleep of one control period before each, and prints the thread CPU time of a
call in both cases, the paced figure as a share of a core at the rate, and the numba law's figures
as ratios to the python law's.

    python bench/bench_control_law.py [--calls 500] [--rate-hz 25] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import time

from report import Report, add_write_docs_option
from wallbot_msgs_py.codec import PlanarState
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.control import TrackingController
from wallbot_sim.control.sampling import CONTROL_RATE_HZ, MAX_WHEEL_TORQUE, SampledController
from wallbot_sim.model import Robot
from wallbot_sim.model.compiled import compile_inverse_dynamics
from wallbot_sim.model.simulation import ENGINES, PYTHON


def sampled_controller(rate_hz: int, engine: str) -> tuple[SampledController, list[PlanarState]]:
    """The node's loop on the circle's first plan with the ``engine`` law, and the states of one lap of its
    control instants (the scenario's start repeated with each instant's stamp: the cost does not depend on
    the state)."""
    robot = Robot(load_robot_parameters())
    scenario = load_scenario('circle')
    plan = messages.plan_ahead(scenario.reference, 0.0)
    controller = TrackingController(robot, messages.sampled_reference(plan), engine=engine)
    q, qd = scenario.initial_state(robot)
    period_ns = round(1e9 / rate_hz)
    instants = int(plan.times[-1] * rate_hz)
    states = [PlanarState(k * period_ns, *q[:3].tolist(), *qd[:3].tolist()) for k in range(instants)]
    return SampledController(controller, rate_hz, MAX_WHEEL_TORQUE), states


def cpu_per_call(loop: SampledController, states: list[PlanarState], calls: int, pause: float) -> float:
    """Mean thread CPU seconds of ``loop.command``, each call after ``pause`` wall seconds of sleep."""
    spent = 0.0
    for k in range(calls):
        if pause:
            time.sleep(pause)
        began = time.thread_time()
        loop.command(states[k % len(states)])
        spent += time.thread_time() - began
    return spent / calls


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--calls', type=int, default=500, help='calls in each case (default 500)')
    parser.add_argument('--rate-hz', type=int, default=CONTROL_RATE_HZ,
                        help=f'control rate: the sleep is one period (default {CONTROL_RATE_HZ})')
    add_write_docs_option(parser)
    options = parser.parse_args()
    report = Report('control-law')
    compile_inverse_dynamics()
    figures = {}
    for engine in ENGINES:
        loop, states = sampled_controller(options.rate_hz, engine)
        cpu_per_call(loop, states, 50, 0.0)  # imports, first-call allocations
        figures[engine] = (cpu_per_call(loop, states, options.calls, 0.0),
                           cpu_per_call(loop, states, options.calls, 1.0 / options.rate_hz))
    baseline_hot, baseline_paced = figures[PYTHON]
    rows = []
    for engine, (hot, paced) in figures.items():
        print(f'{engine:>6} law: back to back {hot * 1e3:6.3f} ms CPU a call ({hot / baseline_hot:.2f} x python); '
              f'one call per period {paced * 1e3:6.3f} ms ({paced / baseline_paced:.2f} x python, {paced / hot:.2f} x '
              f'back to back), {paced * options.rate_hz * 100:.1f} % of a core at {options.rate_hz} Hz')
        rows.append((engine, f'{hot * 1e3:.3f}', f'**{hot / baseline_hot:.2f}**', f'{paced * 1e3:.3f}',
                     f'**{paced / baseline_paced:.2f}**', f'{paced * options.rate_hz * 100:.1f} %'))
    report.table(('law', 'back to back, ms CPU a call', 'x python', 'one call per period, ms', 'x python',
                  f'share of a core at {options.rate_hz} Hz'), rows,
                 f'{options.calls} calls of `SampledController.command` each way; the python law is the baseline:')
    report.write(options.write_docs)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
