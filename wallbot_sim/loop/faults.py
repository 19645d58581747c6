"""Faults of the running robot: a motor delivering less than it is commanded, a suction loss, a sensor going silent.

Each fault is a dynamics setting (``FAULT_PARAMETERS``), changed like any other (``ros2 param set``: from the next
step boundary) or at simulation times by the ``fault_schedule`` setting, whose entries the loop applies at the step
boundary at their time: a scheduled fault meets the same state in every run, whatever the pace. Every change is
told to the graph (``Graph.publish_fault``), which records it as an event on ``faults``.

A schedule is text (a parameter): entries separated by ``;``, each ``at=T NAME=VALUE ...``, e.g.
``at=5.0 motor_efficiency_left=0.0; at=8.0 adhesion_scale=0.6; at=9.0 adhesion_scale=1.0``; each value is read
and checked by its setting, as ``ros2 param set`` would be.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Mapping

from wallbot_msgs_py import topics
from wallbot_sim.settings.dynamics import DYNAMICS, FAULT_PARAMETERS, DynamicsSettings
from wallbot_sim.settings.table import SettingError, Value, parameters, text_of

SILENCED = {'drop_odom': (topics.ODOM, topics.CONTROL_ODOM), 'drop_wheel_states': (topics.WHEEL_STATES,),
            'drop_imu': (topics.IMU,)}
"""The topics each dropout setting silences (control_odom carries odom's messages)."""


@dataclass(frozen=True)
class ScheduledFault:
    """Fault settings to apply at the step boundary at simulation time ``at`` (s)."""

    at: float
    changes: tuple[tuple[str, Value], ...]


@dataclass(frozen=True)
class FaultChange:
    """Fault settings changed at simulation time ``t``: which (``changed``), every fault setting's value from then on
    (``values``, in the order of FAULT_PARAMETERS), and why: 'scheduled', 'parameter' (a set parameter) or 'start'."""

    t: float
    changed: tuple[str, ...]
    values: tuple[tuple[str, Value], ...]
    cause: str


def parse_schedule(text: str) -> tuple[ScheduledFault, ...]:
    """The entries of a ``fault_schedule`` text, in time order (entries at one time in their order); ValueError
    naming the entry and what is wrong with it."""
    entries = []
    for number, entry in enumerate((part.strip() for part in text.split(';') if part.strip()), 1):
        try:
            entries.append(_entry(entry))
        except ValueError as error:
            raise ValueError(f'fault_schedule entry {number} ({entry!r}): {error}') from None
    return tuple(sorted(entries, key=lambda fault: fault.at))


def _entry(entry: str) -> ScheduledFault:
    at, changes = None, {}
    for token in entry.split():
        name, equals, text = token.partition('=')
        if not equals or not text:
            raise ValueError(f'expected NAME=VALUE, got {token!r}')
        if name == 'at':
            try:
                at = float(text)
            except ValueError:
                at = math.nan
            if not (math.isfinite(at) and at >= 0.0):
                raise ValueError(f'at must be a simulation time >= 0 (s), got {text!r}')
        elif name not in FAULT_PARAMETERS:
            raise ValueError(f'{name!r} is no fault parameter ({", ".join(FAULT_PARAMETERS)})')
        elif name in changes:
            raise ValueError(f'{name} is given twice')
        else:
            try:
                changes[name] = DYNAMICS[name].parse(text)
            except SettingError as error:
                raise ValueError(f'{name} {error}') from None
    if at is None:
        raise ValueError('at=T (the simulation time, s) is missing')
    if not changes:
        raise ValueError('no fault parameter is set')
    return ScheduledFault(at, tuple(changes.items()))


def schedule_text(entries: Iterable[ScheduledFault]) -> str:
    """The ``fault_schedule`` text of ``entries`` (what :func:`parse_schedule` reads back)."""
    return '; '.join(' '.join([f'at={fault.at!r}', *(f'{name}={text_of(value)}' for name, value in fault.changes)])
                     for fault in entries)


class FaultSchedule:
    """The scheduled faults not applied yet (loop thread only)."""

    def __init__(self, entries: Iterable[ScheduledFault]) -> None:
        self.pending = list(entries)

    def due(self, t: float, dt: float) -> list[ScheduledFault]:
        """The entries due at the step boundary at ``t`` (at most half a step ``dt`` later), taken off the schedule:
        also those of earlier times (a run resumed past them)."""
        count = 0
        while count < len(self.pending) and self.pending[count].at <= t + 0.5 * dt:
            count += 1
        due, self.pending = self.pending[:count], self.pending[count:]
        return due

    def steps_before_next(self, t: float, dt: float) -> int | None:
        """Steps from the boundary at ``t`` to the boundary of the next entry (None: no entry left)."""
        if not self.pending:
            return None
        return max(round((self.pending[0].at - t) / dt), 0)



def fault_values(settings: DynamicsSettings) -> tuple[tuple[str, Value], ...]:
    """Every fault setting's value in ``settings``, in the order of FAULT_PARAMETERS."""
    values = parameters(settings)
    return tuple((name, values[name]) for name in FAULT_PARAMETERS)


def faults_on(settings: DynamicsSettings) -> tuple[str, ...]:
    """The fault settings in ``settings`` away from their defaults (the faults that are on)."""
    return tuple(name for name, value in fault_values(settings) if value != DYNAMICS[name].default)


def silenced(settings: DynamicsSettings) -> frozenset[topics.Topic]:
    """The topics the dropout settings keep silent."""
    return frozenset(topic for name, silent in SILENCED.items() if getattr(settings, name) for topic in silent)


def delivered(torque: tuple[float, float], settings: DynamicsSettings) -> tuple[float, float]:
    """The side torques the motors deliver for the commanded ``torque`` (N m), by their efficiencies."""
    return torque[0] * settings.motor_efficiency_left, torque[1] * settings.motor_efficiency_right


def fault_changes(changes: Mapping[str, object]) -> tuple[str, ...]:
    """The fault settings among the setting ``changes``, in the order of FAULT_PARAMETERS."""
    return tuple(name for name in FAULT_PARAMETERS if name in changes)
