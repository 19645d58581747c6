"""What reaches the dynamics loop from outside: typed events, posted from any thread (the node's executor),
applied by the loop thread at its next step boundary (``DynamicsLoop.tick``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Union

from wallbot_msgs_py.snapshot import DynamicsSnapshot
from wallbot_sim.model import BaumgarteGains, ConstraintSelection, SampledReference
from wallbot_sim.model.trajectories import STAMP_RESOLUTION


@dataclass(frozen=True)
class ConstraintSwitch:
    """A constraint set to run with (applied once it can be: the trajectory task needs a plan)."""

    selection: ConstraintSelection
    gains: BaumgarteGains


@dataclass(frozen=True)
class NewPlan:
    """A received plan: its reference and the span it covers."""

    reference: SampledReference
    start: float
    end: float
    final: bool

    def covers(self, t0: float, t1: float) -> bool:
        """Whether a step from t0 to t1 may use this plan.

        A plan that ends moving must extend strictly past t1: at its last sample time the
        quintic is evaluated at the segment's far end, which equals the sample only to
        rounding, while the next plan evaluates it exactly; the step waits for that plan. Within
        STAMP_RESOLUTION of its first sample a step is inside it, as the reference samples it.
        """
        return self.start <= t0 + STAMP_RESOLUTION and (self.final or t1 < self.end - STAMP_RESOLUTION)


@dataclass(frozen=True)
class TorqueCommand:
    """A validated wheel_torque_cmd (tau_L, tau_R) in N m."""

    torque: tuple[float, float]


@dataclass(frozen=True)
class PumpCommand:
    """A validated pump_command u in [0, 1]."""

    command: float


@dataclass(frozen=True)
class Reset:
    """Back to the initial state at t = 0 (once lockstep's pending answer arrived)."""


@dataclass(frozen=True)
class Pause:
    """Pause (True) or run again (False)."""

    paused: bool


@dataclass(frozen=True)
class Step:
    """While paused: take ``count`` steps, then hold again (ignored while running)."""

    count: int


@dataclass(frozen=True)
class Teleport:
    """Put the robot at rest at (x, y) m in the wall frame with heading ``theta`` rad; simulation
    time and the wheels' angles go on."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True)
class ResumeSnapshot:
    """A keeper's answer at start: the snapshot to continue from, or None (it holds nothing)."""

    snapshot: DynamicsSnapshot | None


@dataclass(frozen=True)
class ParameterChange:
    """Accepted parameter values, by name (the dynamics' settings, ``settings.dynamics``)."""

    changes: Mapping[str, object]


@dataclass(frozen=True)
class RecordProgress:
    """A recorder has taken every message up to this /clock stamp (ns)."""

    stamp_ns: int


Event = Union[ConstraintSwitch, NewPlan, TorqueCommand, PumpCommand, Reset, Pause, Step, Teleport, ResumeSnapshot, ParameterChange,
              RecordProgress]
