"""The dynamics loop without DDS: events in, decisions and published states out.

A fake graph records what the loop publishes, a fake clock stands for the wall clock of the
waits (lockstep, back-pressure, reset), and the loop runs at factor 0 (no pacing sleeps).
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from scheduling_helpers import VirtualTime
from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_msgs_py.snapshot import DynamicsSnapshot
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import BaumgarteGains, RobotParameters, SampledReference
from wallbot_sim.model.motor import MotorParameters
from wallbot_sim.model.batch import kernel
from wallbot_sim.model.simulation import NUMBA, PYTHON, Simulation
from wallbot_sim.model.trajectories import Circle, sample_plan
from wallbot_sim.loop import (ConstraintSwitch, Decision, DynamicsLoop, NewPlan, Pacer, ParameterChange, Pause,
                              PreparedState, PumpCommand, RecordProgress, Reset, ResumeSnapshot, RunState, Step, Teleport,
                              TorqueCommand)
from wallbot_sim.loop import blocks as loop_blocks
from wallbot_sim.loop import loop as loop_module
from wallbot_sim.loop import pacing
from wallbot_sim.loop.blocks import BLOCK_PACED
from wallbot_sim.loop.faults import parse_schedule, schedule_text
from wallbot_sim.loop.start import COMMAND_WAIT_WARNING, RESEND_EVERY
from wallbot_sim.loop.waits import BACKPRESSURE_TIMEOUT
from wallbot_sim.settings.dynamics import DynamicsSettings

DT = 1e-3
SETTINGS = DynamicsSettings(real_time_factor=0.0, resume_wait=0.0, engine=PYTHON)
"""The node's defaults, at factor 0 (no pacing sleeps), resuming nothing, on the Python engine."""
GAINS = BaumgarteGains(5.0, 5.0)
SWITCHES = dict(belt=False, non_lateral=True, nonslip=True, tangent_heading=True)
DRIVEN = ConstraintSwitch(messages.selection_from_switches({**SWITCHES, 'trajectory_task': False}), GAINS)
TRACKING = ConstraintSwitch(messages.selection_from_switches({**SWITCHES, 'trajectory_task': True}), GAINS)


class FakeGraph:
    def __init__(self) -> None:
        self.published: list[tuple[float, np.ndarray]] = []
        self.clocks: list[float] = []  # the states published with /clock
        self.snapshots = []
        self.faults = []
        self.recorder = self.keeper = False
        self.controller = True
        self.resent: list[float] = []  # the last published time at each resend_to_controller

    def resend_to_controller(self) -> None:
        self.resent.append(self.published[-1][0])

    def prepare(self, out, clock):
        if clock:
            self.clocks.append(out.t)
        return lambda: self.published.append((out.t, out.q.copy()))

    def encodes_blocks(self, burst: bool) -> bool:
        return False

    def publish_snapshot(self, snapshot) -> None:
        self.snapshots.append(snapshot)

    def publish_fault(self, change) -> None:
        self.faults.append(change)

    def recorder_present(self) -> bool:
        return self.recorder

    def recorder_listening(self) -> bool:
        return self.recorder

    def keeper_seen(self) -> bool:
        return self.keeper

    def controller_listening(self) -> bool:
        return self.controller

    @property
    def times(self) -> list[float]:
        return [round(t / DT) * DT for t, _q in self.published]


@pytest.fixture(autouse=True)
def virtual_wall_clock(monkeypatch) -> VirtualTime:
    """The loop and its pacer read and sleep on a virtual clock: whether a state is late, or could be handed
    over ahead of time, follows from the loop's logic, never from how busy the machine is."""
    clock = VirtualTime()
    monkeypatch.setattr(pacing, 'time', clock)
    monkeypatch.setattr(loop_module, 'time', clock)
    monkeypatch.setattr(loop_blocks, 'time', clock)
    return clock


class FakeLog:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def info(self, message: str, **_kwargs) -> None:
        self.lines.append(('info', message))

    def warning(self, message: str, **_kwargs) -> None:
        self.lines.append(('warning', message))

    def error(self, message: str, **_kwargs) -> None:
        self.lines.append(('error', message))

    def said(self, text: str) -> list[str]:
        return [message for _level, message in self.lines if text in message]


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def make_loop(robot_file: RobotParameters | None = None, **settings):
    graph, log, clock = FakeGraph(), FakeLog(), FakeClock()
    loop = DynamicsLoop(replace(SETTINGS, **settings), robot_file or load_robot_parameters(None), graph, log,
                        Pacer(0, log.warning), clock=clock)
    return loop, graph, log, clock


def plan(start: float, end: float, radius: float = 0.8, moved: tuple[float, float] = (0.0, 0.0)) -> NewPlan:
    """The circle's plan over [start, end]; its samples at times in [moved[0], moved[1]) moved a nanometre in x."""
    sampled = sample_plan(Circle(radius=radius, period=20.0), start, end, 0.001)
    sampled.positions[:] = [(x + 1e-9, y) if moved[0] <= t < moved[1] else (x, y)
                            for t, (x, y) in zip(sampled.times, sampled.positions)]
    return NewPlan(SampledReference(*sampled), sampled.times[0], sampled.times[-1], messages.plan_is_final(sampled))


def ticks(loop: DynamicsLoop, count: int) -> list[Decision]:
    return [loop.tick() for _ in range(count)]


def test_nothing_steps_before_a_constraint_set_and_the_start_publishes_t0():
    loop, graph, _log, _clock = make_loop()
    assert ticks(loop, 3) == [Decision.NOT_READY] * 3
    assert str(loop.status) == 'waiting for constraints' and loop.sim is None and not graph.published
    loop.post(DRIVEN)
    assert ticks(loop, 2) == [Decision.STEPPED] * 2
    assert graph.times == pytest.approx([0.0, DT, 2 * DT]) and loop.status.state is RunState.RUNNING
    assert loop.command_state() == 'none yet, zero torque'


def test_lockstep_waits_for_the_command_answering_each_published_state():
    loop, graph, log, clock = make_loop(lockstep_every=1)
    loop.post(DRIVEN)
    assert loop.tick() is Decision.LOCKSTEP  # t = 0 went out: its answer is awaited
    assert ticks(loop, 5) == [Decision.LOCKSTEP] * 5 and graph.times == [0.0]
    loop.post(TorqueCommand((0.2, 0.2)))
    assert ticks(loop, 3) == [Decision.STEPPED, Decision.LOCKSTEP, Decision.LOCKSTEP]
    assert loop.sim.motor_torque == (0.2, 0.2) and loop.sim.steps == 1
    clock.now += SETTINGS.lockstep_timeout + 0.01  # a dead controller: lockstep gives up once
    assert ticks(loop, 3) == [Decision.STEPPED] * 3
    assert len(log.said('stepping on without lockstep until commands return')) == 1
    loop.post(TorqueCommand((0.1, 0.1)))
    assert ticks(loop, 2) == [Decision.STEPPED, Decision.LOCKSTEP]
    assert log.said('lockstep resumed')


def test_back_pressure_holds_the_loop_within_the_window_of_the_recorders_progress():
    loop, graph, log, clock = make_loop(backpressure_window=5)
    graph.recorder = True
    loop.post(DRIVEN)
    assert loop.tick() is Decision.HELD_BACK  # no progress reported yet
    # half-step progress stamps keep float ties out: a step starting at t runs if t - progress <= 5 dt
    loop.post(RecordProgress(500_000))
    decisions = ticks(loop, 10)
    assert decisions[:6] == [Decision.STEPPED] * 6 and set(decisions[6:]) == {Decision.HELD_BACK}
    assert loop.sim.steps == 6
    loop.post(RecordProgress(3_500_000))
    assert ticks(loop, 5) == [Decision.STEPPED] * 3 + [Decision.HELD_BACK] * 2
    assert loop.sim.steps == 9
    clock.now += BACKPRESSURE_TIMEOUT + 0.01  # the recorder stalled: step on without it
    assert ticks(loop, 3) == [Decision.STEPPED] * 3
    assert len(log.said('no record_progress for')) == 1
    graph.recorder = False  # no recorder left (seen at the next graph look): it runs free
    clock.now += 1.0
    assert ticks(loop, 2) == [Decision.STEPPED] * 2


