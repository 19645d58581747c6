"""The trajectory node's settings (``nodes.trajectory``)."""

from __future__ import annotations

from dataclasses import dataclass

from wallbot_msgs_py import topics
from wallbot_sim import messages
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.scenario import SHAPES
from wallbot_sim.settings.common import COORDINATE, recorder_wait
from wallbot_sim.settings.table import setting, table_of

MAX_PLAN_SAMPLES = 5_000
"""Largest plan accepted: every subscriber decodes a whole plan in one callback."""


@dataclass(frozen=True)
class TrajectorySettings:
    """The trajectory node's parameters. With every other parameter at its default, each end of a range is a
    usable plan: 10 samples of 0.05 s fill 0.5 s, 250 s at 0.05 s and 10 s at 0.002 s are MAX_PLAN_SAMPLES."""

    shape: str = setting('circle', 'reference shape', choices=SHAPES)
    radius: float = setting(1.0, 'circle radius (m)', NumberRange(1e-3, 1e4))
    amplitude: float = setting(1.0, 'figure-8 amplitude A (m)', NumberRange(1e-3, 1e4))
    # a shorter lap is no reference a robot follows, and overflows derivatives
    period: float = setting(20.0, 'period of one lap (s)', NumberRange(0.01, 1e6))
    center_x: float = setting(0.0, 'centre of the shape, wall X (m)', COORDINATE)
    center_y: float = setting(0.0, 'centre of the shape, wall Y (m)', COORDINATE)
    duration: float = setting(0.0, 'seconds of simulation time to follow the shape, then stop smoothly; 0 = forever',
                              NumberRange(0.0, 1e9))
    stop_time: float = setting(2.0, 'duration of the smooth stop (s)', NumberRange(1e-3, 1e6))
    # below 1e-3 Hz, 1 / rate is no usable timer period
    publish_rate_hz: float = setting(messages.PUBLISH_RATE_HZ, 'rate of the reference pose in simulation time (Hz)',
                                     NumberRange(1e-3, 1e4))
    # up to 0.1 s the interpolation is accurate
    sample_dt: float = setting(messages.SAMPLE_DT, 'plan sample spacing (s)', NumberRange(2e-3, 0.1))
    horizon: float = setting(messages.HORIZON, 'seconds a plan covers when duration is 0 (renewed at half-way); at '
                                               f'least 10 and at most {MAX_PLAN_SAMPLES} samples of sample_dt',
                             NumberRange(0.5, 250.0))
    odom_frame_id: str = setting(topics.WALL_FRAME, 'frame of the reference poses, path and plan (the wall)',
                                 read_only=True)
    wait_for_recorder: bool = recorder_wait('plan')
    use_sim_time: bool = setting(True, "follow the robot's clock", fixed='the trajectory node plans in simulation time')


TRAJECTORY = table_of(TrajectorySettings)
PLAN_SETTINGS = ('shape', 'radius', 'amplitude', 'period', 'center_x', 'center_y', 'duration', 'stop_time',
                 'publish_rate_hz', 'sample_dt', 'horizon')
"""The settings a plan is built from (changeable while the node runs)."""
