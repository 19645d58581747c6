"""Reference trajectories: analytic derivatives against finite differences, interpolation accuracy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wallbot_sim import messages
from wallbot_sim.model import Circle, FigureEight, ParameterError, SampledReference, SmoothStop, tangent_heading
from wallbot_sim.model.trajectories import sample_plan


def derivative(fn, t, h=1e-5):
    return (np.array(fn(t + h)) - np.array(fn(t - h))) / (2 * h)


@pytest.mark.parametrize('reference', [Circle(1.0, 20.0, (0.5, -0.2)), FigureEight(1.0, 30.0),
                                       SmoothStop(FigureEight(1.0, 10.0), 4.0, 2.0)], ids=repr)
def test_derivatives_are_consistent(reference):
    for t in np.linspace(0.1, 7.9, 40):
        s = reference.sample(t)
        assert np.allclose(derivative(lambda x: reference.sample(x).position, t), s.velocity, atol=1e-7)
        assert np.allclose(derivative(lambda x: reference.sample(x).velocity, t), s.acceleration, atol=1e-7)
        if not any(abs(t - edge) < 1e-3 for edge in (4.0, 6.0)):  # jerk jumps where the stop starts and ends
            assert np.allclose(derivative(lambda x: reference.sample(x).acceleration, t), s.jerk, atol=1e-6)


def test_paper_paths():
    circle, eight = Circle(), FigureEight()
    for t in np.linspace(0, 30, 31):
        x, y = circle.sample(t).position
        assert math.hypot(x, y) == pytest.approx(1.0)
        w = 2 * math.pi / 30
        assert eight.sample(t).position == pytest.approx((math.sin(w * t), 0.5 * math.sin(2 * w * t)))
    assert eight.sample(0.0).velocity == pytest.approx((2 * math.pi / 30, 2 * math.pi / 30))


def test_tangent_heading_rate_is_the_derivative_of_the_angle():
    eight = FigureEight()
    for t in np.linspace(0.3, 29.7, 30):
        heading = tangent_heading(eight.sample(t))
        angle = lambda x: tangent_heading(eight.sample(x)).angle
        rate = lambda x: tangent_heading(eight.sample(x)).rate
        change = math.remainder(angle(t + 1e-5) - angle(t - 1e-5), 2 * math.pi) / 2e-5
        assert heading.rate == pytest.approx(change, abs=1e-6)
        assert heading.acceleration == pytest.approx(derivative(rate, t), abs=1e-6)
    assert tangent_heading(Circle().sample(0.0)).angle == pytest.approx(math.pi / 2)


def test_smooth_stop_ends_at_rest_with_continuous_motion():
    stop = SmoothStop(Circle(1.0, 20.0), duration=5.0, stop_time=2.0)
    end = stop.sample(100.0)
    assert end.velocity == (0.0, 0.0) and end.acceleration == (0.0, 0.0)
    assert end.position == pytest.approx(Circle(1.0, 20.0).sample(6.0).position)
    for edge in (5.0, 7.0):
        before, after = stop.sample(edge - 1e-9), stop.sample(edge + 1e-9)
        assert np.allclose(before.velocity, after.velocity, atol=1e-8)
        assert np.allclose(before.acceleration, after.acceleration, atol=1e-7)
    assert tangent_heading(stop.sample(100.0)) is None


def test_sampled_reference_interpolates_far_below_a_micrometre():
    eight = FigureEight(1.0, 30.0)
    times = np.arange(0.0, 30.0 + 1e-9, 0.01)
    samples = [eight.sample(t) for t in times]
    sampled = SampledReference(times, [s.position for s in samples], [s.velocity for s in samples],
                               [s.acceleration for s in samples])
    worst = max(np.hypot(*np.subtract(sampled.sample(t).position, eight.sample(t).position))
                for t in np.linspace(0.0005, 29.9995, 3001))
    assert worst < 1e-12
    t = 12.3456
    for field in ('velocity', 'acceleration', 'jerk'):
        assert np.allclose(getattr(sampled.sample(t), field), getattr(eight.sample(t), field), atol=1e-6)


def test_a_sampled_reference_moves_a_stamp_s_rounding_beyond_its_ends_and_rests_further_out():
    """Sample times travel as whole nanoseconds: a plan from 0.6 s reads its first sample back at
    0.6000000000000001 s, and a follower at 0.6 s must see the reference moving there, not at rest."""
    eight = FigureEight(1.0, 6.0)
    plan = sample_plan(eight, 0.6, 1.2, 0.02)
    sampled = messages.sampled_reference(plan)  # as the dynamics decodes the plan's message
    assert sampled.start > 0.6 and sampled.end > 1.2
    for t, exact in ((0.6, eight.sample(0.6)), (sampled.end + 0.5e-9, eight.sample(1.2))):
        got = sampled.sample(t)
        assert math.hypot(*exact.velocity) > 0.5
        for field in ('position', 'velocity', 'acceleration'):
            assert np.allclose(getattr(got, field), getattr(exact, field), rtol=0.0, atol=1e-8), field
    for t, rest in ((sampled.start - 2e-9, plan.positions[0]), (sampled.end + 2e-9, plan.positions[-1])):
        held = sampled.sample(t)
        assert held.position == rest and held.velocity == held.acceleration == (0.0, 0.0)


def test_sampled_reference_refuses_bad_samples():
    with pytest.raises(ParameterError, match='increase strictly'):
        SampledReference([0, 0], [(0, 0)] * 2, [(0, 0)] * 2, [(0, 0)] * 2)
    with pytest.raises(ParameterError, match='finite'):
        SampledReference([0, 1], [(0, math.nan), (0, 0)], [(0, 0)] * 2, [(0, 0)] * 2)
    with pytest.raises(ParameterError, match='>= 2 samples'):
        SampledReference([0], [(0, 0)], [(0, 0)], [(0, 0)])
