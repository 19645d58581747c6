"""A ``Simulation``'s steps taken by the compiled kernel: blocks of steps at once and tables of their outputs,
each what stepping one at a time on the same engine gives, to the bit (engine 'numba')."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from wallbot_sim.model.contact_outputs import ideal_contact
from wallbot_sim.model.errors import DivergedError, ModelError
from wallbot_sim.model.friction import FrictionUse
from wallbot_sim.model.outputs import DriveForces, StepBlock, StepOutputs, StepTable
from wallbot_sim.model.wheel_forces import WheelOutputs

if TYPE_CHECKING:
    from wallbot_sim.model.compiled import CompiledDynamics, ReferenceRows
    from wallbot_sim.model.compiled_contact import CompiledCoulomb

TABLE_CHUNK = 1000
"""Instants ``run_table`` computes per call of the compiled kernel (a second at 1 kHz)."""


class CompiledSteps:
    """The compiled engine's part of ``Simulation`` (its base): the kernels configured for what is active, and the
    block and table runs on them. It reads and moves the simulation's state (``_y``, ``steps``, ``_t``)."""

    def _compiled_now(self) -> CompiledDynamics | None:
        """The compiled dynamics configured for what is active, when they cover it (ideal contact, no modules of
        your own)."""
        if self._compiled is None or self._extra_modules or self.coulomb_applies:
            return None
        return self._compiled.configure(self.robot, self.gains, self._selection, self._reference, self.dt)

    def _compiled_contact(self) -> CompiledCoulomb | None:
        """The compiled coulomb boundaries and steps configured for what is active, when they cover it (engine
        'numba', coulomb contact applying, no modules of your own)."""
        if self._compiled is None or self._extra_modules or not self.coulomb_applies:
            return None
        if self._compiled_coulomb is None:
            self._compiled_coulomb = compiled_coulomb(self._initial[0], self.dt)
        return self._compiled_coulomb.configure(self.robot, self.gains, self._selection, self._reference, self.dt)

    @property
    def tabulates(self) -> bool:
        """Whether ``run_table`` can run now: the compiled engine computes the steps, with ideal contact."""
        return self._compiled_now() is not None

    def run_table(self, duration: float, on_table: Callable[[StepTable], None],
                  chunk: int = TABLE_CHUNK) -> StepOutputs:
        """``run`` a chunk of up to ``chunk`` instants at a time, under constant motor torques: ``on_table``
        gets their outputs as arrays, both ends of the run included, where ``tabulates``.

        Every output is the one ``run`` gives on the compiled engine, to the bit: the same kernel
        steps and motions, and the same array functions for the loads, friction use and drive forces.
        """
        count = round(duration / self.dt)
        done = 0
        while True:
            compiled = self._tabulating('run_table')
            instants = min(chunk, count - done + 1)
            steps = min(instants, count - done)
            run = compiled.run(self._y, self.steps, self.motor_torque, instants, steps)
            on_table(compiled.table(run, self._initial[0], self.steps))
            self.steps += run.taken
            self._t = self._initial[0] + self.steps * self.dt
            self._y = run.states[run.taken].copy()
            self._cached = None
            done += run.taken
            if run.taken < steps:
                raise DivergedError(f'state is no longer finite at t = {self._t + self.dt:.3f} s')
            if steps < instants:  # this chunk ended at the run's last instant
                return self.outputs()

    def advance(self, count: int) -> StepBlock | None:
        """``count`` steps at once, under the current motor torques, where ``tabulates``: the outputs of the
        ``count`` instants after the current one, each what ``step`` then ``outputs`` give there, to the bit.

        None, the simulation unchanged, if a state or output among them is not finite: ``step`` one at a
        time to meet the divergence where it happens.
        """
        block = self.compute_block(count)
        if block is not None:
            self.take(block)
        return block

    def sample_reference(self, count: int) -> ReferenceRows:
        """The reference at the RK4 instants of the ``count`` steps from here, for a ``compute_block`` of up to
        ``count`` steps from here: the Python part of its work, which a caller with deadlines can do at another
        time. A block from elsewhere, or after the reference changed, samples its own."""
        return self._tabulating('sample_reference').reference_rows(self.steps, count + 1)

    def compute_block(self, count: int, sampled: ReferenceRows | None = None) -> StepBlock | None:
        """``advance``'s block, the simulation left where it is: ``take`` moves it to the block's end, unless
        something changed it in between (then the block is of no use). ``sampled``: ``sample_reference``'s."""
        compiled = self._tabulating('advance')
        run = compiled.run(self._y, self.steps, self.motor_torque, count + 1, count, sampled)
        if run.taken < count:
            return None
        table = StepTable(*(None if column is None else column[1:]
                            for column in compiled.table(run, self._initial[0], self.steps)))
        if not (np.all(np.isfinite(table.constraint_force)) and np.all(np.isfinite(table.residual))):
            return None
        return StepBlock(table, table.wheel_torques(self.motor_torque))

    def _tabulating(self, what: str) -> CompiledDynamics:
        compiled = self._compiled_now()
        if compiled is None:
            raise ModelError(f'{what} needs the numba engine with ideal contact (Simulation.tabulates)')
        return compiled

    def take(self, block: StepBlock) -> None:
        """Continue from the last instant of ``block``, which ``compute_block`` gave from the current state."""
        self.steps += len(block.t)
        self._t = self._initial[0] + self.steps * self.dt
        self._y = np.concatenate((block.q[-1], block.qd[-1]))
        self._cached = self._last_outputs(block)

    def _last_outputs(self, block: StepBlock) -> StepOutputs:
        """The outputs at the last instant of ``block`` (the current one), as ``outputs`` builds them."""
        table = block.table
        loads = table.loads[-1]
        reference = self._reference.sample(self._t) if self._reference is not None else None
        return StepOutputs(self._t, table.q[-1].copy(), table.qd[-1].copy(), table.acceleration[-1],
                           table.constraint_force[-1], float(table.residual[-1]), self.motor_torque,
                           DriveForces(*table.drive[-1].tolist()), reference,
                           ideal_contact(self.robot, loads, FrictionUse(*table.use[-1].tolist()),
                                         WheelOutputs(table.wheel_forces[-1:], table.wheel_use[-1:],
                                                      table.slip_velocity[-1:])))


def compiled_dynamics(initial_time: float, dt: float) -> CompiledDynamics:
    # imported here: model.compiled reaches the batch package, which imports the simulation
    from wallbot_sim.model.compiled import CompiledDynamics
    return CompiledDynamics(initial_time, dt)


def compiled_coulomb(initial_time: float, dt: float) -> CompiledCoulomb:
    from wallbot_sim.model.compiled_contact import CompiledCoulomb
    return CompiledCoulomb(initial_time, dt)
