"""trajectory_node: the circle / figure-8 reference (docs/model.md section 10) as a plan, a path and a pose.

It publishes the *plan* on ``reference_trajectory`` (transient-local): the reference sampled
every ``sample_dt`` with position, velocity and acceleration, which the dynamics node
interpolates (quintic Hermite) at its own simulation time, so the motion never depends on
message timing. A plan covers ``horizon`` seconds and is replaced by a fresh one once
simulation time passes its middle; with ``duration`` 0 the reference repeats forever, a finite
``duration`` comes to rest through ``SmoothStop`` and its last plan ends at rest. Plan samples
lie on the grid k * sample_dt, so overlapping plans agree exactly where they overlap.
Parameter changes replan from the current simulation time; a clock that jumps back
(``~/reset`` of the dynamics) replans from there. Plans are built on a background thread
(``LatestRequestWorker``), so the node answers parameter and service requests at once
whatever it is planning.

Time. The node follows its robot's ``clock`` (``use_sim_time``, remapped from ``/clock`` onto
it: topics.CLOCK) and does its work in one callback per clock message, which the dynamics
publishes at its ``clock_rate_hz`` (10 Hz by default): it checks the plan, then publishes the reference pose for every point of the
``publish_rate_hz`` grid of simulation time the clock has passed since the last message (at most
MAX_POSE_BURST of them), each stamped with its grid time. So the poses keep their rate and stamps
whatever the clock's rate, and at the default rates the node wakes ten times per simulated second
instead of once per pose and once per plan check.

Recording. With ``wait_for_recorder`` (``wallbot-sim run`` sets it when it records), the first
plan is built only once a recorder (a node publishing ``record_progress``) subscribes
``reference`` and every discovered subscription of it is matched to this node's publisher. The
dynamics starts on that plan, so the bag holds every reference pose from t = 0: the poses are
volatile, and discovery runs per pair of nodes, so the dynamics hearing the recorder says nothing
about this node's publisher.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from nav_msgs.msg import Odometry, Path
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from trajectory_msgs.msg import MultiDOFJointTrajectory

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim import messages
from wallbot_sim.model import Circle, FigureEight, ModelError, SmoothStop, tangent_heading
from wallbot_sim.model.trajectories import Plan, SampledReference
from wallbot_sim.nodes.background import LatestRequestWorker
from wallbot_sim.nodes.common import ROBOT_CLOCK_ARGS, WhenRecorded, exit_process, run, steady_timer
from wallbot_sim.nodes.parameters import declare_settings, param_dict, parameter_result
from wallbot_sim.settings.trajectory import MAX_PLAN_SAMPLES, PLAN_SETTINGS, TRAJECTORY

MAX_POSE_BURST = 100
"""Most reference poses published for one /clock message (the newest ones): a clock that jumps
ahead (a resumed run) is no reason to publish the whole interval."""
RECHECK_PERIOD = 0.01
"""Wall seconds between looks at the planner, from a clock that came while it was busy until it is
idle; then the plan is checked against the newest clock. At factor 0 the dynamics runs to the end
of a new plan as soon as it is published and waits there: the clocks of all those states may come
before the planner thread has finished, and without a later check the run would wait for ever."""
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
    """Reasons why a full set of the plan's settings (``PLAN_SETTINGS``) is unusable (empty if fine)."""
    reasons = TRAJECTORY.reasons(values)
    if reasons:
        return reasons
    if values['horizon'] < 10 * values['sample_dt']:
        reasons.append('horizon must span at least 10 samples of sample_dt')
    if values['horizon'] / values['sample_dt'] > MAX_PLAN_SAMPLES:
        reasons.append(f'a plan of {values["horizon"]:g} s every {values["sample_dt"]:g} s would exceed '
                       f'{MAX_PLAN_SAMPLES} samples: raise sample_dt or shorten horizon')
    return reasons


@dataclass(frozen=True)
class PlanRequest:
    """What a plan is built from: the parameters, the start time and the heading to fall back on."""

    values: dict
    now: float
    fallback_yaw: float
    frame: str = topics.WALL_FRAME


@dataclass(frozen=True)
class BuiltPlan:
    """A plan with its messages, ready to publish."""

    plan: Plan
    reference: SampledReference
    trajectory: bytes
    path: bytes
    yaw: float
    shape: str


def build_plan(request: PlanRequest) -> BuiltPlan:
    """Sample the reference of ``request`` from its start time and encode plan and path."""
    values = request.values
    reference = make_reference(values)
    rest_at = values['duration'] + values['stop_time'] if values['duration'] > 0.0 else None
    plan = messages.plan_ahead(reference, request.now, values['sample_dt'], values['horizon'], rest_at)
    first = tangent_heading(reference.sample(plan.times[0]))
    yaw = first.angle if first is not None else request.fallback_yaw
    return BuiltPlan(plan, messages.sampled_reference(plan), messages.trajectory_message(plan, yaw, request.frame),
                     messages.path_message(plan, fallback_yaw=yaw, frame=request.frame), yaw, values['shape'])


