"""dynamics_node: the constrained model integrated with RK4, owning simulation time: its robot's
``clock`` (and the domain's ``/clock`` with ``domain_clock``, topics.DOMAIN_CLOCK).

Threads. The stepping runs in a dedicated loop thread (``wallbot_sim.loop``, which holds the loop's
state and decisions, free of ROS, and explains determinism, lockstep, back-pressure, blocks of steps
and resume); the executor (main thread) only receives messages, service calls and parameter sets and
hands them to the loop as typed events, which the loop applies at the next step boundary. No physics
runs in a callback.

Pacing (``loop.pacing``). At factor f > 0 each state is published when due (one anchor per run segment, so
lateness never accumulates into drift), its lateness reported in /diagnostics. With ``realtime_priority`` > 0
the loop thread runs under SCHED_FIFO for steps it sleeps before; off by default, since the latency it saves is
shifted onto the rest of the graph (controllers, recorders) on a small machine.

Parameters: the table ``settings.dynamics`` (ranges, choices and read-only flags in their descriptors).
``use_sim_time`` is fixed at false: the node owns the clock.

In process. Composed with the recorder (``dynamics_recorder``) the node also hands every step's
messages to a ``StepTap``, and the topics it taps count as heard by the recorder.
"""

from __future__ import annotations

import gc
import math
import sys
import threading
import time
import traceback
from typing import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import MultiDOFJointTrajectory

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import offered_qos_profile, qos_profile
from wallbot_msgs_py.snapshot import DynamicsSnapshot, decode_snapshot, encode_snapshot
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters, load_world
from wallbot_sim.loop import (ConstraintSwitch, DynamicsLoop, NewPlan, Pacer, ParameterChange, Pause, PreparedState,
                              PumpCommand, RecordProgress, Reset, ResumeSnapshot, RunState, Step, Teleport,
                              TorqueCommand)
from wallbot_sim.loop.commands import THROTTLE
from wallbot_sim.loop.faults import FaultChange, faults_on
from wallbot_sim.model import ModelError, ParameterError, SampledReference, StepOutputs
from wallbot_sim.model.contact import unheld_slip
from wallbot_sim.model.outputs import StepBlock
from wallbot_sim.model.simulation import NUMBA
from wallbot_sim.nodes.common import exit_process, heard_by_every, run, steady_timer
from wallbot_sim.nodes.parameters import declare_typed, param_dict, parameter_result
from wallbot_sim.nodes.state_publisher import StatePublisher
from wallbot_sim.nodes.step_tap import StepTap
from wallbot_sim.settings.dynamics import DYNAMICS, DynamicsSettings
from wallbot_sim.settings.table import SettingsTable, changed, text_of
from wallbot_sim.urdf import RobotFrames

