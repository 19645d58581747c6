"""What a controller test found: how its run went, each expectation's verdict, the faults the bag recorded."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from wallbot_msgs_py import topics
from wallbot_msgs_py.codec import FaultEvent
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import RobotParameters
from wallbot_sim.rundata import RunData, load_run
from wallbot_sim.rundata.faults import fault_events
from wallbot_sim.testing.expectations import Ending, Verdict, judge
from wallbot_sim.testing.spec import Spec

RUN = 'run'
"""The name of the verdict on the run itself (it covered its duration, its controller answering every state)."""


@dataclass(frozen=True)
class Outcome:
    """A controller test's result: the run's verdict, then each expectation's."""

    spec: Spec
    bag: Path
    duration: float
    """The simulated seconds the run was to cover."""
    covered: float
    """The simulated seconds the bag holds (NaN: no state)."""
    ending: Ending | None
    """How the run ended early (None: it covered its duration)."""
    verdicts: tuple[Verdict, ...]
    faults: tuple[FaultEvent, ...]
    wall_time: float

    @property
    def run_verdict(self) -> Verdict:
        ending = self.ending
        if ending is None:
            return Verdict(RUN, True, self.covered, self.duration, 's', math.nan,
                           f'{self.duration:g} s simulated, every state answered')
        return Verdict(RUN, False, self.covered, self.duration, 's', ending.t, ending.reason)

    @property
    def passed(self) -> bool:
        return self.ending is None and all(verdict.passed is not False for verdict in self.verdicts)

    @property
    def failed(self) -> tuple[Verdict, ...]:
        """The verdicts that fail, the run's first."""
        return tuple(verdict for verdict in (self.run_verdict, *self.verdicts) if verdict.passed is False)

    def summary(self) -> str:
        """The verdicts, a line each (the run's first)."""
        return '\n'.join(verdict.line() for verdict in (self.run_verdict, *self.verdicts))


def robot_parameters(spec: Spec) -> RobotParameters:
    """The robot of the run: its robot file, with the spec's adhesion force if it gives one."""
    params = load_robot_parameters(spec.robot)
    return params.replace(adhesion_force=spec.adhesion_force) if spec.adhesion_force else params


def judged(spec: Spec, bag: Path, duration: float, ending: Ending | None, wall_time: float) -> Outcome:
    """The outcome of the run of ``spec`` recorded in ``bag``."""
    run = recorded_run(bag)
    covered = float(run.t[-1] - run.t[0]) if run is not None else math.nan
    faults = tuple(fault_events(bag)) if run is not None else ()
    verdicts = judge(spec.expect, run, robot_parameters(spec), ending)
    return Outcome(spec, bag, duration, covered, ending, tuple(verdicts), faults, wall_time)


def recorded_run(bag: Path) -> RunData | None:
    """The run the bag holds, None if it holds no state (the run never began, or no bag was written)."""
    from wallbot_sim.bag.reader import info
    if not (bag / 'metadata.yaml').is_file():
        return None
    leaf = f'/{topics.ODOM.name}'
    if not any(topic.name.endswith(leaf) and topic.count for topic in info(bag).topics):
        return None
    return load_run(bag)
