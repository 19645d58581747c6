"""The node graph as separate processes over DDS (isolated domain from conftest).

Every node runs as a real process started through ``process_runner``; the test talks to it
with rclpy like the ROS tools do (``ros2 param set`` = the SetParameters service,
``ros2 topic echo`` = a subscription).
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.qos import DurabilityPolicy  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from graph_helpers import MS, STALL, Graph, ns, start_graph  # noqa: E402
from message_fields import quaternion_yaw  # noqa: E402
from scheduling_helpers import may_use_fifo  # noqa: E402
from wallbot_msgs_py import bagio, topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402
from wallbot_sim import messages  # noqa: E402
from wallbot_sim.config import load_robot_parameters  # noqa: E402
from wallbot_sim.model import ConstraintSelection, FigureEight, Robot, Simulation  # noqa: E402
from wallbot_sim.model.trajectories import sample_plan  # noqa: E402
from wallbot_sim.settings.dynamics import CONTROL_ODOM_EVERY  # noqa: E402


@pytest.fixture
def graph(process_runner):
    g = Graph(process_runner)
    try:
        yield g
    finally:
        g.close()


def start_tracking_graph(graph: Graph, *dynamics: str, constraints: tuple[str, ...] = (),
                         trajectory: tuple[str, ...] = ()):
    return start_graph(graph, *dynamics, constraints=constraints, trajectory=trajectory)


def final_state(graph: Graph, t: float):
    """Pose, twist and wheel state published at simulation time t."""
    stamp = round(t * 1e9)
    for topic in (topics.WHEEL_STATES, topics.ODOM):  # each on its own subscription: one may lag the other
        graph.wait_for(lambda: any(ns(m) == stamp for m in graph.messages(topic.name)), 20,
                       f'{topic.name} at {t} s')
    odom = [m for m in graph.messages(topics.ODOM.name) if ns(m) == stamp]
    wheels = [m for m in graph.messages(topics.WHEEL_STATES.name) if ns(m) == stamp]
    assert len(odom) == len(wheels) == 1, f'{len(odom)} odometry messages stamped {t} s: a second publisher?'
    odom, wheels = odom[0], wheels[0]
    p, tw = odom.pose.pose, odom.twist.twist
    return ([p.position.x, p.position.y, p.orientation.z, p.orientation.w, tw.linear.x, tw.linear.y, tw.angular.z]
            + list(wheels.position) + list(wheels.velocity))


# --- tests --------------------------------------------------------------------------------------
def test_topics_types_and_1khz_odometry(graph):
    graph.subscribe(topics.CONTROL_ODOM.name, Odometry, topics.CONTROL_ODOM.resolve(), topics.CONTROL_ODOM)
    dynamics = start_tracking_graph(graph, constraints=('belt:=true', 'non_lateral:=true', 'nonslip:=true'))
    graph.wait_sim_time(0.0)
    wall_start = time.monotonic()
    graph.wait_sim_time(2.0, timeout=60)  # the timeout only catches a stall: a loaded machine may fall behind
    wall = time.monotonic() - wall_start
    # Paced at factor 1, the loop is never ahead of real time (factor 0 runs 2-8x); the 0.5 s of slack
    # covers the first message's delivery and this poll's own delays. Speed is measured in bench/.
    assert wall > 2.0 - 0.5, f'2 s of simulation in {wall:.2f} s of wall time at real-time factor 1'

    odom = graph.messages(topics.ODOM.name)
    stamps = np.array([ns(m) for m in odom])
    assert stamps[0] == 0 and len(stamps) >= 2001
    assert np.all(np.diff(stamps) == MS), 'odometry stamps must be consecutive, 1 ms apart'
    assert odom[0].header.frame_id == 'wall' and odom[0].child_frame_id == 'base_link'
    # control_odom: every CONTROL_ODOM_EVERY-th state (the parameter's default), the same message as on odom
    every = CONTROL_ODOM_EVERY * MS
    graph.wait_for(lambda: len(graph.messages(topics.CONTROL_ODOM.name)) > 2000 // CONTROL_ODOM_EVERY, 10,
                   '2 s of control_odom')
    control = graph.messages(topics.CONTROL_ODOM.name)
    assert [ns(m) for m in control] == list(range(0, every * len(control), every))
    by_stamp = {ns(m): m for m in odom}
    assert all(m == by_stamp[ns(m)] for m in control if ns(m) in by_stamp)
    assert sum(ns(m) in by_stamp for m in control) >= 2000 // CONTROL_ODOM_EVERY

    names = dict(graph.node.get_topic_names_and_types())
    expected = {'/wallbot/odom': 'nav_msgs/msg/Odometry', '/wallbot/control_odom': 'nav_msgs/msg/Odometry',
                '/wallbot/wheel_states': 'sensor_msgs/msg/JointState',
                '/wallbot/constraint_wrench': 'geometry_msgs/msg/WrenchStamped',
                '/wallbot/drive_forces': 'sensor_msgs/msg/JointState', '/clock': 'rosgraph_msgs/msg/Clock',
                '/wallbot/clock': 'rosgraph_msgs/msg/Clock',
                '/diagnostics': 'diagnostic_msgs/msg/DiagnosticArray',
                '/wallbot/reference': 'nav_msgs/msg/Odometry', '/wallbot/reference_path': 'nav_msgs/msg/Path',
                '/wallbot/reference_trajectory': 'trajectory_msgs/msg/MultiDOFJointTrajectory',
                '/wallbot/constraints': 'diagnostic_msgs/msg/DiagnosticStatus',
                '/wallbot/wheel_torque_cmd': 'std_msgs/msg/Float64MultiArray'}
    for name, kind in expected.items():
        assert names.get(name) == [kind], f'{name}: {names.get(name)}'
    unusual = {name: kinds for name, kinds in names.items()
               if any(kind.split('/')[0] not in topics.STANDARD_PACKAGES for kind in kinds)}
    assert not unusual, f'topics of types a Jazzy install does not have: {unusual}'
    graph.wait_for(lambda: {'/wallbot/dynamics', '/wallbot/trajectory', '/wallbot/constraint_config'}
                   <= set(graph.node.get_fully_qualified_node_names()), STALL, 'node names')

    wheels = graph.messages(topics.WHEEL_STATES.name)[-1]
    assert list(wheels.name) == list(topics.WHEEL_JOINTS)
    assert graph.messages(topics.REFERENCE_PATH.name) and graph.messages(topics.REFERENCE_TRAJECTORY.name)
    assert graph.messages(topics.CONSTRAINTS.name)[-1].message == 'trajectory+tangent_heading+belt+non_lateral+nonslip'
    graph.wait_for(lambda: len(graph.messages(topics.REFERENCE.name)) > 20, STALL, 'reference poses')
    diagnostics = graph.wait_for(lambda: graph.messages(topics.DIAGNOSTICS.name), STALL, 'diagnostics')
    values = {kv.key: kv.value for kv in diagnostics[-1].status[0].values}
    assert values['active constraints'] == 'trajectory+tangent_heading+belt+non_lateral+nonslip'
    # heard above by this volatile subscriber, and kept for a transient-local one (wallbot-sim run's monitor)
    offers = {info.node_name: info.qos_profile.durability
              for info in graph.node.get_publishers_info_by_topic(topics.DIAGNOSTICS.name)}
    assert offers.get('dynamics') == DurabilityPolicy.TRANSIENT_LOCAL, offers
    # the rate itself depends on the machine's load (bench/ measures it); here: it steps and says so
    assert float(values['achieved rate (Hz)']) > 0 and 'adsorption margin' in values
    assert values['loop priority'] == 'normal'  # by default
    assert graph.set_parameters('dynamics', realtime_priority=50)[0].successful
    graph.clear(topics.DIAGNOSTICS.name)
    diagnostics = graph.wait_for(lambda: graph.messages(topics.DIAGNOSTICS.name)[1:], STALL,
                                 'diagnostics after the set')
    values = {kv.key: kv.value for kv in diagnostics[-1].status[0].values}
    # the node's decision; whether a step had time to sleep under FIFO depends on the machine's load
    if may_use_fifo():
        assert values['loop priority'] == 'SCHED_FIFO 50 while paced'
    else:  # refused at the first step that sleeps, if one has slept yet
        assert values['loop priority'] in ('SCHED_FIFO 50 while paced', 'normal (SCHED_FIFO 50 not permitted)')
    assert graph.runner.stop(dynamics) == 0, 'SIGTERM must end the node cleanly'
    assert 'Traceback' not in graph.runner.output('dynamics')


def test_set_parameters_switches_constraints_mid_run(graph):
    """A driven robot (th = 0) slides down the wall, i.e. sideways; enabling non_lateral stops that at once."""
    start_graph(graph, constraints=('trajectory_task:=false', 'belt:=true'), trajectory=None)
    graph.wait_sim_time(0.3)
    sliding = graph.messages(topics.ODOM.name)[-1].twist.twist.linear.y
    assert sliding < -2.0, 'without non_lateral gravity pulls the robot sideways (down the wall)'

    results = graph.set_parameters('constraint_config', non_lateral=True)
    assert results[0].successful
    switch = graph.wait_for(lambda: re.search(r'constraints belt -> belt\+non_lateral at t = ([\d.]+) s',
                                              graph.runner.output('dynamics')), 30, 'switch log')
    switched_by = round(float(switch.group(1)) * 1e9)  # when the dynamics applied it, as it says
    graph.wait_sim_time(switched_by * 1e-9 + 0.5)
    after = [m for m in graph.messages(topics.ODOM.name) if ns(m) > switched_by + 200 * MS]
    assert len(after) > 200
    assert max(abs(m.twist.twist.linear.y) for m in after) < 1e-9, 'non_lateral must stop sideways motion'
    log = graph.runner.output('dynamics')
    assert 'velocity violation' in log and 'after projection' in log
    assert graph.messages(topics.CONSTRAINTS.name)[-1].message == 'belt+non_lateral'


def test_invalid_parameters_are_refused_and_the_nodes_keep_running(graph):
    start_tracking_graph(graph)
    graph.wait_sim_time(0.3)
    for node, values in [('dynamics', {'real_time_factor': -1.0}), ('dynamics', {'rate_hz': 0}),
                         ('dynamics', {'command_timeout': math.nan}), ('dynamics', {'max_wheel_torque': 0.0}),
                         ('dynamics', {'initial_x': math.inf}), ('dynamics', {'publish_every': 'often'}),
                         ('dynamics', {'robot_file': '/nonexistent.yaml'}), ('dynamics', {'realtime_priority': 100}),
                         ('dynamics', {'realtime_priority': -1}),
                         ('trajectory', {'shape': 'square'}), ('trajectory', {'radius': -1.0}),
                         ('trajectory', {'period': 0.0}), ('constraint_config', {'baumgarte_alpha': 0.0}),
                         ('constraint_config', {'belt': 'yes'})]:
        result = graph.set_parameters(node, **values)[0]
        assert not result.successful, f'{node} accepted {values}'
        assert result.reason, f'{node} refused {values} without a reason'
    assert graph.get_parameters('dynamics', 'real_time_factor', 'rate_hz') == [1.0, 1000]
    assert graph.get_parameters('trajectory', 'shape') == ['circle']
    before = graph.last_stamp()
    graph.wait_sim_time(before * 1e-9 + 0.3)
    # still stepping at 1 kHz (this test's own subscriber is no recorder: under load it may miss states, which
    # the recorder's back-pressure prevents for a bag; test_recorder and test_cli_run check that)
    steps = np.diff([ns(m) for m in graph.messages(topics.ODOM.name)])
    assert np.all(steps > 0) and np.all(steps % MS == 0)


def test_pause_and_reset(graph):
    start_tracking_graph(graph, 'initial_x:=0.7')
    graph.wait_sim_time(0.5)
    graph.clear(topics.DIAGNOSTICS.name)
    assert graph.call(SetBool, '/wallbot/dynamics/pause', SetBool.Request(data=True)).success
    held = graph.held_at(lambda s: s.message == 'paused', what='the paused simulation')  # asserts it holds
    assert graph.call(SetBool, '/wallbot/dynamics/pause', SetBool.Request(data=False)).success
    graph.wait_sim_time(held * 1e-9 + 0.2)

    graph.clear(topics.ODOM.name)
    assert graph.call(Trigger, '/wallbot/dynamics/reset', Trigger.Request()).success
    first = graph.wait_for(lambda: [m for m in graph.messages(topics.ODOM.name) if ns(m) == 0], 30, 'reset')[0]
    assert (first.pose.pose.position.x, first.pose.pose.position.y, first.twist.twist.linear.x) == (0.7, 0.0, 0.0)

    def since_reset() -> list[int]:
        stamps = [ns(m) for m in graph.messages(topics.ODOM.name)]
        return stamps[stamps.index(0):]
    graph.wait_for(lambda: since_reset()[-1] >= 300 * MS, 30, 'time running again from 0 after the reset')
    assert np.all(np.diff(since_reset()) > 0), 'time runs on from 0 after the reset'



def test_step_and_place_a_paused_robot(graph):
    """Gazebo's step and RViz's 2D Pose Estimate: ~/step takes step_count steps of a paused run (and
    is refused while it runs); an initialpose in frame wall puts the robot there at rest, one in
    another frame is rejected."""
    from geometry_msgs.msg import PoseWithCovarianceStamped

    start_graph(graph, 'step_count:=5', constraints=('trajectory_task:=false', 'belt:=true', 'non_lateral:=true',
                                                     'nonslip:=true'), trajectory=None)
    graph.wait_sim_time(0.05)
    refused = graph.call(Trigger, '/wallbot/dynamics/step', Trigger.Request())
    assert not refused.success and 'running' in refused.message
    assert graph.call(SetBool, '/wallbot/dynamics/pause', SetBool.Request(data=True)).success
    held = graph.held_at(lambda s: s.message == 'paused', what='the paused simulation')

    place = graph.node.create_publisher(PoseWithCovarianceStamped, topics.INITIALPOSE.resolve(),
                                        qos_profile(topics.INITIALPOSE))
    graph.wait_for(lambda: place.get_subscription_count() > 0, STALL, 'the dynamics subscribing initialpose')
    pose = PoseWithCovarianceStamped()
    pose.header.frame_id = 'map'
    place.publish(pose)
    graph.wait_for(lambda: "rejected: initialpose: frame 'map'" in graph.runner.output('dynamics'), STALL,
                   'the rejection')
    pose.header.frame_id = topics.WALL_FRAME
    pose.pose.pose.position.x, pose.pose.pose.position.y = 0.3, -0.4
    pose.pose.pose.orientation.z, pose.pose.pose.orientation.w = math.sin(0.5), math.cos(0.5)  # heading 1 rad
    place.publish(pose)
    placed = graph.wait_for(lambda: [m for m in graph.messages(topics.ODOM.name)
                                     if ns(m) == held and m.pose.pose.position.x == 0.3], STALL, 'the placed state')[0]
    assert placed.pose.pose.position.y == -0.4
    assert quaternion_yaw(placed.pose.pose.orientation) == pytest.approx(1.0, abs=1e-12)
    twist = placed.twist.twist
    assert (twist.linear.x, twist.linear.y, twist.angular.z) == (0.0, 0.0, 0.0)

    graph.clear(topics.DIAGNOSTICS.name)
    assert graph.call(Trigger, '/wallbot/dynamics/step', Trigger.Request()).success
    # held: the diagnostics of the paused loop carry its simulation time
    graph.wait_for(lambda: any(ns(a) == held + 5 * MS and s.message == 'paused'
                               for a in graph.messages(topics.DIAGNOSTICS.name) for s in a.status), 5,
                   'paused again 5 steps later')
    after = [m for m in graph.messages(topics.ODOM.name) if ns(m) > held]
    assert [ns(m) for m in after] == [held + k * MS for k in range(1, 6)]
    assert math.hypot(after[-1].pose.pose.position.x - 0.3, after[-1].pose.pose.position.y + 0.4) < 1e-3


def test_driven_mode_rejects_malformed_commands_and_times_out(graph):
    start_graph(graph, 'max_wheel_torque:=1.0', 'command_timeout:=0.3', constraints=('trajectory_task:=false',),
                trajectory=None)  # driven: no trajectory node needed
    graph.wait_sim_time(0.1)
    for data in ([0.1], [0.1, 0.1, 0.1], [math.nan, 0.0], [0.0, math.inf], [2.0, 0.0]):
        graph.torque_pub.publish(Float64MultiArray(data=data))
    graph.wait_for(lambda: graph.runner.output('dynamics').count('rejected: wheel_torque_cmd') >= 1, 5,
                   'rejection warning')
    t_check = graph.last_stamp() * 1e-9 + 0.2
    graph.wait_sim_time(t_check)
    # nothing was integrated: the state is the free robot's without any torque
    robot = Robot(load_robot_parameters())
    free = Simulation(robot, None, ConstraintSelection(False), np.array([0.8, 0, 0, 0, 0, 0, 0.0]), np.zeros(7))
    steps = round(t_check * 1000)
    for _ in range(steps):
        free.step()
    got = final_state(graph, steps * 1e-3)
    assert got[0] == pytest.approx(free.q[0], abs=1e-12) and got[1] == pytest.approx(free.q[1], abs=1e-12)
    assert got[-4:] == [0.0] * 4, 'wheels must not spin without a valid command'

    graph.torque_pub.publish(Float64MultiArray(data=[0.02, -0.02]))
    spinning = graph.wait_for(lambda: [m for m in graph.messages(topics.WHEEL_STATES.name)
                                       if m.velocity[0] > 0.0], STALL, 'wheels driven by the command')[0]
    assert spinning.velocity[2] < 0.0 and spinning.effort[0] == pytest.approx(0.01, abs=1e-12)
    # held for command_timeout (0.3 s of simulation time), then zero torque and a warning
    after = ns(spinning) + 500 * MS
    graph.wait_sim_time(after * 1e-9)
    graph.wait_for(lambda: ns(graph.messages(topics.WHEEL_STATES.name)[-1]) >= after, 20,
                   'wheel_states as far as odometry')  # its own subscription may lag odom's
    driven = [m for m in graph.messages(topics.WHEEL_STATES.name) if ns(m) >= ns(spinning)]
    with_torque = [m for m in driven if m.effort[0] != 0.0]
    duration = (ns(with_torque[-1]) - ns(with_torque[0])) * 1e-9
    assert 0.28 <= duration <= 0.31, f'command held for {duration} s'
    assert driven[-1].effort[0] == 0.0 and driven[-1].velocity[0] == pytest.approx(50.0 * 0.3, rel=0.05)
    assert 'no wheel_torque_cmd for 0.3 s' in graph.runner.output('dynamics')


def test_diverging_state_pauses_with_an_error_and_never_publishes_nan(graph):
    # RK4 at 1 s steps with Baumgarte gains of 1e4 1/s (each within its range) is unstable: the start
    # 0.2 m off the circle grows about 1e14-fold a step until it overflows (at the 15th step)
    start_graph(graph, 'rate_hz:=1', 'real_time_factor:=0.0',
                constraints=('baumgarte_alpha:=10000.0', 'baumgarte_beta:=10000.0'))
    graph.wait_for(lambda: 'simulation paused' in graph.runner.output('dynamics'), 60, 'divergence')  # a stall
    graph.wait_for(lambda: any(s.level == DiagnosticStatus.ERROR for a in graph.messages(topics.DIAGNOSTICS.name)
                               for s in a.status), STALL, 'ERROR diagnostics')
    for msg in graph.messages(topics.WHEEL_STATES.name):
        assert all(math.isfinite(v) for v in (*msg.position, *msg.velocity, *msg.effort))
    for msg in graph.messages(topics.ODOM.name):
        assert all(math.isfinite(v) for v in (msg.pose.pose.position.x, msg.pose.pose.position.y,
                                                  msg.twist.twist.linear.x, msg.twist.twist.angular.z))
    # the step to the reported time diverged, so the last state published is one step (1 s) before it
    graph.held_at(lambda s: s.level == DiagnosticStatus.ERROR, last_published=1000 * MS, what='the diverged run')
    graph.clear(topics.ODOM.name)
    assert graph.call(Trigger, '/wallbot/dynamics/reset', Trigger.Request()).success
    graph.wait_for(lambda: graph.last_stamp() >= 100 * MS, STALL, 'running again after reset')


def run_to(graph: Graph, factor: str, t_end: float):
    start_tracking_graph(graph, f'real_time_factor:={factor}', f'stop_at:={t_end}',
                         constraints=('belt:=true', 'non_lateral:=true', 'nonslip:=true'),
                         trajectory=('shape:=figure8', 'period:=6.0', 'horizon:=0.6', 'sample_dt:=0.02'))
    return final_state(graph, t_end)


def test_same_final_state_at_real_time_factor_1_and_0(process_runner):
    """Replans every 0.3 s (horizon 0.6 s), so this also shows replanning never changes the motion."""
    states = {}
    for factor in ('1.0', '0.0'):
        graph = Graph(process_runner)
        try:
            states[factor] = run_to(graph, factor, 1.2)
            assert graph.runner.output('trajectory').count('plan figure8') >= 3
        finally:
            graph.close()
            process_runner.stop_all()
    assert states['1.0'] == states['0.0']  # bit for bit
    # and both equal the model run through one plan
    robot = Robot(load_robot_parameters())
    reference = messages.sampled_reference(sample_plan(FigureEight(1.0, 6.0), 0.0, 2.0, 0.02))
    sim = Simulation(robot, reference, ConstraintSelection(True, True, True, True),
                     np.array([0.8, 0, 0, 0, 0, 0, 0.0]), np.zeros(7))
    for _ in range(1200):
        sim.step()
    assert states['0.0'][:2] == sim.q[:2].tolist()


def test_namespace_remap_runs_a_second_robot(process_runner):
    graph = Graph(process_runner, namespace='/robot2')
    try:
        graph.start('constraint_config', 'trajectory_task:=false', remap='__ns:=/robot2')
        graph.start('dynamics', remap='__ns:=/robot2')
        graph.wait_sim_time(0.1)
        graph.wait_for(lambda: '/robot2/dynamics' in graph.node.get_fully_qualified_node_names(), 10,
                       'node /robot2/dynamics')
        names = dict(graph.node.get_topic_names_and_types())
        assert '/robot2/odom' in names and '/wallbot/odom' not in names and '/robot2/clock' in names
        assert graph.call(SetBool, '/robot2/dynamics/pause', SetBool.Request(data=True)).success
    finally:
        graph.close()


def test_a_headless_bag_played_into_a_live_dynamics_node_drives_it(graph, tmp_path):
    """simulate --bag, played with `wallbot-sim play`: the dynamics node takes its constraint set
    and its plan, and runs the very motion the bag holds."""
    from bag_helpers import by_topic, fields

    bag = tmp_path / 'headless'
    result = subprocess.run([sys.executable, '-m', 'wallbot_sim.cli.main', 'simulate', '--scenario', 'circle',
                             '--constraints', 'belt,non_lateral,nonslip', '--duration', '0.5', '--engine', 'python',
                             '--bag', str(bag), '--quiet'], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    graph.start('dynamics', 'initial_x:=0.8')
    odom = topics.ODOM.resolve(graph.namespace)
    graph.wait_for(lambda: graph.node.count_publishers(odom) > 0, STALL, 'discovery of the dynamics node')
    # a message of the dynamics received here: matched both ways, so this test sees t = 0
    graph.wait_for(lambda: graph.messages(topics.DIAGNOSTICS.name), STALL, 'the first diagnostics (1 Hz)')
    # play waits for a subscriber on each topic: let that be the dynamics, not this test's own reader
    # (play's latched messages end with it; acknowledged by this test alone they never reached the node)
    played_topics = {topics.CONSTRAINTS.resolve(graph.namespace), topics.REFERENCE_TRAJECTORY.resolve(graph.namespace)}
    for subscription in [sub for sub in graph.node.subscriptions if sub.topic_name in played_topics]:
        graph.node.destroy_subscription(subscription)
    player = graph.runner.start([sys.executable, '-m', 'wallbot_sim.cli.main', 'play', str(bag), '--topics',
                                 'constraints', 'reference_trajectory', '--wait-subscribers', '20', '--delay', '0'],
                                'play')
    assert player.wait(timeout=60) == 0, graph.runner.output('play')
    graph.wait_sim_time(0.5, timeout=30)
    log = graph.runner.output('dynamics')
    assert 'starting with constraints trajectory+tangent_heading+belt+non_lateral+nonslip' in log, log
    assert 'ignoring' not in log, log
    played = {ns(m): fields(m) for m in by_topic(bag)[topics.ODOM.resolve()]}
    live = [m for m in graph.messages(topics.ODOM.name) if ns(m) <= 500 * MS]
    assert len(live) == 501
    assert all(fields(bagio.deserialize(serialize_message(m), topics.ODOM.type)) == played[ns(m)] for m in live)
