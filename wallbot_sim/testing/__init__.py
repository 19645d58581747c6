"""Controller integration testing: a controller under test, run against the simulated robot and judged.

    from wallbot_sim.testing import load_spec, run_spec
    outcome = run_spec(load_spec('spec.yaml'), Path('out'))   # bag, logs, junit.xml, report.md in out/
    assert outcome.passed, outcome.summary()

``spec``: what a test is (the run, the controller, its faults, the expectations); ``session``: the controller and the
graph as processes of one run, in a domain of their own, in lockstep; ``expectations``: the verdicts, from the bag
through ``wallbot_sim.rundata``; ``junit`` and ``report``: what a CI system and a person read. ``wallbot-sim test``
runs a spec; the pytest plugin (``plugin``, registered as ``pytest11``) gives a test the ``wallbot`` fixture.

The names below are imported when first used, so that the command line's error handling (``errors``) does not load
the rest.
"""

from __future__ import annotations

import importlib
from typing import Any

EXPORTS = {'ControllerWouldNotStart': 'errors', 'SpecError': 'errors', 'Outcome': 'outcome', 'run_spec': 'runner',
           'Spec': 'spec', 'load_spec': 'spec', 'make_spec': 'spec'}
__all__ = sorted(EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in EXPORTS:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'{__name__}.{EXPORTS[name]}'), name)
