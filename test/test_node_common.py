"""nodes.common.run: a clean exit on the shutdown race, a real failure still raised."""

from __future__ import annotations

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
