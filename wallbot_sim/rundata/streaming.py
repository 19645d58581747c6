"""The summary of a recorded run in one pass over its bag, message by message: the time it takes grows
with the bag, and what it holds does not (a few figures per topic, the plan samples around the states
being read, and the states whose reference has not been read yet).

The figures are those of ``load.load_run`` followed by ``summary.summarize_run``, read the same way: the
state from ``ground_truth/odom`` when the bag has it (a run with sensor noise), else ``odom``; the
reference of each state from the recorded plan (quintic Hermite), else from the reference poses (exact
stamps, linear in between); the residual from the dynamics' ``/diagnostics`` in the odometry's
namespace; every topic's figures of its last run (after the last jump back of its stamps).
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from pathlib import Path
from typing import Callable

from wallbot_msgs_py import codec
from wallbot_sim.messages import plan_is_final
from wallbot_sim.model import ModelError, SampledReference
from wallbot_sim.model.trajectories import Plan
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.rundata.bag_run import STAMPED_SERIES, bag_topics, namespace_of, residual_max
from wallbot_sim.rundata.summary import sliding_wheels

PENDING_STATES = 20_000
"""Most states held while the reference at their time has not been read yet (20 s at 1 kHz): a plan or a
pose is logged after the states it covers only when its subscriber lagged the tap; past this many
the oldest is compared with the reference read so far."""
PLAN_MARGIN_NS = 1_000_000_000
"""Plan samples kept before the oldest state still to be compared (the interpolation needs the two around it)."""
PROGRESS_EVERY = 4096
"""Messages between two calls of the progress callback."""


class _Peaks:
    """The largest |value| of each of ``width`` channels (NaN until a finite one)."""

    def __init__(self, width: int) -> None:
        self.values = [math.nan] * width

    def add(self, values: tuple[float, ...]) -> None:
        peaks = self.values
        for i, value in enumerate(values):
            size = abs(value)
            if size == size and not size <= peaks[i]:  # NaN never enters; a NaN peak is replaced
                peaks[i] = size


class _Stream:
    """A topic's stamps, and when they jump back (the dynamics reset or restarted)."""

    def __init__(self) -> None:
        self.latest = -1
        self.restarts = 0

    def restarted(self, stamp_ns: int) -> bool:
        back = stamp_ns < self.latest
        self.restarts += back
        self.latest = stamp_ns
        return back


class _PlanReference:
    """The recorded plans as one reference: later plans override earlier samples at the same time."""

    def __init__(self) -> None:
        self.samples: dict[int, tuple] = {}
        self.reference = None
        self.from_ns = self.until_ns = -1
        self.final = False

    def add(self, data: bytes, keep_from_ns: int) -> None:
        try:
            plan = Plan(*codec.decode_plan(data))
        except ValueError:
            return
        for sample in zip(*plan):
            self.samples[codec.to_nanoseconds(sample[0])] = sample[1:]
        oldest = min(keep_from_ns, codec.to_nanoseconds(plan.times[0])) - PLAN_MARGIN_NS
        for stamp in [stamp for stamp in self.samples if stamp < oldest]:
            del self.samples[stamp]
        times = sorted(self.samples)
        try:
            self.reference = SampledReference([k * 1e-9 for k in times], *(
                [self.samples[k][i] for k in times] for i in range(3)))
        except ModelError:
            return
        self.from_ns, self.until_ns, self.final = times[0], times[-1], plan_is_final(plan)

    def covers(self, stamp_ns: int) -> bool:
        return self.reference is not None and self.from_ns <= stamp_ns and (stamp_ns <= self.until_ns or self.final)

    def position(self, stamp_ns: int) -> tuple[float, float]:
        return self.reference.sample(stamp_ns * 1e-9).position if self.reference is not None else (math.nan, math.nan)


