"""The engine the verbs that compute choose (``run``, ``simulate``): the compiled one unless the robot needs the
python engine or ``--engine`` says otherwise, numba installed where it computes, and ``run``'s patience while its
dynamics loads the kernel (a machine's first run compiles it into numba's cache)."""

from __future__ import annotations

import sys
from importlib.util import find_spec

from wallbot_sim.cli.errors import CliError
from wallbot_sim.graph_options import BY_NAME
from wallbot_sim.model import Robot
from wallbot_sim.model.python_only import python_only_reason
from wallbot_sim.model.simulation import NUMBA, PYTHON

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


def chosen_engine(requested: str | None, robot: Robot, verb: str) -> str:
    """The engine ``verb`` computes ``robot`` on. ``requested`` (its --engine) when given, refused in one line
    (CliError) if it is numba for a robot that needs the python engine (a world file, a motor or vacuum block,
    docs/model.md 13); without --engine the default, numba, but python for such a robot, said in one line on
    stderr. CliError if the engine chosen is numba and numba is not installed."""
    reason = python_only_reason(robot)
    if requested is None:
        engine = BY_NAME['engine'].setting.default if reason is None else PYTHON
        if reason is not None:
            print(f'wallbot-sim {verb}: engine python ({reason})', file=sys.stderr, flush=True)
    elif requested == NUMBA and reason is not None:
        raise CliError(f'--engine numba: {reason} (drop --engine, or --engine python)')
    else:
        engine = requested
    if engine == NUMBA:
        require_compiled_engine()
    return engine


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
