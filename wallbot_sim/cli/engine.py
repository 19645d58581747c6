"""The compiled engine for the verbs that compute on it: numba present (``run``, ``simulate``), its kernel loaded
(``run``, before its nodes start)."""

from __future__ import annotations

import sys
import threading

from wallbot_sim.cli.errors import CliError
from wallbot_sim.model.errors import ParameterError

COMPILE_NOTICE = 2.0
"""Seconds the compiled kernel may take to load from numba's cache before ``run`` says it is compiling."""


def require_compiled_engine() -> None:
    """CliError unless numba imports, naming the package and the other engine."""
    from wallbot_sim.model.compiled import require_numba
    try:
        require_numba()
    except ParameterError as error:
        raise CliError(f'{error}, or --engine python') from None


def load_compiled_kernel(contact: str, inverse_dynamics: bool) -> None:
    """Load the compiled kernel the nodes step by (under ``contact``; and the controller's law) from numba's
    cache, or compile it there (a machine's first run: about a minute, said), before any node starts: the nodes
    then load it in a second, well within the graph's start timeouts."""
    from wallbot_sim.model.compiled import compile_inverse_dynamics, compile_run
    notice = threading.Timer(COMPILE_NOTICE, print, ['wallbot-sim run: compiling the numba kernel into its cache '
                                                     "(a machine's first run: about a minute)..."],
                             {'file': sys.stderr, 'flush': True})
    notice.start()
    try:
        compile_run(contact)
        if inverse_dynamics:
            compile_inverse_dynamics()
    finally:
        notice.cancel()
