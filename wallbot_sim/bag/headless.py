"""``simulate --bag``: the graph's recorded topics written straight from the model, no middleware.

Every message is built by the encoder the graph's nodes publish with (``wallbot_msgs_py.step_cdr``
for the per-step messages, ``wallbot_sim.messages`` and ``wallbot_msgs_py.codec`` for the rest),
so a headless bag holds the messages a recorded ``run`` of the same scenario holds, field for field.
To make that hold for the motion too, the simulation follows what the dynamics node follows: the
trajectory node's plan (the reference sampled every ``messages.SAMPLE_DT``, interpolated quintic
Hermite, renewed at half-way), which agrees with the analytic reference to far below a micrometre.

Log times: a message is logged at the simulation time (ns since 0) of the state it belongs to,
rather than at the recorder's receive time: a step's messages at its stamp; the constraint set and
the robot model (``robot_description``, the URDF constraint_config publishes, once) at the start;
a plan when it is made; a controller's ``wheel_torque_cmd`` (``write_command``) at the stamp of the
state it answers, after that state's messages, as a recorder receives it.

Rates: as the graph publishes them with the nodes' defaults. ``reference`` at ``messages.PUBLISH_RATE_HZ`` of
simulation time, on the trajectory node's grid (every multiple of its period from the plan's start up to the
last state), sampled from the plan as that node samples it; ``/clock`` at ``messages.CLOCK_RATE_HZ`` and at the
last state, as the dynamics node publishes it. One difference, by design: ``/diagnostics``, which the dynamics
publishes once a wall second, is written every DIAGNOSTICS_PERIOD of simulation time (a run at factor 1's rate)
and once at the end, with this process's wall-clock figures.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim import messages
from wallbot_sim.bag.writer import BagWriter
from wallbot_sim.loop.status import MotorSaturation
from wallbot_sim.model import Simulation, StepOutputs, tangent_heading
from wallbot_sim.model.contact import unheld_slip
from wallbot_sim.urdf import robot_urdf

DIAGNOSTICS_PERIOD = 1.0
"""Simulation seconds between /diagnostics messages."""
REFERENCE_PERIOD_NS = round(1e9 / messages.PUBLISH_RATE_HZ)
"""The trajectory node's reference pose period (ns of simulation time) at its default publish_rate_hz."""


