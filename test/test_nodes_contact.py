"""Wheel-wall contact in the node graph over DDS: contact_model and adhesion_force changed while
running, per-step wheel_contact messages, WARN while slipping, ERROR and a pause on detachment."""

from __future__ import annotations

import re

import pytest
import yaml

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from graph_helpers import STALL, Graph, start_graph  # noqa: E402
from wallbot_msgs_py import topics  # noqa: E402
from wallbot_sim.paths import robot_yaml  # noqa: E402

DRIVEN = ('trajectory_task:=false', 'belt:=true', 'non_lateral:=true', 'nonslip:=true')


@pytest.fixture
def graph(process_runner):
    g = Graph(process_runner)
    g.subscribe('contact', JointState, topics.WHEEL_CONTACT.resolve(g.namespace), topics.WHEEL_CONTACT)
    try:
        yield g
    finally:
        g.close()


def simulation_status(graph: Graph, level: int, words: str):
    """The newest dynamics status at ``level`` whose message holds ``words``, or None."""
    for array in reversed(graph.messages(topics.DIAGNOSTICS.name)):
        for status in array.status:
            if 'simulation' in status.name and status.level == level and words in status.message:
                return status
    return None


def test_contact_model_and_adhesion_change_at_run_time(graph):
    start_graph(graph, 'initial_x:=0.0', 'contact_model:=coulomb', constraints=DRIVEN, trajectory=None)
    first = graph.wait_for(lambda: graph.messages('contact'), STALL, 'wheel_contact')[0]
    wheels = list(topics.WHEEL_JOINTS)
    assert list(first.name) == wheels + [f'{w}/x' for w in wheels] + [f'{w}/y' for w in wheels]
    assert list(first.effort[:4]) == pytest.approx([38.10, 38.10, 56.50, 56.50], abs=0.01)
    assert list(first.position[:4]) == pytest.approx([0.667] * 4, abs=5e-4) and list(first.velocity[:4]) == [0.0] * 4
    assert sum(first.effort[8:]) == pytest.approx(9.0 * 9.81)  # the wheels' forces along y_p hold the weight

    refused = graph.set_parameters('dynamics', contact_model='sticky', adhesion_force=-1.0)
    assert not any(result.successful for result in refused)
    assert 'contact_model must be one of ideal, coulomb' in refused[0].reason

    assert all(result.successful for result in graph.set_parameters('dynamics', adhesion_force=100.0))
    slipping = graph.wait_for(lambda: [m for m in graph.messages('contact') if list(m.velocity[:4]) == [1.0] * 4],
                              10, 'every wheel sliding')[0]
    assert sum(slipping.effort[:4]) == pytest.approx(100.0)  # the loads share the new force
    graph.wait_for(lambda: simulation_status(graph, DiagnosticStatus.WARN, 'sliding: left front at'), 10,
                   'WARN while sliding')

    assert all(result.successful for result in graph.set_parameters('dynamics', contact_model='ideal'))
    stamp = graph.last_stamp()
    held = graph.wait_for(lambda: [m for m in graph.messages(topics.ODOM.name)
                                   if m.header.stamp.sec * 10**9 + m.header.stamp.nanosec > stamp
                                   and abs(m.twist.twist.linear.y) < 1e-9], STALL, 'the ideal contact holding')
    assert held
    graph.clear('contact')
    newest = graph.wait_for(lambda: graph.messages('contact'), STALL, 'wheel_contact after the switch')[-1]
    assert list(newest.velocity[:4]) == [0.0] * 4 and min(newest.position[:4]) > 1.0  # ideal: what friction needs


def test_detachment_pauses_with_an_error(graph, tmp_path):
    """A CoM 0.25 m from the wall tips the robot off at 130 N (docs/model.md 11.4's detachment case)."""
    robot = yaml.safe_load(robot_yaml().read_text())
    robot['com_height'] = 0.25
    robot['adhesion_force'] = 400.0
    robot_file = tmp_path / 'tall.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    start_graph(graph, 'initial_x:=0.0', 'contact_model:=coulomb', f'robot_file:={robot_file}', constraints=DRIVEN,
                trajectory=None)
    first = graph.wait_for(lambda: graph.messages('contact'), STALL, 'wheel_contact')[0]
    assert sum(first.effort[:4]) == pytest.approx(400.0)  # the robot file's force (the parameter is 0)
    assert all(result.successful for result in graph.set_parameters('dynamics', adhesion_force=130.0))
    graph.wait_for(lambda: simulation_status(graph, DiagnosticStatus.ERROR, 'detached'), STALL, 'ERROR on detachment')
    detached_at = float(re.search(r'lifted off the wall: normal load -?[\d.]+ N at t = ([\d.]+) s',
                                  graph.runner.output('dynamics')).group(1))
    held = graph.held_at(lambda s: s.level == DiagnosticStatus.ERROR, what='the detached robot')  # asserts it holds
    assert held == round(detached_at * 1e9), 'a detached robot is paused where it lifted off'
    assert graph.procs['dynamics'].poll() is None
