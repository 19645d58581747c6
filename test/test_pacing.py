"""The dynamics loop's pacer: due times, no drift, re-anchoring, real-time priority and its guards.

Time is virtual (a fake perf_counter/sleep) except in the one test that checks the real
scheduling policy of a thread, so nothing here depends on how busy the machine is.
"""

from __future__ import annotations

import os
import threading

import pytest

from scheduling_helpers import VirtualTime, may_use_fifo
from wallbot_sim.loop import pacing
from wallbot_sim.loop.pacing import Pacer


class Scheduler:
    """Stands in for os.sched_setscheduler: records the priorities set, or refuses them."""

    def __init__(self, refuse: bool = False) -> None:
        self.refuse = refuse
        self.calls: list[int] = []

    def __call__(self, pid: int, policy: int, param) -> None:
        if self.refuse and policy == os.SCHED_FIFO:
            raise PermissionError(1, 'Operation not permitted')
        self.calls.append(param.sched_priority if policy == os.SCHED_FIFO else 0)


@pytest.fixture
def clock(monkeypatch):
    virtual = VirtualTime()
    monkeypatch.setattr(pacing, 'time', virtual)
    return virtual


@pytest.fixture
def scheduler(monkeypatch):
    fake = Scheduler()
    monkeypatch.setattr(os, 'sched_setscheduler', fake)
    return fake


def run_steps(pacer: Pacer, clock: VirtualTime, steps: range, factor: float, dt: float = 1e-3,
              compute: float = 0.0) -> list[float]:
    """Wait for each step after ``compute`` seconds of work; the lateness of each."""
    stopping = threading.Event()
    lateness = []
    for step in steps:
        clock.now += compute
        lateness.append(pacer.wait(step, dt, lambda: factor, stopping))
    return lateness


def test_steps_are_due_on_a_fixed_grid_without_drift(clock, scheduler):
    """Each wake-up overshoots by 0.3 ms, yet step k is still due at anchor + k dt / f."""
    clock.overshoot = 3e-4
    warnings: list[str] = []
    pacer = Pacer(0, warnings.append)
    start = clock.now
    lateness = run_steps(pacer, clock, range(1, 2001), factor=2.0, compute=1e-4)
    assert lateness == pytest.approx([3e-4] * 2000, abs=1e-9)
    assert clock.now == pytest.approx(start + 1e-4 + 2000 * 0.5e-3 + 3e-4, abs=1e-9)
    assert warnings == [] and scheduler.calls == []


def test_factor_zero_never_waits_and_keeps_normal_scheduling(clock, scheduler):
    pacer = Pacer(50, [].append)
    assert run_steps(pacer, clock, range(1, 100), factor=0.0, compute=1e-4) == [0.0] * 99
    assert clock.sleeps == 0 and scheduler.calls == [] and pacer.applied_priority == 0


def test_factor_change_while_waiting_makes_the_step_due_and_reanchors(clock, scheduler):
    pacer = Pacer(0, [].append)
    stopping = threading.Event()
    pacer.wait(1, 1.0, lambda: 1.0, stopping)
    factors = iter([1.0])  # read at the start; after the first sleep slice it is 4
    began = clock.now
    assert pacer.wait(2, 1.0, lambda: next(factors, 4.0), stopping) == 0.0
    assert clock.now == pytest.approx(began + pacing.LONGEST_SLEEP)  # one slice, not the whole second
    changed = clock.now
    pacer.wait(3, 1.0, lambda: 4.0, stopping)
    pacer.wait(4, 1.0, lambda: 4.0, stopping)
    assert clock.now == pytest.approx(changed + 0.5)  # a new segment at 4 s of simulation per second


def test_priority_held_while_paced_and_released_at_factor_zero(clock, scheduler):
    pacer = Pacer(50, [].append)
    run_steps(pacer, clock, range(1, 10), factor=1.0)
    assert pacer.applied_priority == 50 and scheduler.calls == [50]
    run_steps(pacer, clock, range(10, 20), factor=0.0)
    assert pacer.applied_priority == 0 and scheduler.calls == [50, 0]
    pacer.priority = 20
    run_steps(pacer, clock, range(20, 30), factor=1.0)
    assert scheduler.calls == [50, 0, 20]


def test_a_loop_catching_up_runs_under_the_normal_scheduler(clock, scheduler):
    """A step already due when its wait begins never sleeps: holding FIFO then would starve the machine."""
    pacer = Pacer(50, [].append)
    run_steps(pacer, clock, range(1, 3), factor=1.0)
    assert scheduler.calls == [50]
    run_steps(pacer, clock, range(3, 500), factor=1.0, compute=2e-3)  # 2 ms a step: falls behind
    assert scheduler.calls == [50, 0] and pacer.applied_priority == 0
    run_steps(pacer, clock, range(500, 1500), factor=1.0)  # caught up: sleeping again
    assert scheduler.calls == [50, 0, 50] and pacer.applied_priority == 50


def test_refused_priority_warns_once_and_runs_normally(clock, monkeypatch):
    monkeypatch.setattr(os, 'sched_setscheduler', Scheduler(refuse=True))
    warnings: list[str] = []
    pacer = Pacer(50, warnings.append)
    lateness = run_steps(pacer, clock, range(1, 100), factor=1.0, compute=1e-4)
    assert max(lateness) == pytest.approx(0.0, abs=1e-12)  # still paced
    assert pacer.applied_priority == 0 and pacer.policy == 'normal (SCHED_FIFO 50 not permitted)'
    assert len(warnings) == 1 and warnings[0].startswith('realtime_priority 50 not applied (Operation not permitted)')


def test_policy_states_the_decision_before_any_step_sleeps(clock, scheduler):
    pacer = Pacer(0, [].append)
    assert pacer.policy == 'normal'
    pacer.priority = 50
    assert pacer.policy == 'SCHED_FIFO 50 while paced' and pacer.applied_priority == 0
    run_steps(pacer, clock, range(1, 5), factor=0.0)  # nothing sleeps at factor 0: the decision stands
    assert pacer.policy == 'SCHED_FIFO 50 while paced' and scheduler.calls == []


def test_real_policy_applies_to_the_loop_thread_only():
    """Not faked: the policy is set on the calling (loop) thread, never on the whole process."""
    seen, warnings = {}, []

    def loop() -> None:
        pacer = Pacer(10, warnings.append)
        pacer.wait(1, 1e-4, lambda: 1.0, threading.Event())
        seen['paced'] = os.sched_getscheduler(0)
        pacer.wait(2, 1e-4, lambda: 0.0, threading.Event())
        seen['factor 0'] = os.sched_getscheduler(0)

    thread = threading.Thread(target=loop)
    thread.start()
    thread.join(timeout=10)
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # this (main) thread is untouched
    if may_use_fifo():
        assert seen == {'paced': os.SCHED_FIFO, 'factor 0': os.SCHED_OTHER} and warnings == []
    else:
        assert seen == {'paced': os.SCHED_OTHER, 'factor 0': os.SCHED_OTHER}
        assert len(warnings) == 1 and 'not applied' in warnings[0]
