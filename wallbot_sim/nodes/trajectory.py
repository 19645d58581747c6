"""trajectory_node: the circle / figure-8 reference (MODEL.md section 8) as a plan, a path and a pose.

It publishes the *plan* on ``reference_trajectory`` (transient-local): the reference sampled
every ``sample_dt`` with position, velocity and acceleration, which the dynamics node
interpolates (quintic Hermite) at its own simulation time, so the motion never depends on
message timing. With ``duration`` 0 the reference repeats forever: a plan covers ``horizon``
seconds and is replaced by a fresh one once simulation time passes its middle. Plan samples
lie on the grid k * sample_dt, so overlapping plans agree exactly where they overlap.
A finite ``duration`` comes to rest through ``SmoothStop`` and is published as one plan
that ends at rest. Parameter changes replan from the current simulation time; a clock that
jumps back (``~/reset`` of the dynamics) replans from there.
"""

from __future__ import annotations

import sys

from nav_msgs.msg import Odometry, Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from trajectory_msgs.msg import MultiDOFJointTrajectory

from wallbot_msgs_py import conversions, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.model import Circle, FigureEight, ModelError, SmoothStop, tangent_heading
from wallbot_sim.model.scenario import SHAPES
from wallbot_sim.model.trajectories import sample_plan
from wallbot_sim.nodes.common import check_number, declare, param_dict, parameter_result, run

REPLAN_CHECK_PERIOD = 0.02
"""Wall-clock period (s) of the check whether the plan needs renewing."""
MAX_PLAN_SAMPLES = 200_000
"""Largest plan accepted: beyond this a parameter set would stall the node building it."""
LIMITS = {'radius': 1e4, 'amplitude': 1e4, 'publish_rate_hz': 1e4}
"""Upper bounds (m, Hz) on sizes that no wall and no subscriber needs beyond."""
MIN_PERIOD = 0.01
"""A lap shorter than this (s) is no reference a robot can follow, and overflows its derivatives."""
MIN_PUBLISH_RATE = 1e-3
"""Hz; below it the timer period 1 / rate is no usable period (at 1e-300 Hz it overflows rclpy's timer)."""


def make_reference(values: dict):
    """The reference the parameters describe (a SmoothStop around the path if duration > 0)."""
    center = (float(values['center_x']), float(values['center_y']))
    if values['shape'] == 'circle':
        path = Circle(float(values['radius']), float(values['period']), center)
    else:
        path = FigureEight(float(values['amplitude']), float(values['period']), center)
    if values['duration'] > 0.0:
        return SmoothStop(path, float(values['duration']), float(values['stop_time']))
    return path


def check_values(values: dict) -> list[str]:
    """Reasons why a full set of trajectory parameters is unusable (empty if fine)."""
    reasons = []
    if values['shape'] not in SHAPES:
        reasons.append(f'unknown shape {values["shape"]!r}: use {" or ".join(SHAPES)}')
    for name in ('radius', 'amplitude', 'period', 'stop_time', 'publish_rate_hz', 'sample_dt', 'horizon'):
        reasons.append(check_number(name, values[name], minimum=0.0, exclusive=True))
    for name in ('center_x', 'center_y'):
        reasons.append(check_number(name, values[name]))
    reasons.append(check_number('duration', values['duration'], minimum=0.0))
    if not reasons[-1] and values['sample_dt'] > 0.1:
        reasons.append(f'sample_dt must be <= 0.1 s to keep the interpolation accurate, got {values["sample_dt"]!r}')
    reasons = [r for r in reasons if r]
    if reasons:
        return reasons
    for name, limit in LIMITS.items():
        if values[name] > limit:
            reasons.append(f'{name} must be <= {limit:g}, got {values[name]!r}')
    if values['publish_rate_hz'] < MIN_PUBLISH_RATE:
        reasons.append(f'publish_rate_hz must be >= {MIN_PUBLISH_RATE:g}, got {values["publish_rate_hz"]!r}')
    if values['period'] < MIN_PERIOD:
        reasons.append(f'period must be >= {MIN_PERIOD:g} s, got {values["period"]!r}')
    if values['horizon'] < 10 * values['sample_dt']:
        reasons.append('horizon must span at least 10 samples')
    span = values['duration'] + values['stop_time'] if values['duration'] > 0.0 else values['horizon']
    if span / values['sample_dt'] > MAX_PLAN_SAMPLES:
        reasons.append(f'a plan of {span:g} s every {values["sample_dt"]:g} s would exceed '
                       f'{MAX_PLAN_SAMPLES} samples: raise sample_dt or shorten duration/horizon/stop_time')
    return reasons


