"""The dynamics node's state snapshot: what a restarted dynamics needs to continue a run.

The dynamics publishes it on ``state_snapshot`` and a keeper (the recorder) republishes the
newest one on ``resume_state``, both std_msgs/Float64MultiArray, RELIABLE, TRANSIENT_LOCAL,
KEEP_LAST(1). A dynamics killed with SIGKILL takes its own transient-local sample with it; the
keeper's copy outlives it, and a restarted dynamics reads that copy at start.

Layout: ``layout.dim[0].label`` = LABEL, ``size`` = ``stride`` = LENGTH, then ``data``:

=========  ======================================================================
index      meaning
=========  ======================================================================
0          anchor (s): simulation time of step 0 of the run segment
1          steps: RK4 steps since the anchor (a whole number); t = anchor + steps * dt
2          dt (s): the step
3 .. 9     q = x, y, theta (unwrapped), phi1 .. phi4 (wheel spin angles)
10 .. 16   qd, the time derivatives of q (wall frame)
17, 18     motor torque (tau_L, tau_R) applied in the step that reached this state (N m)
19         1 if a wheel_torque_cmd is held, else 0
20, 21     the held command (tau_L, tau_R) (N m)
22         simulation time the held command arrived (s)
23         1 if the held command has timed out, else 0
24 .. 28   constraint switches in force, 1/0, in the order of ``constraint_modules.CONSTRAINT_SWITCHES``:
           trajectory_task, belt, non_lateral, nonslip, tangent_heading
29, 30     Baumgarte gains alpha, beta (1/s)
31         1 if the simulation is paused, else 0
32         seen until (ns): the newest step stamp the rest of the graph has received; the
           dynamics writes the snapshot's own stamp, a keeper the newest it received
33         1 if coulomb contact's state follows (the contact model is coulomb), else 0 and
           34 .. 49 are 0
34 .. 37   the wheels sliding over the step from this state, 1/0, wheel 1 .. 4
38 .. 41   the wheels' normal loads N_1 .. N_4 held over that step (N)
42 .. 49   the sliding wheels' friction (f_x, f_y) in body axes, wheel 1 .. 4 (N), 0 for the
           others
=========  ======================================================================

Coulomb contact's state is that of the boundary the state was published at (after its stick/slip
transitions): a restarted dynamics settles that boundary again from it and continues the run bit
for bit. A ``wallbot_dynamics_snapshot_v1`` message (the first 33 values) is still read, without
the contact state: a coulomb run resumed from one finds its sliding wheels again from every wheel
sticking.

A keeper that holds nothing yet publishes the LABEL with empty ``data`` ("nothing to resume
from"), so a dynamics starting fresh beside it need not wait. ``encode_snapshot`` and
``decode_snapshot`` are the message's codec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

from wallbot_msgs_py import cdr, constraint_modules

TYPE = 'std_msgs/msg/Float64MultiArray'
LABEL = 'wallbot_dynamics_snapshot_v2'
LENGTH = 50
"""Values in a snapshot."""
LABEL_V1 = 'wallbot_dynamics_snapshot_v1'
LENGTH_V1 = 33
"""Values in a snapshot of the first layout (no contact state), still read."""
SWITCHES = constraint_modules.CONSTRAINT_SWITCHES
"""The order of the constraint switches at indices 24 .. 28."""


@dataclass(frozen=True)
class ContactState:
    """Coulomb contact's state at a step boundary: what the step from it holds."""

    sliding: tuple[bool, bool, bool, bool]
    loads: tuple[float, float, float, float]
    """N_1 .. N_4 (N)."""
    friction: tuple[float, ...]
    """(f_x, f_y) of each wheel in body axes (8 values, N), 0 where it does not slide."""

    def to_values(self) -> list[float]:
        return [*(float(s) for s in self.sliding), *map(float, self.loads), *map(float, self.friction)]