def test_a_command_is_held_for_command_timeout_then_zero_torque():
    loop, _graph, log, _clock = make_loop(command_timeout=0.005)
    loop.post(DRIVEN)
    loop.post(TorqueCommand((1.0, -1.0)))
    applied = []
    for _ in range(8):
        assert loop.tick() is Decision.STEPPED
        applied.append(loop.sim.motor_torque)
    # the command came at t = 0; the steps from t = 0 .. 0.005 use it, the later ones do not
    assert applied == [(1.0, -1.0)] * 6 + [(0.0, 0.0)] * 2
    assert loop.command_state() == 'timed out, zero torque' and loop.commands.expired
    assert len(log.said('zero torque from t = 0.006 s')) == 1
    loop.post(TorqueCommand((0.5, 0.5)))
    loop.tick()
    assert loop.sim.motor_torque == (0.5, 0.5) and loop.command_state() == messages.applied_command(0.5, 0.5)


def test_the_trajectory_task_waits_for_a_plan_covering_the_next_step():
    loop, graph, log, _clock = make_loop()
    loop.post(TRACKING)
    assert loop.tick() is Decision.NOT_READY and str(loop.status) == 'waiting for reference_trajectory'
    loop.post(plan(0.0, 0.01))  # ends moving: no step may end at or past its end
    decisions = ticks(loop, 12)
    assert decisions[:9] == [Decision.STEPPED] * 9 and set(decisions[9:]) == {Decision.NOT_READY}
    assert str(loop.status) == 'waiting for a reference_trajectory covering t = 0.009 s'
    assert not log.said('plan')  # said by the node that receives it, not in the loop thread (0.3 ms a line)
    assert loop.command_state() == messages.COMMAND_IGNORED
    assert graph.clocks == pytest.approx([0.0, 0.009])  # the start, and the state it waits at
    loop.post(plan(0.005, 0.02))
    assert loop.tick() is Decision.STEPPED and graph.times[-1] == pytest.approx(0.01)


def test_stop_at_stops_the_loop_until_it_moves():
    loop, _graph, log, _clock = make_loop(stop_at=0.003)
    loop.post(DRIVEN)
    assert ticks(loop, 5) == [Decision.STEPPED] * 3 + [Decision.NOT_READY] * 2
    assert str(loop.status) == 'stopped at t = 0.003 s (stop_at)' == messages.stopped_status(0.003)
    assert str(loop.status).startswith('stopped')
    loop.post(ParameterChange({'stop_at': 0.0}))
    assert loop.tick() is Decision.STEPPED and loop.sim.steps == 4
    assert log.said('parameters: stop_at = 0.0')


def test_clock_goes_with_the_first_state_of_each_period_the_start_the_stop_and_a_reset():
    """clock_rate_hz 10 at 1 kHz: /clock at t = 0 (the start), every 100 ms, at the state the loop
    stops at (stop_at off the 100 ms grid), and at the state a reset goes back to; the per-step
    messages go out for every state."""
    loop, graph, _log, _clock = make_loop(stop_at=0.26)
    loop.post(DRIVEN)
    while loop.tick() is Decision.STEPPED:
        pass
    assert len(graph.published) == 261  # t = 0 and 260 steps
    assert graph.clocks == pytest.approx([0.0, 0.1, 0.2, 0.26])
    loop.post(Reset())
    loop.tick()
    assert graph.clocks[-1] == 0.0 and graph.published[-1][0] == pytest.approx(0.001)


def test_pause_resume_and_reset_transitions():
    loop, graph, log, _clock = make_loop()
    loop.post(DRIVEN)
    ticks(loop, 4)
    loop.post(Pause(True))
    assert ticks(loop, 2) == [Decision.NOT_READY] * 2 and str(loop.status) == 'paused'
    assert graph.snapshots[-1].paused and loop.sim.steps == 4
    loop.post(Pause(False))
    assert loop.tick() is Decision.STEPPED and loop.sim.steps == 5 and not graph.snapshots[-1].paused
    loop.post(TorqueCommand((0.3, 0.3)))
    loop.post(Reset())
    published = len(graph.published)
    assert loop.tick() is Decision.STEPPED  # the reset state went out, then the first step from it
    assert graph.times[published:] == pytest.approx([0.0, DT])
    assert loop.commands.command is None and log.said('reset to the initial state at t = 0')
    np.testing.assert_array_equal(graph.published[published][1], graph.published[0][1])


def test_step_takes_its_steps_while_paused_and_is_ignored_while_running():
    loop, graph, log, _clock = make_loop()
    loop.post(DRIVEN)
    ticks(loop, 3)
    loop.post(Pause(True))
    loop.post(Step(2))
    assert ticks(loop, 4) == [Decision.STEPPED] * 2 + [Decision.NOT_READY] * 2
    assert str(loop.status) == 'paused' and graph.times == pytest.approx([k * DT for k in range(6)])
    loop.post(Step(1))
    loop.post(Step(2))  # requests add up
    assert ticks(loop, 4) == [Decision.STEPPED] * 3 + [Decision.NOT_READY]
    loop.post(Step(5))
    loop.post(Pause(True))  # a new pause (or running again) drops the steps still to take
    assert loop.tick() is Decision.NOT_READY and loop.sim.steps == 8
    loop.post(Pause(False))
    loop.post(Step(3))
    assert loop.tick() is Decision.STEPPED and log.said('~/step ignored: the simulation is running')
    assert loop.steps_to_take == 0


def test_a_teleport_places_the_robot_at_rest_and_time_goes_on():
    """The placed state is published at once; the run goes on from it as a simulation started at
    rest there and then (an independent Simulation) does, the wheels' angles kept."""
    from wallbot_sim.model import Robot, Simulation
    loop, graph, log, _clock = make_loop()
    loop.post(DRIVEN)
    loop.post(TorqueCommand((0.4, 0.1)))
    ticks(loop, 5)
    loop.post(Pause(True))
    loop.tick()
    wheels = loop.sim.q[3:].copy()
    assert np.any(wheels != 0.0)
    loop.post(Teleport(0.2, -0.3, 1.0))
    assert loop.tick() is Decision.NOT_READY
    t, q = graph.published[-1]
    assert t == pytest.approx(5 * DT) and np.array_equal(q, [0.2, -0.3, 1.0, *wheels])
    assert not np.any(loop.sim.qd) and log.said('placed at rest at x = 0.200 m, y = -0.300 m, heading 1.000 rad')
    assert graph.snapshots[-1].q == (0.2, -0.3, 1.0, *wheels) and graph.snapshots[-1].paused
    loop.post(Step(3))
    ticks(loop, 4)
    expected = Simulation(Robot(load_robot_parameters(None)), None, DRIVEN.selection, np.array(q), np.zeros(7),
                          dt=DT, t0=5 * DT, gains=GAINS)
    expected.set_motor_torque(0.4, 0.1)
    for _ in range(3):
        expected.step()
    assert graph.times[-3:] == pytest.approx([6 * DT, 7 * DT, 8 * DT])
    np.testing.assert_array_equal(graph.published[-1][1], expected.q)


def test_a_teleport_before_the_start_is_ignored_and_after_a_divergence_recovers():
    loop, graph, log, _clock = make_loop()
    loop.post(Teleport(0.2, 0.0, 0.0))
    assert loop.tick() is Decision.NOT_READY and log.said('initialpose ignored') and not graph.published
    loop.post(DRIVEN)
    loop.post(TorqueCommand((1e308, -1e308)))
    ticks(loop, 2)
    assert loop.diverged
    loop.post(TorqueCommand((0.0, 0.0)))
    loop.post(Teleport(0.2, 0.0, 0.0))
    assert loop.tick() is Decision.STEPPED and not loop.diverged
    assert np.array_equal(graph.published[-2][1][:3], [0.2, 0.0, 0.0])


def test_a_diverged_run_holds_until_a_reset():
    loop, graph, log, _clock = make_loop()
    loop.post(DRIVEN)
    loop.post(TorqueCommand((1e308, -1e308)))  # the node refuses such a command; the loop must survive it
    assert ticks(loop, 3) == [Decision.STEPPED, Decision.NOT_READY, Decision.NOT_READY]
    assert str(loop.status) == 'diverged' and loop.diverged and graph.times == [0.0]
    assert log.said('simulation paused (reset with ~/reset)')
    loop.post(Reset())
    assert loop.tick() is Decision.STEPPED and not loop.diverged and loop.status.state is RunState.RUNNING
    assert graph.times == pytest.approx([0.0, 0.0, DT])