class HeadlessBagWriter:
    """Writes every step's outputs of a Simulation into a new bag (and makes it follow the plan)."""

    def __init__(self, writer: BagWriter, simulation: Simulation, namespace: str = topics.NAMESPACE) -> None:
        self.writer, self.simulation, self.namespace = writer, simulation, namespace
        self._conn = {t.name: writer.add_graph_topic(t, namespace) for t in topics.NOISELESS_RECORDED}
        self._step = StepEncoder()
        self._clock_schedule = messages.ClockSchedule(messages.CLOCK_RATE_HZ)
        self._unwritten_clock: tuple[float, bytes] | None = None
        """The newest state's /clock if it was not due: written at the end (the state the run stops at)."""
        self._node_name = f'{namespace.rstrip("/")}/{topics.NODE_DYNAMICS}'
        self._path_reference = simulation.reference
        """The reference the trajectory node samples (the simulation follows its plans)."""
        self._yaw = 0.0
        self._plan = None
        self._last_pose: int | None = None
        """Grid index (stamp / REFERENCE_PERIOD_NS) of the newest reference pose written."""
        self._window_start = time.perf_counter()
        self._window_steps = 0
        self._step_time_max = 0.0
        self._last_write = self._window_start
        self._next_diagnostics = simulation.t
        self._residual_max = 0.0
        self._saturation = MotorSaturation(simulation.robot.params.motor is not None)
        self._residual_settled = math.nan
        self._unreported: StepOutputs | None = None
        t = simulation.t
        selection = simulation.selection
        self._put(topics.CONSTRAINTS, t, messages.constraints_message(
            messages.switches_from_selection(selection), simulation.gains))
        self._put(topics.ROBOT_DESCRIPTION, t, codec.robot_description(robot_urdf(simulation.robot.params)))
        if self._path_reference is not None:
            self._replan(t)

    @classmethod
    def open(cls, path: Path, simulation: Simulation) -> HeadlessBagWriter:
        """A new bag at ``path`` (must not exist); BagError (one line) if it cannot be created."""
        writer = BagWriter(Path(path))
        writer.set_custom_data('wallbot.recorder', 'simulate --bag (headless)')
        writer.set_custom_data('wallbot.constraints', simulation.selection.label())
        return cls(writer, simulation)

    def _put(self, topic: topics.Topic, t: float, data: bytes) -> None:
        self.writer.write(self._conn[topic.name], codec.to_nanoseconds(t), data)

    def _replan(self, t: float) -> None:
        """A plan from t, as the trajectory node makes it, written and handed to the simulation."""
        plan = messages.plan_ahead(self._path_reference, t)
        first = tangent_heading(self._path_reference.sample(plan.times[0]))
        if first is not None:
            self._yaw = first.angle
        self._put(topics.REFERENCE_TRAJECTORY, t, messages.trajectory_message(plan, self._yaw))
        self._put(topics.REFERENCE_PATH, t, messages.path_message(plan, fallback_yaw=self._yaw))
        self.simulation.set_reference(messages.sampled_reference(plan))
        self._plan = plan

    def write(self, out: StepOutputs) -> None:
        """All topics of one step (state, wrench, drive forces, clock, reference, diagnostics)."""
        t = out.t
        for topic, data in self._step.encode(out):
            if topic is not topics.CLOCK:
                self._put(topic, t, data)
            elif self._clock_schedule.due(codec.to_nanoseconds(t)):
                self._put(topic, t, data)
                self._unwritten_clock = None
            else:
                self._unwritten_clock = (t, data)
        if self._plan is not None:
            self._write_poses(codec.to_nanoseconds(t))
        if self._plan is not None and messages.replan_due(self._plan, t):
            self._replan(t)
        self._note(out)

    def _write_poses(self, stamp_ns: int) -> None:
        """The reference poses of the grid points up to ``stamp_ns`` not written yet (from the plan's start), each
        sampled at its grid time from the plan, as the trajectory node publishes them."""
        newest = stamp_ns // REFERENCE_PERIOD_NS
        last = self._last_pose
        if last is None:
            last = -(-codec.to_nanoseconds(self._plan.times[0]) // REFERENCE_PERIOD_NS) - 1
        reference = self.simulation.reference
        for k in range(last + 1, newest + 1):
            t = k * REFERENCE_PERIOD_NS * 1e-9
            data, self._yaw = messages.reference_message(reference.sample(t), t, self._yaw)
            self._put(topics.REFERENCE, t, data)
        self._last_pose = max(last, newest)

    def write_command(self, t: float, tau_left: float, tau_right: float) -> None:
        """A controller's ``wheel_torque_cmd`` answering the state of time ``t`` (call it after that
        step's ``write``); the topic is registered with its first command, as a recorder adds it."""
        if topics.WHEEL_TORQUE_CMD.name not in self._conn:
            self._conn[topics.WHEEL_TORQUE_CMD.name] = self.writer.add_graph_topic(topics.WHEEL_TORQUE_CMD,
                                                                                   self.namespace)
        self._put(topics.WHEEL_TORQUE_CMD, t, codec.wheel_torque_cmd(tau_left, tau_right))

    def _note(self, out: StepOutputs) -> None:
        now = time.perf_counter()
        self._step_time_max = max(self._step_time_max, now - self._last_write)
        self._last_write = now
        self._window_steps += 1
        self._residual_max = max(self._residual_max, out.residual)
        self._residual_settled = messages.settled_residual(self._residual_settled, out.residual, out.t)
        self._unreported = out
        self._saturation.note(out.t, self.simulation.motor_torque, out.motor_torque)
        if out.t >= self._next_diagnostics - 1e-12:
            self._diagnostics(out, 'running')

    def _diagnostics(self, out: StepOutputs, status: str) -> None:
        elapsed = max(time.perf_counter() - self._window_start, 1e-9)
        rate = self._window_steps / elapsed
        loop = messages.LoopFigures(rate, rate * self.simulation.dt, 0.0, 1e3 * elapsed / max(self._window_steps, 1),
                                    1e3 * self._step_time_max, 0.0, 0, 'normal')
        selection = self.simulation.selection
        command = messages.COMMAND_IGNORED if selection.trajectory else messages.applied_command(*out.motor_torque)
        sim = self.simulation
        motor, saturated = self._saturation.report()
        diagnostics = messages.simulation_status(
            self._node_name, status, False, command, out.t, loop, out.residual, self._residual_max,
            selection.label(), sim.robot.adsorption, residual_settled=self._residual_settled,
            contact=messages.contact_values(sim.contact_model, sim.coulomb_applies, out.contact),
            sliding=unheld_slip(sim.robot, selection, out), slipping=messages.slipping_wheels(out.contact),
            motor=motor, saturated=saturated)
        self._put(topics.DIAGNOSTICS, out.t, codec.diagnostics(out.t, [diagnostics]))
        self._next_diagnostics = out.t + DIAGNOSTICS_PERIOD
        self._window_start, self._window_steps, self._step_time_max = time.perf_counter(), 0, 0.0
        self._residual_max, self._residual_settled = 0.0, math.nan
        self._unreported = None

    def close(self) -> None:
        """Write the last state's /clock and report the steps since the last diagnostics (their
        residuals belong to the run), then close."""
        if self._unwritten_clock is not None:
            self._put(topics.CLOCK, *self._unwritten_clock)
        if self._unreported is not None:
            self._diagnostics(self._unreported, messages.stopped_status(self._unreported.t))
        self.writer.close()