class TrajectoryNode(Node):
    """Plans the reference, keeps the plan ahead of simulation time, publishes the reference pose."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_TRAJECTORY, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)
        self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, True)])
        declared = declare_settings(self, TRAJECTORY)
        self.values = {name: declared[name] for name in PLAN_SETTINGS}
        self.frame = declared['odom_frame_id']
        reasons = check_values(self.values)
        if reasons:
            raise ValueError('; '.join(reasons))
        self.trajectory_pub = self.create_publisher(MultiDOFJointTrajectory, topics.REFERENCE_TRAJECTORY.name,
                                                    qos_profile(topics.REFERENCE_TRAJECTORY))
        self.path_pub = self.create_publisher(Path, topics.REFERENCE_PATH.name, qos_profile(topics.REFERENCE_PATH))
        self.reference_pub = self.create_publisher(Odometry, topics.REFERENCE.name, qos_profile(topics.REFERENCE))
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.plan: Plan | None = None  # the plan last published
        self.last_now = 0.0
        self.yaw = 0.0
        self.reference: SampledReference | None = None
        self.planner = LatestRequestWorker(build_plan, self._publish_plan, self._planning_failed, 'planner')
        self.last_pose: int | None = None
        """Grid index (simulation time / pose period) of the newest reference pose published."""
        self.clock_ns: int | None = None
        self.pose_lock = threading.Lock()  # poses go out from the executor and, for a new plan, the planner
        self.recorder_wait = None
        if declared['wait_for_recorder']:
            self.recorder_wait = WhenRecorded(self, [self.reference_pub], lambda: self.replan(self._now()),
                                              'a recorder hears reference: planning')
        else:
            self.replan(self._now())
        self.recheck = steady_timer(self, RECHECK_PERIOD, self._recheck)
        self.recheck.cancel()
        self.create_subscription(Clock, topics.CLOCK.name, self._on_clock, qos_profile(topics.CLOCK), raw=True)

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_clock(self, data: bytes) -> None:
        now_ns = codec.decode_clock(data)
        self.clock_ns = now_ns
        self._check_plan(now_ns * 1e-9)
        self._publish_reference(now_ns)

    # --- planning ----------------------------------------------------------------------------
    def replan(self, now: float) -> None:
        """Plan from ``now`` (``messages.plan_ahead``) on the planner thread; returns at once."""
        self.planner.submit(PlanRequest(dict(self.values), now, self.yaw, self.frame))

    def _publish_plan(self, built: BuiltPlan) -> None:
        """Planner thread: publish plan and path, then make the plan the current reference."""
        self.trajectory_pub.publish(built.trajectory)
        self.path_pub.publish(built.path)
        times = built.plan.times
        with self.pose_lock:
            self.reference, self.yaw, self.plan = built.reference, built.yaw, built.plan
        clock_ns = self.clock_ns
        if clock_ns is not None:  # the poses owed since the clock passed them without a plan
            self._publish_reference(clock_ns)
        self.get_logger().info(
            f'plan {built.shape} from t = {times[0]:.3f} s to {times[-1]:.3f} s '
            f'({len(times)} samples{", ends at rest" if messages.plan_is_final(built.plan) else ""})')

    def _planning_failed(self, error: Exception) -> None:
        self.get_logger().error(f'planning failed: {error}')

    def _check_plan(self, now: float) -> None:
        plan = self.plan
        jumped_back = now < self.last_now - 1e-9 or (plan is not None and now < plan.times[0])
        self.last_now = now
        if self.planner.busy:
            if self.recheck.is_canceled():
                self.recheck.reset()
            return
        if plan is None:
            return
        if jumped_back:
            self.get_logger().info(f'simulation time went back to {now:.3f} s: replanning')
            self.replan(now)
        elif messages.replan_due(plan, now):
            self.replan(now)

    def _recheck(self) -> None:
        if self.planner.busy:
            return
        self.recheck.cancel()
        self._check_plan(self.clock_ns * 1e-9)

    def close(self) -> None:
        """Stop the planner thread (called by ``run`` before the node is destroyed)."""
        self.planner.stop()

    def _publish_reference(self, now_ns: int) -> None:
        """The poses of the grid points in (last pose, now_ns], at most MAX_POSE_BURST; the first
        ones from the plan's start; only the newest if time went back."""
        with self.pose_lock:
            reference, plan = self.reference, self.plan
            if reference is None or plan is None:
                return
            period_ns = max(1, round(1e9 / self.values['publish_rate_hz']))
            newest = now_ns // period_ns
            last = self.last_pose
            if last is None:
                last = -(-codec.to_nanoseconds(plan.times[0]) // period_ns) - 1
            if last > newest:
                last = newest - 1
            for k in range(max(last, newest - MAX_POSE_BURST) + 1, newest + 1):
                t = k * period_ns * 1e-9
                data, self.yaw = messages.reference_message(reference.sample(t), t, self.yaw, self.frame)
                self.reference_pub.publish(data)
            self.last_pose = newest

    # --- parameters --------------------------------------------------------------------------
    def _on_set(self, parameters):
        reasons = TRAJECTORY.reasons(param_dict(parameters))
        merged = {**self.values, **param_dict(parameters, self.values)}
        reasons = reasons or check_values(merged)
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
            self.last_pose = None  # a new grid: it starts at the next clock
        if set(changes) - {'publish_rate_hz'} and not (self.recorder_wait and self.recorder_wait.waiting):
            self.replan(self._now())  # (a node still waiting for its recorder plans the new values then)


def main(args: list[str] | None = None) -> None:
    exit_process(run(TrajectoryNode, args, events=True))


if __name__ == '__main__':
    main()
