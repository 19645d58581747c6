"""Reference trajectories of the centre: position and its first three time derivatives.

The trajectory task needs position, velocity and acceleration; the tangent-heading task also
needs the jerk (its angular acceleration is the derivative of the path's turning rate).
"""

from __future__ import annotations

import bisect
import math
from array import array
from dataclasses import dataclass
from typing import NamedTuple, Protocol, Sequence

from wallbot_sim.model.errors import ParameterError
from wallbot_sim.model.numbers import POSITIVE

Vec2 = tuple[float, float]

_REST_SPEED = 1e-9
"""Below this reference speed (m/s) the tangent direction is undefined."""
STAMP_RESOLUTION = 1e-9
"""Sample times travel as whole-nanosecond stamps (s): a time this close to a sampled reference's span is in it."""


class ReferenceSample(NamedTuple):
    """The reference point and its derivatives at one instant (wall frame)."""

    position: Vec2
    velocity: Vec2
    acceleration: Vec2
    jerk: Vec2


class Heading(NamedTuple):
    """A heading and its first two time derivatives."""

    angle: float
    rate: float
    acceleration: float


class Reference(Protocol):
    """Anything that gives the reference point at a time."""

    def sample(self, t: float) -> ReferenceSample:
        """Position, velocity, acceleration and jerk at time t (s)."""
        ...


class LastSample:
    """A reference that keeps its latest sample: tasks evaluated at one instant share it."""

    def __init__(self, reference: Reference) -> None:
        self.reference = reference
        self._time: float | None = None
        self._sample: ReferenceSample | None = None

    def sample(self, t: float) -> ReferenceSample:
        if t != self._time:
            self._time, self._sample = t, self.reference.sample(t)
        return self._sample


def tangent_heading(sample: ReferenceSample) -> Heading | None:
    """th_d = atan2(yd, xd), its rate (xd ydd - yd xdd)/|v|^2 and that rate's derivative.

    None when the reference is at rest and so has no direction.
    """
    (vx, vy), (ax, ay), (jx, jy) = sample.velocity, sample.acceleration, sample.jerk
    speed2 = vx * vx + vy * vy
    if speed2 < _REST_SPEED * _REST_SPEED:
        return None
    cross_va = vx * ay - vy * ax
    rate = cross_va / speed2
    acceleration = (vx * jy - vy * jx) / speed2 - 2.0 * cross_va * (vx * ax + vy * ay) / (speed2 * speed2)
    return Heading(math.atan2(vy, vx), rate, acceleration)




@dataclass(frozen=True)
class Circle:
    """p_d = centre + R (cos wt, sin wt), w = 2 pi / period."""

    radius: float = 1.0
    period: float = 20.0
    center: Vec2 = (0.0, 0.0)

    def __post_init__(self) -> None:
        POSITIVE.check('radius', self.radius)
        POSITIVE.check('period', self.period)

    def sample(self, t: float) -> ReferenceSample:
        w = 2.0 * math.pi / self.period
        c, s = math.cos(w * t), math.sin(w * t)
        r1, r2, r3 = self.radius * w, self.radius * w * w, self.radius * w ** 3
        return ReferenceSample(
            (self.center[0] + self.radius * c, self.center[1] + self.radius * s),
            (-r1 * s, r1 * c), (-r2 * c, -r2 * s), (r3 * s, -r3 * c))


@dataclass(frozen=True)
class FigureEight:
    """p_d = centre + (A sin wt, (A/2) sin 2wt), w = 2 pi / period."""

    amplitude: float = 1.0
    period: float = 30.0
    center: Vec2 = (0.0, 0.0)

    def __post_init__(self) -> None:
        POSITIVE.check('amplitude', self.amplitude)
        POSITIVE.check('period', self.period)

    def sample(self, t: float) -> ReferenceSample:
        w, amp = 2.0 * math.pi / self.period, self.amplitude
        s1, c1, s2, c2 = math.sin(w * t), math.cos(w * t), math.sin(2 * w * t), math.cos(2 * w * t)
        return ReferenceSample(
            (self.center[0] + amp * s1, self.center[1] + 0.5 * amp * s2),
            (amp * w * c1, amp * w * c2),
            (-amp * w * w * s1, -2.0 * amp * w * w * s2),
            (-amp * w ** 3 * c1, -4.0 * amp * w ** 3 * c2))


