"""The composed process's in-process tap (nodes.step_tap), without DDS: what a drain writes, in
which order, at which log time, and what it refuses after a stop."""

from __future__ import annotations

import itertools
import threading

from wallbot_msgs_py import topics
from wallbot_sim.nodes.step_tap import StepTap

NAMES = {topics.ODOM: '/wallbot/odom', topics.WHEEL_STATES: '/wallbot/wheel_states', topics.CLOCK: '/wallbot/clock'}


def step(index: int) -> list[tuple[topics.Topic, bytes]]:
    """A step's messages as StepEncoder orders them: odom, wheel_states, drive_forces, /clock last."""
    return [(topic, f'{topic.name}:{index}'.encode())
            for topic in (topics.ODOM, topics.WHEEL_STATES, topics.DRIVE_FORCES, topics.CLOCK)]


def tap_at(times: list[int]) -> StepTap:
    """A tap whose clock reads ``times`` one after another."""
    return StepTap(NAMES, iter(times).__next__)


def test_a_drain_writes_the_tapped_topics_of_every_step_in_order_at_its_log_time():
    tap = tap_at([100, 200, 250, 300])  # the last two: the drains' own times
    tap.put(step(0), clock=True)
    tap.put(step(1), clock=False)
    written = []
    assert tap.drain(lambda *entry: written.append(entry), floor_ns=0) == 0
    assert written == [
        (topics.ODOM, '/wallbot/odom', b'odom:0', 100), (topics.WHEEL_STATES, '/wallbot/wheel_states',
                                                         b'wheel_states:0', 100),
        (topics.CLOCK, '/wallbot/clock', b'clock:0', 100),
        # the second step's clock message was not sent, drive_forces is not tapped
        (topics.ODOM, '/wallbot/odom', b'odom:1', 200), (topics.WHEEL_STATES, '/wallbot/wheel_states',
                                                         b'wheel_states:1', 200)]
    assert tap.drain(lambda *entry: written.append(entry), floor_ns=0) == 0 and len(written) == 5


def test_log_times_never_go_back():
    # the floor: the last log time the recorder wrote (a DDS message's callback time); then a step
    # logged before the previous one (a wall clock stepped back) takes the previous one's time
    tap = tap_at([100, 300, 250, 400, 500])
    for index in range(4):
        tap.put(step(index), clock=True)
    written = []
    tap.drain(lambda *entry: written.append(entry), floor_ns=150)
    assert [log_ns for *_, log_ns in written[::3]] == [150, 300, 300, 400]


def test_after_a_stop_only_steps_logged_up_to_it_are_written_and_the_rest_are_counted():
    tap = tap_at([100, 200, 201, 300, 400])
    for index in range(4):
        tap.put(step(index), clock=index != 3)
    written = []
    refused = tap.drain(lambda *entry: written.append(entry), floor_ns=0, stopped_at=lambda: 200)
    assert [data for *_, data, _log in written] == [b'odom:0', b'wheel_states:0', b'clock:0',
                                                   b'odom:1', b'wheel_states:1', b'clock:1']
    assert refused == 3 + 2  # step 2 with its clock, step 3 without


def test_steps_put_by_another_thread_while_draining_arrive_whole_and_in_order():
    count = 20_000
    clock = itertools.count()
    tap = StepTap(NAMES, clock.__next__)
    done = threading.Event()

    def loop() -> None:
        for index in range(count):
            tap.put(step(index), clock=True)
        done.set()

    written = []
    producer = threading.Thread(target=loop)
    producer.start()
    while True:
        finished = done.is_set()  # then every step was put before this drain
        tap.drain(lambda *entry: written.append(entry), floor_ns=written[-1][3] if written else 0)
        if finished:
            break
    producer.join()
    assert [data for *_, data, _log in written] == [message for index in range(count)
                                                   for topic, message in step(index)
                                                   if topic in NAMES]
    step_times = [log_ns for *_, log_ns in written[::3]]  # each its own put time, the drains' between them
    assert all(earlier < later for earlier, later in itertools.pairwise(step_times))


def test_a_drain_reports_the_stamp_of_the_newest_step_it_wrote():
    """The recorder's progress comes from it (one stamp a step, not a parse of each message)."""
    tap = tap_at([100, 200, 300, 400])
    assert tap.newest_stamp_ns is None
    for index in range(3):
        tap.put(step(index), clock=True, stamp_ns=1_000_000 * index)
    tap.drain(lambda *entry: None, floor_ns=0, stopped_at=lambda: 200)  # the third step was logged after the stop
    assert tap.newest_stamp_ns == 1_000_000


def test_a_stop_requested_while_a_drain_runs_cuts_off_the_steps_the_loop_puts_after_it():
    """The signal handler runs between two bytecodes of a drain (both on the main thread) while the
    dynamics' loop thread goes on putting steps: none logged after the stop is written, by this
    drain or the next."""
    now = [100]
    tap = StepTap(NAMES, lambda: now[0])
    tap.put(step(0), clock=True)
    stop: list[int] = []

    def write_then_signal(*entry: object) -> None:
        written.append(entry)
        if not stop:  # the handler notes the stop at 160, the loop then puts a step at 170
            now[0] = 160
            stop.append(160)
            now[0] = 170
            tap.put(step(1), clock=True)

    written: list[tuple] = []
    now[0] = 150  # the drain's own time
    assert tap.drain(write_then_signal, floor_ns=0, stopped_at=lambda: stop[0] if stop else None) == 0
    assert [data for *_, data, _log in written] == [b'odom:0', b'wheel_states:0', b'clock:0']
    now[0] = 180  # the drain at the stop
    assert tap.drain(write_then_signal, floor_ns=0, stopped_at=lambda: stop[0]) == 3
    assert len(written) == 3


def test_a_step_handed_over_ahead_of_time_is_logged_and_written_when_it_is_due():
    """The paced dynamics hands a block's states to the tap ahead of their due times (nobody outside hears them):
    each is logged at its due time and no drain writes it before; after a stop, one due after it is refused."""
    now = [1_000]
    tap = StepTap(NAMES, lambda: now[0])
    for index in range(4):
        tap.put(step(index), clock=index == 0, stamp_ns=index, ahead=index * 1e-6)  # due 1 us apart from now
    written: list[tuple] = []
    now[0] = 2_500  # steps 0 and 1 are due, 2 and 3 not yet
    assert tap.drain(lambda *entry: written.append(entry), floor_ns=0) == 0
    assert [(data, log_ns) for *_, data, log_ns in written] == [
        (b'odom:0', 1_000), (b'wheel_states:0', 1_000), (b'clock:0', 1_000),
        (b'odom:1', 2_000), (b'wheel_states:1', 2_000)] and tap.newest_stamp_ns == 1
    now[0] = 3_500  # a stop at 3,200: step 2 (due at 3,000) is written, step 3 (4,000) refused and not kept
    assert tap.drain(lambda *entry: written.append(entry), floor_ns=0, stopped_at=lambda: 3_200) == 2
    assert [log_ns for *_, log_ns in written[5:]] == [3_000, 3_000] and tap.newest_stamp_ns == 2
    now[0] = 5_000
    assert tap.drain(lambda *entry: written.append(entry), floor_ns=0, stopped_at=lambda: 3_200) == 0
    assert len(written) == 7
