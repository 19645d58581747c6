"""The loop's run segments: each begins with a new ``Simulation`` of the loop's robot, plan, constraint set and
settings, at the start, a rate change, a reset (the initial state at t = 0) or a teleport (at rest where the robot
is put)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from wallbot_sim.loop.events import Teleport
from wallbot_sim.model import DOF, Simulation
from wallbot_sim.model.scenario import moving_start

if TYPE_CHECKING:
    from wallbot_sim.loop.loop import DynamicsLoop


class Segments:
    """The simulations ``loop`` runs, one per run segment, and the resets and teleports that begin a new one."""

    def __init__(self, loop: DynamicsLoop) -> None:
        self.loop = loop

    def simulation(self, q: np.ndarray, qd: np.ndarray, t0: float,
                   torque: tuple[float, float] = (0.0, 0.0)) -> Simulation:
        """A simulation from (q, qd) at ``t0`` under ``torque``, with what is in force now (robot, plan, constraint
        set and gains, settings, the pump's command)."""
        loop = self.loop
        reference = loop.plan.reference if loop.plan is not None else None
        settings = loop.settings
        sim = Simulation(loop.robot, reference, loop.selection, q, qd, dt=1.0 / settings.rate_hz, t0=t0,
                         gains=loop.gains, contact=settings.contact_model, engine=settings.engine)
        sim.set_motor_torque(*torque)
        if loop.pump_command != 1.0:
            sim.set_pump_command(loop.pump_command)
        return sim

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) of the settings' initial pose: at rest, or moving with the plan's reference (initial_at_rest)."""
        loop = self.loop
        s = loop.settings
        q0 = np.array([s.initial_x, s.initial_y, s.initial_theta, 0, 0, 0, 0], dtype=float)
        if s.initial_at_rest or loop.plan is None:
            return q0, np.zeros(DOF)
        return q0, moving_start(loop.robot, loop.plan.reference, s.initial_theta)

    def reset_when_answered(self) -> None:
        """Reset once lockstep's answer to the last published state came (at most lockstep_timeout): arriving after
        the reset, that answer to a state of the old run would be taken for the answer to the reset state."""
        loop = self.loop
        if (loop.sim is None or not loop.waits.answer_awaited()
                or loop.clock() - loop.reset_requested > loop.settings.lockstep_timeout):
            loop.reset_requested = None
            self._reset()

    def _reset(self) -> None:
        loop = self.loop
        loop.commands.command, loop.diverged, loop.detached = None, False, None
        loop.resume.stop_catch_up()
        if loop.sim is not None:
            loop.sim = self.simulation(*self.initial_state(), 0.0)
            loop.log.info('reset to the initial state at t = 0')
            loop.publish(loop.sim.outputs())
            loop.snapshot()
        loop.pacer.reanchor()

    def teleport(self, pose: Teleport) -> None:
        """A new run segment from the current time, at rest at ``pose``; published at once, so a
        paused robot is seen where it was put."""
        loop = self.loop
        sim = loop.sim
        if sim is None:
            loop.log.warning('initialpose ignored: the simulation starts with the first constraint set')
            return
        loop.diverged, loop.detached = False, None
        q = np.array([pose.x, pose.y, pose.theta, *sim.q[3:]])
        loop.sim = self.simulation(q, np.zeros(DOF), sim.t, sim.motor_torque)
        loop.log.info(f'placed at rest at x = {pose.x:.3f} m, y = {pose.y:.3f} m, heading {pose.theta:.3f} rad '
                      f'at t = {sim.t:.3f} s')
        loop.publish(loop.sim.outputs())
        loop.snapshot()
        loop.pacer.reanchor()