@dataclass(frozen=True)
class SmoothStop:
    """Follows ``path`` until ``duration``, then slows to rest at a point over ``stop_time``.

    Time is warped: s(t) = t until the stop starts, then s' = 1 - 3u^2 + 2u^3 with
    u = (t - duration) / stop_time, so velocity and acceleration stay continuous and the
    reference ends at rest at path(duration + stop_time / 2).
    """

    path: Reference
    duration: float
    stop_time: float = 2.0

    def __post_init__(self) -> None:
        POSITIVE.check('duration', self.duration)
        POSITIVE.check('stop_time', self.stop_time)

    def _warp(self, t: float) -> tuple[float, float, float, float]:
        """s and its first three derivatives at t."""
        if t <= self.duration:
            return t, 1.0, 0.0, 0.0
        tau = self.stop_time
        u = min((t - self.duration) / tau, 1.0)
        s = self.duration + tau * (u - u ** 3 + 0.5 * u ** 4)
        if u >= 1.0:
            return s, 0.0, 0.0, 0.0
        return s, 1.0 - 3.0 * u * u + 2.0 * u ** 3, (-6.0 * u + 6.0 * u * u) / tau, (-6.0 + 12.0 * u) / tau ** 2

    def sample(self, t: float) -> ReferenceSample:
        s, s1, s2, s3 = self._warp(t)
        base = self.path.sample(s)
        (p1x, p1y), (p2x, p2y), (p3x, p3y) = base.velocity, base.acceleration, base.jerk
        return ReferenceSample(
            base.position,
            (p1x * s1, p1y * s1),
            (p2x * s1 * s1 + p1x * s2, p2y * s1 * s1 + p1y * s2),
            (p3x * s1 ** 3 + 3.0 * p2x * s1 * s2 + p1x * s3, p3y * s1 ** 3 + 3.0 * p2y * s1 * s2 + p1y * s3))


