"""nodes.common: run exits cleanly on the shutdown race and still raises a real failure;
heard_by_every."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.node import Node  # noqa: E402

from wallbot_sim.nodes import common  # noqa: E402


def spin_raising(shut_down_first: bool):
    def spin(node: Node) -> None:
        if shut_down_first:  # what SIGTERM does, here while the executor builds its wait set
            rclpy.shutdown(context=node.context)
        raise RuntimeError('failed to initialize wait set: the given context is not valid')
    return spin


def test_shutdown_during_spin_is_a_clean_exit(monkeypatch):
    monkeypatch.setattr(common.rclpy, 'spin', spin_raising(shut_down_first=True))
    assert common.run(lambda: Node('shutdown_race'), []) == 0


def test_an_error_while_running_is_not_hidden(monkeypatch):
    monkeypatch.setattr(common.rclpy, 'spin', spin_raising(shut_down_first=False))
    with pytest.raises(RuntimeError, match='wait set'):
        common.run(lambda: Node('real_failure'), [])


class FakeGraph:
    """The graph queries heard_by_every makes, answered from fixed endpoint lists."""

    def __init__(self, senders, listeners):
        self.senders, self.listeners = senders, listeners

    def get_publishers_info_by_topic(self, topic):
        return [SimpleNamespace(node_namespace=ns, node_name=name) for ns, name in self.senders]

    def get_subscriptions_info_by_topic(self, topic):
        return [SimpleNamespace(node_namespace=ns, node_name=name) for ns, name in self.listeners]


def publisher(matched: int):
    return SimpleNamespace(topic_name='/wallbot/odom', get_subscription_count=lambda: matched)


CONTROLLER, RECORDER = ('/wallbot', 'controller'), ('/wallbot', 'recorder')
UNKNOWN = ('_NODE_NAMESPACE_UNKNOWN_', common.UNKNOWN_NODE)


@pytest.mark.parametrize('senders, listeners, matched, heard', [
    ([CONTROLLER], [CONTROLLER, RECORDER], 2, True),
    ([], [RECORDER], 1, False),                             # nobody sends yet
    ([CONTROLLER], [RECORDER], 1, False),                   # the sender does not listen
    ([CONTROLLER], [CONTROLLER, RECORDER], 1, False),       # a listener not matched yet
    ([UNKNOWN], [UNKNOWN, RECORDER], 2, False),             # two unidentified nodes are not one
])
def test_heard_by_every(senders, listeners, matched, heard):
    assert common.heard_by_every(FakeGraph(senders, listeners), publisher(matched), '/wallbot/cmd') is heard
