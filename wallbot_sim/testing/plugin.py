"""The pytest plugin of wallbot_sim, registered through the ``pytest11`` entry point: the ``wallbot`` fixture.

A test starts the simulated robot and its controller under test in a domain of their own, runs it a number of
simulated seconds at a time, looks at its state, injects faults, and judges the run with the expectations of a test
spec::

    def test_my_controller(wallbot):
        wallbot.start(scenario='figure8', contact='coulomb', controller=['python3', '-m', 'my_pkg.controller'])
        wallbot.run(1.0)
        assert wallbot.state.t == pytest.approx(1.0)
        wallbot.inject(motor_left=0.5)          # from now on; inject({'at': 1.5, 'for': 0.2, 'drop': 'odom'}) later
        wallbot.run(1.0)
        wallbot.expect_no_slip()
        wallbot.expect_max_motor_torque(2.5)

``start`` takes a spec's keys (``wallbot_sim.testing.spec``) but ``duration`` and ``expect``: the run lasts as long as
``run`` takes it, and the ``expect_*`` helpers judge it, each an assertion whose message is the verdict (with a figure
of the failing quantity in the fixture's folder). The first of them, or ``bag``, ends the recording. ``run_spec``
runs a whole spec file instead. Whatever the test does, every process the fixture started is ended after it.

Imported by every pytest session where wallbot_sim is installed, so the simulator's modules load only when a test
uses the fixture.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterator, Mapping

import pytest

from wallbot_sim.testing.errors import SpecError

if TYPE_CHECKING:
    from wallbot_sim.testing.expectations import Ending, Verdict
    from wallbot_sim.testing.outcome import Outcome
    from wallbot_sim.testing.session import RobotState, Session
    from wallbot_sim.testing.spec import Spec

HOLD = 1e-9
"""The dynamics' first stop (s): it publishes the state at t = 0 and holds there until the first ``run``."""
HORIZON = 1e6
"""The longest run the fixture's spec allows (s): its faults are checked against it."""