def test_a_reset_waits_for_lockstep_s_pending_answer():
    loop, graph, _log, _clock = make_loop(lockstep_every=1)
    loop.post(DRIVEN)
    loop.post(TorqueCommand((0.2, 0.2)))  # came before the t = 0 state: not its answer
    assert loop.tick() is Decision.LOCKSTEP
    loop.post(TorqueCommand((0.2, 0.2)))
    assert ticks(loop, 2) == [Decision.STEPPED, Decision.LOCKSTEP]
    loop.post(Reset())
    assert ticks(loop, 3) == [Decision.LOCKSTEP] * 3 and loop.sim.steps == 1  # the answer to t = 0.001 is due
    loop.post(TorqueCommand((0.2, 0.2)))  # that answer: the reset comes after it
    loop.tick()
    assert loop.sim.t == 0.0 and graph.times[-1] == 0.0 and loop.commands.command is None


NEEDS_NUMBA = pytest.mark.skipif(not kernel.available(), reason='numba is not installed')


@pytest.mark.parametrize('engine', [PYTHON, pytest.param(NUMBA, marks=NEEDS_NUMBA)])
def test_a_kept_snapshot_resumes_bit_for_bit_without_republishing_what_the_graph_saw(engine):
    first, first_graph, _log, _clock = make_loop(snapshot_period=0.005, engine=engine)
    first.post(DRIVEN)
    first.post(TorqueCommand((0.4, -0.2)))
    ticks(first, 12)
    kept = next(s for s in first_graph.snapshots if s.steps == 5)
    seen = replace(kept, seen_until_ns=codec.to_nanoseconds(8 * DT))  # the graph saw up to step 8

    second, graph, log, _clock = make_loop(snapshot_period=0.005, resume_wait=2.0, engine=engine)
    second.post(DRIVEN)
    assert second.tick() is Decision.NOT_READY
    assert str(second.status) == 'waiting for a kept snapshot to resume from (resume_state)'
    second.post(ResumeSnapshot(seen))
    ticks(second, 7)
    assert log.said('resuming from the kept snapshot at t = 0.005 s (step 5')
    assert graph.times == pytest.approx([0.009, 0.010, 0.011, 0.012])
    for (t, q), (t_first, q_first) in zip(graph.published, first_graph.published[9:13]):
        assert t == t_first
        np.testing.assert_array_equal(q, q_first)
    assert second.sim.engine == engine


@pytest.mark.parametrize('engine', [PYTHON, pytest.param(NUMBA, marks=NEEDS_NUMBA)])
def test_a_coulomb_run_resumes_bit_for_bit_with_the_contact_state_its_snapshot_kept(engine):
    """Two wheels sliding and two sticking at the kept boundary: the snapshot holds that set with its loads and
    friction, and the resumed run settles the boundary again from them to the bit. (Resumed from every wheel
    sticking instead, the run differs by up to ~1e-14 m in 16 steps: the set is found again, the friction not to
    the bit.)"""
    first, first_graph, _log, _clock = make_loop(snapshot_period=0.005, engine=engine, contact_model='coulomb')
    first.post(DRIVEN)
    first.post(TorqueCommand((2.0, -2.0)))
    ticks(first, 40)
    kept = next(s for s in first_graph.snapshots if s.steps == 20)
    assert kept.contact is not None and kept.contact.sliding == (True, False, True, False)
    assert all(load > 0.0 for load in kept.contact.loads)
    assert all(kept.contact.friction[2 * wheel] or kept.contact.friction[2 * wheel + 1]
               for wheel in range(4) if kept.contact.sliding[wheel])
    assert DynamicsSnapshot.from_values(kept.to_values()) == kept

    second, graph, _log, _clock = make_loop(snapshot_period=0.005, resume_wait=2.0, engine=engine,
                                            contact_model='coulomb')
    second.post(DRIVEN)
    second.tick()
    second.post(ResumeSnapshot(replace(kept, seen_until_ns=codec.to_nanoseconds(22 * DT))))
    ticks(second, 18)
    assert graph.times == pytest.approx([0.001 * k for k in range(23, 39)])
    for (t, q), (t_first, q_first) in zip(graph.published, first_graph.published[23:]):
        assert t == t_first
        np.testing.assert_array_equal(q, q_first)


def planned(reference, now: float, horizon: float) -> NewPlan:
    """The trajectory node's plan from ``now`` as the dynamics node decodes it (sample times through nanoseconds)."""
    renewal = messages.plan_ahead(reference, now, 0.02, horizon)
    sampled = messages.sampled_reference(renewal)
    return NewPlan(sampled, sampled.start, sampled.end, messages.plan_is_final(renewal))


@pytest.mark.parametrize('engine', [PYTHON, pytest.param(NUMBA, marks=NEEDS_NUMBA)])
def test_a_renewal_from_the_step_the_loop_stands_at_continues_the_motion_to_the_bit(engine):
    """Renewals made at 0.06 s and 0.12 s, applied with the loop at those very steps: on the sample grid, where a
    stamp reads back a rounding later (0.060000000000000005 s). The states are those of one plan for the run."""
    circle = Circle(radius=0.8, period=2.0)
    renewed, graph, _log, _clock = make_loop(engine=engine)
    renewed.post(TRACKING)
    renewed.post(planned(circle, 0.0, 0.1))
    while len(graph.published) <= 150:
        if renewed.sim is not None and renewed.sim.steps in (60, 120):
            renewed.post(planned(circle, renewed.sim.t, 0.1))
        assert renewed.tick() is Decision.STEPPED or renewed.sim is None
    one_plan, single, _log, _clock = make_loop(engine=engine)
    one_plan.post(TRACKING)
    one_plan.post(planned(circle, 0.0, 1.0))
    ticks(one_plan, 151)
    assert graph.times == single.times[:len(graph.times)] and len(graph.times) > 150
    for (_t, q), (_t_single, q_single) in zip(graph.published, single.published):
        np.testing.assert_array_equal(q, q_single)


def resumed_driven_loop(**settings):
    """A driven loop with wait_for_command resuming the snapshot of step 5 of a run the graph saw
    up to step 8, its controller not yet there."""
    first, first_graph, _log, _clock = make_loop(snapshot_period=0.005)
    first.post(DRIVEN)
    first.post(TorqueCommand((0.4, -0.2)))
    ticks(first, 12)
    kept = next(s for s in first_graph.snapshots if s.steps == 5)
    loop, graph, log, clock = make_loop(snapshot_period=0.005, resume_wait=2.0, wait_for_command=True, **settings)
    graph.controller = False
    loop.post(DRIVEN)
    loop.post(ResumeSnapshot(replace(kept, seen_until_ns=codec.to_nanoseconds(8 * DT))))
    return loop, graph, log, clock


def test_a_resumed_driven_start_waits_for_its_controller_and_its_answer_as_a_start_does():
    """A resumed node is a new participant: the controller hears it only after discovery (its
    answer was seen 2.4 s late under load), so the resumed loop waits for the controller before
    publishing, and for the answer to its first sync state (the controller acts again from the
    next control instant) with command_wait_timeout, not lockstep_timeout (which would step on
    without the answers the controller then holds back)."""
    loop, graph, log, clock = resumed_driven_loop(lockstep_every=5)
    assert ticks(loop, 3) == [Decision.NOT_READY] * 3 and loop.status.state is RunState.WAITING_CONTROLLER
    assert loop.sim is None and not graph.published
    graph.controller = True
    ticks(loop, 6)  # the catch-up (steps 6-8, unpublished), steps 9 and 10 go out
    assert graph.times == pytest.approx([0.009, 0.010]) and loop.status.state is RunState.WAITING_RESUMED_COMMAND
    clock.now += 3 * SETTINGS.lockstep_timeout
    assert ticks(loop, 3) == [Decision.NOT_READY] * 3 and graph.times == pytest.approx([0.009, 0.010])
    assert str(loop.status) == ('waiting for the first wheel_torque_cmd since the resume (the answer to the '
                                't = 0.010 s state) for 6 s (wall), giving up after 30 s (command_wait_timeout)')
    assert not log.said('without lockstep')
    loop.post(TorqueCommand((0.1, 0.1)))
    assert ticks(loop, 6) == [Decision.STEPPED] * 5 + [Decision.LOCKSTEP]  # lockstep as before
    assert loop.sim.motor_torque == (0.1, 0.1) and graph.times[-1] == pytest.approx(0.015)
    # without lockstep the loop cannot tell which state the controller answers: it steps on
    loop, graph, _log, _clock = resumed_driven_loop()
    graph.controller = True
    ticks(loop, 8)
    assert graph.times == pytest.approx([0.009, 0.010, 0.011, 0.012, 0.013])


