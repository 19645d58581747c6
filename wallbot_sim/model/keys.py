"""Mappings read from files refuse keys they do not know, naming the closest one they do."""

from __future__ import annotations

import difflib
from typing import Any, Iterable, Mapping, Sequence

from wallbot_sim.model.errors import ParameterError


def unknown_key(values: Mapping[str, Any], known: Iterable[str], what: str) -> str | None:
    """The one-line reason ``values`` is no mapping or has a key not in ``known`` (its first, sorted), or None.

    ``what`` names what a key of the mapping is ('scenario key', 'robot parameter', ...). The reason names the
    closest known key when one is close, else every known key."""
    if not isinstance(values, Mapping):
        return f'expected a mapping of {what}s to values, got {values!r}'
    names = sorted(known)
    unknown = sorted(str(key) for key in values if key not in names)
    if not unknown:
        return None
    close = difflib.get_close_matches(unknown[0], names, n=1)
    hint = f'did you mean {close[0]!r}?' if close else f'known: {", ".join(names)}'
    return f'unknown {what} {unknown[0]!r} ({hint})'


def check_keys(values: Mapping[str, Any], known: Iterable[str], what: str) -> None:
    """Raise ParameterError if ``values`` has a key not in ``known`` (see :func:`unknown_key`)."""
    reason = unknown_key(values, known, what)
    if reason is not None:
        raise ParameterError(reason)


def check_block(values: Any, known: Sequence[str], where: str) -> None:
    """Raise ParameterError unless ``values`` is a mapping of exactly the keys ``known`` (a block of a file, named
    ``where``): no mapping, an unknown key (the closest named) or a missing one."""
    if not isinstance(values, Mapping):
        raise ParameterError(f'{where} must be a mapping of {", ".join(known)}, got {values!r}')
    check_keys(values, known, f'{where} key')
    missing = [key for key in known if key not in values]
    if missing:
        raise ParameterError(f'{where} needs {missing[0]!r}')