@dataclass(frozen=True)
class DynamicsSnapshot:
    """The state of the dynamics loop at a step boundary (see the module's layout table)."""

    anchor: float
    steps: int
    dt: float
    q: tuple[float, ...]
    qd: tuple[float, ...]
    motor_torque: tuple[float, float]
    command: tuple[float, float] | None
    command_since: float
    command_expired: bool
    switches: tuple[bool, ...]
    gains: tuple[float, float]
    paused: bool
    seen_until_ns: int
    contact: ContactState | None = None
    """Coulomb contact's state (None: ideal contact, or a v1 snapshot)."""

    @property
    def t(self) -> float:
        """Simulation time of the state (s), computed as the simulation computes it."""
        return self.anchor + self.steps * self.dt

    @property
    def stamp_ns(self) -> int:
        """Simulation time as the step messages stamp it (ns)."""
        return round(self.t * 1e9)

    def to_values(self) -> list[float]:
        """The ``data`` of the message."""
        command = self.command or (0.0, 0.0)
        return [float(self.anchor), float(self.steps), float(self.dt), *map(float, self.q), *map(float, self.qd),
                *map(float, self.motor_torque), float(self.command is not None), *map(float, command),
                float(self.command_since), float(self.command_expired), *(float(s) for s in self.switches),
                *map(float, self.gains), float(self.paused), float(self.seen_until_ns),
                float(self.contact is not None), *(self.contact.to_values() if self.contact else [0.0] * 16)]

    @classmethod
    def from_values(cls, values: Sequence[float]) -> DynamicsSnapshot:
        """The snapshot in a message's ``data`` (LENGTH values, or LENGTH_V1 of the first layout); ValueError
        naming what is wrong."""
        values = [float(v) for v in values]
        if len(values) not in (LENGTH, LENGTH_V1):
            raise ValueError(f'a dynamics snapshot has {LENGTH} values ({LENGTH_V1} in v1), got {len(values)}')
        if not all(math.isfinite(v) for v in values):
            raise ValueError('a dynamics snapshot holds a value that is not finite')
        steps, dt, seen = values[1], values[2], values[32]
        if steps < 0 or steps != int(steps) or seen != int(seen):
            raise ValueError(f'dynamics snapshot: steps and seen until must be whole numbers, got {steps}, {seen}')
        if dt <= 0.0:
            raise ValueError(f'dynamics snapshot: dt must be > 0, got {dt}')
        contact_flags = range(33, 38) if len(values) == LENGTH else range(0)
        flags = [values[i] for i in (19, 23, 24, 25, 26, 27, 28, 31, *contact_flags)]
        if any(flag not in (0.0, 1.0) for flag in flags):
            raise ValueError('dynamics snapshot: a flag is neither 0 nor 1')
        contact = None
        if len(values) == LENGTH and values[33]:
            contact = ContactState(sliding=tuple(bool(v) for v in values[34:38]), loads=tuple(values[38:42]),
                                   friction=tuple(values[42:50]))
        return cls(anchor=values[0], steps=int(steps), dt=dt, q=tuple(values[3:10]), qd=tuple(values[10:17]),
                   motor_torque=(values[17], values[18]),
                   command=(values[20], values[21]) if values[19] else None, command_since=values[22],
                   command_expired=bool(values[23]), switches=tuple(bool(v) for v in values[24:29]),
                   gains=(values[29], values[30]), paused=bool(values[31]), seen_until_ns=int(seen),
                   contact=contact)


@cdr.encoder('state_snapshot', TYPE)
def encode_snapshot(snapshot: DynamicsSnapshot | None) -> bytes:
    """``state_snapshot`` / ``resume_state``: the snapshot's values under LABEL (None: empty, nothing held)."""
    values = snapshot.to_values() if snapshot is not None else []
    out = cdr.Writer()
    out.float64_multiarray([(LABEL, len(values), len(values))], values)
    return out.bytes()


@cdr.decoder('state_snapshot', TYPE)
def decode_snapshot(message: cdr.Reader) -> DynamicsSnapshot | None:
    """The snapshot in a serialized message (None: the keeper holds nothing); ValueError if it is no snapshot."""
    dims, values = message.float64_multiarray()
    labels = [label for label, _size, _stride in dims]
    if labels not in ([LABEL], [LABEL_V1]):
        raise ValueError(f'not a dynamics snapshot: layout labels {labels}, expected [{LABEL!r}]')
    length = LENGTH if labels == [LABEL] else LENGTH_V1
    if values and len(values) != length:
        raise ValueError(f'a dynamics snapshot ({labels[0]}) has {length} values, got {len(values)}')
    return DynamicsSnapshot.from_values(values) if values else None


class SnapshotKeeper:
    """What a keeper node republishes: the newest snapshot not past what it received, seen until the newest
    step stamp received.

    ``stamp`` takes the header stamp of every step message the keeper receives, per topic: one
    writer per topic delivers in order, so each topic's last stamp is where that stream is,
    across a reset too (time going back), and their maximum is the newest state the keeper saw.
    Snapshots come on a topic of their own and may overtake the step messages of a loaded keeper;
    a resume from a snapshot newer than those would leave the steps between out of the record, so
    the keeper holds on to the snapshots newer than what it saw and republishes the newest of the
    others (the resumed dynamics recomputes from it, unpublished, up to ``seen_until``).
    """

    def __init__(self) -> None:
        self._snapshots: list[DynamicsSnapshot] = []
        """Since the last time the snapshots went back (a reset): in order of time."""
        self._last_ns: dict[str, int] = {}
        self._changed = True  # a keeper announces at start that it holds nothing yet

    def snapshot(self, snapshot: DynamicsSnapshot) -> None:
        """A snapshot from the dynamics."""
        if self._snapshots and snapshot.stamp_ns < self._snapshots[-1].stamp_ns:
            self._snapshots.clear()
        self._snapshots.append(snapshot)
        self._changed = True

    def stamp(self, topic: str, stamp_ns: int) -> None:
        """The header stamp of a step message received on ``topic``."""
        if self._last_ns.get(topic) != stamp_ns:
            self._last_ns[topic] = stamp_ns
            self._changed = self._changed or bool(self._snapshots)

    def held(self) -> DynamicsSnapshot | None:
        """The snapshot to republish, with seen-until set; None while nothing is held."""
        if not self._snapshots:
            return None
        seen = max(self._last_ns.values(), default=self._snapshots[-1].seen_until_ns)
        reached = [k for k, kept in enumerate(self._snapshots) if kept.stamp_ns <= seen]
        del self._snapshots[:reached[-1] if reached else 0]  # older than the newest reached: not needed again
        return replace(self._snapshots[0], seen_until_ns=seen)

    def due(self) -> bytes | None:
        """The message of ``held()`` if it changed since the last call, else None."""
        if not self._changed:
            return None
        self._changed = False
        return encode_snapshot(self.held())