def test_a_resumed_start_gives_up_on_an_answer_after_command_wait_timeout():
    loop, graph, log, clock = resumed_driven_loop(lockstep_every=5, command_wait_timeout=10.0)
    graph.controller = True
    ticks(loop, 6)
    assert graph.times == pytest.approx([0.009, 0.010]) and loop.status.state is RunState.WAITING_RESUMED_COMMAND
    clock.now += 10.01
    loop.tick()
    assert loop.stopping.is_set() and loop.status.state is RunState.GAVE_UP
    assert log.said('no wheel_torque_cmd answering the resumed state at t = 0.010 s within command_wait_timeout 10 s')


def run_through_every_rebuild(engine: str) -> tuple[FakeGraph, list[str]]:
    """A tracking run through each path that builds a simulation (start, rate change, reset,
    teleport) and a plan replaced mid-run; the published states and the engine of each simulation built."""
    loop, graph, _log, _clock = make_loop(engine=engine)
    engines = []
    loop.post(TRACKING)
    loop.post(plan(0.0, 0.05))
    ticks(loop, 30)
    engines.append(loop.sim.engine)
    loop.post(plan(0.0, 0.3))
    ticks(loop, 10)
    loop.post(ParameterChange({'rate_hz': 500}))
    ticks(loop, 10)
    engines.append(loop.sim.engine)
    loop.post(Reset())
    ticks(loop, 10)
    engines.append(loop.sim.engine)
    loop.post(Pause(True))
    loop.post(Teleport(0.2, -0.3, 1.0))
    loop.post(Step(5))
    ticks(loop, 6)
    engines.append(loop.sim.engine)
    return graph, engines


@NEEDS_NUMBA
def test_the_numba_engine_builds_every_simulation_and_agrees_with_the_python_engine():
    """engine numba: each simulation the loop builds computes with the compiled kernel, and the
    published states are the Python engine's to 1e-9 relative (the model's agreement, not bit for bit)."""
    python, python_engines = run_through_every_rebuild(PYTHON)
    numba, numba_engines = run_through_every_rebuild(NUMBA)
    assert python_engines == [PYTHON] * 4 and numba_engines == [NUMBA] * 4
    assert [t for t, _q in numba.published] == [t for t, _q in python.published]
    # 41 states at 1 ms, 10 at 2 ms, 11 from the reset, the teleported state and its 5 steps
    assert len(python.published) == 68 and np.array_equal(python.published[-6][1][:3], [0.2, -0.3, 1.0])
    expected, computed = np.array([q for _t, q in python.published]), np.array([q for _t, q in numba.published])
    scale = np.max(np.abs(expected), axis=0)
    assert np.all(np.abs(computed - expected) <= 1e-9 * scale)


def test_a_driven_start_waits_for_a_controller_and_its_first_command():
    loop, graph, _log, _clock = make_loop(wait_for_command=True)
    graph.controller = False
    loop.post(DRIVEN)
    assert loop.tick() is Decision.NOT_READY and loop.sim is None
    assert loop.status.state is RunState.WAITING_CONTROLLER
    graph.controller = True
    assert ticks(loop, 2) == [Decision.NOT_READY] * 2 and graph.times == [0.0]
    assert str(loop.status) == ('waiting for the first wheel_torque_cmd (the answer to the t = 0 state) for 0 s '
                                '(wall), giving up after 30 s (command_wait_timeout)')
    loop.post(TorqueCommand((0.1, 0.1)))
    assert loop.tick() is Decision.STEPPED


def test_an_unanswered_state_goes_to_the_controller_again_every_few_seconds_until_answered():
    """A controller whose odometry reader matched after the t = 0 state went out never gets it: without an answer
    the loop sends that state again every RESEND_EVERY (wall), and not once an answer came."""
    loop, graph, log, clock = make_loop(wait_for_command=True, command_wait_timeout=0.0)
    loop.post(DRIVEN)
    ticks(loop, 2)
    assert graph.times == [0.0] and not graph.resent
    clock.now += RESEND_EVERY - 0.1
    loop.tick()
    assert not graph.resent
    clock.now += 0.2
    ticks(loop, 3)
    assert graph.resent == [0.0] and log.said('no answer yet: the t = 0.000 s state goes to the controller again')
    clock.now += RESEND_EVERY + 0.1
    ticks(loop, 2)
    assert graph.resent == [0.0, 0.0]
    loop.post(TorqueCommand((0.1, 0.1)))
    assert loop.tick() is Decision.STEPPED
    clock.now += 2 * RESEND_EVERY
    ticks(loop, 3)
    assert graph.resent == [0.0, 0.0]


def test_a_start_without_a_controller_says_so_then_gives_up_after_command_wait_timeout():
    """wait_for_command set and no controller: the status names the wait and how long it lasted,
    the log says so once after a few seconds, and after command_wait_timeout (wall) the loop stops
    with one error line naming what was missing (the node then exits with status 1)."""
    loop, graph, log, clock = make_loop(wait_for_command=True, command_wait_timeout=10.0)
    graph.controller = False
    loop.post(DRIVEN)
    assert loop.tick() is Decision.NOT_READY and loop.status.state is RunState.WAITING_CONTROLLER
    clock.now += 4.0
    loop.tick()
    assert str(loop.status) == ('waiting for a controller (a wheel_torque_cmd publisher that hears odom) for 4 s '
                                '(wall), giving up after 10 s (command_wait_timeout)')
    assert not log.said('waiting for a controller') and not loop.in_error
    clock.now += COMMAND_WAIT_WARNING - 4.0 + 0.1
    ticks(loop, 3)
    assert [level for level, message in log.lines if 'waiting for a controller' in message] == ['warning']
    clock.now = 100.0 + 10.0  # the limit itself still waits
    assert loop.tick() is Decision.NOT_READY and not loop.stopping.is_set() and loop.gave_up is None
    clock.now += 0.01
    assert loop.tick() is Decision.NOT_READY and loop.stopping.is_set()
    assert loop.gave_up.startswith('no controller (a wheel_torque_cmd publisher subscribing odom, matched both ways) '
                                   'within command_wait_timeout 10 s (wall) with wait_for_command set')
    assert [(level, message) for level, message in log.lines if level == 'error'] == [
        ('error', f'{loop.gave_up}; exiting')]
    assert loop.status.state is RunState.GAVE_UP and str(loop.status).startswith('gave up: no controller')
    assert loop.in_error and loop.sim is None and not graph.published
    loop.run()  # returns at once: the loop has stopped
    loop.tick()
    assert len(log.said('within command_wait_timeout')) == 1 and loop.status.state is RunState.GAVE_UP


def test_the_wait_for_the_first_command_counts_from_the_t0_state_and_gives_up_too():
    """The answer to t = 0 can only come once that state is out (a numba compilation may delay it):
    each wait has the whole timeout, counted from its own start."""
    loop, graph, log, clock = make_loop(wait_for_command=True, command_wait_timeout=10.0)
    graph.controller = False
    loop.post(DRIVEN)
    loop.tick()
    clock.now += 9.0
    graph.controller = True
    assert loop.tick() is Decision.NOT_READY and graph.times == [0.0]
    assert loop.status.state is RunState.WAITING_FIRST_COMMAND and loop.status.waited == 0.0
    clock.now += 9.0
    assert loop.tick() is Decision.NOT_READY and loop.gave_up is None
    clock.now += 1.01
    loop.tick()
    assert loop.stopping.is_set() and loop.status.state is RunState.GAVE_UP
    assert log.said('no wheel_torque_cmd answering the t = 0 state within command_wait_timeout 10 s (wall)')


def test_command_wait_timeout_0_waits_for_ever_and_a_wait_after_the_start_never_gives_up():
    loop, graph, _log, clock = make_loop(wait_for_command=True, command_wait_timeout=0.0)
    graph.controller = False
    loop.post(DRIVEN)
    loop.tick()
    clock.now += 1e6
    assert loop.tick() is Decision.NOT_READY and not loop.stopping.is_set()
    assert str(loop.status).endswith('hears odom) for 1000000 s (wall)')  # no limit named
    # with a limit: once stepping, a reset's wait for the first command is not a start's
    loop, graph, _log, clock = make_loop(wait_for_command=True, command_wait_timeout=10.0)
    loop.post(DRIVEN)
    loop.tick()
    loop.post(TorqueCommand((0.1, 0.1)))
    assert ticks(loop, 2) == [Decision.STEPPED] * 2
    loop.post(Reset())
    assert loop.tick() is Decision.NOT_READY and loop.status.state is RunState.WAITING_FIRST_COMMAND
    clock.now += 100.0
    assert loop.tick() is Decision.NOT_READY and not loop.stopping.is_set() and loop.gave_up is None
    assert str(loop.status) == 'waiting for the first wheel_torque_cmd (the answer to the t = 0 state) for 100 s (wall)'


