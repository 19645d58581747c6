"""A node's parameters as one typed table: name, type, default, range or choices, read-only, help.

A node's settings are a frozen dataclass whose fields are declared with :func:`setting`; the field's
default gives the type, the metadata the rest. :func:`table_of` turns the dataclass into a
:class:`SettingsTable`, from which everything that speaks of the parameters is derived: the node's
declarations and ParameterDescriptors (``nodes.parameters``), its checks of a start value or a
``ros2 param set`` (:meth:`SettingsTable.reasons`), the graph description's parameter dictionaries
(:meth:`SettingsTable.values`), the launch file's arguments and the command line's options
(``graph_options``, ``cli.options``). A value one of them accepts, the others accept.

ROS-free (tested without DDS).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Iterator, Mapping, Union

from wallbot_sim.model.numbers import NumberRange

Value = Union[bool, int, float, str, tuple]
"""What a setting holds: a ROS parameter's bool, integer, double, string or string array (a tuple of strings)."""
SETTING = 'wallbot.setting'
"""The key of a settings dataclass field's metadata."""
WORDS = {bool: 'true or false', int: 'an integer', float: 'a finite number', str: 'a string',
         tuple: 'a list of strings'}


class SettingError(ValueError):
    """A value refused by a setting (its one-line reason)."""


@dataclass(frozen=True)
class Setting:
    """One parameter: its ``default`` gives its type; a number has the range ``allowed`` holding every value it
    accepts; a string may be one of ``choices``; ``read_only`` ones take their value at start only; a
    ``fixed`` one (read-only) takes no value but its default, ``fixed`` saying why."""

    name: str
    default: Value
    help: str
    allowed: NumberRange | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = False
    fixed: str | None = None

    def __post_init__(self) -> None:
        numeric = self.kind in (int, float)
        if numeric != (self.allowed is not None):
            raise TypeError(f'setting {self.name}: a range is given for a number, and only for a number')
        if self.allowed is not None and None in self.allowed.bounds():
            raise TypeError(f'setting {self.name}: a range needs both ends (a parameter descriptor carries it)')
        if self.choices and self.kind is not str:
            raise TypeError(f'setting {self.name}: choices are for a string')
        problem = self.problem(self.default)
        if problem is not None:
            raise TypeError(f'setting {self.name}: its default {self.default!r} is refused: {problem}')

    @property
    def kind(self) -> type:
        """bool, int, float or str."""
        return type(self.default)

    @property
    def locked(self) -> bool:
        """Whether the value is set at start only (read-only or fixed)."""
        return self.read_only or self.fixed is not None

    def description(self) -> str:
        """The help with the choices, or why the value is fixed: the parameter descriptor's description."""
        if self.fixed is not None:
            return f'{self.help}; fixed at {text_of(self.default)} here: {self.fixed}'
        if self.choices:
            return f'{self.help} ({choice_words(self.choices)})'
        return self.help

    def problem(self, value: object) -> str | None:
        """What is wrong with ``value`` ('must be ..., got ...'), or None if it is accepted. An integer is a
        number for a double setting; a bool is not a number, and a double is not an integer."""
        if self.fixed is not None:
            return None if value == self.default and type(value) is self.kind else (
                f'is fixed at {text_of(self.default)} here ({self.fixed}), got {value!r}')
        kind = self.kind
        if kind is tuple:
            strings = isinstance(value, (list, tuple)) and all(isinstance(item, str) for item in value)
            return None if strings else f'must be {WORDS[kind]}, got {value!r}'
        if isinstance(value, bool) != (kind is bool) or not isinstance(value, (int, float) if kind is float else kind):
            return f'must be {WORDS[kind]}, got {value!r}'
        if self.allowed is not None:
            return self.allowed.problem(value)
        if self.choices and value not in self.choices:
            return f'must be one of {", ".join(self.choices)}, got {value!r}'
        return None

    def reason(self, value: object) -> str | None:
        """The one-line reason naming the setting why ``value`` is refused, or None."""
        problem = self.problem(value)
        return None if problem is None else f'{self.name} {problem}'

    def parse(self, text: str) -> Value:
        """The value a text (a command-line option, a launch argument) gives; SettingError with the problem
        (not naming the setting: the caller's words name the option) if it is refused."""
        value = value_of(self.kind, text)
        problem = self.problem(value)
        if problem is not None:
            raise SettingError(problem)
        return value

    def renamed(self, name: str, help: str | None = None) -> Setting:
        """This setting under another name (a launch argument or option), with other help if given."""
        return dataclasses.replace(self, name=name, help=self.help if help is None else help)

    def fixed_at(self, value: Value, why: str) -> Setting:
        """This setting fixed at ``value`` (read-only, nothing else accepted), ``why`` saying why."""
        return dataclasses.replace(self, default=value, fixed=why)


