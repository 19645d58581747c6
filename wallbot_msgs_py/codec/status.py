"""diagnostic_msgs: ``/diagnostics`` (DiagnosticArray), the constraint set, ``constraints`` (DiagnosticStatus), and the
fault events, ``faults`` (DiagnosticArray)."""

from __future__ import annotations

from typing import Mapping, NamedTuple, Sequence

from wallbot_msgs_py import cdr
from wallbot_msgs_py.constraint_modules import CONSTRAINT_SWITCHES

DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
DIAGNOSTIC_STATUS = 'diagnostic_msgs/msg/DiagnosticStatus'
LEVELS = {'ok': 0, 'warn': 1, 'error': 2, 'stale': 3}
LEVEL_NAMES = {value: name for name, value in LEVELS.items()}
HARDWARE_ID = 'wallbot_sim'
SIMULATION = ': simulation'
"""The end of the name of a dynamics node's status, after the node's fully qualified name."""


class Status(NamedTuple):
    """One diagnostic_msgs/DiagnosticStatus: level one of LEVELS' keys, values in order."""

    name: str
    level: str
    message: str
    values: Sequence[tuple[str, object]]

    def value_map(self) -> dict[str, str]:
        return {str(key): str(value) for key, value in self.values}


def simulation_status_name(node: str) -> str:
    """The name of the status a dynamics node (``node``: its fully qualified name) publishes."""
    return node + SIMULATION


def simulation_status(statuses: Sequence[Status], namespace: str) -> Status | None:
    """The status of the dynamics node in ``namespace`` among ``statuses`` (``/diagnostics`` is one
    topic for every robot of a domain), or None."""
    for status in statuses:
        if status.name.endswith(SIMULATION):
            node = status.name[:-len(SIMULATION)]
            if node.rsplit('/', 1)[0] == namespace.rstrip('/'):
                return status
    return None


def _text(value: object) -> str:
    return f'{value:.6g}' if isinstance(value, float) else str(value)


def _write_status(out: cdr.Writer, status: Status) -> None:
    out.octet(LEVELS[status.level])
    out.string(status.name)
    out.string(status.message)
    out.string(HARDWARE_ID)
    out.uint32(len(status.values))
    for key, value in status.values:
        out.string(str(key))
        out.string(_text(value))


def _read_status(message: cdr.Reader) -> Status:
    level = message.octet()
    name, text = message.string(), message.string()
    message.string()  # hardware_id
    values = [(message.string(), message.string()) for _ in range(message.uint32())]
    return Status(name, LEVEL_NAMES.get(level, f'level {level}'), text, values)


class Diagnostics(NamedTuple):
    stamp_ns: int
    statuses: list[Status]


@cdr.encoder('diagnostics', DIAGNOSTIC_ARRAY)
def diagnostics(t: float, statuses: Sequence[Status]) -> bytes:
    """``/diagnostics`` stamped with simulation time t; floats written with 6 significant digits."""
    out = cdr.Writer()
    out.header(cdr.to_nanoseconds(t), '')
    out.uint32(len(statuses))
    for status in statuses:
        _write_status(out, status)
    return out.bytes()


@cdr.decoder('diagnostics', DIAGNOSTIC_ARRAY)
def decode_diagnostics(message: cdr.Reader) -> Diagnostics:
    stamp_ns, _frame = message.header()
    return Diagnostics(stamp_ns, [_read_status(message) for _ in range(message.uint32())])


# --- the constraint set ----------------------------------------------------------------------------
CONSTRAINTS_STATUS_NAME = 'wallbot constraints'
GAINS = ('baumgarte_alpha', 'baumgarte_beta')


class ConstraintSwitches(NamedTuple):
    """What a ``constraints`` message says: every switch, the Baumgarte gains."""

    switches: dict[str, bool]
    alpha: float
    beta: float


@cdr.encoder('constraints', DIAGNOSTIC_STATUS)
def constraints(switches: Mapping[str, bool], alpha: float, beta: float, active: Sequence[str], label: str) -> bytes:
    """``constraints``: a DiagnosticStatus whose values hold every switch ('true'/'false'), the
    gains (repr of the float) and 'active' (the active modules, comma-separated); its message
    is ``label``, e.g. 'trajectory+belt'."""
    values = {name: 'true' if switches[name] else 'false' for name in CONSTRAINT_SWITCHES}
    values.update({'baumgarte_alpha': repr(float(alpha)), 'baumgarte_beta': repr(float(beta)),
                   'active': ','.join(active)})
    out = cdr.Writer()
    _write_status(out, Status(CONSTRAINTS_STATUS_NAME, 'ok', label, list(values.items())))
    return out.bytes()


@cdr.decoder('constraints', DIAGNOSTIC_STATUS)
def decode_constraints(message: cdr.Reader) -> ConstraintSwitches:
    """The switches and gains of a serialized ``constraints``; ValueError naming what is wrong."""
    values = _read_status(message).value_map()
    switches = {}
    for name in CONSTRAINT_SWITCHES:
        text = values.get(name, '').strip().lower()
        if text not in ('true', 'false'):
            raise ValueError(f'constraints message: {name} must be true or false, got {values.get(name)!r}')
        switches[name] = text == 'true'
    gains = []
    for name in GAINS:
        try:
            gains.append(float(values[name]))
        except (KeyError, ValueError):
            raise ValueError(f'constraints message: {name} must be a number, got {values.get(name)!r}') from None
    return ConstraintSwitches(switches, *gains)


# --- fault events ----------------------------------------------------------------------------------
FAULTS = ': faults'
"""The end of the name of a dynamics node's fault event status, after the node's fully qualified name."""


class FaultEvent(NamedTuple):
    """What a ``faults`` message says: at simulation time ``stamp_ns`` the dynamics ``node`` changed the fault
    settings ``changed`` (``cause``: why), after which every fault setting has the value ``values`` gives (text)."""

    stamp_ns: int
    node: str
    changed: tuple[str, ...]
    cause: str
    values: dict[str, str]


@cdr.encoder('faults', DIAGNOSTIC_ARRAY)
def fault_event(t: float, node: str, changed: Sequence[str], cause: str, values: Sequence[tuple[str, str]],
                level: str) -> bytes:
    """``faults``: a DiagnosticArray stamped with simulation time ``t`` holding one status named after ``node`` (the
    dynamics' fully qualified name), its values 'changed' (comma-separated), 'cause', then each fault setting's
    value as text; ``level`` (one of LEVELS) says whether a fault is on."""
    out = cdr.Writer()
    out.header(cdr.to_nanoseconds(t), '')
    out.uint32(1)
    message = f'{", ".join(changed)} ({cause})'
    _write_status(out, Status(node + FAULTS, level, message, [('changed', ','.join(changed)), ('cause', cause),
                                                               *values]))
    return out.bytes()


@cdr.decoder('faults', DIAGNOSTIC_ARRAY)
def decode_fault_event(message: cdr.Reader) -> FaultEvent:
    """The event of a serialized ``faults`` message; ValueError if it holds none."""
    stamp_ns, _frame = message.header()
    statuses = [_read_status(message) for _ in range(message.uint32())]
    for status in statuses:
        if status.name.endswith(FAULTS):
            values = status.value_map()
            changed, cause = values.pop('changed', ''), values.pop('cause', '')
            return FaultEvent(stamp_ns, status.name[:-len(FAULTS)], tuple(name for name in changed.split(',') if name),
                              cause, values)
    raise ValueError('faults message without a fault event status')