def test_the_loop_thread_wakes_on_a_posted_event_and_stops():
    loop, graph, _log, _clock = make_loop(stop_at=0.05)
    thread = threading.Thread(target=loop.run, daemon=True)
    thread.start()
    loop.post(DRIVEN)
    deadline = time.monotonic() + 10.0
    while loop.status.state is not RunState.STOPPED and time.monotonic() < deadline:
        time.sleep(0.01)
    assert loop.status.state is RunState.STOPPED and len(graph.published) == 51
    loop.stop()
    thread.join(timeout=5.0)
    assert not thread.is_alive()


class EncodingGraph(FakeGraph):
    """Publishes what the node publishes, the CDR bytes of every message with its /clock flag; with
    ``blocks`` it takes blocks of states (prepare_block) too. ``heard_every``: a subscriber outside the process
    takes every state (1), none (0), or those at multiples of this many steps (as a controller's control_odom);
    a paced loop may hand the others over ahead of time (``aheads``: by how much, per state)."""

    def __init__(self, blocks: bool, heard_every: int = 1) -> None:
        super().__init__()
        self.blocks, self.heard_every = blocks, heard_every
        self.encoder = StepEncoder()
        self.messages: list[tuple[list, bool]] = []
        self.block_sizes: list[int] = []
        self.leads: list[int] = []
        self.aheads: list[float] = []

    def prepare(self, out, clock):
        encoded = self.encoder.encode(out)
        send = super().prepare(out, clock)
        return lambda: (send(), self.messages.append((encoded, clock)), self.aheads.append(0.0))

    def encodes_blocks(self, burst: bool) -> bool:
        return self.blocks

    def prepare_block(self, block):
        self.block_sizes.append(len(block.t))
        if self.published:  # how many steps after the newest state published the block starts
            self.leads.append(round((block.t[0] - self.published[-1][0]) / 1e-3))

        def sender(encoded, t, q):
            def send(clock, ahead):
                self.published.append((t, q.copy()))
                self.messages.append((encoded, clock))
                self.aheads.append(ahead)
                if clock:
                    self.clocks.append(t)
            return send
        every = self.heard_every
        return [PreparedState(sender(encoded, t, q), every > 0 and round(t / DT) % every == 0)
                for encoded, t, q in zip(self.encoder.encode_rows(block), block.t.tolist(), block.q)]


def run_as_fast_as_possible(blocks: bool) -> tuple[EncodingGraph, DynamicsLoop, FakeClock]:
    """A tracking run at factor 0 on the numba engine through what ends a block: snapshots every 7 ms,
    a recorder 30 steps of window behind, plans that end moving, a reset, stop_at. Events come while the
    loop waits: at factor 0 a running loop applies them at the next boundary, which a block moves."""
    graph, log, clock = EncodingGraph(blocks), FakeLog(), FakeClock()
    loop = DynamicsLoop(replace(SETTINGS, engine=NUMBA, snapshot_period=0.007, backpressure_window=30, stop_at=0.2405,
                                clock_rate_hz=100.0), load_robot_parameters(None), graph, log,
                        Pacer(0, log.warning), clock=clock)
    graph.recorder = True
    loop.post(TRACKING)
    loop.post(plan(0.0, 0.0915))
    loop.post(RecordProgress(0))

    def until_waiting(limit: int = 400) -> None:
        for _ in range(limit):
            decision = loop.tick()
            if decision is Decision.HELD_BACK and graph.published:  # the recorder takes what went out
                loop.post(RecordProgress(codec.to_nanoseconds(graph.published[-1][0])))
            elif decision is not Decision.STEPPED:
                return
    until_waiting()
    loop.post(plan(0.05, 0.15))
    until_waiting()
    loop.post(Reset())  # back to t = 0, where the newest plan does not reach
    until_waiting()
    loop.post(plan(0.0, 0.3))
    until_waiting()
    return graph, loop, clock


@NEEDS_NUMBA
def test_blocks_of_steps_at_factor_0_publish_what_single_steps_publish_to_the_bit():
    """At factor 0 the loop takes blocks of steps (one kernel call, the messages encoded as arrays);
    the messages, their /clock flags, the snapshots and where it stops are those of one step per tick."""
    single, single_loop, _ = run_as_fast_as_possible(blocks=False)
    blocks, block_loop, _ = run_as_fast_as_possible(blocks=True)
    assert blocks.messages == single.messages
    assert [(s.steps, s.q, s.qd) for s in blocks.snapshots] == [(s.steps, s.q, s.qd) for s in single.snapshots]
    assert blocks.clocks == single.clocks and len(blocks.clocks) > 10
    assert block_loop.sim.t == single_loop.sim.t and str(block_loop.status) == str(single_loop.status)
    assert max(blocks.block_sizes) > 5 and sum(blocks.block_sizes) > 0.8 * len(blocks.messages)
    # the run: to the first plan's end, the second's, a reset at 0.149 s, then up to stop_at
    times = [t for t, _q in single.published]
    assert times.count(0.0) == 2 and abs(times[-1] - 0.24) < 1e-12


PACED_EVENTS = {0: [TRACKING, plan(0.0, 0.3)], 33: [ConstraintSwitch(TRACKING.selection, BaumgarteGains(8.0, 8.0))],
                61: [plan(0.05, 0.35)], 90: [Reset()], 95: [plan(0.0, 0.3)]}
"""New gains, a plan replaced, a reset and its new plan, by tick."""


def run_paced(blocks: bool, events: dict[int, list] = PACED_EVENTS, ticks: int = 220) -> EncodingGraph:
    """A paced tracking run on the numba engine (factor 20: a short sleep a step) with ``events`` between its
    states, and a recorder's progress every 7 ticks."""
    graph, log = EncodingGraph(blocks), FakeLog()
    loop = DynamicsLoop(replace(SETTINGS, engine=NUMBA, real_time_factor=20.0, snapshot_period=0.05, clock_rate_hz=100.0),
                        load_robot_parameters(None), graph, log, Pacer(0, log.warning))
    for tick in range(ticks):
        for event in events.get(tick, []):
            loop.post(event)
        if tick % 7 == 3:
            loop.post(RecordProgress(codec.to_nanoseconds(graph.published[-1][0])))
        loop.tick()
    return graph


@NEEDS_NUMBA
def test_paced_blocks_publish_one_state_a_tick_and_an_event_drops_the_rest_of_the_block(monkeypatch):
    """Paced, the loop computes a block ahead and publishes one state a tick when due; an event (not a
    recorder's progress) drops the states not yet published and applies after the last one that was,
    as between single steps: the same messages, /clock flags and snapshots, to the bit."""
    sampled_ahead = []  # per block computed: whether its reference was sampled a state before, for it

    def compute_block(simulation, count, sampled=None, _compute=Simulation.compute_block):
        sampled_ahead.append(sampled is not None and sampled.sampled_for[3] == simulation.steps)
        return _compute(simulation, count, sampled)
    monkeypatch.setattr(Simulation, 'compute_block', compute_block)
    single, blocks = run_paced(blocks=False), run_paced(blocks=True)
    # a block computed at the boundary after the last state published (lead 1: the start's, after an event)
    # samples its own reference; the others' was sampled a state before
    assert sampled_ahead.count(False) == blocks.leads.count(1) and sampled_ahead.count(True) >= 8
    assert blocks.messages == single.messages and len(single.messages) > 200
    assert [(s.steps, s.q, s.qd) for s in blocks.snapshots] == [(s.steps, s.q, s.qd) for s in single.snapshots]
    assert sum(blocks.block_sizes) > len(blocks.messages) + 10  # some states were computed and dropped
    assert max(blocks.block_sizes) == 20
    # the next block is encoded while the last state of the one before waits (computed one state earlier):
    # a block's boundary publishes without computing; after an event the block is computed there
    assert blocks.leads.count(2) >= 5 and set(blocks.leads) <= {1, 2}


