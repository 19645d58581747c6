"""Option types the verbs share: a number checked by the same rule the library and the nodes apply."""

from __future__ import annotations

import argparse
from typing import Callable

from wallbot_sim.model.numbers import NumberRange


def number(allowed: NumberRange) -> Callable[[str], float]:
    """An argparse ``type``: the option's value as a float that ``allowed`` accepts. A refused value
    is argparse's one-line error naming the option, e.g. ``argument --rate: must be > 0, got -1.0``."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'must be a finite number, got {text!r}') from None
        problem = allowed.problem(value)
        if problem is not None:
            raise argparse.ArgumentTypeError(problem)
        return value
    return parse
