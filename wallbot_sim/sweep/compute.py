"""The work of one chunk: its robots' runs, each summarized as one results row.

Every robot runs as ``wallbot-sim simulate`` runs it (same scenario, constraints, contact, controller,
step), and its row holds the numbers the run summary and the motor analysis of ``wallbot_sim.rundata``
give for that run's CSV. :func:`robot_runs` is the one place that chooses how the runs are computed, on the
vertical, uniform wall: with ideal contact and no controller (constant motor torques) simulate's own compiled
blocks (``Simulation.compute_block``: the kernel's steps and the tables of their outputs, vectorized over the
instants of a block), robot after robot a block at a time, the reference sampled once per block for them all;
else the batch core (``wallbot_sim.model.batch``: coulomb contact, or the example controller closing the loop
every few steps). On a world file's surface, which neither computes, the single-robot ``Simulation`` (python
engine) robot by robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Iterator, NamedTuple, Sequence

import numpy as np

from wallbot_sim.control import ControllerGains, TrackingController
from wallbot_sim.control.sampling import (
    CONTROL_RATE_HZ, MAX_WHEEL_TORQUE, SampledController, close_loop, controller_robot)
from wallbot_sim.model import ConstraintSelection, Robot, RobotParameters, Scenario, Simulation, StepOutputs
from wallbot_sim.model.contact import IDEAL, DetachedError
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.world import World
from wallbot_sim.rundata.csv_format import CSV_COLUMNS, csv_row, fill_motion_rows, fill_rows, fill_wheel_rows
from wallbot_sim.rundata.load import run_from_columns
from wallbot_sim.rundata.motors import motor_report
from wallbot_sim.rundata.summary import summarize_run
from wallbot_sim.sweep.reduce import DecidingRows

if TYPE_CHECKING:
    from wallbot_sim.model.batch import BatchOutputs
    from wallbot_sim.model.batch.outputs import BatchTable
    from wallbot_sim.model.compiled import ReferenceRows

OUTPUTS = ('final_err', 'peak_err_after_5s', 'peak_abs_F_left', 'peak_abs_F_right', 'peak_abs_F_lateral',
           'peak_motor_torque_left', 'peak_motor_torque_right', 'min_normal_load', 'max_use1', 'max_use2',
           'max_use3', 'max_use4', 'least_adhesion_force', 'applied_adhesion_force', 'slipped', 'detached',
           't_detached', 'max_residual', 'feasible')
"""The results columns after a robot's parameters (``max_use1..4``: each wheel's peak friction use)."""
OUTPUT_UNITS = {
    'final_err': 'm', 'peak_err_after_5s': 'm', 'peak_abs_F_left': 'N', 'peak_abs_F_right': 'N',
    'peak_abs_F_lateral': 'N', 'peak_motor_torque_left': 'N m', 'peak_motor_torque_right': 'N m',
    'min_normal_load': 'N', 'max_use1': '-', 'max_use2': '-', 'max_use3': '-', 'max_use4': '-',
    'least_adhesion_force': 'N', 'applied_adhesion_force': 'N', 'slipped': '0 or 1', 'detached': '0 or 1',
    't_detached': 's', 'max_residual': 'm/s^2, rad/s^2', 'feasible': '0 or 1',
}
"""The unit of each output ('-': a ratio; the residual |A qdd - b| mixes the rows' accelerations)."""
BLOCK = 2048
"""Instants of a robot held at once before they are reduced to the rows deciding its results (simulate's blocks)."""
BATCH_BLOCK = 256
"""Instants of a batch chunk's robots held at once before they are reduced: 100 robots' rows are then 10 MB (at
2048 instants, 80 MB, a coulomb chunk of 100 robots x 10 s took some 78,000 page faults, at 256 a dozen)."""
HELD_MOST = 128
"""Steps of a chunk's robots in one kernel call at held motor torques at most (``BatchSimulation.run_held``)."""
FEASIBLE_USE = NumberRange(high=1.0)
"""Friction use a feasible robot stays within: above 1 a wheel would slide on a real wall."""


@dataclass(frozen=True)
class RunSettings:
    """What every robot of a sweep runs, as ``simulate`` would run it."""

    scenario: Scenario
    selection: ConstraintSelection
    contact: str
    duration: float
    dt: float
    controller: bool
    controller_mass_scale: float
    world: World | None = None
    """The world file's surface (None: a vertical, uniform wall), as ``simulate --world``."""

    @property
    def steps(self) -> int:
        """RK4 steps of each run (its CSV has one row more)."""
        return round(self.duration / self.dt)


def batch_supports(settings: RunSettings) -> bool:
    """Whether the batch core runs these settings (no world file: the batch computes the vertical, uniform wall
    only)."""
    return settings.world is None


def tabulates(settings: RunSettings) -> bool:
    """Whether the runs are simulate's compiled blocks (``_tabulated_runs``): ideal contact under constant motor
    torques (no controller) on the vertical, uniform wall, numba installed."""
    # imported here: the kernel loads numba, which the CLI's other verbs, importing the sweep's spec, do not need
    from wallbot_sim.model.batch import kernel
    return batch_supports(settings) and settings.contact == IDEAL and not settings.controller and kernel.available()


def load_kernels(settings: RunSettings) -> None:
    """Load the compiled code ``robot_runs`` steps and reduces these runs by from numba's cache (or compile it), as
    its first run would. numba loads it through C callbacks, which swallow a KeyboardInterrupt raised in them (the
    command then runs on): a caller that handles Ctrl-C holds it back meanwhile."""
    from wallbot_sim.model import compiled
    from wallbot_sim.model.batch import kernel
    from wallbot_sim.sweep.screen import compile_screen
    if not (batch_supports(settings) and kernel.available()):  # robot by robot on the python engine
        return
    if tabulates(settings):
        compiled.compile_run(IDEAL)
    else:
        compiled.compile_batch((settings.contact,))
    compile_screen()  # both reduce their rows by the compiled screen


class RobotRun(NamedTuple):
    """One robot's run as ``simulate`` makes it."""

    steps: np.ndarray
    """Its CSV rows (steps + 1, len(CSV_COLUMNS)), fewer if it detached; from the batch, the few of them that
    decide its results row (``reduce.DecidingRows``), in time order."""
    lift_off: DetachedError | None = None
    """The lift-off that ended it, as simulate reports it (exit status 3). Its load need not be in the
    rows: a command answered at the last written instant can lift a wheel at that same instant."""


def robot_runs(settings: RunSettings, robots: Sequence[RobotParameters]) -> Iterator[RobotRun]:
    """Per robot, in order, its run."""
    if tabulates(settings):
        yield from _tabulated_runs(settings, robots)
    elif batch_supports(settings):
        yield from _batch_runs(settings, robots)
    else:
        for params in robots:
            yield single_robot_run(settings, params)


def chunk_results(settings: RunSettings, robots: Sequence[RobotParameters]) -> list[list[float]]:
    """The OUTPUTS of each robot's run, in order."""
    return [result_row(run, params) for run, params in zip(robot_runs(settings, robots), robots)]


def result_row(robot_run: RobotRun, params: RobotParameters) -> list[float]:
    """OUTPUTS of one run from its steps, by the run summary and the motor analysis (and simulate's
    verdict on a lift-off)."""
    run = run_from_columns(robot_run.steps, 'sweep robot')
    summary = summarize_run(run, 'sweep robot')
    report = motor_report(run, params)
    contact = report.contact
    use = contact.peak_use if contact is not None else (math.nan,) * 4
    lift_off = summary.lift_off
    if lift_off is None and robot_run.lift_off is not None:
        lift_off = (robot_run.lift_off.t, robot_run.lift_off.wheel, robot_run.lift_off.load)
    min_load = float(np.nanmin(run.loads)) if lift_off is None else min(float(np.nanmin(run.loads)), lift_off[2])
    slipped, detached = summary.first_slip is not None, lift_off is not None
    feasible = not slipped and not detached and all(FEASIBLE_USE.problem(value) is None for value in use)
    return [summary.final_tracking_error, summary.peak_tracking_error_after_5s, summary.peak_drive_force_left,
            summary.peak_drive_force_right, summary.peak_lateral_force, report.left.peak_torque,
            report.right.peak_torque, min_load, *use,
            report.adsorption.needed, report.adsorption.applied,
            int(slipped), int(detached), lift_off[0] if detached else math.nan, summary.max_residual,
            int(feasible)]


def single_robot_run(settings: RunSettings, params: RobotParameters) -> RobotRun:
    """One robot's run on the single-robot ``Simulation`` (python engine), as simulate runs it."""
    robot = Robot(params, settings.world)
    q0, qd0 = settings.scenario.initial_state(robot)
    simulation = Simulation(robot, settings.scenario.reference, settings.selection, q0, qd0, dt=settings.dt,
                            contact=settings.contact)
    controller = None
    if settings.controller:  # the controller's robot is the robot file's, its mass scaled
        model = controller_robot(params, settings.controller_mass_scale)
        controller = close_loop(simulation, SampledController(TrackingController(model, simulation.reference)))
    rows: list[list[float]] = []

    def on_step(out: StepOutputs) -> None:
        rows.append(csv_row(out))
        if controller is not None:  # after the state was recorded, as simulate answers a written state
            controller(out)

    try:
        simulation.run(settings.duration, on_step)
    except DetachedError as lift_off:  # the run ends where simulate's ends
        return RobotRun(np.array(rows, dtype=float), lift_off)
    return RobotRun(np.array(rows, dtype=float))


def _tabulated_runs(settings: RunSettings, robots: Sequence[RobotParameters],
                    block_size: int = BLOCK) -> Iterator[RobotRun]:
    """Every robot's run as simulate takes it with ideal contact (engine 'numba'): ``block_size`` steps of each
    robot in turn by ``Simulation.compute_block`` (its rows to the bit, as ``run`` writes them), each robot's block
    reduced at once to the rows deciding its results row (``reduce.DecidingRows``): one robot's block at a time,
    written and read while in the core's cache."""
    simulations = []
    for params in robots:
        robot = Robot(params)
        q0, qd0 = settings.scenario.initial_state(robot)
        simulations.append(Simulation(robot, settings.scenario.reference, settings.selection, q0, qd0,
                                      dt=settings.dt, contact=settings.contact, engine='numba'))
    reduced = DecidingRows(robots, len(CSV_COLUMNS))
    reduced.add(np.array([[csv_row(simulation.outputs())] for simulation in simulations]),
                np.ones((len(robots), 1), dtype=bool))
    done = 0
    block = np.empty((1, min(block_size, settings.steps), len(CSV_COLUMNS)))  # one robot's, reused
    written = np.ones(block.shape[:2], dtype=bool)
    while done < settings.steps:
        count = min(block_size, settings.steps - done)
        sampled = _shared_samples(simulations[0], count)  # the same reference at the same instants for all
        rows = block[0, :count]
        for robot, simulation in enumerate(simulations):
            steps = simulation.compute_block(count, sampled)
            if steps is None:  # not finite in this block: step by step, to where simulate meets it
                for instant in range(count):
                    simulation.step()
                    rows[instant] = csv_row(simulation.outputs())
            else:
                simulation.take(steps)
                fill_rows(steps.table, rows, simulation.motor_torque)
            reduced.add(block[:, :count], written[:, :count], slice(robot, robot + 1))
        done += count
    for robot in range(len(robots)):
        yield RobotRun(reduced.run(robot))


_SAMPLES: dict[tuple, ReferenceRows | np.ndarray] = {}
"""The reference's samples of the blocks and runs this process computed, for the sweep's next chunk on it (a
sweep's chunks share their scenario: sampling it in Python costs about 20 us a step)."""


def _shared(key: tuple, sample: Callable[[], ReferenceRows | np.ndarray]) -> ReferenceRows | np.ndarray:
    """``sample()``, from ``_SAMPLES`` where a chunk before sampled the same reference (equal by value) at the same
    instants (``key``: the reference, dt, then what says the instants); only one reference's samples are kept."""
    sampled = _SAMPLES.get(key)
    if sampled is None:
        if any(kept[:2] != key[:2] for kept in _SAMPLES):
            _SAMPLES.clear()
        sampled = _SAMPLES[key] = sample()
    return sampled


def _shared_samples(simulation: Simulation, count: int) -> ReferenceRows:
    """``simulation.sample_reference(count)``, shared (``_shared``)."""
    return _shared((simulation.reference, simulation.dt, simulation.t, simulation.steps, count),
                   lambda: simulation.sample_reference(count))


def _batch_runs(settings: RunSettings, robots: Sequence[RobotParameters],
                block_size: int = BATCH_BLOCK) -> Iterator[RobotRun]:
    """Every robot's run on the batch core (the compiled engine where numba is installed), under the example
    controller if asked, reduced ``block_size`` instants at a time to the rows deciding its results row
    (``reduce.DecidingRows``) of its rows up to its lift-off instant, as simulate writes them."""
    # imported here: the batch loads numba (a quarter second), which the CLI's other verbs, importing
    # the sweep's errors and spec, do not need
    from wallbot_sim.model.batch import BatchSimulation, BatchTrackingController, kernel
    models = [Robot(params) for params in robots]
    simulation = BatchSimulation.from_scenario(models, settings.scenario, settings.selection, settings.dt,
                                               contact=settings.contact,
                                               engine='numba' if kernel.available() else 'numpy')
    answer, loop = None, None
    if settings.controller:  # each controller's robot is its robot's, its mass scaled
        loop = BatchTrackingController([controller_robot(params, settings.controller_mass_scale) for params in robots],
                                       settings.scenario.reference, ControllerGains(), CONTROL_RATE_HZ,
                                       MAX_WHEEL_TORQUE)
        answer = loop.hook(simulation)
    rows = _ChunkRows(DecidingRows(robots, len(CSV_COLUMNS)), len(models), block_size, settings.steps + 1)

    def on_step(out: BatchOutputs) -> None:
        rows.add_instant(out)
        if answer is not None:  # after the state was recorded, as simulate answers a written state
            answer(out)

    threads = kernel.numba.get_num_threads() if kernel.available() else 1
    if kernel.available():  # a chunk is one core's work: the cores run chunks (workers), not a chunk's robots
        kernel.numba.set_num_threads(1)
    try:
        if simulation.runs_held:  # the steps between the controller's instants in one kernel call each
            sampled = _shared((simulation.reference, simulation.dt, 'run', simulation.initial_time, settings.steps),
                              lambda: kernel.reference_samples(simulation.reference, simulation.initial_time, 0,
                                                               settings.steps, simulation.dt))
            step = 0
            while True:
                on_step(simulation.outputs())
                if step == settings.steps:
                    break
                most = min(settings.steps - step, HELD_MOST)
                held = most if loop is None else loop.instants_until_due(simulation, most)
                rows.add_table(simulation.run_held(held, sampled[step:step + held]))
                step += held
        else:
            simulation.run(settings.steps, on_step)
    finally:
        if kernel.available():
            kernel.numba.set_num_threads(threads)
    reduced = rows.close()
    for i in range(len(models)):
        yield RobotRun(reduced.run(i), simulation.lift_off(i))


class _ChunkRows:
    """A chunk's CSV rows of its ``total`` instants, ``instants`` of its robots at a time, each block reduced as it
    fills (``DecidingRows.add``); the last block as long as the instants left, so that it too is reduced whole (a
    part of a block would be copied first)."""

    def __init__(self, reduced: DecidingRows, robots: int, instants: int, total: int) -> None:
        self.reduced = reduced
        self.left = total
        """The instants not yet in a block."""
        self.filled = 0
        self._new_block(robots, min(instants, total))

    def _new_block(self, robots: int, instants: int) -> None:
        self.block = np.empty((robots, instants, len(CSV_COLUMNS)))
        self.written = np.empty(self.block.shape[:2], dtype=bool)
        """Whether each robot's run has the row: the instants before it detached."""

    def add_instant(self, out: BatchOutputs) -> None:
        """The rows of the robots' outputs at one instant."""
        _fill(out, self.block[:, self.filled])
        self.written[:, self.filled] = ~out.detached
        self._advance(1)

    def add_table(self, table: BatchTable) -> None:
        """The rows of a table of instants (``BatchSimulation.run_held``)."""
        rows = np.empty((*table.on_wall.shape, len(CSV_COLUMNS)))
        _fill(table, rows)
        done = 0
        while done < rows.shape[1]:
            count = min(rows.shape[1] - done, self.block.shape[1] - self.filled)
            self.block[:, self.filled:self.filled + count] = rows[:, done:done + count]
            self.written[:, self.filled:self.filled + count] = table.on_wall[:, done:done + count]
            done += count
            self._advance(count)

    def _advance(self, count: int) -> None:
        self.filled += count
        if self.filled == self.block.shape[1]:
            self.reduced.add(self.block, self.written)
            self.left -= self.filled
            self.filled = 0
            if 0 < self.left < self.block.shape[1]:
                self._new_block(self.block.shape[0], self.left)

    def close(self) -> DecidingRows:
        """The reduced rows, the last block's included (none left when the instants filled whole blocks)."""
        if self.filled:
            self.reduced.add(self.block[:, :self.filled], self.written[:, :self.filled])
        return self.reduced


def _fill(out: BatchOutputs | BatchTable, rows: np.ndarray) -> None:
    """The CSV rows of a batch's outputs at one instant (rows (robots, columns)) or of a table of them (rows
    (robots, instants, columns))."""
    fill_motion_rows(out, rows, out.wheel_torques)
    fill_wheel_rows(rows, out.wheel_use, out.wheel_slipping, out.wheel_forces)