class TrajectoryNode(Node):
    """Plans the reference, keeps the plan ahead of simulation time, publishes the reference pose."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_TRAJECTORY, namespace=topics.NAMESPACE, **kwargs)
        self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, True)])
        self.values = {
            'shape': declare(self, 'shape', 'circle', 'reference shape: circle or figure8'),
            'radius': declare(self, 'radius', 1.0, 'circle radius (m, > 0)'),
            'amplitude': declare(self, 'amplitude', 1.0, 'figure-8 amplitude A (m, > 0)'),
            'period': declare(self, 'period', 20.0, 'period of one lap (s, > 0)'),
            'center_x': declare(self, 'center_x', 0.0, 'centre of the shape, wall X (m)'),
            'center_y': declare(self, 'center_y', 0.0, 'centre of the shape, wall Y (m)'),
            'duration': declare(self, 'duration', 0.0,
                                'seconds of simulation time to follow the shape, then stop smoothly; 0 = forever',
                                low=0.0, high=1e9),
            'stop_time': declare(self, 'stop_time', 2.0, 'duration of the smooth stop (s, > 0)'),
            'publish_rate_hz': declare(self, 'publish_rate_hz', 100.0,
                                       'rate of the reference pose in simulation time (Hz, > 0)'),
            'sample_dt': declare(self, 'sample_dt', 0.05, 'plan sample spacing (s, in (0, 0.1])'),
            'horizon': declare(self, 'horizon', 10.0,
                               'seconds a plan covers when duration is 0 (renewed at half-way)'),
        }
        reasons = check_values(self.values)
        if reasons:
            raise ValueError('; '.join(reasons))
        self.trajectory_pub = self.create_publisher(MultiDOFJointTrajectory, topics.REFERENCE_TRAJECTORY.name,
                                                    qos_profile(topics.REFERENCE_TRAJECTORY))
        self.path_pub = self.create_publisher(Path, topics.REFERENCE_PATH.name, qos_profile(topics.REFERENCE_PATH))
        self.reference_pub = self.create_publisher(Odometry, topics.REFERENCE.name, qos_profile(topics.REFERENCE))
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.plan_start = self.plan_end = 0.0
        self.final = False
        self.last_now = 0.0
        self.yaw = 0.0
        self.reference = None
        self.replan(self._now())
        self.create_timer(REPLAN_CHECK_PERIOD, self._check_plan, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.pose_timer = self.create_timer(1.0 / self.values['publish_rate_hz'], self._publish_reference)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # --- planning ----------------------------------------------------------------------------
    def replan(self, now: float) -> None:
        """Plan from ``now`` (rounded down to the sample grid) and publish plan and path."""
        values, dt = self.values, self.values['sample_dt']
        reference = make_reference(values)
        if values['duration'] > 0.0:
            end = max(values['duration'] + values['stop_time'] + dt, now)
        else:
            end = now + values['horizon']
        plan = sample_plan(reference, now, end, dt)
        first = tangent_heading(reference.sample(plan.times[0]))
        if first is not None:
            self.yaw = first.angle
        self.trajectory_pub.publish(conversions.trajectory_message(plan, self.yaw))
        self.path_pub.publish(conversions.path_message(plan, fallback_yaw=self.yaw))
        self.reference = conversions.sampled_reference(plan)
        self.plan_start, self.plan_end = plan.times[0], plan.times[-1]
        self.final = conversions.plan_is_final(plan)
        self.get_logger().info(
            f'plan {values["shape"]} from t = {self.plan_start:.3f} s to {self.plan_end:.3f} s '
            f'({len(plan.times)} samples{", ends at rest" if self.final else ""})')

    def _check_plan(self) -> None:
        now = self._now()
        jumped_back = now < self.last_now - 1e-9 or now < self.plan_start
        self.last_now = now
        if jumped_back:
            self.get_logger().info(f'simulation time went back to {now:.3f} s: replanning')
            self.replan(now)
        elif not self.final and now > 0.5 * (self.plan_start + self.plan_end):
            self.replan(now)

    def _publish_reference(self) -> None:
        now = self._now()
        if self.reference is None:
            return
        msg = conversions.reference_odometry_message(self.reference.sample(now), now, self.yaw)
        self.yaw = conversions.quaternion_yaw(msg.pose.pose.orientation)
        self.reference_pub.publish(msg)

    # --- parameters --------------------------------------------------------------------------
    def _on_set(self, parameters):
        merged = {**self.values, **param_dict(parameters, self.values)}
        reasons = check_values(merged)
        if not reasons:
            try:
                make_reference(merged)
            except ModelError as error:
                reasons.append(str(error))
        return parameter_result(reasons)

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, self.values)
        if not changes:
            return
        self.values.update(changes)
        if 'publish_rate_hz' in changes:
            self.destroy_timer(self.pose_timer)
            self.pose_timer = self.create_timer(1.0 / self.values['publish_rate_hz'], self._publish_reference)
        if set(changes) - {'publish_rate_hz'}:
            self.replan(self._now())


def main(args: list[str] | None = None) -> None:
    sys.exit(run(TrajectoryNode, args))


if __name__ == '__main__':
    main()
