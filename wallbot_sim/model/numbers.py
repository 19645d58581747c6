"""Which numbers a parameter accepts, and the one-line reason when a value is refused.

One rule for every number the simulator reads (the robot file, scenarios, the nodes' parameters,
the command line), so a value one of them accepts is not refused by another with other words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from wallbot_sim.model.errors import ParameterError


@dataclass(frozen=True)
class NumberRange:
    """Finite numbers from ``low`` (excluded when ``low_open``) up to ``high``; ``zero`` says what 0
    means where it is accepted outside that range (e.g. 'as fast as possible')."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    zero: str | None = None

    def describe(self) -> str:
        """The accepted values in words, e.g. '> 0' or '0 (as fast as possible) or in [0.001, 1e+06]'."""
        if self.low is None and self.high is None:
            span = 'a finite number'
        elif self.high is None:
            span = f'{">" if self.low_open else ">="} {self.low:g}'
        elif self.low is None:
            span = f'<= {self.high:g}'
        else:
            span = f'in {"(" if self.low_open else "["}{self.low:g}, {self.high:g}]'
        return span if self.zero is None else f'0 ({self.zero}) or {span}'

    def problem(self, value: object) -> str | None:
        """What is wrong with ``value`` ('must be ..., got ...'), or None if it is accepted."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return f'must be a finite number, got {value!r}'
        if self.zero is not None and value == 0:
            return None
        if ((self.low is not None and (value <= self.low if self.low_open else value < self.low))
                or (self.high is not None and value > self.high)):
            return f'must be {self.describe()}, got {value!r}'
        return None

    def reason(self, name: str, value: object) -> str | None:
        """The one-line reason naming ``name`` why ``value`` is refused, or None."""
        problem = self.problem(value)
        return None if problem is None else f'{name} {problem}'

    def check(self, name: str, value: object) -> float:
        """``value`` as a float; ParameterError naming ``name`` if it is refused."""
        reason = self.reason(name, value)
        if reason is not None:
            raise ParameterError(reason)
        return float(value)

    def bounds(self) -> tuple[float | None, float | None]:
        """The closed interval holding every accepted value (what a ROS parameter descriptor can say)."""
        low = self.low
        if self.zero is not None and low is not None:
            low = min(low, 0.0)
        return low, self.high


FINITE = NumberRange()
POSITIVE = NumberRange(0.0, low_open=True)
NON_NEGATIVE = NumberRange(0.0)
