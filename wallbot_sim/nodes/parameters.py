"""A node's parameters declared from its settings table (``wallbot_sim.settings``), with descriptors a ROS user
discovers (``ros2 param describe``: ranges, choices, read-only), and its checks of what a user sets."""

from __future__ import annotations

import copy
from typing import Any, Iterable, Mapping

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node
from rclpy.parameter import Parameter

from wallbot_sim.settings.table import Setting, SettingsTable, Value, choice_words, typed

TYPE_WORDS = {bool: 'true or false', int: 'an integer', float: 'a double (a number written with a point, e.g. 2.0)',
              str: 'a string', tuple: 'a list of strings'}
"""A parameter's ROS type in words, for a start value of another type (rclpy refuses an integer for a double)."""


def declare_settings(node: Node, table: SettingsTable, defaults: Mapping[str, Value] = {}) -> dict[str, Value]:
    """Declare every setting of ``table`` (``defaults`` replacing some of the table's, e.g. from the robot file)
    and return the values by name; a start value a setting refuses is a ValueError naming every such one."""
    values, reasons = {}, []
    for entry in table:
        value, reason = declare_setting(node, entry, defaults.get(entry.name, entry.default))
        values[entry.name] = value
        if reason:
            reasons.append(reason)
    if reasons:
        raise ValueError('; '.join(reasons))
    return values


def declare_typed(node: Node, settings: type, table: SettingsTable, defaults: Mapping[str, Value] = {}) -> Any:
    """:func:`declare_settings`, the values as an instance of the settings dataclass ``settings``."""
    return typed(settings, declare_settings(node, table, defaults))


def declare_setting(node: Node, entry: Setting, default: Value) -> tuple[Value, str | None]:
    """Declare one setting (a parameter rclpy declared already, such as use_sim_time, gets its descriptor);
    return its start value and, if the setting refuses it, why (the parameter then keeps its declaration
    without the descriptor's range).

    The descriptor carries the closed interval holding every value a number accepts (the node's own check,
    :func:`settings_callback`, refuses what an interval cannot say, like "0 or at least 0.001", and what
    rclpy lets through within 1e-6 relative of an end), an enumerated string's choices in its description and
    ``additional_constraints``, and whether it is read-only (a fixed setting is).
    """
    descriptor = ParameterDescriptor(description=entry.description())
    if entry.choices:
        descriptor.additional_constraints = choice_words(entry.choices)
    try:
        if node.has_parameter(entry.name):
            value = node.get_parameter(entry.name).value
            if node.describe_parameter(entry.name).read_only:  # declared here already (robot_file, read first)
                return value, entry.reason(value)
        else:  # declared first without a range or read-only (rclpy keeps this object: a copy is declared)
            value = node.declare_parameter(entry.name, list(default) if isinstance(default, tuple) else default,
                                           copy.copy(descriptor)).value
    except InvalidParameterTypeException as error:  # a start value of another type: the parameter is not declared
        given = error.args[0].split("' to '", 1)[-1].split("' of type", 1)[0]
        return default, f'{entry.name} must be {TYPE_WORDS[entry.kind]}, got {given}'
    reason = entry.reason(value)
    if reason:
        return value, reason
    low, high = (entry.default, entry.default) if entry.fixed is not None else (
        entry.allowed.bounds() if entry.allowed is not None else (None, None))
    if entry.kind is int:
        descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
    elif entry.kind is float:
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    descriptor.read_only = entry.locked
    descriptor.type = node.describe_parameter(entry.name).type
    node.set_descriptor(entry.name, descriptor)
    return value, None


def parameter_result(reasons: Iterable[str | None]) -> SetParametersResult:
    """Successful unless a reason is given; the reasons are what ``ros2 param set`` prints."""
    problems = [reason for reason in reasons if reason]
    return SetParametersResult(successful=not problems, reason='; '.join(problems))


def param_dict(parameters_: list[Parameter], known: Iterable[str] | None = None) -> dict[str, object]:
    """{name: value} of a parameter callback's list; only the names in ``known`` when given."""
    names = None if known is None else set(known)
    return {p.name: p.value for p in parameters_ if names is None or p.name in names}
