"""dynamics_node: the constrained model integrated with RK4, owning simulation time and /clock.

Threads. The stepping runs in a dedicated loop thread; the executor (main thread) only
receives messages, service calls and parameter sets and hands them to the loop as events,
which the loop applies at the next step boundary. No physics runs in a callback.

Determinism. The loop does not integrate until it has a constraint set (``constraints``)
and, while the trajectory task is on, a plan (``reference_trajectory``) covering the next
step; both are transient-local. It never steps past the end of a plan that ends moving
(it waits for the next plan instead), so the state sequence does not depend on pacing,
CPU load or message timing: the same configuration gives the same states at any
``real_time_factor``.

Pacing. At factor f > 0 the step reaching simulation time k*dt is computed ahead and
published when due, at wall time anchor + k*dt/f (one anchor per run segment, re-anchored
after a pause, a wait or a factor change, so lateness never accumulates into drift);
lateness = publish time - due time is measured and reported in /diagnostics. With
``realtime_priority`` > 0 the loop thread runs under SCHED_FIFO for steps it sleeps before, so
a busy machine does not delay its wake-ups (``pacing``); off by default, since the latency it
saves is shifted onto the rest of the graph (controllers, recorders) on a small machine.

Back-pressure (lossless recording at any factor). DDS acknowledgements are not enough: a
reliable KEEP_LAST reader acknowledges a sample once it is in its history, not once the
application has taken it, so a recorder slower than the simulation still loses samples
(measured: ``wait_for_all_acked`` every 200 steps returned within 4 ms while a slow
subscriber lost 70 % of the samples), and acknowledgements may wait for Fast DDS's
heartbeat period (up to 3 s per wait measured). So the recorder reports its progress
instead: it publishes on ``record_progress`` (rosgraph_msgs/Clock, relative to the
namespace) the newest /clock stamp up to which it has taken every message. While at least
one publisher exists on that topic, the loop never runs more than ``backpressure_window`` steps
(default 200, well below the recorded topics' depth of 1000) ahead of the reported progress: at
factor 0 that paces the loop to the recorder; at factor 1 it only acts when the recorder falls
behind (a loaded machine, or the burst of a loop catching up after a stall), which then slows the
simulation instead of losing messages. Without a recorder it runs free.

Resume. Every ``snapshot_period`` of simulation time and at every event (start, reset, pause,
constraint switch, new plan, command) the loop publishes its full state on ``state_snapshot``
(``wallbot_msgs_py.snapshot``); the recorder keeps the newest and republishes it, transient-local,
on ``resume_state``. A node started again after a SIGKILL takes that snapshot at start and
continues the run bit for bit (``resume``), ``~/reset`` being the explicit way back to t = 0.
"""

from __future__ import annotations

import gc
import math
import queue
import sys
import threading
import time
import traceback
from dataclasses import dataclass, field

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import MultiDOFJointTrajectory

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_msgs_py.snapshot import SWITCHES, DynamicsSnapshot, snapshot_from_message, snapshot_message
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import DOF, BaumgarteGains, DivergedError, ModelError, Robot, SampledReference, Simulation
from wallbot_sim.model.contact import CONTACT_MODELS, DetachedError, unheld_slip
from wallbot_sim.model.numbers import FINITE, NON_NEGATIVE, POSITIVE
from wallbot_sim.model.scenario import moving_start
from wallbot_sim.nodes.common import declare, heard_by_every, param_dict, parameter_result, run
from wallbot_sim.nodes.pacing import REAL_TIME_FACTOR, Pacer
from wallbot_sim.nodes.resume import ResumeGate

BACKPRESSURE_TIMEOUT = 2.0
"""Wall seconds the loop waits for a recorder's progress to move before stepping on without it: a
recorder that was killed, restarted or starved must not stop the simulation for ever (a restarted
dynamics, or one beside a restarted recorder, would otherwise wait for a report that never comes)."""
LATE_LIMIT = 2e-3
"""A step published more than this after its due time counts as late (s)."""
THROTTLE = 1.0
"""Seconds between repeated warnings of one kind."""
MESSAGE_TYPES = {topics.ODOM: Odometry, topics.WHEEL_STATES: JointState,
                 topics.CONSTRAINT_WRENCH: WrenchStamped, topics.DRIVE_FORCES: JointState,
                 topics.WHEEL_CONTACT: JointState,
                 topics.CLOCK: ClockMsg}
"""The per-step topics; published as CDR bytes from ``step_cdr`` (rclpy's publish takes bytes as serialized)."""


