"""What ``wallbot-sim run`` sees of the graph it started: how far the recorder got, the dynamics' diagnostics,
the trajectory node's reference poses (a node of its own, in the run's domain and the robot's namespace)."""

from __future__ import annotations

import math

from wallbot_msgs_py import codec, topics
from wallbot_sim import messages


class Monitor:
    """The launcher's own view of the graph: how far the recorder got, the dynamics' diagnostics."""

    def __init__(self, namespace: str = topics.NAMESPACE) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock

        from wallbot_msgs_py.qos import qos_profile
        from wallbot_sim.nodes.common import events_executor
        self._rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.node = rclpy.create_node('run_monitor', namespace=namespace, context=self.context)
        self.executor = events_executor(self.context)  # a callback per message, no wait set per wake-up
        self.executor.add_node(self.node)
        self.recorded = -math.inf
        """Simulation time up to which the recorder has written the run: its newest record_progress (which
        goes back with the run at a ``~/reset`` of the dynamics)."""
        self.diagnostics: dict[str, str] = {}
        """The values of the newest status of the dynamics in ``namespace``."""
        self.reference_time = -math.inf
        self.progress_topic = topics.RECORD_PROGRESS.resolve(namespace)
        self.node.create_subscription(Clock, topics.RECORD_PROGRESS.name, self._on_progress,
                                      qos_profile(topics.RECORD_PROGRESS), raw=True)
        self.node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS.name, self._on_diagnostics,
                                      qos_profile(topics.DIAGNOSTICS), raw=True)
        # only the stamp is read (100 poses per simulated second)
        self.node.create_subscription(Odometry, topics.REFERENCE.name, self._on_reference,
                                      qos_profile(topics.REFERENCE), raw=True)

    def _on_progress(self, data: bytes) -> None:
        self.recorded = codec.decode_clock(data) * 1e-9

    def _on_reference(self, data: bytes) -> None:
        stamp_ns = codec.leading_stamp_ns(data)
        if stamp_ns is not None:
            self.reference_time = stamp_ns * 1e-9

    def _on_diagnostics(self, data: bytes) -> None:
        try:  # every robot of the domain publishes on /diagnostics: its own dynamics' status only
            status = codec.simulation_status(codec.decode_diagnostics(data).statuses, self.node.get_namespace())
        except ValueError:
            return
        if status is not None:
            self.diagnostics = status.value_map()

    def dynamics_stopped(self) -> bool:
        """Whether the dynamics' latest diagnostics say it has stopped (so they cover every step)."""
        return self.diagnostics.get('status', '').startswith('stopped')

    def reference_reached(self, duration: float) -> bool:
        """Whether the trajectory node has published its last reference pose of a run of ``duration``."""
        return self.reference_time >= duration - 1.0 / messages.PUBLISH_RATE_HZ - 1e-9

    def spin(self, seconds: float) -> None:
        self.executor.spin_once(timeout_sec=seconds)

    def recorder_ready(self) -> bool:
        return self.node.count_publishers(self.progress_topic) > 0

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self._rclpy.try_shutdown(context=self.context)
