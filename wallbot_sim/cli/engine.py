"""The compiled engine for the verbs that compute on it: numba installed (``run``, ``simulate``), and ``run``'s patience
while its dynamics loads the kernel (a machine's first run compiles it into numba's cache)."""

from __future__ import annotations

from importlib.util import find_spec

from wallbot_sim.cli.errors import CliError

COMPILE_NOTICE = 5.0
"""Wall seconds the dynamics may say it is loading its compiled kernel before ``run`` says why that takes long (a
load from numba's cache takes one to three seconds, compiling about a minute)."""
COMPILE_LIMIT = 600.0
"""Most wall seconds of a kernel's load that ``run`` does not count against its start timeouts."""


def require_compiled_engine() -> None:
    """CliError unless numba is installed, naming the package and the other engine. Looked up, not imported:
    importing numba takes about a second, which only the processes computing on it pay."""
    if find_spec('numba') is None:
        raise CliError("engine 'numba' needs the numba package (pip install numba), or --engine python")


class StartClock:
    """Wall time a starting graph has taken, not counting (up to COMPILE_LIMIT) the time its dynamics said it was
    loading its compiled kernel, which a machine's first run spends compiling it (about a minute)."""

    def __init__(self, now: float) -> None:
        self.start = self.last = now
        self.loading = 0.0
        """Wall seconds the dynamics has said it is loading."""
        self.said = False

    def tick(self, now: float, loading: bool) -> bool:
        """Count the time since the last tick (as loading if ``loading``); True once, when the load has taken
        COMPILE_NOTICE: the moment to say why the start takes long."""
        if loading:
            self.loading += now - self.last
        self.last = now
        if loading and self.loading > COMPILE_NOTICE and not self.said:
            self.said = True
            return True
        return False

    def waited(self) -> float:
        """Wall seconds since the start, the kernel's load left out."""
        return self.last - self.start - min(self.loading, COMPILE_LIMIT)
