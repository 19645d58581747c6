"""What the dynamics loop needs of the ROS graph around it (the node implements it), and of a log."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol, Sequence

from wallbot_msgs_py.snapshot import DynamicsSnapshot
from wallbot_sim.loop.faults import FaultChange
from wallbot_sim.model import StepOutputs
from wallbot_sim.model.outputs import StepBlock


class Graph(Protocol):
    """What the loop needs of the ROS graph around it (the node implements it)."""

    def prepare(self, out: StepOutputs, clock: bool) -> Callable[[], None]:
        """Encode a state's per-step messages, with /clock if ``clock``; calling the result publishes them."""

    def encodes_blocks(self, burst: bool) -> bool:
        """Whether ``prepare_block`` may be called (the messages carry the states as they are: no sensor noise);
        ``burst``: its states will be published back to back (factor 0), not each when it is due."""

    def prepare_block(self, block: StepBlock) -> Sequence[PreparedState]:
        """``prepare`` of each state of ``block`` at once, in order."""

    def publish_snapshot(self, snapshot: DynamicsSnapshot) -> None: ...

    def publish_fault(self, change: FaultChange) -> None:
        """Record a change of the fault settings (an event on ``faults``)."""

    def recorder_present(self) -> bool:
        """Whether some node publishes record_progress."""

    def recorder_listening(self) -> bool:
        """Whether a recorder publishes record_progress and every step topic has a subscriber."""

    def keeper_seen(self) -> bool:
        """Whether some node publishes resume_state."""

    def resend_to_controller(self) -> None:
        """Publish the last state sent on control_odom again (to a controller whose reader matched after it)."""

    def controller_listening(self) -> bool:
        """Whether a wheel_torque_cmd publisher exists and hears the command sensor, odom (or control_odom) or
        wheel_states (``command_sensor``; see ``heard_by_every``)."""


@dataclass(frozen=True)
class PreparedState:
    """A state of a block with its messages encoded (``Graph.prepare_block``)."""

    send: Callable[[bool, float], None]
    """Publishes it, with /clock if the first argument is true; the second: how many seconds before its due time
    it is handed over (0: when due; only a state not ``heard`` is handed over ahead of time)."""
    heard: bool
    """Whether a subscriber outside the loop's process takes one of its messages over DDS."""


class Log(Protocol):
    def info(self, message: str, **kwargs: object) -> object: ...

    def warning(self, message: str, **kwargs: object) -> object: ...

    def error(self, message: str, **kwargs: object) -> object: ...