class SampledReference:
    """A reference given at sample times with position, velocity and acceleration.

    Between samples it is the quintic Hermite polynomial matching all three at both ends
    (continuous acceleration, so the trajectory task sees no jumps); more than STAMP_RESOLUTION
    before the first or after the last sample it holds that sample's position at rest.
    """

    def __init__(self, times: Sequence[float], positions: Sequence[Vec2],
                 velocities: Sequence[Vec2], accelerations: Sequence[Vec2]) -> None:
        if not (len(times) == len(positions) == len(velocities) == len(accelerations)) or len(times) < 2:
            raise ParameterError('a sampled reference needs >= 2 samples, each with position, velocity and acceleration')
        if any(t1 <= t0 for t0, t1 in zip(times, times[1:])):
            raise ParameterError('sample times of a reference must increase strictly')
        samples = [tuple(map(float, (*p, *v, *a))) for p, v, a in zip(positions, velocities, accelerations)]
        if any(len(s) != 6 for s in samples):
            raise ParameterError('every reference sample needs 2-D position, velocity and acceleration')
        if not all(math.isfinite(v) for v in (*times, *(x for s in samples for x in s))):
            raise ParameterError('a sampled reference must be finite')
        self.times = [float(t) for t in times]
        self._samples = samples
        self._segment = 0
        self._coefficients = self._segment_coefficients(0)

    @property
    def start(self) -> float:
        """Time of the first sample (s)."""
        return self.times[0]

    @property
    def end(self) -> float:
        """Time of the last sample (s)."""
        return self.times[-1]

    def sample(self, t: float) -> ReferenceSample:
        # The sample points themselves belong to the interpolated span, and so does a stamp's rounding
        # around them: a plan that starts at the current time (0.6 s, whose stamp reads back as
        # 0.6000000000000001), or the step that ends at a plan's last sample, must see it moving.
        times = self.times
        if t < times[0] - STAMP_RESOLUTION or t > times[-1] + STAMP_RESOLUTION:
            px, py = self._samples[0 if t < times[0] else -1][:2]
            return ReferenceSample((px, py), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
        k = self._segment
        if not times[k] <= t < times[k + 1]:  # the segment bisect would pick; mostly the last one
            k = self._segment = min(max(bisect.bisect_right(times, t) - 1, 0), len(times) - 2)
            self._coefficients = self._segment_coefficients(k)
        x = t - times[k]
        cx, cy = self._coefficients
        return ReferenceSample(*zip(_quintic(x, *cx), _quintic(x, *cy)))

    def agrees(self, other: SampledReference, t0: float, t1: float) -> bool:
        """Whether ``sample`` gives bit-identical values in both for every t in [t0, t1]: both interpolate there
        (t0 at or after each one's first sample, t1 before each one's last) between the same samples, to the bit.

        Two plans of one reference on one grid agree wherever they overlap (``sample_plan``); this checks it.
        """
        if not (max(self.times[0], other.times[0]) <= t0 <= t1 < min(self.times[-1], other.times[-1])):
            return False
        mine, theirs = self._samples_over(t0, t1), other._samples_over(t0, t1)
        return array('d', mine).tobytes() == array('d', theirs).tobytes()  # bits: 0.0 and -0.0 differ

    def _samples_over(self, t0: float, t1: float) -> list[float]:
        """The times and samples of the segments that ``sample`` uses for t in [t0, t1], flat."""
        first = bisect.bisect_right(self.times, t0) - 1
        last = bisect.bisect_right(self.times, t1)
        return [value for k in range(first, last + 1) for value in (self.times[k], *self._samples[k])]

    def _segment_coefficients(self, k: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
        h = self.times[k + 1] - self.times[k]
        p0x, p0y, v0x, v0y, a0x, a0y = self._samples[k]
        p1x, p1y, v1x, v1y, a1x, a1y = self._samples[k + 1]
        return (_quintic_coefficients(h, p0x, v0x, a0x, p1x, v1x, a1x),
                _quintic_coefficients(h, p0y, v0y, a0y, p1y, v1y, a1y))


def _quintic_coefficients(h: float, p0: float, v0: float, a0: float,
                          p1: float, v1: float, a1: float) -> tuple[float, ...]:
    """c0..c5 of the quintic on [0, h] matching position, velocity and acceleration at both ends."""
    d = p1 - (p0 + v0 * h + 0.5 * a0 * h * h)
    e = (v1 - (v0 + a0 * h)) * h
    f = (a1 - a0) * h * h
    return (p0, v0, 0.5 * a0, (10.0 * d - 4.0 * e + 0.5 * f) / h ** 3, (-15.0 * d + 7.0 * e - f) / h ** 4,
            (6.0 * d - 3.0 * e + 0.5 * f) / h ** 5)


def _quintic(x: float, c0: float, c1: float, c2: float, c3: float, c4: float,
             c5: float) -> tuple[float, float, float, float]:
    """Value and first three derivatives at x of c0 + c1 x + ... + c5 x^5."""
    return (c0 + x * (c1 + x * (c2 + x * (c3 + x * (c4 + x * c5)))),
            c1 + x * (2.0 * c2 + x * (3.0 * c3 + x * (4.0 * c4 + x * 5.0 * c5))),
            2.0 * c2 + x * (6.0 * c3 + x * (12.0 * c4 + x * 20.0 * c5)),
            6.0 * c3 + x * (24.0 * c4 + x * 60.0 * c5))


class Plan(NamedTuple):
    """A reference sampled on a time grid: what the trajectory node publishes as its plan."""

    times: list[float]
    positions: list[Vec2]
    velocities: list[Vec2]
    accelerations: list[Vec2]


def sample_plan(reference: Reference, start: float, end: float, sample_dt: float) -> Plan:
    """Sample ``reference`` at the grid times k * sample_dt covering [start, end].

    The grid is anchored at t = 0, not at ``start``: k runs from floor(start / sample_dt) to
    ceil(end / sample_dt) (at least two samples), so two plans of the same reference that
    overlap share their sample points exactly, and a SampledReference built from either gives
    bit-identical values there. That is what makes replanning ahead invisible to the dynamics.
    """
    POSITIVE.check('sample_dt', sample_dt)
    if not (math.isfinite(start) and math.isfinite(end) and end >= start >= 0.0):
        raise ParameterError(f'a plan needs finite times 0 <= start <= end, got [{start!r}, {end!r}]')
    first = math.floor(start / sample_dt + 1e-9)
    last = max(math.ceil(end / sample_dt - 1e-9), first + 1)
    times = [k * sample_dt for k in range(first, last + 1)]
    samples = [reference.sample(t) for t in times]
    return Plan(times, [s.position for s in samples], [s.velocity for s in samples],
                [s.acceleration for s in samples])