class _PoseReference:
    """The reference poses of the last run: exact at their stamps, linear in between, held beyond the ends."""

    def __init__(self) -> None:
        self.stamps: list[int] = []
        self.xy: list[tuple[float, float]] = []

    def add(self, data: bytes, keep_from_ns: int) -> None:
        pose = codec.decode_odometry(data)
        if self.stamps and pose.stamp_ns < self.stamps[-1]:
            self.stamps, self.xy = [], []
        keep = max(bisect.bisect_left(self.stamps, keep_from_ns) - 1, 0)
        if keep > 1000:  # the poses before the states still to be compared are not needed
            del self.stamps[:keep], self.xy[:keep]
        self.stamps.append(pose.stamp_ns)
        self.xy.append((pose.x, pose.y))

    def covers(self, stamp_ns: int) -> bool:
        return bool(self.stamps) and self.stamps[-1] >= stamp_ns

    def position(self, stamp_ns: int) -> tuple[float, float]:
        stamps = self.stamps
        if not stamps:
            return math.nan, math.nan
        k = bisect.bisect_left(stamps, stamp_ns)
        if k < len(stamps) and stamps[k] == stamp_ns or k == len(stamps):
            return self.xy[min(k, len(stamps) - 1)]
        if k == 0:
            return self.xy[0]
        (x0, y0), (x1, y1), t0, t1 = self.xy[k - 1], self.xy[k], stamps[k - 1], stamps[k]
        w = (stamp_ns - t0) / (t1 - t0)
        return x0 + w * (x1 - x0), y0 + w * (y1 - y0)


class _Tracking:
    """The states of the last run: their span, and their tracking errors once the reference at each is read."""

    def __init__(self, reference: _PlanReference | _PoseReference | None) -> None:
        self.reference = reference
        self.stream = _Stream()
        self._reset()

    def _reset(self) -> None:
        self.first_ns: int | None = None
        self.last_ns, self.count = 0, 0
        self.pending: deque[tuple[int, float, float]] = deque()
        self.final = self.peak = self.peak_after_5s = math.nan

    def state(self, data: bytes) -> None:
        state = codec.decode_odometry(data).planar_state()
        if self.stream.restarted(state.stamp_ns):
            self._reset()
        elif self.first_ns is not None and state.stamp_ns == self.last_ns:
            return  # the same state again (a resumed dynamics): counted once, as at its first time
        if self.first_ns is None:
            self.first_ns = state.stamp_ns
        self.last_ns, self.count = state.stamp_ns, self.count + 1
        if self.reference is not None:
            self.pending.append((state.stamp_ns, state.x, state.y))
            self.compare()

    def keep_from_ns(self) -> int:
        """The oldest stamp the reference must still answer for."""
        return self.pending[0][0] if self.pending else self.last_ns

    def compare(self, every: bool = False) -> None:
        """The errors of the pending states the reference covers (``every``: of all of them)."""
        pending, reference = self.pending, self.reference
        while pending and (every or reference.covers(pending[0][0]) or len(pending) > PENDING_STATES):
            stamp_ns, x, y = pending.popleft()
            ref_x, ref_y = reference.position(stamp_ns)
            error = math.hypot(x - ref_x, y - ref_y)
            if error == error:
                self.final = error
                self.peak = error if not error <= self.peak else self.peak
                if stamp_ns >= self.first_ns + 5_000_000_000 and not error <= self.peak_after_5s:
                    self.peak_after_5s = error


class _Contact:
    """The first slip, the first negative normal load and each wheel's peak friction use of the last run."""

    def __init__(self) -> None:
        self.stream = _Stream()
        self.first_slip: tuple[float, str] | None = None
        self.lift_off: tuple[float, int, float] | None = None
        self.use = _Peaks(4)

    def add(self, data: bytes) -> None:
        contact = codec.decode_wheel_contact(data)
        if self.stream.restarted(contact.stamp_ns):
            self.first_slip = self.lift_off = None
            self.use = _Peaks(4)
        t = contact.stamp_ns * 1e-9
        self.use.add(contact.use)
        if self.first_slip is None and any(flag > 0.5 for flag in contact.slipping):
            self.first_slip = (t, sliding_wheels([flag > 0.5 for flag in contact.slipping]))
        loads = [1.0 if math.isnan(load) else load for load in contact.loads]
        if self.lift_off is None and min(loads) < 0.0:
            wheel = loads.index(min(loads))
            self.lift_off = (t, wheel + 1, contact.loads[wheel])