@NEEDS_NUMBA
@pytest.mark.parametrize('renewal, recomputes', [
    ({61: [plan(0.05, 0.35)]}, False),  # the trajectory node's renewal: the same samples where they overlap
    ({68: [plan(0.05, 0.35, moved=(0.095, 1.0))]}, False),  # other samples only after the blocks computed
    ({61: [plan(0.05, 0.35, radius=0.81)]}, True),  # another reference
    ({61: [plan(0.05, 0.35, moved=(0.063, 0.066))]}, True),  # other samples in the steps just after the event
    ({68: [plan(0.05, 0.35, moved=(0.075, 1.0))]}, True),  # the block being published stays, the next one not
], ids=['renewal', 'differs-later', 'other-reference', 'differs-next', 'differs-in-the-next-block'])
def test_a_plan_that_gives_the_states_computed_ahead_keeps_them(renewal, recomputes):
    """A plan that gives the steps computed ahead (paced: the block being published and the next one) as the
    plan in force did, to the bit, keeps them; otherwise the steps it changes are dropped and computed again.
    Either way the messages and snapshots are the single steps'."""
    start = {0: [TRACKING, plan(0.0, 0.3)]}
    without = run_paced(blocks=True, events=start, ticks=120)
    single, blocks = run_paced(False, {**start, **renewal}, 120), run_paced(True, {**start, **renewal}, 120)
    assert blocks.messages == single.messages and len(blocks.messages) == 121
    assert [(s.steps, s.q, s.qd) for s in blocks.snapshots] == [(s.steps, s.q, s.qd) for s in single.snapshots]
    assert len(blocks.snapshots) == len(without.snapshots) + 1  # the plan's
    # a block computed at the boundary after the last state published (lead 1) is the start's, or a recomputation
    assert blocks.leads.count(1) == (2 if recomputes else 1) and without.leads.count(1) == 1
    assert blocks.block_sizes == without.block_sizes or recomputes


HANDED_OVER_EVENTS = {0: [TRACKING, plan(0.0, 0.3)],
                      33: [ConstraintSwitch(TRACKING.selection, BaumgarteGains(8.0, 8.0))],
                      61: [plan(0.05, 0.35, radius=0.81)], 90: [Reset(), plan(0.0, 0.3)],
                      150: [TorqueCommand((0.1, 0.2)), DRIVEN], 190: [TorqueCommand((-0.3, 0.2))]}
"""New gains, another reference, a reset and its new plan, then driven under two torques, by states published."""


class CountingPacer(Pacer):
    """Counts the loop's waits (each a wake-up when it sleeps)."""

    waits = 0

    def wait(self, *args, **kwargs) -> float:
        self.waits += 1
        return super().wait(*args, **kwargs)


def run_handed_over(blocks: bool, heard_every: int, applied_at: dict[int, int]) -> tuple[EncodingGraph, int]:
    """A paced run on the numba engine (factor 2) with ``HANDED_OVER_EVENTS`` posted once as many states as their
    key are out; ``applied_at`` maps each key to the count of states out when it was posted (filled in if empty,
    else used as the keys: a run of single steps then gets each event after the same state). Returns the graph
    and the loop's waits for 240 states."""
    graph, log = EncodingGraph(blocks, heard_every), FakeLog()
    pacer = CountingPacer(0, log.warning)
    loop = DynamicsLoop(replace(SETTINGS, engine=NUMBA, real_time_factor=2.0, snapshot_period=0.05, clock_rate_hz=40.0,
                                command_timeout=1.0), load_robot_parameters(None), graph, log,
                        pacer)
    given, pending, ticks = dict(applied_at), sorted(HANDED_OVER_EVENTS), 0
    while len(graph.published) < 240 and ticks < 1000:
        while pending and len(graph.published) >= given.get(pending[0], pending[0]):
            key = pending.pop(0)
            applied_at.setdefault(key, len(graph.published))
            for event in HANDED_OVER_EVENTS[key]:
                loop.post(event)
        loop.tick()
        ticks += 1
    return graph, pacer.waits


@NEEDS_NUMBA
@pytest.mark.parametrize('heard_every', [0, 7], ids=['nobody-outside', 'every-7th-heard'])
def test_states_nobody_outside_hears_are_handed_over_ahead_of_time_a_wake_up_a_block(heard_every):
    """Paced with no subscriber outside the process for a state (a composed recorder takes it from its tap), a
    block's states are handed over at once, ahead of their due times, up to the next one carrying /clock or heard
    outside (as a controller's control_odom), which waits until due: a wait (a wake-up) per block and per such
    state, not per state. Events apply after the last state handed over: the messages, /clock flags and snapshots
    are those of single steps given the same events after the same states, to the bit. Driven without lockstep
    (from state 150 on) each state waits until due, so a command applies within a step."""
    applied_at: dict[int, int] = {}
    early, early_waits = run_handed_over(True, heard_every, applied_at)
    single, single_waits = run_handed_over(False, 1, applied_at)
    heard, heard_waits = run_handed_over(True, 1, {})
    assert len(single.messages) == 240 and early.messages[:240] == single.messages
    kept = [(s.steps, s.q, s.qd) for s in single.snapshots]
    assert [(s.steps, s.q, s.qd) for s in early.snapshots][:len(kept)] == kept and len(kept) > 4
    assert sum(early.block_sizes) > len(early.messages)  # an event dropped states computed ahead
    # under the trajectory task, all but the states that wait until due (/clock, heard) after one wait a block
    driven = applied_at[150]
    assert early_waits < driven / 4 + (len(early.messages) - driven) and min(heard_waits, single_waits) > 200
    waited = [ahead == 0.0 for ahead in early.aheads]
    assert all(waited[index] for index, (_encoded, clock) in enumerate(early.messages) if clock)
    assert all(waited[index] for index, (t, _q) in enumerate(early.published) if heard_every and round(t / DT) % 7 == 0)
    assert not all(waited[:driven]) and all(waited[driven:]) and not any(heard.aheads) and len(early.clocks) > 8


DRIVEN_COMMANDS = {0: [DRIVEN], 4: [TorqueCommand((0.4, 0.3))], 57: [TorqueCommand((-0.2, 0.5))],
                   140: [TorqueCommand((0.1, 0.1))]}
"""A free-running driven run's commands by tick: each is 30 ms old (command_timeout) before the next comes."""


def run_driven(blocks: bool, factor: float, lockstep_every: int = 0, events: dict[int, list] = DRIVEN_COMMANDS,
               stop_at: float = 0.0, ticks: int = 260, heard_every: int = 1) -> tuple[EncodingGraph, FakeLog]:
    """A driven run on the numba engine at ``factor`` (20: paced, a short sleep a step) with ``events`` by tick;
    with ``lockstep_every``, a controller answers each state the loop waits on at once, with a torque of its time.
    ``heard_every``: which states a subscriber outside the process takes (``EncodingGraph``)."""
    graph, log = EncodingGraph(blocks, heard_every), FakeLog()
    loop = DynamicsLoop(replace(SETTINGS, engine=NUMBA, real_time_factor=factor, snapshot_period=0.05,
                                lockstep_every=lockstep_every, command_timeout=0.03, stop_at=stop_at, clock_rate_hz=100.0),
                        load_robot_parameters(None), graph, log, Pacer(0, log.warning))
    for tick in range(ticks):
        for event in events.get(tick, []):
            loop.post(event)
        if loop.tick() is Decision.LOCKSTEP:
            t = graph.published[-1][0]
            loop.post(TorqueCommand((0.5 * np.sin(20.0 * t), 0.4 * np.cos(15.0 * t))))
    return graph, log


@NEEDS_NUMBA
@pytest.mark.parametrize('factor, lockstep_every, events, stop_at, ticks, timeouts, largest, heard_every', [
    (20.0, 0, DRIVEN_COMMANDS, 0.0, 260, 3, BLOCK_PACED, 1),
    (20.0, 0, DRIVEN_COMMANDS, 0.0, 260, 3, BLOCK_PACED, 0),
    (20.0, 20, {0: [DRIVEN]}, 0.0, 260, 0, 19, 1),
    (20.0, 20, {0: [DRIVEN]}, 0.25, 300, 0, 19, 20),
    (0.0, 40, {0: [DRIVEN]}, 0.25, 300, 6, 30, 1)],  # answers at 0, 40, ..., 240 ms, each timed out 31 steps later
    ids=['paced-free', 'paced-free-unheard', 'paced-lockstep', 'paced-lockstep-control-odom', 'fast-lockstep'])
