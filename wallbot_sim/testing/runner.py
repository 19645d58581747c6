"""One controller test from its spec to its outcome: the run (``session``), the verdicts (``expectations``), the JUnit
file and the report. What ``wallbot-sim test`` does, and the fixture's ``run_spec``."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

from wallbot_sim.testing.junit import write_junit
from wallbot_sim.testing.outcome import Outcome, judged
from wallbot_sim.testing.report import write_report
from wallbot_sim.testing.session import RunFailed, Session
from wallbot_sim.testing.spec import Spec


def run_spec(spec: Spec, out: Path, junit: Path | None = None,
             progress: Callable[[float], None] | None = None) -> Outcome:
    """Run ``spec`` into ``out`` (bag, logs, report.md, plots) and judge it; the JUnit file at ``junit`` (default
    ``out/junit.xml``). ControllerWouldNotStart if its controller cannot be started; SpecError for a spec that
    cannot run (a bag in ``out`` already)."""
    began = time.monotonic()
    duration = spec.run_duration()
    session = Session(spec, out, progress)
    ending = None
    try:
        session.start(duration)
        session.advance(duration)
        session.finish()
    except RunFailed as failure:
        ending = failure.ending(session.now)
    finally:
        session.close()
    outcome = judged(spec, session.bag, duration, ending, time.monotonic() - began)
    write_junit(outcome, junit or out / 'junit.xml')
    write_report(outcome, out)
    return outcome
