"""Option types the verbs share: a number checked by the same rule the library and the nodes apply, and an
option that sets a node's parameter, derived from that parameter's setting (``wallbot_sim.settings``)."""

from __future__ import annotations

import argparse
from typing import Any, Callable

from wallbot_sim.graph_options import BY_NAME
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.settings.table import Setting, SettingError, Value, text_of


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


def setting_type(setting: Setting) -> Callable[[str], Value]:
    """An argparse ``type``: the option's value as ``setting`` reads and checks it (the node's own check), a
    refused one argparse's one-line error naming the option."""
    def parse(text: str) -> Value:
        try:
            return setting.parse(text)
        except SettingError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
    parse.__name__ = setting.kind.__name__  # argparse names the type in some errors
    return parse


SETTING_DEFAULT = object()
"""An option's default is its setting's."""


def add_setting(parser: argparse.ArgumentParser, flag: str, setting: Setting, *, default: Any = SETTING_DEFAULT,
                help_suffix: str = '', **kwargs: Any) -> None:
    """``flag`` for ``setting``: its type and check, its help (with ``help_suffix``, else the default), its
    choices, ``default`` (by default the setting's)."""
    words = setting.help
    if setting.choices:  # checked by the type first (the node's words); argparse lists them
        kwargs.setdefault('choices', setting.choices)
    if setting.allowed is not None:
        words += f' ({setting.allowed.describe()})'
    if default is SETTING_DEFAULT:
        default = setting.default
        help_suffix = help_suffix or f' (default {text_of(default) or "empty"})'
    parser.add_argument(flag, type=setting_type(setting), default=default, help=words + help_suffix, **kwargs)


def add_graph_option(parser: argparse.ArgumentParser, name: str, **kwargs: Any) -> None:
    """The option of the graph option ``name`` (``graph_options.OPTIONS``): a node's setting, or the graph's own."""
    option = BY_NAME[name]
    add_setting(parser, option.flag, option.setting, **kwargs)
