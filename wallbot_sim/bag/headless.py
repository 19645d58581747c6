"""``simulate --bag``: the graph's recorded topics written straight from the model, no middleware.

The per-step messages are the dynamics node's own bytes (``wallbot_msgs_py.step_cdr``, ROS-free).
The reference pose is the trajectory node's conversion serialized by rclpy when ROS is installed,
else the ROS-free encoder of ``wallbot_msgs_py.bagio`` (same type, frames and field layout).
Either way the loader, plots, ``play`` and ``summary`` treat this bag like one recorded from ``run``. Differences, by design: the receive timestamps are the
simulation time (ns since 0) rather than the recorder's clock, and ``/diagnostics`` is written at
DIAGNOSTICS_RATE Hz with ``max_residual``, the largest residual since the previous one.
"""

from __future__ import annotations

import math
from pathlib import Path

from wallbot_msgs_py import bagio, topics
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim.bag.writer import BagWriter
from wallbot_sim.model import ReferenceSample, Simulation, StepOutputs, tangent_heading

DIAGNOSTICS_RATE = 10.0
"""Hz of /diagnostics (residual, constraint set)."""
PATH_STEP = 0.05
"""Seconds between points of the recorded reference_path."""


class HeadlessBagWriter:
    """Writes every step's outputs of a Simulation into a new bag."""

    def __init__(self, writer: BagWriter, simulation: Simulation, namespace: str = topics.NAMESPACE) -> None:
        self.writer, self.simulation, self.namespace = writer, simulation, namespace
        self._next_diagnostics = -math.inf
        self._max_residual = 0.0
        self._conn = {t.name: writer.add_graph_topic(t, namespace)
                      for t in (topics.ODOM, topics.WHEEL_STATES, topics.CONSTRAINT_WRENCH, topics.DRIVE_FORCES,
                                topics.WHEEL_CONTACT,
                                topics.REFERENCE, topics.REFERENCE_PATH, topics.CONSTRAINTS, topics.CLOCK,
                                topics.DIAGNOSTICS)}
        self._latched_done = False
        self._ros = _ros_conversions()
        self._step = StepEncoder()

    @classmethod
    def open(cls, path: Path, simulation: Simulation) -> HeadlessBagWriter:
        """A new bag at ``path`` (must not exist); BagError (one line) if it cannot be created."""
        writer = BagWriter(Path(path))
        writer.set_custom_data('wallbot.recorder', 'simulate --bag (headless)')
        writer.set_custom_data('wallbot.constraints', simulation.selection.label())
        return cls(writer, simulation)

    def _put_raw(self, topic: topics.Topic, t: float, data: bytes) -> None:
        self.writer.write(self._conn[topic.name], int(round(t * 1e9)), data)

    def _put(self, topic: topics.Topic, t: float, msg: object) -> None:
        self.writer.write(self._conn[topic.name], int(round(t * 1e9)), bagio.serialize(msg, topic.type))

    def _latched(self, t: float) -> None:
        reference = self.simulation.reference
        if reference is not None:
            horizon = float(getattr(reference, 'period', 30.0))
            count = int(round(horizon / PATH_STEP))
            points = []
            for k in range(count + 1):
                tp = t + k * PATH_STEP
                px, py = reference.sample(tp).position
                points.append((tp, px, py))
            self._put(topics.REFERENCE_PATH, t, bagio.path(t, points))
        selection = self.simulation.selection
        self._put(topics.CONSTRAINTS, t, bagio.diagnostic_status(
            'wallbot/constraints', selection.label(), {'active': ','.join(selection.active_names())}))
        self._latched_done = True

    def write(self, out: StepOutputs) -> None:
        """All topics of one step (t, state, wrench, drive forces, reference, clock, diagnostics)."""
        t = out.t
        if not self._latched_done:
            self._latched(t)
        for topic, data in self._step.encode(out):
            self._put_raw(topic, t, data)
        if out.reference is not None:
            self._put_raw(topics.REFERENCE, t, self._reference_bytes(out.reference, t))
        self._diagnostics(out)

    def _reference_bytes(self, sample: ReferenceSample, t: float) -> bytes:
        if self._ros is not None:
            conversions, serialize = self._ros
            return serialize(conversions.reference_odometry_message(sample, t))
        heading = tangent_heading(sample)
        theta = heading.angle if heading is not None else 0.0
        rate = heading.rate if heading is not None else 0.0
        return bagio.serialize(bagio.odometry(t, *sample.position, theta, *sample.velocity, rate,
                                              child=topics.REFERENCE_FRAME), topics.REFERENCE.type)

    def _diagnostics(self, out: StepOutputs) -> None:
        t = out.t
        self._max_residual = max(self._max_residual, out.residual)
        if t >= self._next_diagnostics - 1e-12:
            self._next_diagnostics = t + 1.0 / DIAGNOSTICS_RATE
            status = bagio.diagnostic_status('wallbot/dynamics', 'running', {
                'residual': f'{out.residual:.17g}', 'max_residual': f'{self._max_residual:.17g}',
                'tracking_error': f'{out.tracking_error:.17g}', 'constraints': self.simulation.selection.label()})
            self._put(topics.DIAGNOSTICS, t, bagio.diagnostic_array(t, [status]))
            self._max_residual = 0.0

    def close(self) -> None:
        self.writer.close()


def _ros_conversions():
    """(conversions module, rclpy serialize_message), or None without a ROS install."""
    try:
        from rclpy.serialization import serialize_message

        from wallbot_msgs_py import conversions
        conversions.reference_odometry_message  # noqa: B018 (API check)
    except Exception:  # no ROS, or conversions not there yet: the ROS-free encoders
        return None
    return conversions, serialize_message
