"""Trajectory planning off the executor: LatestRequestWorker, plan windows, and a node that answers
parameter requests while a plan is being built."""

from __future__ import annotations

import math
import threading

import pytest

from message_fields import stamp_ns
from wallbot_sim.nodes.background import LatestRequestWorker

WAIT = 10.0
"""Bound (s) on waits for the worker thread: catches a stall, asserts no speed."""


class Recorder:
    def __init__(self) -> None:
        self.delivered: list = []
        self.errors: list[Exception] = []


def test_newest_request_wins_and_superseded_results_are_dropped():
    release, started = threading.Event(), threading.Event()
    seen = Recorder()

    def build(request):
        started.set()
        release.wait(WAIT)
        return request * 10

    worker = LatestRequestWorker(build, seen.delivered.append, seen.errors.append)
    try:
        worker.submit(1)
        assert started.wait(WAIT)
        worker.submit(2)  # waits behind 1, then is replaced by 3 before it starts
        worker.submit(3)
        assert worker.busy
        release.set()
        assert worker.wait_idle(WAIT)
        assert seen.delivered == [30]  # 1 was superseded while it ran, 2 before it started
        assert not seen.errors and not worker.busy
    finally:
        release.set()
        worker.stop()


def test_a_failing_build_is_reported_and_the_worker_goes_on():
    seen = Recorder()

    def build(request):
        if request == 'bad':
            raise ValueError('cannot plan that')
        return request

    worker = LatestRequestWorker(build, seen.delivered.append, seen.errors.append)
    try:
        worker.submit('bad')
        assert worker.wait_idle(WAIT)
        worker.submit('good')
        assert worker.wait_idle(WAIT)
        assert [str(e) for e in seen.errors] == ['cannot plan that'] and seen.delivered == ['good']
    finally:
        worker.stop()


def test_submit_never_waits_for_a_build():
    release = threading.Event()
    worker = LatestRequestWorker(lambda r: release.wait(WAIT), lambda r: None, lambda e: None)
    try:
        for request in range(100):  # would take 100 * WAIT if submit waited for a build
            worker.submit(request)
        assert worker.busy
    finally:
        release.set()
        worker.stop()
    assert not worker._thread.is_alive()


DEFAULTS = {'shape': 'circle', 'radius': 1.0, 'amplitude': 1.0, 'period': 20.0, 'center_x': 0.0,
            'center_y': 0.0, 'duration': 0.0, 'stop_time': 2.0, 'publish_rate_hz': 100.0, 'sample_dt': 0.05,
            'horizon': 10.0}


def test_plans_cover_at_most_the_horizon_and_a_finite_run_ends_at_rest():
    pytest.importorskip('rclpy')
    from wallbot_sim import messages
    from wallbot_sim.nodes.trajectory import MAX_PLAN_SAMPLES, PlanRequest, build_plan, check_values

    long_run = {**DEFAULTS, 'duration': 1464.9, 'sample_dt': 0.05}  # once a 29,257-sample plan
    assert not check_values(long_run)
    first = build_plan(PlanRequest(long_run, 2.1, 0.0)).plan
    # from a sample before the grid point at or before 2.1 s: a follower at 2.1 s is inside it, stamps rounded
    assert 2.1 - 2 * 0.05 < first.times[0] <= 2.1 - 0.05 + 1e-12 and first.times[-1] == pytest.approx(12.1, abs=0.05)
    assert not messages.plan_is_final(first)
    last = build_plan(PlanRequest(long_run, 1460.0, 0.0)).plan
    assert last.times[-1] >= 1464.9 + 2.0 and messages.plan_is_final(last)
    assert len(last.times) <= MAX_PLAN_SAMPLES
    assert check_values({**DEFAULTS, 'horizon': 1000.0, 'sample_dt': 0.001})  # 10^6 samples: refused


def test_the_reference_messages_carry_the_odom_frame_id():
    pytest.importorskip('rclpy')
    from wallbot_msgs_py import bagio, topics
    from wallbot_sim import messages
    from wallbot_sim.nodes.trajectory import PlanRequest, build_plan

    built = build_plan(PlanRequest(DEFAULTS, 0.0, 0.0, 'map'))
    plan = bagio.deserialize(built.trajectory, topics.REFERENCE_TRAJECTORY.type)
    path = bagio.deserialize(built.path, topics.REFERENCE_PATH.type)
    assert plan.header.frame_id == path.header.frame_id == 'map'
    assert {pose.header.frame_id for pose in path.poses} == {'map'}
    pose, _yaw = messages.reference_message(built.reference.sample(1.0), 1.0, frame='map')
    assert bagio.deserialize(pose, topics.REFERENCE.type).header.frame_id == 'map'
    default = build_plan(PlanRequest(DEFAULTS, 0.0, 0.0))
    assert bagio.deserialize(default.trajectory, topics.REFERENCE_TRAJECTORY.type).header.frame_id == 'wall'


class HeldPlanner:
    """A trajectory node whose plan builds block until ``release`` is set (``building`` is set when one starts)."""

    def __init__(self, node, building: threading.Event, release: threading.Event) -> None:
        self.node, self.building, self.release = node, building, release


@pytest.fixture
def held_planner(monkeypatch, ros_domain):
    rclpy = pytest.importorskip('rclpy')
    from wallbot_sim.nodes import trajectory

    release, building = threading.Event(), threading.Event()
    real_build = trajectory.build_plan

    def slow_build(request):
        building.set()
        release.wait(WAIT)
        return real_build(request)

    monkeypatch.setattr(trajectory, 'build_plan', slow_build)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = None
    try:
        node = trajectory.TrajectoryNode(context=context)
        yield HeldPlanner(node, building, release)
    finally:
        release.set()
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.shutdown(context=context)