class DynamicsNode(Node):
    """The ROS interface of the simulation loop (``wallbot_sim.loop``): parameters, topics, services,
    diagnostics, and the loop thread. ``tap``: a recorder in the same process also gets every
    step's messages from it (the per-step topics it taps need no DDS subscriber to count as heard).
    ``table``: the settings it declares (the composed process fixes some)."""

    def __init__(self, tap: StepTap | None = None, table: SettingsTable = DYNAMICS, **kwargs) -> None:
        super().__init__(topics.NODE_DYNAMICS, namespace=topics.NAMESPACE, **kwargs)
        self.tap, self.table = tap, table
        self.settings: DynamicsSettings = declare_typed(self, DynamicsSettings, table)
        frames = RobotFrames(self.settings.odom_frame_id, self.settings.base_frame_id, self.settings.frame_prefix)
        if frames.reasons():
            raise ValueError('; '.join(frames.reasons()))
        self._warn_lockstep_unseen()
        self.exit_status: int | None = None
        """Set once the node cannot go on (its start gave up, or a strict lockstep's answer did not come):
        ``common.run_nodes`` ends the process with it."""
        self.loop = DynamicsLoop(self.settings, load_robot_parameters(self.settings.robot_file or None), self,
                                 self.get_logger(), Pacer(self.settings.realtime_priority, self.get_logger().warning),
                                 world=load_world(self.settings.world_file))
        self._create_publishers(frames)
        self._create_subscriptions()
        self.pause_requested = False
        """What the last ~/pause asked (the loop applies it at its next step boundary)."""
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.create_service(Trigger, '~/step', self._on_step)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        steady_timer(self, 1.0, self._publish_diagnostics)
        self._stop_reported = False
        steady_timer(self, STOP_POLL, self._report_stop)
        self.loop_thread = threading.Thread(target=self._run_loop, name='simulation', daemon=True)
        self.loop_thread.start()

    def _kernel_loaded(self) -> bool:
        """Load the compiled kernel the steps take, or compile it into numba's cache (a machine's first start, about
        a minute), in the loop thread while the executor discovers the graph and takes its first messages; False if
        numba is missing (said on one line; the node then exits with status 1)."""
        # imported only here: numba takes about a second to import, which the python engine need not pay
        from wallbot_sim.model.compiled import compile_run, require_numba
        try:
            require_numba()
        except ParameterError as error:
            self.get_logger().error(f'{error}; exiting')
            self.exit_status = 1
            return False
        self.get_logger().info("engine numba: loading the compiled kernel (a machine's first start compiles it into "
                               "numba's cache, about a minute)")
        with self.loop.loading_kernel():
            compile_run(self.settings.contact_model)
            # the objects the load made live for the whole run: frozen with the start-up's (started_node), out of
            # every collection's reach (left to the collector, they cost the loop a full collection of 12 ms later)
            gc.collect()
            gc.freeze()
        return True

    def _create_publishers(self, frames: RobotFrames) -> None:
        """The per-step topics' publishers (``StatePublisher``), diagnostics, snapshots and fault events."""
        self.states = StatePublisher(self, frames, self.loop.robot, self.tap)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name,
                                                     offered_qos_profile(topics.DIAGNOSTICS))
        self.snapshot_pub = self.create_publisher(Float64MultiArray, topics.STATE_SNAPSHOT.name,
                                                  qos_profile(topics.STATE_SNAPSHOT))
        self.fault_pub = self.create_publisher(DiagnosticArray, topics.FAULTS.name, qos_profile(topics.FAULTS))

    def _create_subscriptions(self) -> None:
        self.progress_topic = self.resolve_topic_name(topics.RECORD_PROGRESS.name)
        self.command_topic = self.resolve_topic_name(topics.WHEEL_TORQUE_CMD.name)
        self.resume_topic = self.resolve_topic_name(topics.RESUME_STATE.name)
        self.create_subscription(DiagnosticStatus, topics.CONSTRAINTS.name, self._on_constraints,
                                 qos_profile(topics.CONSTRAINTS), raw=True)
        self.create_subscription(MultiDOFJointTrajectory, topics.REFERENCE_TRAJECTORY.name, self._on_plan,
                                 qos_profile(topics.REFERENCE_TRAJECTORY), raw=True)  # see plan_from_cdr
        self.command_sub = self.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, self._on_command,
                                                    qos_profile(topics.WHEEL_TORQUE_CMD), raw=True)
        self.create_subscription(Float64, topics.PUMP_COMMAND.name, self._on_pump_command,
                                 qos_profile(topics.PUMP_COMMAND), raw=True)
        self.create_subscription(ClockMsg, topics.RECORD_PROGRESS.name, self._on_progress,
                                 qos_profile(topics.RECORD_PROGRESS), raw=True)
        self.create_subscription(Float64MultiArray, topics.RESUME_STATE.name, self._on_resume_state,
                                 qos_profile(topics.RESUME_STATE), raw=True)
        self.create_subscription(PoseWithCovarianceStamped, topics.INITIALPOSE.name, self._on_initialpose,
                                 qos_profile(topics.INITIALPOSE), raw=True)

    # --- executor side: callbacks decode messages and post them to the loop ------------------
    def _on_constraints(self, data: bytes) -> None:
        try:
            self.loop.post(ConstraintSwitch(*messages.constraints_from_cdr(data)))
        except ValueError as error:
            self.get_logger().error(f'ignoring constraints message: {error}')

    def _on_plan(self, data: bytes) -> None:
        try:
            plan = messages.plan_from_cdr(data)
            reference = SampledReference(*plan)
        except (ValueError, ModelError) as error:
            self.get_logger().error(f'ignoring reference_trajectory: {error}')
            return
        final = messages.plan_is_final(plan)
        self.loop.post(NewPlan(reference, plan.times[0], plan.times[-1], final))
        # said here, not where the loop applies it: an rclpy log line takes 0.3 ms (up to 15 ms), which in the
        # loop thread came out of the 1 ms before the state after every plan is due
        self.get_logger().info(f'reference plan {plan.times[0]:.3f} .. {plan.times[-1]:.3f} s'
                               f'{" (ends at rest)" if final else ""}')

    def _on_command(self, data: bytes) -> None:
        try:
            self.loop.post(TorqueCommand(codec.decode_wheel_torque_cmd(data, self.settings.max_wheel_torque)))
        except ValueError as error:
            self.get_logger().warning(f'rejected: {error}', throttle_duration_sec=THROTTLE)

    def _on_pump_command(self, data: bytes) -> None:
        try:
            self.loop.post(PumpCommand(codec.decode_pump_command(data)))
        except ValueError as error:
            self.get_logger().warning(f'rejected: {error}', throttle_duration_sec=THROTTLE)

    def _on_progress(self, data: bytes) -> None:
        self.loop.post(RecordProgress(codec.decode_clock(data)))

    def _on_resume_state(self, data: bytes) -> None:
        if self.loop.resume.settled:  # read by the executor thread: at worst one more message is decoded
            return
        try:
            self.loop.post(ResumeSnapshot(decode_snapshot(data)))
        except ValueError as error:
            self.get_logger().error(f'ignoring resume_state: {error}')

    def _on_reset(self, _request, response):
        self.loop.post(Reset())
        response.success, response.message = True, 'reset to the initial state at t = 0 at the next step boundary'
        return response

    def _on_pause(self, request, response):
        self.pause_requested = bool(request.data)
        self.loop.post(Pause(bool(request.data)))
        response.success = True
        response.message = 'paused' if request.data else 'running'
        return response

    def _on_step(self, _request, response):
        if not (self.pause_requested or self.loop.paused):
            response.success, response.message = False, 'running: ~/step advances a paused simulation (~/pause true)'
            return response
        count = self.settings.step_count
        self.loop.post(Step(count))
        response.success, response.message = True, f'{count} step(s) (step_count) at the next step boundary'
        return response

    def _on_initialpose(self, data: bytes) -> None:
        try:
            self.loop.post(Teleport(*codec.decode_initial_pose(data, self.settings.odom_frame_id)))
        except ValueError as error:
            self.get_logger().warning(f'rejected: {error}', throttle_duration_sec=THROTTLE)

    def _on_set(self, parameters):
        return parameter_result(self.table.reasons(param_dict(parameters)))

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, self.table.names)
        if changes:
            self.settings = changed(self.settings, changes)
            self.loop.post(ParameterChange(changes))
            if {'lockstep_every', 'control_odom_every'} & set(changes):
                self._warn_lockstep_unseen()

    def _warn_lockstep_unseen(self) -> None:
        lockstep, every = self.settings.lockstep_every, self.settings.control_odom_every
        if lockstep and every and lockstep % every:
            self.get_logger().warning(f'lockstep_every {lockstep} is not a multiple of control_odom_every {every}: '
                                      'a controller on control_odom misses states the loop waits on')

    # --- the loop's view of the graph (dynamics_loop.Graph), called from the loop thread --------
    def prepare(self, out: StepOutputs, clock: bool) -> Callable[[], None]:
        return self.states.prepare(out, clock)

    def encodes_blocks(self, burst: bool) -> bool:
        return self.states.encodes_blocks(burst)

    def prepare_block(self, block: StepBlock) -> list[PreparedState]:
        return self.states.prepare_block(block)

    def publish_snapshot(self, snapshot: DynamicsSnapshot) -> None:
        self.snapshot_pub.publish(encode_snapshot(snapshot))

    def publish_fault(self, change: FaultChange) -> None:
        self.fault_pub.publish(codec.fault_event(
            change.t, self.get_fully_qualified_name(), change.changed, change.cause,
            [(name, text_of(value)) for name, value in change.values], 'warn' if faults_on(self.loop.settings) else 'ok'))

    def recorder_present(self) -> bool:
        return self.count_publishers(self.progress_topic) > 0

    def recorder_listening(self) -> bool:
        tapped = self.tap.names if self.tap is not None else {}
        return self.recorder_present() and all(topic in tapped or pub.get_subscription_count() > 0
                                               for topic, pub in self.states.publishers_.items())

    def keeper_seen(self) -> bool:
        return self.count_publishers(self.resume_topic) > 0

    def resend_to_controller(self) -> None:
        self.states.resend_to_controller()

    def controller_listening(self) -> bool:
        # and every discovered command publisher is matched here: its answer to the first state
        # must not be sent before (the other direction is the controller's to check)
        states = self.states
        sensors = ((states.publishers_[topics.ODOM], states.control_odom_pub) if self.settings.command_sensor == 'odom'
                   else (states.publishers_[topics.WHEEL_STATES],))
        return (any(heard_by_every(self, publisher, self.command_topic) for publisher in sensors)
                and self.command_sub.get_publisher_count() >= self.count_publishers(self.command_topic))

    def _run_loop(self) -> None:
        try:
            if self.settings.engine == NUMBA and not self._kernel_loaded():
                return
            self.loop.run()
        except Exception:  # noqa: BLE001 - a loop crash must be visible, not a silent thread death
            if self.loop.stopping.is_set() or not self.context.ok():
                return  # shutting down (Ctrl-C, SIGTERM): publishers are gone, nothing to report
            self.get_logger().fatal('simulation loop failed:\n' + traceback.format_exc())
            self.loop.fail()
            return
        if self.loop.gave_up is not None and self.context.ok():
            self._publish_diagnostics()  # the ERROR status naming what was missing, before the process ends
            # taken by every subscriber before the node leaves DDS: a starved one still behind on the
            # WARN ones would otherwise never get it (Fast DDS repairs at its heartbeat, after the exit)
            self.diagnostics_pub.wait_for_all_acked(Duration(seconds=FINAL_DIAGNOSTICS_WAIT))
            self.exit_status = 1

    # --- diagnostics (executor, 1 Hz wall) --------------------------------------------------
    def _report_stop(self) -> None:
        """The diagnostics of a stop (stop_at reached) at once, not up to a second later: they close the run's last
        window of residuals, which ``wallbot-sim run`` waits for before it ends the graph."""
        stopped = self.loop.status.state is RunState.STOPPED
        if stopped and not self._stop_reported:
            self._publish_diagnostics()
        self._stop_reported = stopped

    def _publish_diagnostics(self) -> None:
        loop = self.loop
        window = loop.statistics.take()
        sim, out, status = loop.sim, loop.last_outputs, loop.status
        motor, saturated = loop.saturation.report()
        elapsed = max(time.perf_counter() - window.started, 1e-9)
        t = sim.t if sim is not None else 0.0
        rate = window.steps / elapsed
        dt = sim.dt if sim is not None else 1.0 / self.settings.rate_hz
        figures = messages.LoopFigures(
            rate, rate * dt, self.settings.real_time_factor, 1e3 * window.step_time_sum / max(window.steps, 1),
            1e3 * window.step_time_max, 1e3 * window.lateness_max, window.late,
            loop.pacer.policy)
        report = messages.simulation_status(
            self.get_fully_qualified_name(), str(status), loop.in_error, loop.command_state(), t, figures,
            float(out.residual) if out is not None else math.nan, window.residual_max,
            sim.selection.label() if sim is not None else 'none yet', loop.robot.adsorption,
            residual_settled=window.residual_settled, detached=loop.detached is not None,
            contact=messages.contact_values(self.settings.contact_model, sim is None or sim.coulomb_applies,
                                            out.contact if out is not None else None),
            sliding=unheld_slip(loop.robot, sim.selection, out) if sim is not None and out is not None else {},
            slipping=messages.slipping_wheels(out.contact) if out is not None else (),
            motor=motor, saturated=saturated)
        self.diagnostics_pub.publish(codec.diagnostics(t, [report]))

    def close(self) -> None:
        """Stop the loop thread (called by main on shutdown, before what was published is delivered:
        a recorder may be up to ``backpressure_window`` steps behind, see ``common.deliver_published``)."""
        self.loop.stop()
        self.loop_thread.join(timeout=2.0)


def main(args: list[str] | None = None) -> None:
    sys.setswitchinterval(SWITCH_INTERVAL)
    exit_process(run(started_node, args))


STOP_POLL = 0.05
"""Wall seconds between looks for a stop to report on /diagnostics."""
FINAL_DIAGNOSTICS_WAIT = 5.0
"""Most wall seconds a node that gives up waits for its last /diagnostics to be acknowledged (at the writer's
heartbeat: 0.1 s with the nodes' profile, 3 s with Fast DDS's default under a user's profile that sets none)."""
SWITCH_INTERVAL = 5e-4
"""sys.setswitchinterval of a process hosting the dynamics: executor callbacks yield the GIL to the loop within 0.5 ms."""


def started_node(**kwargs) -> DynamicsNode:
    """The node (``kwargs`` as DynamicsNode's), the process's start-up allocations frozen."""
    node = DynamicsNode(**kwargs)
    # Everything allocated so far (rclpy, numpy, the model) lives for the whole run: move it
    # out of the collector's reach, so a full collection never stalls a step for milliseconds.
    gc.collect()
    gc.freeze()
    return node


if __name__ == '__main__':
    main()
