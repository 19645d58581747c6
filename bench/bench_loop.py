"""CPU time of the dynamics loop per step, state by state against blocks of steps (a measurement).

Runs the dynamics node's loop (``DynamicsLoop``, ROS-free) on the numba engine through the circle
scenario with all constraints, encoding every state's messages to CDR as the node does and sending
them nowhere, in this process: once with single steps (a graph that does not take blocks, as with
sensor noise or the Python engine), once with blocks of steps (``Simulation.advance`` and
``StepEncoder.encode_rows``) heard by a subscriber outside the process (each state published when
due), and at factor 1 once more with blocks nobody outside hears (a composed recorder's: handed over
ahead of time, a wake-up a block). At factor 1 each for --seconds of wall time, at factor 0 for
--fast-steps steps; beside them a bare 1 kHz sleep loop, the cost of the wake-ups alone. Prints the
loop thread's CPU time per step and the ratios to single steps.

    python bench/bench_loop.py [--seconds 4] [--fast-steps 20000] [--write-docs [FILE]]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from typing import Callable

from report import Report, add_write_docs_option
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters, load_scenario
from wallbot_sim.model import BaumgarteGains, SampledReference
from wallbot_sim.model.compiled import compile_kernel
from wallbot_sim.model.outputs import StepBlock
from wallbot_sim.model.trajectories import sample_plan
from wallbot_sim.loop import ConstraintSwitch, DynamicsLoop, NewPlan, Pacer, PreparedState
from wallbot_sim.settings.dynamics import DynamicsSettings

SETTINGS = DynamicsSettings(snapshot_period=1.0, resume_wait=0.0)
"""The dynamics node's defaults (the numba engine), a snapshot a second, resuming nothing."""


class EncodingGraph:
    """Encodes every state's messages as the node does; publishes nothing; no recorder, keeper or controller."""

    def __init__(self, blocks: bool, heard: bool) -> None:
        self.blocks, self.heard = blocks, heard
        self.encoder = StepEncoder()

    def prepare(self, out, clock: bool) -> Callable[[], None]:
        self.encoder.encode(out)
        return lambda: None

    def encodes_blocks(self, burst: bool) -> bool:
        return self.blocks

    def prepare_block(self, block: StepBlock) -> list[PreparedState]:
        return [PreparedState(lambda clock, ahead: None, self.heard) for _encoded in self.encoder.encode_rows(block)]

    def publish_snapshot(self, snapshot) -> None:
        pass

    def recorder_present(self) -> bool:
        return False

    def recorder_listening(self) -> bool:
        return False

    def keeper_seen(self) -> bool:
        return False

    def controller_listening(self) -> bool:
        return False


class QuietLog:
    def info(self, message: str, **kwargs: object) -> None:
        pass

    warning = error = info


def running_loop(blocks: bool, heard: bool, factor: float) -> DynamicsLoop:
    """A loop through its first 300 ticks of the circle (the kernel warm), at ``factor``."""
    scenario = load_scenario('circle')
    plan = sample_plan(scenario.reference, 0.0, 1e4, 0.01)
    selection = messages.selection_from_switches(dict(belt=True, non_lateral=True, nonslip=True,
                                                      tangent_heading=True, trajectory_task=True))
    loop = DynamicsLoop(replace(SETTINGS, real_time_factor=factor, initial_x=float(plan.positions[0][0])),
                        load_robot_parameters(None), EncodingGraph(blocks, heard), QuietLog(), Pacer(0, print))
    loop.post(ConstraintSwitch(selection, BaumgarteGains(5.0, 5.0)))
    loop.post(NewPlan(SampledReference(*plan), plan.times[0], plan.times[-1], messages.plan_is_final(plan)))
    for _ in range(300):
        loop.tick()
    return loop


def cpu_per_step(blocks: bool, heard: bool, factor: float, seconds: float, steps: int) -> float:
    """The loop thread's CPU seconds per step: for ``seconds`` of wall time, or ``steps`` steps at factor 0."""
    loop = running_loop(blocks, heard, factor)
    first, started, cpu = loop.sim.steps, time.perf_counter(), time.thread_time()
    while (time.perf_counter() - started < seconds) if factor > 0 else (loop.sim.steps - first < steps):
        loop.tick()
    return (time.thread_time() - cpu) / (loop.sim.steps - first)


def wake_up_cost(seconds: float) -> float:
    """CPU seconds per wake-up of a bare loop sleeping to each 1 ms deadline."""
    due, cpu, wakes = time.perf_counter(), time.thread_time(), 0
    end = due + seconds
    while due < end:
        due += 1e-3
        while (remaining := due - time.perf_counter()) > 0.0:
            time.sleep(remaining)
        wakes += 1
    return (time.thread_time() - cpu) / wakes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--seconds', type=float, default=4.0, help='wall seconds of each run at factor 1 (default 4)')
    parser.add_argument('--fast-steps', type=int, default=20000, help='steps of each run at factor 0 (default 20000)')
    add_write_docs_option(parser)
    args = parser.parse_args()
    report = Report('loop')
    rows = []
    compile_kernel()
    wake = wake_up_cost(args.seconds)
    print(f'bare 1 kHz sleep loop: {1e6 * wake:.1f} us CPU per wake-up')
    for factor in (1.0, 0.0):
        single = cpu_per_step(False, True, factor, args.seconds, args.fast_steps)
        block = cpu_per_step(True, True, factor, args.seconds, args.fast_steps)
        line = (f'factor {factor:g}: single steps {1e6 * single:6.1f} us CPU per step, blocks {1e6 * block:6.1f} us '
                f'(ratio {block / single:.2f})')
        row = [f'factor {factor:g}', f'{1e6 * single:.1f} us', f'{1e6 * block:.1f} us', f'**{block / single:.2f}**']
        if factor > 0.0:
            unheard = cpu_per_step(True, False, factor, args.seconds, args.fast_steps)
            line += f', blocks nobody outside hears {1e6 * unheard:6.1f} us (ratio {unheard / single:.2f})'
            row += [f'{1e6 * unheard:.1f} us', f'**{unheard / single:.2f}**']
        else:
            row += ['', '']
        print(line)
        rows.append(row)
    rows.append(('a bare 1 kHz sleep loop, per wake-up', f'{1e6 * wake:.1f} us', '', '', '', ''))
    report.table(('', 'single steps', 'blocks, each state when due', 'ratio to single steps',
                  'blocks handed over ahead of time', 'ratio to single steps'), rows,
                 "The dynamics loop alone (numba engine, circle, all constraints, every state's messages encoded), "
                 "the loop thread's CPU time per step:")
    report.write(args.write_docs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
