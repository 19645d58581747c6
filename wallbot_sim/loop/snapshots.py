"""The loop's state as a snapshot (``wallbot_msgs_py.snapshot``), and what a resumed loop takes from one.

Every ``snapshot_period`` of simulation time and at every event (start, reset, pause, constraint switch, new
plan, command) the loop publishes its full state on ``state_snapshot``; the recorder keeps the newest and
republishes it, transient-local, on ``resume_state``. A node started again after a SIGKILL takes that snapshot
at start and continues the run bit for bit (``loop.resume``), ``~/reset`` being the explicit way back to t = 0.
"""

from __future__ import annotations

import numpy as np

from wallbot_msgs_py import codec
from wallbot_msgs_py.snapshot import SWITCHES, ContactState, DynamicsSnapshot
from wallbot_sim import messages
from wallbot_sim.loop.commands import Commands
from wallbot_sim.loop.events import ConstraintSwitch
from wallbot_sim.model import BaumgarteGains, ConstraintSelection, Simulation
from wallbot_sim.model.contact import CoulombState


def snapshot_every(period: float, dt: float) -> int:
    """Steps between two periodic snapshots (0: only at events)."""
    return round(period / dt)


def snapshot_of(sim: Simulation, published: tuple[int, np.ndarray, np.ndarray], commands: Commands,
                paused: bool) -> DynamicsSnapshot:
    """The snapshot of the state last ``published`` (step count, q, qd) of ``sim``, with its coulomb contact's
    state (``sim``'s own: a coulomb run publishes every state it reaches, never a block ahead of it)."""
    steps, q, qd = published
    held = sim.contact_state
    command, since = commands.command if commands.command is not None else (None, 0.0)
    switches = messages.switches_from_selection(sim.selection)
    return DynamicsSnapshot(
        anchor=sim.initial_time, steps=steps, dt=sim.dt, q=tuple(q), qd=tuple(qd),
        motor_torque=sim.motor_torque, command=command, command_since=since, command_expired=commands.expired,
        switches=tuple(switches[name] for name in SWITCHES),
        gains=(float(sim.gains.alpha), float(sim.gains.beta)), paused=paused,
        seen_until_ns=codec.to_nanoseconds(sim.initial_time + steps * sim.dt),
        contact=None if held is None else ContactState(
            sliding=tuple(wheel in held.sliding for wheel in range(4)), loads=tuple(held.loads.tolist()),
            friction=tuple(held.friction.reshape(8).tolist())))


def kept_contact(kept: DynamicsSnapshot) -> CoulombState | None:
    """The coulomb contact state a resume takes up (None: the snapshot holds none)."""
    contact = kept.contact
    if contact is None:
        return None
    return CoulombState(frozenset(wheel for wheel in range(4) if contact.sliding[wheel]), np.array(contact.loads),
                        np.array(contact.friction).reshape(4, 2))


def kept_constraints(kept: DynamicsSnapshot, switch: ConstraintSwitch,
                     planned: bool) -> tuple[ConstraintSelection, BaumgarteGains]:
    """The constraint set a resume continues with: the kept one, or the one in force now (``switch``) if the kept
    one runs the trajectory task and no plan is there (the task was switched off meanwhile)."""
    selection = messages.selection_from_switches(dict(zip(SWITCHES, kept.switches)))
    if selection.trajectory and not planned:
        return switch.selection, switch.gains
    return selection, BaumgarteGains(*kept.gains)
