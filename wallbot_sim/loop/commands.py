"""The wheel torque command in force (driven mode): held for ``command_timeout`` of simulation time, then zero."""

from __future__ import annotations

from wallbot_sim import messages
from wallbot_sim.loop.graph import Log

THROTTLE = 1.0
"""Seconds between repeated warnings of one kind."""


class Commands:
    """The newest wheel_torque_cmd and the simulation time it came (loop thread only)."""

    def __init__(self) -> None:
        self.command: tuple[tuple[float, float], float] | None = None
        """(torque, simulation time it came), or None: none yet."""
        self.expired = False
        """Whether the command timed out (said once)."""

    def receive(self, torque: tuple[float, float], t: float) -> None:
        self.command, self.expired = (torque, t), False

    def timed_out(self, t: float, timeout: float) -> bool:
        """Whether the command is more than ``timeout`` seconds old at simulation time ``t``."""
        return self.command is not None and t - self.command[1] > timeout + 1e-12

    def torque_at(self, t: float, trajectory: bool, timeout: float) -> tuple[float, float]:
        """The motor torque of a step from time ``t``: the command in force while driven, zero under the
        trajectory task, before the first command and once the command is ``timeout`` old."""
        if trajectory or self.command is None or self.timed_out(t, timeout):
            return (0.0, 0.0)
        return self.command[0]

    def note_expiry(self, t: float, trajectory: bool, timeout: float, log: Log) -> None:
        """Say once that the command timed out, at the first step from ``t`` it no longer applies to."""
        if not trajectory and self.timed_out(t, timeout) and not self.expired:
            self.expired = True
            log.warning(f'no wheel_torque_cmd for {timeout:g} s of simulation time (the last at '
                        f't = {self.command[1]:.3f} s): zero torque from t = {t:.3f} s', throttle_duration_sec=THROTTLE)

    def state(self, trajectory: bool) -> str:
        """The 'command' value of /diagnostics."""
        if trajectory:
            return messages.COMMAND_IGNORED
        if self.command is None:
            return 'none yet, zero torque'
        if self.expired:
            return 'timed out, zero torque'
        (left, right), _since = self.command
        return messages.applied_command(left, right)