class _PeakStream:
    """Peaks of a per-step topic's values over its last run."""

    def __init__(self, read: Callable[[bytes], tuple[int, tuple[float, ...]]], width: int) -> None:
        self.read, self.width = read, width
        self.stream, self.peaks = _Stream(), _Peaks(width)

    def add(self, data: bytes) -> None:
        stamp_ns, values = self.read(data)
        if self.stream.restarted(stamp_ns):
            self.peaks = _Peaks(self.width)
        self.peaks.add(values)


class _Residual(_PeakStream):
    """The largest residual the dynamics in ``namespace`` reported over its last run."""

    def __init__(self, namespace: str) -> None:
        super().__init__(self._residual, 2)
        self.namespace = namespace

    def _residual(self, data: bytes) -> tuple[int, tuple[float, ...]]:
        found = residual_max(data, self.namespace)
        return (self.stream.latest, ()) if found is None else (found[0], found[1:])


def summarize_bag(path: Path, progress: Callable[[float, float], None] | None = None):
    """The ``summary.RunSummary`` of the bag at ``path``, read once. ``progress(done, total)`` is called
    every few thousand messages with the log time read and the bag's (s). RunDataError / BagError."""
    from wallbot_sim.bag.reader import info, messages
    from wallbot_sim.rundata.summary import RunSummary

    bag = info(path)
    leaves = bag_topics(bag)
    counts = {topic.name: topic.count for topic in bag.topics}
    source = ('reference_trajectory' if counts.get(leaves.get('reference_trajectory'), 0) else
              'reference' if counts.get(leaves.get('reference'), 0) else None)
    reference = {'reference_trajectory': _PlanReference, 'reference': _PoseReference}.get(source, lambda: None)()
    tracking, contact = _Tracking(reference), _Contact()
    wrench, drive = (_PeakStream(*STAMPED_SERIES[leaf]) for leaf in ('constraint_wrench', 'drive_forces'))
    residual = _Residual(namespace_of(leaves['odom']))
    readers: dict[str, Callable[[bytes], None]] = {
        'ground_truth' if 'ground_truth' in leaves else 'odom': tracking.state, 'constraint_wrench': wrench.add,
        'drive_forces': drive.add, 'wheel_contact': contact.add, 'diagnostics': residual.add}
    if source is not None:
        readers[source] = lambda data: (reference.add(data, tracking.keep_from_ns()), tracking.compare())
    names = {leaves[leaf]: read for leaf, read in readers.items() if leaf in leaves}
    for index, raw in enumerate(messages(path, list(names))):
        try:
            names[raw.topic](raw.data)
        except ValueError as error:
            raise RunDataError(f'{path}: {raw.topic}: {error}') from None
        if progress is not None and index % PROGRESS_EVERY == 0:
            progress((raw.timestamp - bag.start_ns) * 1e-9, bag.duration)
    if tracking.first_ns is None:
        raise RunDataError(f'{path} has no odometry messages')
    if reference is not None:
        tracking.compare(every=True)
    return RunSummary(Path(path), (tracking.last_ns - tracking.first_ns) * 1e-9, tracking.count, tracking.final,
                      tracking.peak, tracking.peak_after_5s, *wrench.peaks.values, *drive.peaks.values,
                      *residual.peaks.values, tracking.stream.restarts, contact.first_slip, contact.lift_off,
                      tuple(contact.use.values))