def test_the_node_answers_parameter_requests_while_planning(held_planner):
    """A plan that takes for ever to build does not hold up set_parameters (it runs on the planner thread)."""
    from rclpy.parameter import Parameter

    node = held_planner.node
    assert held_planner.building.wait(WAIT), 'the first plan is built on the planner thread'
    results = node.set_parameters([Parameter('radius', Parameter.Type.DOUBLE, 2.0),
                                   Parameter('period', Parameter.Type.DOUBLE, 0.0)])
    assert results[0].successful and not results[1].successful and 'period' in results[1].reason
    assert node.planner.busy and node.reference is None  # answered while the plan was still building
    held_planner.release.set()
    assert node.planner.wait_idle(WAIT)
    assert node.reference is not None  # the plan of the accepted radius
    assert node.reference.sample(1.0).position[0] == pytest.approx(2.0 * math.cos(2 * math.pi / 20.0), abs=1e-6)


def test_poses_the_clock_passed_while_planning_go_out_with_the_plan(held_planner, monkeypatch):
    """/clock messages that arrive while the first plan builds (a short factor-0 run on a loaded
    machine) are not lost: once the plan lands, the poses of every grid point since its start up
    to the newest clock are published, each stamped on its grid and sampled from the plan."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message

    from wallbot_sim import messages

    node = held_planner.node
    published = []
    monkeypatch.setattr(node.reference_pub, 'publish', published.append)
    for t_ms in (0, 100, 200, 300):  # the run's clock passes without a plan to sample
        node._on_clock(clock_message(t_ms * 1_000_000))
    assert not published
    held_planner.release.set()
    assert node.planner.wait_idle(WAIT)
    poses = [deserialize_message(data, Odometry) for data in published]
    stamps = [stamp_ns(m.header.stamp) for m in poses]
    period = round(1e9 / messages.PUBLISH_RATE_HZ)
    assert stamps == list(range(0, 300_000_001, period))
    x = [m.pose.pose.position.x for m in poses]
    assert x == [node.reference.sample(s * 1e-9).position[0] for s in stamps]


def clock_message(t_ns: int) -> bytes:
    """A serialized rosgraph_msgs/Clock of ``t_ns``, as the node's raw subscription hands it over."""
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock
    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = divmod(t_ns, 1_000_000_000)
    return serialize_message(clock)


def test_a_clock_that_came_while_a_plan_was_built_is_checked_once_the_planner_is_idle(held_planner):
    """At factor 0 the dynamics runs to the end of a new plan as soon as it is published and waits
    there, publishing no more clocks: the clocks of those states may all come before the planner
    thread has finished. The newest of them is checked once the planner is idle, and the node
    replans from it, without another clock."""
    from rclpy.executors import SingleThreadedExecutor

    from recorder_probe import spin_until
    from wallbot_sim import messages

    node = held_planner.node
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        held_planner.release.set()
        assert node.planner.wait_idle(WAIT)
        first = node.plan
        middle = 0.5 * (first.times[0] + first.times[-1])
        held_planner.release.clear()  # the next plan is held while it builds
        node._on_clock(clock_message(round((middle + 0.1) * 1e9)))  # past the middle: a replan
        assert node.planner.busy
        waiting_at = first.times[-1] + 4.0  # the dynamics ran past the replan's middle meanwhile
        node._on_clock(clock_message(round(waiting_at * 1e9)))
        held_planner.release.set()
        spin_until(executor, lambda: not node.planner.busy and not messages.replan_due(node.plan, waiting_at),
                   WAIT, f'no plan for t = {waiting_at} s, where the dynamics waits')
        assert node.plan.times[0] <= waiting_at < node.plan.times[-1]
    finally:
        executor.shutdown()


def test_with_wait_for_recorder_the_first_plan_waits_until_a_recorder_hears_reference(ros_domain):
    """The reference poses are volatile: a run that records must not start (the dynamics starts on
    the first plan) before the recorder's reference subscription is matched to this node."""
    rclpy = pytest.importorskip('rclpy')
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from recorder_probe import recorder_probe, spin_for, spin_until
    from wallbot_msgs_py import topics
    from wallbot_msgs_py.qos import qos_profile
    from wallbot_sim.nodes.trajectory import TrajectoryNode

    context = rclpy.Context()
    rclpy.init(context=context)
    node = probe = None
    executor = SingleThreadedExecutor(context=context)
    try:
        node = TrajectoryNode(context=context,
                              parameter_overrides=[Parameter('wait_for_recorder', Parameter.Type.BOOL, True)])
        executor.add_node(node)
        probe = recorder_probe(context, executor)
        spin_for(executor, 1.0)  # a recorder known, but not listening on reference: still no plan
        assert node.count_publishers(node.resolve_topic_name(topics.RECORD_PROGRESS.name)) == 1
        assert node.plan is None and not node.planner.busy and node.recorder_wait.waiting
        probe.create_subscription(Odometry, topics.REFERENCE.name, lambda _msg: None, qos_profile(topics.REFERENCE))
        spin_until(executor, lambda: node.plan is not None, 30.0, 'no plan after the recorder subscribed reference')
        assert node.reference_pub.get_subscription_count() == 1 and not node.recorder_wait.waiting
    finally:
        if node is not None:
            node.close()
        executor.shutdown()
        for n in (probe, node):
            if n is not None:
                n.destroy_node()
        rclpy.shutdown(context=context)