def test_driven_blocks_hold_one_torque_and_publish_what_single_steps_publish(factor, lockstep_every, events,
                                                                                 stop_at, ticks, timeouts, largest,
                                                                                 heard_every):
    """Driven, the loop takes blocks under the torque in force: a new command drops the states computed ahead
    and applies after the last one published; a block ends before the command times out (zero torque from
    there, said once) and at each lockstep state (the step after it waits for the answer). A new torque's
    first step is a single one (so the largest block after an answer is a step short of lockstep_every; at
    factor 0, the 30 steps left to the timeout). The messages, their wheel efforts included, and the snapshots
    are those of one step per tick, to the bit. With lockstep and only the lockstep states heard outside the
    process (a controller's control_odom), the others are handed over ahead of time; free-running, a command may
    come at any step, so each state waits until due even where nobody outside hears it."""
    (single, single_log), (blocks, block_log) = (run_driven(b, factor, lockstep_every, events, stop_at, ticks,
                                                            heard_every if b else 1) for b in (False, True))
    assert blocks.messages == single.messages and len(single.messages) > 240
    assert [(s.steps, s.q, s.qd) for s in blocks.snapshots] == [(s.steps, s.q, s.qd) for s in single.snapshots]
    timed_out = block_log.said('no wheel_torque_cmd for 0.03 s')
    assert timed_out == single_log.said('no wheel_torque_cmd for 0.03 s') and len(timed_out) == timeouts
    assert max(blocks.block_sizes) == largest and not single.block_sizes
    handed_over = [ahead > 0.0 for ahead in blocks.aheads]
    assert any(handed_over) == (factor > 0.0 and lockstep_every > 0 and heard_every != 1)
    assert not any(early for early, (t, _q) in zip(handed_over, blocks.published) if round(t / DT) % 20 == 0)


# --- faults ------------------------------------------------------------------------------------------
def model_steps(torques: list[tuple[float, float]], adhesion: dict[int, float] = {}) -> list[np.ndarray]:
    """The states of the driven model alone (no loop), the motor torque of each step given, and the adhesion force
    changed before the steps ``adhesion`` names: the independent account of what the loop's faults do."""
    robot = loop_module.robot_with(load_robot_parameters(None), 0.0)
    q0 = np.array([SETTINGS.initial_x, SETTINGS.initial_y, SETTINGS.initial_theta, 0, 0, 0, 0], dtype=float)
    sim = Simulation(robot, None, DRIVEN.selection, q0, np.zeros(7), dt=DT, gains=GAINS, engine=PYTHON)
    states = [sim.q.copy()]
    for step, torque in enumerate(torques):
        if step in adhesion:
            sim.set_adhesion_force(adhesion[step])
        sim.set_motor_torque(*torque)
        sim.step()
        states.append(sim.q.copy())
    return states


def test_scheduled_faults_apply_at_their_step_boundaries_as_the_model_with_those_inputs_does():
    """A left motor dead from 5 ms and the adhesion halved from 9 ms to 12 ms: the loop's states are the model's
    stepped with the delivered torques and the adhesion forces by hand, each change at its boundary, and every
    change is told to the graph once, stamped with its time, naming what changed and every fault value after it."""
    schedule = 'at=0.005 motor_efficiency_left=0.0; at=0.009 adhesion_scale=0.5; at=0.012 adhesion_scale=1.0'
    loop, graph, log, _clock = make_loop(fault_schedule=schedule)
    loop.post(DRIVEN)
    loop.post(TorqueCommand((1.0, 0.5)))
    ticks(loop, 15)
    applied = loop_module.robot_with(load_robot_parameters(None), 0.0).adsorption.applied_force
    expected = model_steps([(1.0, 0.5)] * 5 + [(0.0, 0.5)] * 10, {9: 0.5 * applied, 12: applied})
    assert [q.tolist() for _t, q in graph.published] == [q.tolist() for q in expected]
    assert [(round(change.t, 9), change.changed, change.cause) for change in graph.faults] == [
        (0.005, ('motor_efficiency_left',), 'scheduled'), (0.009, ('adhesion_scale',), 'scheduled'),
        (0.012, ('adhesion_scale',), 'scheduled')]
    assert dict(graph.faults[1].values) == {'adhesion_scale': 0.5, 'motor_efficiency_left': 0.0,
                                            'motor_efficiency_right': 1.0, 'drop_odom': False,
                                            'drop_wheel_states': False, 'drop_imu': False}
    assert log.said('scheduled faults: motor_efficiency_left = 0.0 at t = 0.005 s')


def test_a_fault_parameter_set_while_running_applies_at_the_next_boundary_and_is_told():
    loop, graph, _log, _clock = make_loop()
    loop.post(DRIVEN)
    loop.post(TorqueCommand((1.0, 1.0)))
    ticks(loop, 3)
    loop.post(ParameterChange({'motor_efficiency_right': 0.25}))
    loop.tick()
    assert loop.sim.motor_torque == (1.0, 0.25)
    assert [(change.t, change.changed, change.cause) for change in graph.faults] == [
        (pytest.approx(0.003), ('motor_efficiency_right',), 'parameter')]


def test_faults_set_at_start_are_told_at_t0():
    loop, graph, _log, _clock = make_loop(drop_wheel_states=True, adhesion_scale=2.0)
    loop.post(DRIVEN)
    loop.tick()
    assert [(change.t, change.changed, change.cause) for change in graph.faults] == [
        (0.0, ('adhesion_scale', 'drop_wheel_states'), 'start')]


def test_a_dropout_silences_its_topics_and_lockstep_waits_for_no_answer_to_what_the_controller_did_not_get():
    """drop_odom silences odom and control_odom (the controller's sensor) for the states after its boundary:
    lockstep waits for no answer to those, and again for the answer to the first state the controller gets."""
    loop, graph, _log, _clock = make_loop(lockstep_every=2, fault_schedule='at=0.002 drop_odom=true; at=0.006 '
                                                                            'drop_odom=false')
    loop.post(DRIVEN)
    assert loop.tick() is Decision.LOCKSTEP  # t = 0 went out: its answer is awaited
    loop.post(TorqueCommand((0.1, 0.1)))
    assert ticks(loop, 3) == [Decision.STEPPED, Decision.STEPPED, Decision.LOCKSTEP]  # 2 ms went out before the fault
    assert loop.silenced == {topics.ODOM, topics.CONTROL_ODOM} and loop.sim.steps == 2
    loop.post(TorqueCommand((0.1, 0.1)))
    assert ticks(loop, 6) == [Decision.STEPPED] * 6 and loop.sim.steps == 8  # 4 and 6 ms were silent
    assert loop.silenced == frozenset()
    assert loop.tick() is Decision.LOCKSTEP  # 8 ms went out again: its answer is awaited
    loop.post(ParameterChange({'drop_wheel_states': True}))
    loop.post(TorqueCommand((0.1, 0.1)))
    loop.tick()
    assert loop.silenced == {topics.WHEEL_STATES} and loop.sim.steps == 9


def diagnosed(loop: DynamicsLoop) -> codec.Status:
    """The dynamics' /diagnostics status as the node builds it from ``loop`` (its loop figures zero)."""
    motor, saturated = loop.saturation.report()
    figures = messages.LoopFigures(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 'normal')
    return messages.simulation_status('/wallbot/dynamics', str(loop.status), False, loop.command_state(), loop.sim.t,
                                      figures, 0.0, 0.0, loop.sim.selection.label(), loop.robot.adsorption,
                                      motor=motor, saturated=saturated)


