"""Values near the ends of a setting's range, and how the command line writes them (test_settings,
test_parameter_ranges)."""

from __future__ import annotations

import math

from wallbot_sim.settings.table import Setting, text_of


def boundary_values(setting: Setting) -> list[object]:
    """Just inside, at and just outside each end of a number's range (0 too where it is accepted outside it), NaN,
    infinities and values of other types; a string's choices and others."""
    if setting.kind is str:
        return [*setting.choices, 'no_such_choice', '', 'robot2/'] if setting.choices else ['', 'x', '/tmp/r.yaml']
    allowed = setting.allowed
    low, high = allowed.low, allowed.high
    if setting.kind is int:
        return [low - 1, low, low + 1, high - 1, high, high + 1, 0, 1.5, float(low), 'abc', True]
    return [math.nextafter(low, -math.inf), low, math.nextafter(low, math.inf), math.nextafter(high, -math.inf),
            high, math.nextafter(high, math.inf), 0.0, -0.0, 0.5 * (low + high), 2 * high + 1.0, math.nan, math.inf,
            -math.inf, 'abc', True]


def cli_text(value: object) -> str:
    """How a value is written on the command line (a double always with its point or exponent)."""
    return repr(value) if isinstance(value, float) else text_of(value)
