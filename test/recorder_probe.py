"""A stand-in recorder for the nodes that hold back until a recorder hears them (``wait_for_recorder``),
spun with them in one process: a node in the graph's namespace publishing record_progress."""

from __future__ import annotations

import time
from typing import Callable

from rclpy.executors import Executor
from rclpy.node import Node


def recorder_probe(context, executor: Executor) -> Node:
    """A node publishing record_progress (a recorder, as the graph's nodes tell one), added to ``executor``."""
    import rclpy
    from rosgraph_msgs.msg import Clock

    from wallbot_msgs_py import topics
    from wallbot_msgs_py.qos import qos_profile
    probe = rclpy.create_node('recorder_probe', namespace=topics.NAMESPACE, context=context)
    probe.create_publisher(Clock, topics.RECORD_PROGRESS.name, qos_profile(topics.RECORD_PROGRESS))
    executor.add_node(probe)
    return probe


def spin_for(executor: Executor, seconds: float) -> None:
    """Spin ``executor`` for ``seconds`` of wall time (to show that something does not happen)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.02)


def spin_until(executor: Executor, condition: Callable[[], bool], seconds: float, what: str) -> None:
    """Spin ``executor`` until ``condition`` holds; AssertionError naming ``what`` after ``seconds``."""
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, what
        executor.spin_once(timeout_sec=0.02)