def value_of(kind: type, text: str) -> Value:
    """``text`` read as a ``kind`` (true/false, an integer, a number, a list ``[a,b]``), or the text itself where
    it is not one (the setting then refuses it by type)."""
    if kind is tuple:
        inner = text.strip().removeprefix('[').removesuffix(']')
        return tuple(item.strip() for item in inner.split(',') if item.strip())
    if kind is bool:
        words = {'true': True, 'false': False}
        return words.get(text.strip().lower(), text)
    for read in ((int,) if kind is int else (float,) if kind is float else ()):
        try:
            return read(text)
        except ValueError:
            return text
    return text


def text_of(value: Value) -> str:
    """A value as a launch argument or ``--ros-args -p`` writes it (true/false for a bool)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, tuple):
        return '[' + ','.join(value) + ']'
    return str(value)


def choice_words(choices: Iterable[str]) -> str:
    """How an enumerated setting's allowed values are written: 'one of: a, b' (ROS' additional_constraints)."""
    return 'one of: ' + ', '.join(choices)


class SettingsTable:
    """A node's settings by name, in declaration order."""

    def __init__(self, settings: Iterable[Setting]) -> None:
        self._settings = {s.name: s for s in settings}

    def __getitem__(self, name: str) -> Setting:
        return self._settings[name]

    def __contains__(self, name: object) -> bool:
        return name in self._settings

    def __iter__(self) -> Iterator[Setting]:
        return iter(self._settings.values())

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._settings)

    def defaults(self) -> dict[str, Value]:
        return {s.name: s.default for s in self}

    def reasons(self, values: Mapping[str, object]) -> list[str]:
        """The reasons why settings among ``values`` are refused (names not in the table are not checked: ROS'
        own parameters, another node's)."""
        return [reason for name, value in values.items() if name in self._settings
                for reason in [self._settings[name].reason(value)] if reason]

    def values(self, **values: object) -> dict[str, object]:
        """``values`` checked (a parameter dictionary of the graph description): SettingError naming the first
        unknown name or refused value."""
        unknown = [name for name in values if name not in self._settings]
        if unknown:
            raise SettingError(f'no such parameter: {unknown[0]} (known: {", ".join(self.names)})')
        reasons = self.reasons(values)
        if reasons:
            raise SettingError('; '.join(reasons))
        return dict(values)

    def fixing(self, fixed: Mapping[str, tuple[Value, str]]) -> SettingsTable:
        """This table with the settings named in ``fixed`` fixed at their (value, why)."""
        return SettingsTable(s.fixed_at(*fixed[s.name]) if s.name in fixed else s for s in self)


def setting(default: Value, help: str, allowed: NumberRange | None = None, *, choices: tuple[str, ...] = (),
            read_only: bool = False, fixed: str | None = None, name: str | None = None) -> Any:
    """A settings dataclass field (see :class:`Setting`); the parameter's name is the field's unless ``name``
    gives one (a ROS name with dots, e.g. ``linear.x.max_velocity``)."""
    return field(default=default, metadata={SETTING: dict(help=help, allowed=allowed, choices=choices,
                                                         read_only=read_only, fixed=fixed, name=name)})


def table_of(settings: type) -> SettingsTable:
    """The table of a settings dataclass (every field declared with :func:`setting`, its annotation its
    default's type)."""
    table = []
    for item in dataclasses.fields(settings):
        described = dict(item.metadata[SETTING])
        entry = Setting(described.pop('name') or item.name, item.default, **described)
        if str(item.type).split('[')[0] not in (entry.kind.__name__, str(entry.kind)):
            raise TypeError(f'{settings.__name__}.{item.name}: annotated {item.type}, its default is a '
                            f'{entry.kind.__name__}')
        table.append(entry)
    return SettingsTable(table)


def typed(settings: type, values: Mapping[str, object]) -> Any:
    """An instance of the settings dataclass ``settings`` from ``values`` (a node's parameters by name, every one
    of the table's; other names are left out), doubles as floats."""
    fields = {item.metadata[SETTING]['name'] or item.name: item for item in dataclasses.fields(settings)}
    return settings(**{item.name: kind_of(item.default)(values[name]) for name, item in fields.items()})


def kind_of(default: Value) -> Callable[[object], Value]:
    """How a settings dataclass field holds a parameter's value: a number of a double setting as a float, a
    string array (a list from ROS) as a tuple, the rest as it is."""
    kind = type(default)
    return kind if kind in (float, tuple) else (lambda value: value)


def changed(current: Any, values: Mapping[str, object]) -> Any:
    """The settings dataclass instance ``current`` with the parameters among ``values`` (by name) changed."""
    fields = {item.metadata[SETTING]['name'] or item.name: item for item in dataclasses.fields(current)}
    return dataclasses.replace(current, **{fields[name].name: kind_of(fields[name].default)(value)
                                           for name, value in values.items() if name in fields})


def parameters(current: Any) -> dict[str, Value]:
    """A settings dataclass instance's values by parameter name."""
    return {item.metadata[SETTING]['name'] or item.name: getattr(current, item.name)
            for item in dataclasses.fields(current)}