def test_the_diagnostics_name_a_saturated_motor_since_when_commanded_and_applied():
    """A 4 N m stall torque, 20 rad/s no-load speed: 50 N m on the left from rest saturates it from t = 0, each step
    applying T_s (1 - w/w_0) at its wheels' speed w there (the model's envelope, computed here from the state), while
    the right's 0.5 N m is applied; a command inside the envelope ends it, and the next saturation has its own start."""
    motor = MotorParameters(stall_torque=4.0, no_load_speed=20.0)
    loop, _graph, _log, _clock = make_loop(load_robot_parameters(None).replace(motor=motor))
    loop.post(DRIVEN)
    loop.post(TorqueCommand((50.0, 0.5)))
    ticks(loop, 20)
    speed = 0.5 * float(loop.last_outputs.qd[3] + loop.last_outputs.qd[4])  # the left wheels' now
    loop.tick()  # the step from now
    left, right = loop.saturation.sides
    assert 0.5 < speed < 20.0 and (left.commanded, left.saturated_since) == (50.0, 0.0)
    assert left.applied == pytest.approx(4.0 * (1.0 - speed / 20.0), rel=1e-12)
    assert (right.commanded, right.applied, right.saturated_since) == (0.5, 0.5, None)
    status = diagnosed(loop)
    values = dict(status.values)
    assert status.level == 'warn' and 'motor saturated: left since t = 0.000 s (commanded 50 N m, applied' in status.message
    assert 'right since' not in status.message
    assert values['left motor saturated since (s)'] == 0.0 and values['right motor saturated since (s)'] == 'not saturated'
    assert values['left motor applied (N m)'] == left.applied and values['right motor commanded (N m)'] == 0.5
    loop.post(TorqueCommand((0.5, 0.5)))
    loop.tick()
    assert [side.saturated_since for side in loop.saturation.sides] == [None, None]
    assert diagnosed(loop).level == 'ok' and 'saturated' not in diagnosed(loop).message
    loop.post(TorqueCommand((0.5, -50.0)))
    ticks(loop, 3)
    assert [side.saturated_since for side in loop.saturation.sides] == [None, pytest.approx(0.022)]
    assert loop.saturation.sides[1].applied == -4.0  # braking against forward wheels: the current limit, T_s


def test_without_a_motor_block_the_diagnostics_carry_no_motor_entries():
    loop, _graph, _log, _clock = make_loop()
    loop.post(DRIVEN)
    loop.post(TorqueCommand((50.0, 0.5)))
    ticks(loop, 3)
    assert loop.saturation.sides == () and not any('motor' in key for key, _value in diagnosed(loop).values)


def test_a_strict_lockstep_ends_the_run_naming_the_state_left_unanswered():
    loop, graph, log, clock = make_loop(lockstep_every=1, strict_lockstep=True, lockstep_timeout=0.5)
    loop.post(DRIVEN)
    assert loop.tick() is Decision.LOCKSTEP
    loop.post(TorqueCommand((0.1, 0.1)))
    assert ticks(loop, 2) == [Decision.STEPPED, Decision.LOCKSTEP]
    clock.now += 0.5
    assert loop.tick() is Decision.LOCKSTEP and loop.gave_up is None  # the limit itself still waits
    clock.now += 0.01
    assert loop.tick() is Decision.LOCKSTEP and loop.stopping.is_set()
    assert loop.gave_up == 'no wheel_torque_cmd answering the state at t = 0.001 s within lockstep_timeout 0.5 s (wall)'
    assert loop.status.state is RunState.GAVE_UP and loop.in_error and graph.times == pytest.approx([0.0, DT])
    assert [message for level, message in log.lines if level == 'error'] == [
        f'{loop.gave_up} with strict_lockstep set; exiting']


def test_the_state_a_stop_stands_at_goes_out_as_a_snapshot():
    loop, graph, _log, _clock = make_loop(stop_at=0.004)
    loop.post(DRIVEN)
    ticks(loop, 8)
    assert graph.snapshots[-1].steps == 4 and graph.snapshots[-1].q == tuple(loop.sim.q)
    assert len([s for s in graph.snapshots if s.steps == 4]) == 1  # once, not at every tick of the stop


@pytest.mark.parametrize('text, reason', [
    ('at=1 motor_efficiency_left=1.5', "entry 1 ('at=1 motor_efficiency_left=1.5'): motor_efficiency_left must be in "
                                      '[0, 1], got 1.5'),
    ('at=1 drop_odom=true; motor_efficiency_left=0', 'entry 2 (\'motor_efficiency_left=0\'): at=T (the simulation '
                                                     'time, s) is missing'),
    ('at=-1 drop_odom=true', 'at must be a simulation time >= 0 (s), got \'-1\''),
    ('at=1 gain=2', "'gain' is no fault parameter (adhesion_scale, motor_efficiency_left, motor_efficiency_right, "
                    'drop_odom, drop_wheel_states, drop_imu)'),
    ('at=1', 'no fault parameter is set'),
    ('at=1 drop_odom', "expected NAME=VALUE, got 'drop_odom'"),
    ('at=1 drop_odom=yes', "drop_odom must be true or false, got 'yes'")])
def test_a_bad_fault_schedule_is_refused_naming_the_entry_and_why(text, reason):
    with pytest.raises(ValueError) as refused:
        parse_schedule(text)
    assert reason in str(refused.value) and '\n' not in str(refused.value)
    with pytest.raises(ValueError, match='fault_schedule entry'):
        make_loop(fault_schedule=text)


def test_a_schedule_reads_back_what_it_writes_in_time_order():
    entries = parse_schedule('at=2.5 adhesion_scale=0.6 ; at=0.5 motor_efficiency_right=0.0 drop_odom=true')
    assert [entry.at for entry in entries] == [0.5, 2.5]
    assert parse_schedule(schedule_text(entries)) == entries
    assert entries[0].changes == (('motor_efficiency_right', 0.0), ('drop_odom', True))


@NEEDS_NUMBA
def test_driven_blocks_end_at_scheduled_faults_and_publish_what_single_steps_publish():
    """On the compiled engine at factor 0 with lockstep every 20 steps, faults scheduled inside what would be a
    block apply at its boundary: the messages and the snapshots are those of one step per tick, to the bit."""
    schedule = 'at=0.013 motor_efficiency_left=0.3; at=0.031 adhesion_scale=0.7; at=0.052 motor_efficiency_left=1.0'
    runs = []
    for blocks in (False, True):
        graph, log = EncodingGraph(blocks), FakeLog()
        loop = DynamicsLoop(replace(SETTINGS, engine=NUMBA, lockstep_every=20, fault_schedule=schedule,
                                    snapshot_period=0.05, stop_at=0.08), load_robot_parameters(None), graph, log,
                            Pacer(0, log.warning))
        loop.post(DRIVEN)
        while loop.status.state is not RunState.STOPPED:
            if loop.tick() is Decision.LOCKSTEP:
                t = graph.published[-1][0]
                loop.post(TorqueCommand((0.5 * np.sin(20.0 * t), 0.4 * np.cos(15.0 * t))))
        runs.append(graph)
    single, blocks = runs
    assert blocks.messages == single.messages and len(single.messages) == 81
    assert [(s.steps, s.q, s.qd) for s in blocks.snapshots] == [(s.steps, s.q, s.qd) for s in single.snapshots]
    assert [(change.t, change.changed) for change in blocks.faults] == [
        (change.t, change.changed) for change in single.faults] and len(single.faults) == 3
    assert max(blocks.block_sizes) > 5


def test_a_pump_command_reaches_the_chamber_at_the_next_boundary_and_outlives_a_reset():
    """u = 0.5 from the start: dp relaxes to the chamber's balance at half flow (tau about 23 ms, so within 0.1 % after
    0.3 s) and a reset's new simulation keeps the command; a robot without the adhesion block refuses it in one
    line and runs at full command."""
    vacuum = load_robot_parameters(None).replace(adhesion={
        'chamber_area': 0.02, 'chamber_volume': 0.002, 'pump_max_pressure': 12000.0, 'pump_max_flow': 0.01,
        'leak_area': 2.0e-5})
    graph, log, clock = FakeGraph(), FakeLog(), FakeClock()
    loop = DynamicsLoop(SETTINGS, vacuum, graph, log, Pacer(0, log.warning), clock=clock)
    loop.post(DRIVEN)
    loop.post(PumpCommand(0.5))
    ticks(loop, 300)
    half = vacuum.adhesion.steady_pressure(vacuum.adhesion.leak_area, 0.5)
    assert loop.sim.pump_command == 0.5 and loop.sim.pressure == pytest.approx(half, rel=1e-3)
    assert half < 0.9 * vacuum.adhesion.steady_pressure(vacuum.adhesion.leak_area, 1.0)
    loop.post(Reset())
    ticks(loop, 1)
    assert loop.sim.t == pytest.approx(DT) and loop.sim.pump_command == 0.5
    plain, _graph, plain_log, _clock = make_loop()
    plain.post(DRIVEN)
    plain.post(PumpCommand(0.2))
    ticks(plain, 2)
    assert plain.sim.pump_command == 1.0
    assert plain_log.said('pump_command 0.2 ignored: the robot file has no adhesion block')