class Wallbot:
    """The fixture's object: one simulated robot and its controller under test, output in ``out``."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.session: Session | None = None
        self.spec: Spec | None = None
        self.ending: Ending | None = None
        self._run = None
        self._specs = 0

    def start(self, **keys: Any) -> None:
        """Start the graph and the controller (``controller=``, a command line or its words) with a spec's keys;
        it holds at t = 0 until :meth:`run`."""
        if self.session is not None:
            raise SpecError('wallbot.start: started already (one run a test)')
        from wallbot_sim.testing.session import Session
        from wallbot_sim.testing.spec import make_spec
        refused = sorted({'duration', 'expect'} & set(keys))
        if refused:
            raise SpecError(f'wallbot.start: {refused[0]} is not taken: run() says how long, the expect_ helpers '
                            'judge the run')
        self.spec = make_spec(duration=HORIZON, name='wallbot', **keys)
        self.session = Session(self.spec, self.out, ground_truth=True)  # an injected dropout keeps the states
        self.session.start(HOLD)

    def run(self, seconds: float) -> RobotState:
        """Run ``seconds`` of simulation time (applying the faults due on the way) and hold; the state there.
        AssertionError naming why if the run ends first (the controller did not answer, the robot left the wall)."""
        from wallbot_sim.testing.session import RunFailed
        session = self._running()
        if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
            raise SpecError(f'wallbot.run: seconds must be a number > 0, got {seconds!r}')
        try:
            session.advance(session.now + seconds)
        except RunFailed as failure:
            self.ending = failure.ending(session.now)
            raise AssertionError(f'the run ended at t = {session.now:.3f} s: {failure}') from None
        return self.state

    @property
    def state(self) -> RobotState | None:
        """The robot's state where the run stands (None before the graph published one)."""
        return self.session.state if self.session is not None else None

    def inject(self, fault: Mapping[str, Any] | None = None, **keys: Any) -> None:
        """A fault as a spec's ``faults`` entry gives it (``motor_left``, ``motor_right``, ``adhesion_scale``,
        ``drop``), as a mapping or keywords; from now on, or from its ``at``, and for ``for`` seconds if given."""
        from wallbot_sim.testing.spec import fault_entry, healed
        session = self._running()
        entry = {**(fault or {}), **keys}
        entry.setdefault('at', session.now)
        try:
            at, until, changes = fault_entry(entry)
        except SpecError as error:
            raise SpecError(f'wallbot.inject: {error}') from None
        session.inject(changes, at)
        if until < math.inf:
            session.inject(healed(changes), until)

    @property
    def bag(self) -> Path:
        """The bag of the run; asking for it ends the recording (no :meth:`run` after it)."""
        from wallbot_sim.testing.session import RunFailed
        if self.session is None:
            raise SpecError('wallbot.bag: nothing was started')
        if not self.session.closed:
            try:
                self.session.finish()
            except RunFailed as failure:
                self.ending = failure.ending(self.session.now)
            self.session.close()
        return self.session.bag

    @property
    def processes(self) -> dict[str, int]:
        """The process id of each process started (the graph's nodes and the controller), by name."""
        return self.session.pids() if self.session is not None else {}

    # --- the spec's expectations, as assertions --------------------------------------------------
    def expect_max_tracking_error_after(self, t: float, m: float) -> Verdict:
        """After ``t`` s the centre stays within ``m`` metres of the reference."""
        return self._expect('max_tracking_error_after', {'t': t, 'm': m})

    def expect_no_slip(self) -> Verdict:
        """No wheel slips; the friction use stays at most 1."""
        return self._expect('no_slip', True)

    def expect_no_detachment(self) -> Verdict:
        """Every normal load stays >= 0."""
        return self._expect('no_detachment', True)

    def expect_min_adhesion_margin(self, limit: float) -> Verdict:
        """Applied over least-needed adhesion force stays at least ``limit``."""
        return self._expect('min_adhesion_margin', limit)

    def expect_max_motor_torque(self, limit: float) -> Verdict:
        """Each side's motor delivers at most ``limit`` N m."""
        return self._expect('max_motor_torque', limit)

    def _expect(self, name: str, value: object) -> Verdict:
        """The verdict of the expectation ``name`` (a spec's ``expect`` key) with ``value``; AssertionError with it
        (and a figure of the failing quantity) unless it holds."""
        from wallbot_sim.testing.expectations import judge
        from wallbot_sim.testing.outcome import recorded_run, robot_parameters
        from wallbot_sim.testing.spec import parse_expectations
        expectations = parse_expectations({name: value})  # the spec's checks of the limits
        bag = self.bag
        if self._run is None:
            self._run = recorded_run(bag)
        if self._run is None:
            raise AssertionError(f'{name}: not judged: the run recorded no state')
        verdict, = judge(expectations, self._run, robot_parameters(self.spec), self.ending)
        if verdict.passed is not True:
            figure = self._figure(verdict)
            raise AssertionError(verdict.line() + (f' (figure: {figure})' if figure else ''))
        return verdict

    def _figure(self, verdict: Verdict) -> Path | None:
        from wallbot_sim.rundata.faults import fault_events
        from wallbot_sim.testing.outcome import Outcome
        from wallbot_sim.testing.report import failing_figure
        if verdict.passed is None:
            return None
        outcome = Outcome(self.spec, self.bag, self.session.now, math.nan, self.ending, (verdict,),
                          tuple(fault_events(self.bag)), 0.0)
        events = [(event.stamp_ns * 1e-9, ', '.join(event.changed)) for event in outcome.faults]
        return failing_figure(verdict, self._run, outcome, self.out / 'plots', events)

    # --- a whole spec --------------------------------------------------------------------------
    def run_spec(self, spec: str | Path | Spec) -> Outcome:
        """Run a spec (a file, or a ``Spec``) in its own folder under the fixture's, judged; its outcome (JUnit file
        and report beside its bag)."""
        from wallbot_sim.testing.runner import run_spec
        from wallbot_sim.testing.spec import Spec, load_spec
        loaded = spec if isinstance(spec, Spec) else load_spec(spec)
        self._specs += 1
        out = self.out / f'spec{self._specs}'
        out.mkdir(parents=True, exist_ok=True)
        return run_spec(loaded, out)

    def close(self) -> None:
        """End every process of the run (safe to call again)."""
        if self.session is not None:
            self.session.close()

    def _running(self) -> Session:
        if self.session is None:
            raise SpecError('wallbot: start() first')
        if self.session.closed:
            raise SpecError('wallbot: the recording has ended (bag or an expect_ helper was used)')
        return self.session


@pytest.fixture
def wallbot(tmp_path: Path) -> Iterator[Wallbot]:
    """A simulated robot for a controller under test (:class:`Wallbot`); every process it starts ends after the
    test, whatever the test does."""
    robot = Wallbot(tmp_path / 'wallbot')
    try:
        yield robot
    finally:
        robot.close()