@dataclass
class Window:
    """Loop statistics since the last diagnostics message."""

    started: float = field(default_factory=time.perf_counter)
    sim_start: float | None = None
    steps: int = 0
    step_time_sum: float = 0.0
    step_time_max: float = 0.0
    lateness_max: float = 0.0
    late: int = 0
    residual_max: float = 0.0
    """Largest constraint residual of every state of the window (not a sample of one)."""


@dataclass
class Plan:
    """A received plan: its reference and the span it covers."""

    reference: SampledReference
    start: float
    end: float
    final: bool

    def covers(self, t0: float, t1: float) -> bool:
        """Whether a step from t0 to t1 may use this plan.

        A plan that ends moving must extend strictly past t1: at its last sample time the
        quintic is evaluated at the segment's far end, which equals the sample only to
        rounding, while the next plan evaluates it exactly; the step waits for that plan.
        """
        return self.start <= t0 + 1e-9 and (self.final or t1 < self.end - 1e-9)


class DynamicsNode(Node):
    """The simulation loop and its ROS interface."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_DYNAMICS, namespace=topics.NAMESPACE, **kwargs)
        p = {
            'initial_x': declare(self, 'initial_x', 0.8, 'initial X of the centre (m); applies at start and reset'),
            'initial_y': declare(self, 'initial_y', 0.0, 'initial Y of the centre (m); applies at start and reset'),
            'initial_theta': declare(self, 'initial_theta', 0.0, 'initial heading (rad); applies at start and reset'),
            'initial_at_rest': declare(self, 'initial_at_rest', True,
                                       'start at rest; false: with the reference velocity at t = 0, wheels rolling'),
            'robot_file': declare(self, 'robot_file', '', 'robot parameter YAML; empty = installed config/robot.yaml',
                                  read_only=True),
            'rate_hz': declare(self, 'rate_hz', 1000, 'integration rate (RK4 steps per second of simulation time)',
                               low=1, high=100000),
            'publish_every': declare(self, 'publish_every', 1, 'publish every N steps', low=1, high=1000000),
            'real_time_factor': declare(self, 'real_time_factor', 1.0,
                                        'simulation seconds per wall second; 0 = as fast as possible',
                                        allowed=REAL_TIME_FACTOR),
            'command_timeout': declare(self, 'command_timeout', 0.5,
                                       'seconds of simulation time a wheel_torque_cmd is held (> 0)'),
            'max_wheel_torque': declare(self, 'max_wheel_torque', 5.0,
                                        'largest accepted |torque| per side in wheel_torque_cmd (N m, > 0)'),
            'stop_at': declare(self, 'stop_at', 0.0, 'pause when simulation time reaches this (s); 0 = never',
                               low=0.0, high=1e9),
            'wait_for_recorder': declare(self, 'wait_for_recorder', False,
                                         'do not start until a recorder (record_progress) hears every topic',
                                         read_only=True),
            'wait_for_command': declare(self, 'wait_for_command', False,
                                        'driven mode: start once a wheel_torque_cmd publisher hears odom, and take '
                                        'the first step only after its first command (a closed loop from t = 0)',
                                        read_only=True),
            'lockstep_every': declare(self, 'lockstep_every', 0,
                                      'driven mode: after publishing every Nth step, wait for the command '
                                      'answering that state before stepping on (at most lockstep_timeout); 0 = off',
                                      low=0, high=1000000),
            'lockstep_timeout': declare(self, 'lockstep_timeout', 2.0,
                                        'wall seconds lockstep waits for a command before stepping on without it '
                                        'until commands return (a dead controller costs this once)',
                                        low=0.01, high=60.0),
            'realtime_priority': declare(self, 'realtime_priority', 0,
                                         'SCHED_FIFO priority of the paced loop thread for steps it sleeps before '
                                         '(Linux; needs an rtprio limit, else a warning); 0 = normal scheduling',
                                         low=0, high=99),
            'contact_model': declare(self, 'contact_model', 'ideal',
                                     'wheel-wall contact: ideal, or coulomb (channels stick or slip, a wheel lifting '
                                     'off pauses the run; acts while the trajectory task is off)'),
            'adhesion_force': declare(self, 'adhesion_force', 0.0,
                                      "force pressing the robot to the wall (N); 0 = the robot file's"),
            'backpressure_window': declare(self, 'backpressure_window', 200,
                                           'max steps ahead of a recorder\'s record_progress (any factor)',
                                           low=1, high=1000000),
            'snapshot_period': declare(self, 'snapshot_period', 0.01,
                                       'simulation seconds between state snapshots (kept by the recorder for a '
                                       'restart); 0 = only at events (start, reset, pause, switch, plan)',
                                       low=0.0, high=1e6),
            'resume_wait': declare(self, 'resume_wait', 2.0,
                                   'wall seconds from the first constraint set to wait for a keeper of snapshots '
                                   '(resume_state) to continue from; 0 = always start from the initial state',
                                   low=0.0, high=60.0,
                                   read_only=True),
        }
        reasons = self._check(p)
        if reasons:
            raise ValueError('; '.join(reasons))
        self.params = p
        self.robot_file_params = load_robot_parameters(p['robot_file'] or None)
        self.robot = Robot(self._robot_params(p['adhesion_force']))
        sys.setswitchinterval(5e-4)  # executor callbacks yield the GIL to the loop within 0.5 ms

        self.publishers_ = {topic: self.create_publisher(kind, topic.name, qos_profile(topic))
                            for topic, kind in MESSAGE_TYPES.items()}
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name,
                                                     qos_profile(topics.DIAGNOSTICS))
        self.create_subscription(DiagnosticStatus, topics.CONSTRAINTS.name, self._on_constraints,
                                 qos_profile(topics.CONSTRAINTS))
        self.create_subscription(MultiDOFJointTrajectory, topics.REFERENCE_TRAJECTORY.name, self._on_plan,
                                 qos_profile(topics.REFERENCE_TRAJECTORY), raw=True)  # see plan_from_cdr
        self.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, self._on_command,
                                 qos_profile(topics.WHEEL_TORQUE_CMD))
        self.create_subscription(ClockMsg, topics.RECORD_PROGRESS.name, self._on_progress,
                                 qos_profile(topics.RECORD_PROGRESS))
        self.snapshot_pub = self.create_publisher(Float64MultiArray, topics.STATE_SNAPSHOT.name,
                                                  qos_profile(topics.STATE_SNAPSHOT))
        self.create_subscription(Float64MultiArray, topics.RESUME_STATE.name, self._on_resume_state,
                                 qos_profile(topics.RESUME_STATE))
        self.progress_topic = self.resolve_topic_name(topics.RECORD_PROGRESS.name)
        self.command_topic = self.resolve_topic_name(topics.WHEEL_TORQUE_CMD.name)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.create_timer(1.0, self._publish_diagnostics, clock=Clock(clock_type=ClockType.STEADY_TIME))

        # loop state: written by the loop thread only (events carry everything else)
        self.events: queue.SimpleQueue = queue.SimpleQueue()
        self.sim: Simulation | None = None
        self.plan: Plan | None = None
        self.selection = self.gains = None
        self.pending_constraints = None
        self.paused = self.diverged = False
        self.detached: str | None = None
        """Why the robot left the wall (coulomb contact), until a reset."""
        self.status = 'waiting for constraints'
        self.command: tuple[tuple[float, float], float] | None = None
        self.command_expired = False
        self.command_serial = self.sync_serial = 0  # commands received; that count when a sync state went out
        self.lockstep_since: float | None = None
        self.lockstep_lost = False
        self.reset_requested: float | None = None  # monotonic time of a ~/reset not yet applied
        self.progress_ns: int | None = None
        self.recorder_present = False
        self.recorder_checked = 0.0
        self.held_since: tuple[float, int | None] | None = None  # wall time a back-pressure wait began, progress then
        self.last_outputs = None
        self.window = Window()
        self.window_lock = threading.Lock()
        self.encoder = StepEncoder()
        self.pacer = Pacer(p['realtime_priority'], self.get_logger().warning)
        self.resume = ResumeGate(p['resume_wait'])
        self.resume_topic = self.resolve_topic_name(topics.RESUME_STATE.name)
        self.stopping = threading.Event()
        self.wake = threading.Event()
        # Everything allocated so far (rclpy, numpy, the model) lives for the whole run: move it
        # out of the collector's reach, so a full collection never stalls a step for milliseconds.
        gc.collect()
        gc.freeze()
        self.loop_thread = threading.Thread(target=self._loop, name='simulation', daemon=True)
        self.loop_thread.start()

    # --- executor side: callbacks only queue events ---------------------------------------
    def _on_constraints(self, msg: DiagnosticStatus) -> None:
        try:
            self._post('constraints', messages.constraints_from_message(msg))
        except ValueError as error:
            self.get_logger().error(f'ignoring constraints message: {error}')

    def _on_plan(self, data: bytes) -> None:
        try:
            plan = messages.plan_from_cdr(data)
            reference = SampledReference(*plan)
        except (ValueError, ModelError) as error:
            self.get_logger().error(f'ignoring reference_trajectory: {error}')
            return
        self._post('plan', Plan(reference, plan.times[0], plan.times[-1], messages.plan_is_final(plan)))

    def _on_command(self, msg: Float64MultiArray) -> None:
        try:
            self._post('command', codec.torque_command(msg, self.params['max_wheel_torque']))
        except ValueError as error:
            self.get_logger().warning(f'rejected: {error}', throttle_duration_sec=THROTTLE)

    def _on_progress(self, msg: ClockMsg) -> None:
        self.progress_ns = codec.stamp_nanoseconds(msg.clock)

    def _on_resume_state(self, msg: Float64MultiArray) -> None:
        if self.resume.settled:  # read by the executor thread: at worst one more message is decoded
            return
        try:
            self._post('resume', snapshot_from_message(msg))
        except ValueError as error:
            self.get_logger().error(f'ignoring resume_state: {error}')

    def _on_reset(self, _request, response):
        self._post('reset', None)
        response.success, response.message = True, 'reset to the initial state at t = 0 at the next step boundary'
        return response

    def _on_pause(self, request, response):
        self._post('pause', bool(request.data))
        response.success = True
        response.message = 'paused' if request.data else 'running'
        return response

    @staticmethod
    def _check(values: dict) -> list[str]:
        reasons = []
        for name in ('initial_x', 'initial_y', 'initial_theta'):
            if name in values:
                reasons.append(FINITE.reason(name, values[name]))
        for name in ('command_timeout', 'max_wheel_torque'):
            if name in values:
                reasons.append(POSITIVE.reason(name, values[name]))
        if 'contact_model' in values and values['contact_model'] not in CONTACT_MODELS:
            reasons.append(f'contact_model must be one of {", ".join(CONTACT_MODELS)}, got {values["contact_model"]!r}')
        for name in ('stop_at', 'adhesion_force', 'snapshot_period'):
            if name in values:
                reasons.append(NON_NEGATIVE.reason(name, values[name]))
        if 'real_time_factor' in values:
            reasons.append(REAL_TIME_FACTOR.reason('real_time_factor', values['real_time_factor']))
        return [r for r in reasons if r]

    def _on_set(self, parameters):
        return parameter_result(self._check(param_dict(parameters)))

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, self.params)
        if changes:
            self.params = {**self.params, **changes}
            self._post('params', changes)

    def _post(self, kind: str, payload) -> None:
        self.events.put((kind, payload))
        self.wake.set()

    # --- loop side ---------------------------------------------------------------------------
    def _loop(self) -> None:
        try:
            while not self.stopping.is_set():
                self._apply_events()
                if self.reset_requested is not None and (
                        not self._answer_pending() or time.monotonic() - self.reset_requested > self.params['lockstep_timeout']):
                    self.reset_requested = None
                    self._reset()
                if not self._ready():
                    self.pacer.reanchor()
                    self.wake.wait(0.005)
                    self.wake.clear()
                    continue
                if self._lockstep_blocked():  # no re-anchor: a prompt answer costs no pace
                    self.wake.wait(0.0005)
                    self.wake.clear()
                    continue
                if self._held_back():
                    self.wake.wait(0.0005)
                    self.wake.clear()
                    continue
                self._step()
        except Exception:  # noqa: BLE001 - a loop crash must be visible, not a silent thread death
            if self.stopping.is_set() or not self.context.ok():
                return  # shutting down (Ctrl-C, SIGTERM): publishers are gone, nothing to report
            self.get_logger().fatal('simulation loop failed:\n' + traceback.format_exc())
            self.status, self.diverged = 'internal error', True

    def _apply_events(self) -> None:
        while True:
            try:
                kind, payload = self.events.get_nowait()
            except queue.Empty:
                return
            if kind == 'constraints':
                self.pending_constraints = payload
            elif kind == 'plan':
                self.plan = payload
                self.get_logger().info(
                    f'reference plan {payload.start:.3f} .. {payload.end:.3f} s'
                    f'{" (ends at rest)" if payload.final else ""} at t = {self.sim.t if self.sim else 0.0:.3f} s')
                if self.sim is not None:
                    self.sim.set_reference(payload.reference)
                    self._snapshot()
            elif kind == 'command':
                self.command = (payload, self.sim.t if self.sim is not None else 0.0)
                self.command_expired = False
                self.command_serial += 1
                if self.lockstep_lost:
                    self.lockstep_lost = False
                    self.get_logger().info(f'wheel_torque_cmd again at t = {self.sim.t:.3f} s: lockstep resumed')
                self._snapshot()  # so a resume recomputes the steps after it with the commands they had
            elif kind == 'reset':
                self.reset_requested = time.monotonic()
            elif kind == 'pause':
                self.paused = payload
                self.get_logger().info('paused' if payload else 'running again')
                self._snapshot()
            elif kind == 'resume':
                self.resume.offer(payload)
            elif kind == 'params':
                self._apply_params(payload)
        # not reached

    def _apply_params(self, changes: dict) -> None:
        if 'realtime_priority' in changes:
            self.pacer.priority = changes['realtime_priority']
        if 'rate_hz' in changes and self.sim is not None:
            self.sim = self._simulation(self.sim.q, self.sim.qd, self.sim.t, self.sim.motor_torque)
            self._snapshot()
        if 'adhesion_force' in changes:
            self.robot = Robot(self._robot_params(changes['adhesion_force']))
            if self.sim is not None:
                self.sim.set_adhesion_force(self.robot.params.adhesion_force)
        if 'contact_model' in changes and self.sim is not None:
            self.sim.set_contact_model(changes['contact_model'])
        self.pacer.reanchor()
        self.get_logger().info('parameters: ' + ', '.join(f'{k} = {v}' for k, v in changes.items()))

    def _robot_params(self, adhesion_force: float):
        """The robot file's parameters, with the adhesion_force parameter (N) unless it is 0."""
        params = self.robot_file_params
        return params.replace(adhesion_force=adhesion_force) if adhesion_force else params

    def _simulation(self, q, qd, t0: float, torque=(0.0, 0.0)) -> Simulation:
        reference = self.plan.reference if self.plan is not None else None
        sim = Simulation(self.robot, reference, self.selection, q, qd, dt=1.0 / self.params['rate_hz'],
                         t0=t0, gains=self.gains, contact=self.params['contact_model'])
        sim.set_motor_torque(*torque)
        return sim

    def _initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        p = self.params
        q0 = np.array([p['initial_x'], p['initial_y'], p['initial_theta'], 0, 0, 0, 0], dtype=float)
        if p['initial_at_rest'] or self.plan is None:
            return q0, np.zeros(DOF)
        return q0, moving_start(self.robot, self.plan.reference, p['initial_theta'])

    def _reset(self) -> None:
        self.command, self.diverged, self.detached = None, False, None
        self.resume.stop_catch_up()
        if self.sim is not None:
            self.sim = self._simulation(*self._initial_state(), 0.0)
            self.get_logger().info('reset to the initial state at t = 0')
            self._publish(self.sim.outputs())
            self._snapshot()
        self.pacer.reanchor()

    def _restore(self, kept: DynamicsSnapshot, selection, gains) -> None:
        """Continue from a kept snapshot; then apply the constraint set in force now, if it differs."""
        self.selection = messages.selection_from_switches(dict(zip(SWITCHES, kept.switches)))
        self.gains = BaumgarteGains(*kept.gains)
        if self.selection.trajectory and self.plan is None:  # the task was switched off meanwhile, no plan here
            self.selection, self.gains = selection, gains
        if kept.dt == 1.0 / self.params['rate_hz']:
            self.sim = self._simulation(kept.q, kept.qd, kept.anchor, kept.motor_torque)
            self.sim.restore(kept.steps, kept.q, kept.qd)
        else:  # another rate_hz: a new run segment from the kept time, as a rate change makes
            self.sim = self._simulation(kept.q, kept.qd, kept.t, kept.motor_torque)
        self.command = (kept.command, kept.command_since) if kept.command is not None else None
        self.command_expired = kept.command_expired
        self.paused = kept.paused
        self.resume.catch_up_to(kept.seen_until_ns)
        behind = max(0, kept.seen_until_ns - kept.stamp_ns) * 1e-9
        self.get_logger().info(
            f'resuming from the kept snapshot at t = {kept.t:.3f} s (step {kept.steps}, constraints '
            f'{self.selection.label()}{", paused" if kept.paused else ""}); the graph has seen up to '
            f't = {kept.seen_until_ns * 1e-9:.3f} s: {behind:.3f} s recomputed unpublished')
        if (selection, gains) != (self.selection, self.gains):
            self._switch(selection, gains)
        out = self.sim.outputs()  # the solve the first step reuses, as after every step of the first life
        if self.resume.publishes(codec.to_nanoseconds(self.sim.t)):
            self._publish(out)
        self._snapshot()

    def _ready(self) -> bool:
        """Apply a pending constraint set if possible; say whether the next step may run."""
        if self.sim is None and self.params['wait_for_recorder'] and not self._recorder_listening():
            self.status = 'waiting for a recorder'
            return False
        # the wait counts from the constraint set's arrival: by then discovery is under way
        if (self.sim is None and self.pending_constraints is not None
                and not self.resume.settle(time.monotonic(), self.count_publishers(self.resume_topic) > 0)):
            self.status = 'waiting for a kept snapshot to resume from (resume_state)'
            return False
        if self.pending_constraints is not None:
            selection, gains = self.pending_constraints
            if self.sim is None and not selection.trajectory and self.resume.snapshot is None:
                waiting = self._driven_start_blocked()
                if waiting:
                    self.status = waiting
                    return False
            if selection.trajectory and self.plan is None:
                self.status = 'waiting for reference_trajectory'
                if self.sim is None:
                    return False
            else:
                self.pending_constraints = None
                self._switch(selection, gains)
        if self.sim is None:
            return False
        if self.paused or self.diverged or self.detached:
            self.status = 'diverged' if self.diverged else (self.detached or 'paused')
            return False
        sim = self.sim
        stop_at = self.params['stop_at']
        if stop_at > 0.0 and sim.t >= stop_at - 0.5 * sim.dt:
            self.status = messages.stopped_status(sim.t)
            return False
        if sim.selection.trajectory and not self.plan.covers(sim.t, sim.t + sim.dt):
            if self.resume.catching_up and self.plan.start > sim.t + 1e-9:
                # the plan of the kept state was replaced before the kill: publishing this earlier
                # state makes the trajectory node replan from it (its clock went back)
                self.get_logger().warning(f'the newest plan starts at {self.plan.start:.3f} s, after the kept '
                                          f'state at {sim.t:.3f} s: publishing from there')
                self.resume.stop_catch_up()
                self._publish(sim.outputs())
            self.status = f'waiting for a reference_trajectory covering t = {sim.t:.3f} s'
            return False
        if (self.params['wait_for_command'] and not sim.selection.trajectory and sim.steps == 0
                and self.command is None):
            self.status = 'waiting for the first wheel_torque_cmd'
            return False
        self.status = 'running'
        return True

    def _switch(self, selection, gains) -> None:
        if self.sim is None and self.resume.snapshot is not None:
            self._restore(self.resume.snapshot, selection, gains)
            return
        if self.sim is None:
            self.selection, self.gains = selection, gains
            self.sim = self._simulation(*self._initial_state(), 0.0)
            fresh = f' from the initial state ({self.resume.timed_out})' if self.resume.timed_out else ''
            self.get_logger().info(f'starting with constraints {selection.label()}{fresh}')
            self._publish(self.sim.outputs())
            self._snapshot()
            return
        report = self.sim.set_constraints(selection, gains)
        self.selection, self.gains = selection, gains
        self.get_logger().info(
            f'constraints {report.previous.label()} -> {selection.label()} at t = {self.sim.t:.3f} s: '
            f'velocity violation {report.violation_before:.3e} before, {report.violation_after:.3e} after projection')
        self._snapshot()

    def _driven_start_blocked(self) -> str | None:
        """Why a driven run may not create its simulation yet (None: it may).

        A moving start (initial_at_rest false) takes the reference velocity at t = 0, so it
        needs the plan. With wait_for_command, a controller must be there to hear the initial
        state: a wheel_torque_cmd publisher exists, its node subscribes odom, and every
        discovered odom subscription is matched (odom is volatile: a subscriber matched later
        would miss the t = 0 state, and the first step would wait for ever).
        """
        if not self.params['initial_at_rest'] and self.plan is None:
            return 'waiting for reference_trajectory (the moving start takes its velocity)'
        if self.params['wait_for_command']:
            if not heard_by_every(self, self.publishers_[topics.ODOM], self.command_topic):
                return 'waiting for a controller (a wheel_torque_cmd publisher that hears odom)'
        return None

    def _recorder_listening(self) -> bool:
        """Whether a recorder publishes record_progress and every step topic has a subscriber."""
        return (self.count_publishers(self.progress_topic) > 0
                and all(pub.get_subscription_count() > 0 for pub in self.publishers_.values()))

    def _lockstep_blocked(self) -> bool:
        """Lockstep (driven mode, lockstep_every N > 0): whether to wait for the controller.

        After the state of every Nth step is published, the next step waits for a command that
        arrived after it: the controller's answer to that very state, so the loop behaves like
        a controller sampling every N steps with no delay, at any pace or CPU load. Without an
        answer within ``lockstep_timeout`` (wall) it steps on, free-running until commands return
        (then command_timeout brings zero torque, as without lockstep). The timeout is long
        against a loaded machine's scheduling delays (a 0.25 s one was exceeded under load, and
        the loop then no longer equalled the model's), short against a controller's death.
        """
        every, sim = self.params['lockstep_every'], self.sim
        if (every <= 0 or sim.selection.trajectory or self.lockstep_lost or sim.steps % every != 0
                or self.command_serial != self.sync_serial or self.resume.catching_up):
            self.lockstep_since = None
            return False
        now = time.monotonic()
        if self.lockstep_since is None:
            self.lockstep_since = now
        if now - self.lockstep_since <= self.params['lockstep_timeout']:
            return True
        self.lockstep_since, self.lockstep_lost = None, True
        self.pacer.reanchor()  # the time spent waiting for a dead controller is not caught up in a burst
        self.get_logger().warning(f'no wheel_torque_cmd within {self.params["lockstep_timeout"]:g} s (wall) of the state at '
                                  f't = {sim.t:.3f} s: stepping on without lockstep until commands return')
        return False

    def _answer_pending(self) -> bool:
        """Lockstep: whether the controller's answer to the last published state is still to come.

        A reset waits for it (at most lockstep_timeout): arriving after the reset, that answer to a
        state of the old run would be taken for the answer to the reset state.
        """
        every, sim = self.params['lockstep_every'], self.sim
        return (sim is not None and every > 0 and not sim.selection.trajectory and not self.lockstep_lost
                and sim.steps % every == 0 and self.command_serial == self.sync_serial
                and not self.resume.catching_up)

    def _mark_sync(self) -> None:
        """The current state was just published: lockstep waits for a command newer than this."""
        self.sync_serial = self.command_serial

    def _held_back(self) -> bool:
        """Whether a recorder's progress is more than the window behind (at any factor: a recorder
        that falls behind on a loaded machine slows the simulation down instead of losing messages)."""
        now = time.monotonic()
        if now - self.recorder_checked > 0.2:
            self.recorder_checked = now
            self.recorder_present = self.count_publishers(self.progress_topic) > 0
        if not self.recorder_present:
            return False
        window = self.params['backpressure_window'] * self.sim.dt
        progress = -math.inf if self.progress_ns is None else self.progress_ns * 1e-9
        if self.sim.t - progress <= window:
            self.held_since = None
            return False
        if self.held_since is None or self.held_since[1] != self.progress_ns:  # a new wait, or progress moved
            self.held_since = (now, self.progress_ns)
        if now - self.held_since[0] <= BACKPRESSURE_TIMEOUT:
            return True
        if self.held_since[0] > 0.0:  # once per stalled progress value
            self.get_logger().warning(f'no record_progress for {BACKPRESSURE_TIMEOUT:g} s (wall) at t = {self.sim.t:.3f} s: '
                                      'stepping on until the recorder reports again')
            self.held_since = (-math.inf, self.progress_ns)
        return False

    def _command_state(self) -> str:
        """The 'command' value of /diagnostics."""
        sim = self.sim
        if sim is None:
            return 'no simulation yet'
        if sim.selection.trajectory:
            return messages.COMMAND_IGNORED
        if self.command is None:
            return 'none yet, zero torque'
        if self.command_expired:
            return 'timed out, zero torque'
        (left, right), _since = self.command
        return messages.applied_command(left, right)

    def _motor_torque(self) -> tuple[float, float]:
        sim = self.sim
        if sim.selection.trajectory or self.command is None:
            return (0.0, 0.0)
        torque, since = self.command
        if sim.t - since > self.params['command_timeout'] + 1e-12:
            if not self.command_expired:
                self.command_expired = True
                self.get_logger().warning(
                    f'no wheel_torque_cmd for {self.params["command_timeout"]:g} s of simulation time (the last '
                    f'at t = {since:.3f} s): zero torque from t = {sim.t:.3f} s', throttle_duration_sec=THROTTLE)
            return (0.0, 0.0)
        return torque

    def _step(self) -> None:
        sim = self.sim
        torque = self._motor_torque()
        if torque != sim.motor_torque:
            sim.set_motor_torque(*torque)
        began = time.perf_counter()
        try:
            sim.step()
            out = sim.outputs()
            if not (math.isfinite(float(np.sum(out.constraint_force))) and math.isfinite(out.residual)):
                raise DivergedError(f'constraint force is no longer finite at t = {sim.t:.3f} s')
        except DivergedError as error:
            self.diverged = True
            self.status = 'diverged'
            self.get_logger().error(f'{error}: simulation paused (reset with ~/reset)')
            return
        except DetachedError as error:
            self.detached = self.status = f'detached: {error}'
            self.get_logger().error(f'{error}: simulation paused (reset with ~/reset)')
            return
        step_time = time.perf_counter() - began
        if self.resume.catching_up and not self.resume.publishes(codec.to_nanoseconds(sim.t)):
            self.last_outputs = out  # the graph has this state: recomputed, not published nor paced
            return
        window = self.window
        window.steps += 1
        window.step_time_sum += step_time
        window.step_time_max = max(window.step_time_max, step_time)
        publish = sim.steps % self.params['publish_every'] == 0
        if publish:
            encoded = self.encoder.encode(out)
        self._pace(sim.steps, sim.dt)
        if publish:
            for topic, data in encoded:
                self.publishers_[topic].publish(data)
            self._mark_sync()
            every = round(self.params['snapshot_period'] / sim.dt)
            if every > 0 and sim.steps % every == 0:
                self._snapshot()
        self._note_residual(out.residual)
        self.last_outputs = out

    def _pace(self, step: int, dt: float) -> None:
        lateness = self.pacer.wait(step, dt, lambda: self.params['real_time_factor'], self.stopping)
        window = self.window
        window.lateness_max = max(window.lateness_max, lateness)
        if lateness > LATE_LIMIT:
            window.late += 1

    def _snapshot(self) -> None:
        """Publish the loop's state on state_snapshot (a keeper holds it for a restarted node)."""
        sim = self.sim
        if sim is None:
            return
        command, since = self.command if self.command is not None else (None, 0.0)
        kept = DynamicsSnapshot(
            anchor=sim.initial_time, steps=sim.steps, dt=sim.dt, q=tuple(sim.q), qd=tuple(sim.qd),
            motor_torque=sim.motor_torque, command=command, command_since=since,
            command_expired=self.command_expired,
            switches=tuple(messages.switches_from_selection(sim.selection)[name] for name in SWITCHES),
            gains=(float(sim.gains.alpha), float(sim.gains.beta)), paused=self.paused,
            seen_until_ns=codec.to_nanoseconds(sim.t))
        self.snapshot_pub.publish(snapshot_message(kept.to_values()))

    def _publish(self, out) -> None:
        """Publish the messages of the current state (start, reset)."""
        self.last_outputs = out
        self._note_residual(out.residual)
        for topic, data in self.encoder.encode(out):
            self.publishers_[topic].publish(data)
        self._mark_sync()

    def _note_residual(self, residual: float) -> None:
        with self.window_lock:  # the diagnostics swap windows on the executor thread: lose no step
            self.window.residual_max = max(self.window.residual_max, residual)

    # --- diagnostics (executor, 1 Hz wall) --------------------------------------------------
    def _publish_diagnostics(self) -> None:
        with self.window_lock:
            window, self.window = self.window, Window()
        sim, out = self.sim, self.last_outputs
        elapsed = max(time.perf_counter() - window.started, 1e-9)
        t = sim.t if sim is not None else 0.0
        rate = window.steps / elapsed
        dt = sim.dt if sim is not None else 1.0 / self.params['rate_hz']
        loop = messages.LoopFigures(
            rate, rate * dt, float(self.params['real_time_factor']), 1e3 * window.step_time_sum / max(window.steps, 1),
            1e3 * window.step_time_max, 1e3 * window.lateness_max, window.late,
            self.pacer.policy)
        status = messages.simulation_status(
            self.get_fully_qualified_name(), self.status, self.diverged, self._command_state(), t, loop,
            float(out.residual) if out is not None else math.nan, window.residual_max,
            sim.selection.label() if sim is not None else 'none yet', self.robot.adsorption,
            detached=self.detached is not None,
            contact=messages.contact_values(self.params['contact_model'], sim is None or sim.coulomb_applies,
                                            out.contact if out is not None else None),
            sliding=unheld_slip(self.robot, sim.selection, out) if sim is not None and out is not None else {},
            slipping=messages.slipping_channels(out.contact) if out is not None else ())
        self.diagnostics_pub.publish(codec.diagnostics(t, [status]))

    def close(self) -> None:
        """Stop the loop thread (called by main on shutdown)."""
        self.stopping.set()
        self.wake.set()
        self.loop_thread.join(timeout=2.0)


def main(args: list[str] | None = None) -> None:
    sys.exit(run(DynamicsNode, args))


if __name__ == '__main__':
    main()
