"""dynamics_node: the constrained model integrated with RK4, owning simulation time: its robot's
``clock`` (and the domain's ``/clock`` with ``domain_clock``, topics.DOMAIN_CLOCK).

Threads. The stepping runs in a dedicated loop thread (``dynamics_loop``, which holds the loop's
state and decisions, free of ROS); the executor (main thread) only receives messages, service
calls and parameter sets and hands them to the loop as typed events, which the loop applies at
the next step boundary. No physics runs in a callback.

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
On the compiled engine with ideal contact (under the trajectory task, or driven under one torque),
the loop computes blocks of steps ahead and publishes each state when due (``dynamics_loop``: an
event drops the states not yet published, so it applies as between single steps). A state no
subscriber outside the process hears (a composed recorder takes the per-step topics from its tap)
is handed over ahead of time, logged at its due time, under the trajectory task or with lockstep:
the loop wakes once per block and for the states that carry /clock or are heard outside.

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
from typing import Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import MultiDOFJointTrajectory

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_msgs_py.snapshot import DynamicsSnapshot, decode_snapshot, encode_snapshot
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.sampling import CONTROL_RATE_HZ, steps_per_period
from wallbot_sim.control.wheel_speed import SPEED_LOOP_RATE_HZ
from wallbot_sim.model import ModelError, SampledReference, StepOutputs
from wallbot_sim.model.contact import CONTACT_MODELS, unheld_slip
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.outputs import StepBlock
from wallbot_sim.model.simulation import ENGINES, NUMBA, PYTHON
from wallbot_sim.nodes.common import (COORDINATE, FRAME_PREFIX_DESCRIPTION, WHEEL_TORQUE_LIMIT, choice_reason, declare,
                                      heard_by_every, param_dict, parameter_result, range_reasons, run, steady_timer)
from wallbot_sim.nodes.dynamics_loop import (THROTTLE, ConstraintSwitch, DynamicsLoop, NewPlan, ParameterChange, Pause,
                                             PreparedState, RecordProgress, Reset, ResumeSnapshot, Step, Teleport,
                                             TorqueCommand)
from wallbot_sim.nodes.pacing import REAL_TIME_FACTOR, REALTIME_PRIORITY, Pacer
from wallbot_sim.nodes.sensor_noise import NoiseLevels, SensorNoise
from wallbot_sim.nodes.step_tap import StepTap
from wallbot_sim.urdf import RobotFrames

NOISE_PARAMETERS = {
    'odom_noise_position': 'standard deviation of the Gaussian noise on the published odometry X and Y (m); '
                           '0 = exact',
    'odom_noise_heading': 'standard deviation of the noise on the published odometry yaw (rad); 0 = exact',
    'odom_noise_linear': 'standard deviation of the noise on each linear velocity of the published odometry '
                         '(m/s); 0 = exact',
    'odom_noise_angular': 'standard deviation of the noise on the published odometry turning rate (rad/s); 0 = exact',
    'encoder_noise': 'standard deviation of the noise on each wheel angle in wheel_states (rad); 0 = exact',
    'encoder_velocity_noise': 'standard deviation of the noise on each wheel speed in wheel_states (rad/s); 0 = exact',
}
"""The sensor noise parameters, in the order of ``NoiseLevels``' fields. Any of them above 0 also
publishes the exact state on ground_truth/odom."""
RANGES = {
    'initial_x': COORDINATE, 'initial_y': COORDINATE, 'initial_theta': NumberRange(-1e4, 1e4),
    'rate_hz': NumberRange(1, 100_000), 'publish_every': NumberRange(1, 1_000_000),
    'clock_rate_hz': NumberRange(1e-3, 1e6), 'control_odom_every': NumberRange(0, 1_000_000),
    'real_time_factor': REAL_TIME_FACTOR,
    'command_timeout': NumberRange(1e-3, 3600.0), 'max_wheel_torque': WHEEL_TORQUE_LIMIT,
    'stop_at': NumberRange(0.0, 1e9), 'lockstep_every': NumberRange(0, 1_000_000),
    'lockstep_timeout': NumberRange(0.01, 60.0), 'realtime_priority': REALTIME_PRIORITY,
    'adhesion_force': NumberRange(0.0, 1e6), 'backpressure_window': NumberRange(1, 1_000_000),
    'snapshot_period': NumberRange(0.0, 1e6), 'step_count': NumberRange(1, 1_000_000),
    'resume_wait': NumberRange(0.0, 60.0), 'command_wait_timeout': NumberRange(0.0, 3600.0),
    'odom_noise_position': NumberRange(0.0, 10.0), 'odom_noise_heading': NumberRange(0.0, 10.0),
    'odom_noise_linear': NumberRange(0.0, 100.0), 'odom_noise_angular': NumberRange(0.0, 100.0),
    'encoder_noise': NumberRange(0.0, 10.0), 'encoder_velocity_noise': NumberRange(0.0, 1000.0),
    'noise_seed': NumberRange(0, 2**31 - 1),
}
"""What each numeric parameter accepts: its descriptor's range and the node's own check."""
COMMAND_WAIT_TIMEOUT = 30.0
"""Default command_wait_timeout (wall s). A controller started with the dynamics (``wallbot-sim run``,
the launch file) is there within seconds; ``run`` gives the whole graph 60 s to record its first
state, so a missing controller ends the run with the dynamics' reason before ``run``'s own limit. A
controller started by hand later wants more, or 0."""
CONTROL_ODOM_EVERY = math.gcd(steps_per_period(CONTROL_RATE_HZ), steps_per_period(SPEED_LOOP_RATE_HZ))
"""Default control_odom_every (steps): every state either commander acts on at its default rate
(20: the cmd_vel node's 50 Hz at 1 kHz; the tracking controller's 25 Hz is every 40th)."""
BURST_CONTROL_ODOM_EVERY = 10
"""Smallest control_odom_every at which the loop publishes a block's states at once (factor 0) to a DDS
subscriber of control_odom: five of its messages at most in a burst of 50 states."""
BACKPRESSURE_WINDOW = 200
"""Default backpressure_window (steps): how far the loop may run ahead of a recorder's progress, so
how many steps' messages (and, at lockstep_every 1, commands) a starved recorder may owe."""
MESSAGE_TYPES = {topics.ODOM: Odometry, topics.WHEEL_STATES: JointState,
                 topics.CONSTRAINT_WRENCH: WrenchStamped, topics.DRIVE_FORCES: JointState,
                 topics.WHEEL_CONTACT: JointState,
                 topics.CLOCK: ClockMsg}
"""The per-step topics; published as CDR bytes from ``step_cdr`` (rclpy's publish takes bytes as serialized)."""
STEP_TOPICS = (*MESSAGE_TYPES, topics.GROUND_TRUTH_ODOM)
"""Every topic ``prepare``'s send may publish (ground_truth/odom while the sensor noise is on)."""


class DynamicsNode(Node):
    """The ROS interface of the simulation loop (``dynamics_loop``): parameters, topics, services,
    diagnostics, and the loop thread. ``tap``: a recorder in the same process also gets every
    step's messages from it (the per-step topics it taps need no DDS subscriber to count as heard)."""

    def __init__(self, tap: StepTap | None = None, **kwargs) -> None:
        super().__init__(topics.NODE_DYNAMICS, namespace=topics.NAMESPACE, **kwargs)
        self.tap = tap
        p = {
            'initial_x': declare(self, 'initial_x', 0.8, 'initial X of the centre (m); applies at start and reset',
                                 allowed=RANGES['initial_x']),
            'initial_y': declare(self, 'initial_y', 0.0, 'initial Y of the centre (m); applies at start and reset',
                                 allowed=RANGES['initial_y']),
            'initial_theta': declare(self, 'initial_theta', 0.0, 'initial heading (rad); applies at start and reset',
                                     allowed=RANGES['initial_theta']),
            'initial_at_rest': declare(self, 'initial_at_rest', True,
                                       'start at rest; false: with the reference velocity at t = 0, wheels rolling'),
            'robot_file': declare(self, 'robot_file', '', 'robot parameter YAML; empty = installed config/robot.yaml',
                                  read_only=True),
            'rate_hz': declare(self, 'rate_hz', 1000, 'integration rate (RK4 steps per second of simulation time)',
                               allowed=RANGES['rate_hz']),
            'publish_every': declare(self, 'publish_every', 1, 'publish every N steps',
                                     allowed=RANGES['publish_every']),
            'clock_rate_hz': declare(self, 'clock_rate_hz', messages.CLOCK_RATE_HZ,
                                     'clock messages per second of simulation time (at most one per published '
                                     'step, and always the state before a stop); the per-step topics carry '
                                     'every published step', allowed=RANGES['clock_rate_hz'], read_only=True),
            'control_odom_every': declare(self, 'control_odom_every', CONTROL_ODOM_EVERY,
                                          'publish every Nth step\'s odometry on control_odom too, for controllers '
                                          'acting every N steps or a multiple of N; 0 = never',
                                          allowed=RANGES['control_odom_every']),
            'real_time_factor': declare(self, 'real_time_factor', 1.0,
                                        'simulation seconds per wall second; 0 = as fast as possible',
                                        allowed=RANGES['real_time_factor']),
            'command_timeout': declare(self, 'command_timeout', 0.5,
                                       'seconds of simulation time a wheel_torque_cmd is held',
                                       allowed=RANGES['command_timeout']),
            'max_wheel_torque': declare(self, 'max_wheel_torque', 5.0,
                                        'largest accepted |torque| per side in wheel_torque_cmd (N m)',
                                        allowed=RANGES['max_wheel_torque']),
            'stop_at': declare(self, 'stop_at', 0.0, 'pause when simulation time reaches this (s); 0 = never',
                               allowed=RANGES['stop_at']),
            'wait_for_recorder': declare(self, 'wait_for_recorder', False,
                                         'do not start until a recorder (record_progress) hears every topic',
                                         read_only=True),
            'wait_for_command': declare(self, 'wait_for_command', False,
                                        'driven mode: start (or resume) once a wheel_torque_cmd publisher hears odom, '
                                        'and take the first step only after its answer to the first state published '
                                        '(a closed loop from t = 0, or from the resumed state)',
                                        read_only=True),
            'command_wait_timeout': declare(self, 'command_wait_timeout', COMMAND_WAIT_TIMEOUT,
                                            'wall seconds a start (or resume) with wait_for_command waits for the '
                                            'controller, and then for its first command; after that the node logs '
                                            'what was missing and exits with status 1 (0 = wait for ever)',
                                            allowed=RANGES['command_wait_timeout'], read_only=True),
            'lockstep_every': declare(self, 'lockstep_every', 0,
                                      'driven mode: after publishing every Nth step, wait for the command '
                                      'answering that state before stepping on (at most lockstep_timeout); 0 = off',
                                      allowed=RANGES['lockstep_every']),
            'lockstep_timeout': declare(self, 'lockstep_timeout', 2.0,
                                        'wall seconds lockstep waits for a command before stepping on without it '
                                        'until commands return (a dead controller costs this once)',
                                        allowed=RANGES['lockstep_timeout']),
            'realtime_priority': declare(self, 'realtime_priority', 0,
                                         'SCHED_FIFO priority of the paced loop thread for steps it sleeps before '
                                         '(Linux; needs an rtprio limit, else a warning); 0 = normal scheduling',
                                         allowed=RANGES['realtime_priority']),
            'contact_model': declare(self, 'contact_model', 'ideal',
                                     'wheel-wall contact: ideal, or coulomb (channels stick or slip, a wheel lifting '
                                     'off pauses the run; acts while the trajectory task is off)',
                                     choices=CONTACT_MODELS),
            'engine': declare(self, 'engine', PYTHON,
                              'how the steps are computed: python (the model), or numba (the batch\'s compiled '
                              'kernel, ideal and coulomb contact, the same states to 1e-9; it compiles on first '
                              'use on a machine, then loads from the cache)',
                              choices=ENGINES, read_only=True),
            'adhesion_force': declare(self, 'adhesion_force', 0.0,
                                      "force pressing the robot to the wall (N); 0 = the robot file's",
                                      allowed=RANGES['adhesion_force']),
            'backpressure_window': declare(self, 'backpressure_window', BACKPRESSURE_WINDOW,
                                           'max steps ahead of a recorder\'s record_progress (any factor)',
                                           allowed=RANGES['backpressure_window']),
            'snapshot_period': declare(self, 'snapshot_period', 0.01,
                                       'simulation seconds between state snapshots (kept by the recorder for a '
                                       'restart); 0 = only at events (start, reset, pause, switch, plan)',
                                       allowed=RANGES['snapshot_period']),
            'step_count': declare(self, 'step_count', 1, 'steps one ~/step call takes while paused',
                                  allowed=RANGES['step_count']),
            'domain_clock': declare(self, 'domain_clock', True,
                                    "also publish the robot's clock on the domain's /clock, which ROS tools "
                                    'with use_sim_time follow; false for every robot but one in a domain',
                                    read_only=True),
            'resume_wait': declare(self, 'resume_wait', 2.0,
                                   'wall seconds from the first constraint set to wait for a keeper of snapshots '
                                   '(resume_state) to continue from; 0 = always start from the initial state',
                                   allowed=RANGES['resume_wait'], read_only=True),
            'odom_frame_id': declare(self, 'odom_frame_id', topics.WALL_FRAME,
                                     'frame of the odometry pose, the constraint wrench and initialpose (the wall)',
                                     read_only=True),
            'base_frame_id': declare(self, 'base_frame_id', topics.BASE_FRAME,
                                     "the odometry's child frame (the robot's centre), in which its twist is given, "
                                     'after frame_prefix', read_only=True),
            'frame_prefix': declare(self, 'frame_prefix', '', FRAME_PREFIX_DESCRIPTION, read_only=True),
            **{name: declare(self, name, 0.0, description, allowed=RANGES[name], read_only=True)
               for name, description in NOISE_PARAMETERS.items()},
            'noise_seed': declare(self, 'noise_seed', 0, 'seed of the sensor noise (the same seed, the same noise)',
                                  allowed=RANGES['noise_seed'], read_only=True),
        }
        frames = RobotFrames(p['odom_frame_id'], p['base_frame_id'], p['frame_prefix'])
        reasons = self._check(p) + frames.reasons()
        if reasons:
            raise ValueError('; '.join(reasons))
        if p['engine'] == NUMBA:
            # imported only here: numba takes about 0.4 s to import, which the python engine need not pay
            from wallbot_sim.model.compiled import compile_run, require_numba
            require_numba()  # a missing package is said at start, not by a failing loop thread
            self.get_logger().info("engine numba: loading the compiled kernel (a machine's first start compiles "
                                   "it into numba's cache, about a minute)")
            # loaded here, not by the first step: the objects loading makes are then frozen with the rest of
            # the start-up's (started_node), where in the loop thread they cost a 12 ms collection seconds later
            compile_run(p['contact_model'])
        self.params = p
        self._warn_lockstep_unseen()
        self.exit_status: int | None = None
        """Set once the node cannot go on (its start gave up): ``common.run_nodes`` ends the process with it."""
        self.loop = DynamicsLoop(p, load_robot_parameters(p['robot_file'] or None), self, self.get_logger(),
                                 Pacer(p['realtime_priority'], self.get_logger().warning))
        self.publishers_ = {topic: self.create_publisher(kind, topic.name, qos_profile(topic))
                            for topic, kind in MESSAGE_TYPES.items()}
        self.control_odom_pub = self.create_publisher(Odometry, topics.CONTROL_ODOM.name,
                                                      qos_profile(topics.CONTROL_ODOM))
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS.name,
                                                     qos_profile(topics.DIAGNOSTICS))
        self.snapshot_pub = self.create_publisher(Float64MultiArray, topics.STATE_SNAPSHOT.name,
                                                  qos_profile(topics.STATE_SNAPSHOT))
        self.progress_topic = self.resolve_topic_name(topics.RECORD_PROGRESS.name)
        self.command_topic = self.resolve_topic_name(topics.WHEEL_TORQUE_CMD.name)
        self.resume_topic = self.resolve_topic_name(topics.RESUME_STATE.name)
        self.domain_clock_pub = (self.create_publisher(ClockMsg, topics.DOMAIN_CLOCK.name,
                                                       qos_profile(topics.DOMAIN_CLOCK))
                                 if p['domain_clock'] else None)
        levels = NoiseLevels(*(float(p[name]) for name in NOISE_PARAMETERS))
        self.noise = SensorNoise(levels, p['noise_seed']) if levels.on else None
        self.encoder = StepEncoder(frames.odom, frames.base_link, levels.pose_variances(),
                                   levels.twist_variances(), ground_truth=levels.on)
        if levels.on:
            self.publishers_[topics.GROUND_TRUTH_ODOM] = self.create_publisher(
                Odometry, topics.GROUND_TRUTH_ODOM.name, qos_profile(topics.GROUND_TRUTH_ODOM))

        self.create_subscription(DiagnosticStatus, topics.CONSTRAINTS.name, self._on_constraints,
                                 qos_profile(topics.CONSTRAINTS), raw=True)
        self.create_subscription(MultiDOFJointTrajectory, topics.REFERENCE_TRAJECTORY.name, self._on_plan,
                                 qos_profile(topics.REFERENCE_TRAJECTORY), raw=True)  # see plan_from_cdr
        self.command_sub = self.create_subscription(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name, self._on_command,
                                                    qos_profile(topics.WHEEL_TORQUE_CMD), raw=True)
        self.create_subscription(ClockMsg, topics.RECORD_PROGRESS.name, self._on_progress,
                                 qos_profile(topics.RECORD_PROGRESS), raw=True)
        self.create_subscription(Float64MultiArray, topics.RESUME_STATE.name, self._on_resume_state,
                                 qos_profile(topics.RESUME_STATE), raw=True)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.pause_requested = False
        """What the last ~/pause asked (the loop applies it at its next step boundary)."""
        self.create_service(Trigger, '~/step', self._on_step)
        self.create_subscription(PoseWithCovarianceStamped, topics.INITIALPOSE.name, self._on_initialpose,
                                 qos_profile(topics.INITIALPOSE), raw=True)
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        steady_timer(self, 1.0, self._publish_diagnostics)
        self.loop_thread = threading.Thread(target=self._run_loop, name='simulation', daemon=True)
        self.loop_thread.start()

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
            self.loop.post(TorqueCommand(codec.decode_wheel_torque_cmd(data, self.params['max_wheel_torque'])))
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
        count = int(self.params['step_count'])
        self.loop.post(Step(count))
        response.success, response.message = True, f'{count} step(s) (step_count) at the next step boundary'
        return response

    def _on_initialpose(self, data: bytes) -> None:
        try:
            self.loop.post(Teleport(*codec.decode_initial_pose(data, self.params['odom_frame_id'])))
        except ValueError as error:
            self.get_logger().warning(f'rejected: {error}', throttle_duration_sec=THROTTLE)

    @staticmethod
    def _check(values: dict) -> list[str]:
        reasons = range_reasons(values, RANGES)
        if 'contact_model' in values:
            reasons.append(choice_reason('contact_model', values['contact_model'], CONTACT_MODELS))
        if 'engine' in values:
            reasons.append(choice_reason('engine', values['engine'], ENGINES))
        return [r for r in reasons if r]

    def _on_set(self, parameters):
        return parameter_result(self._check(param_dict(parameters)))

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, self.params)
        if changes:
            self.params = {**self.params, **changes}
            self.loop.post(ParameterChange(changes))
            if {'lockstep_every', 'control_odom_every'} & set(changes):
                self._warn_lockstep_unseen()

    def _warn_lockstep_unseen(self) -> None:
        lockstep, every = self.params['lockstep_every'], self.params['control_odom_every']
        if lockstep and every and lockstep % every:
            self.get_logger().warning(f'lockstep_every {lockstep} is not a multiple of control_odom_every {every}: '
                                      'a controller on control_odom misses states the loop waits on')

    # --- the loop's view of the graph (dynamics_loop.Graph), called from the loop thread --------
    def prepare(self, out: StepOutputs, clock: bool) -> Callable[[], None]:
        sensed = self.noise.sense(out.q, out.qd) if self.noise is not None else None
        encoded, stamp_ns = self.encoder.encode(out, sensed), codec.to_nanoseconds(out.t)

        def send() -> None:
            heard = self._heard()
            self._send(encoded, clock, stamp_ns, heard, self._to_controller(heard, stamp_ns), 0.0)
        return send

    def encodes_blocks(self, burst: bool) -> bool:
        # A burst of a block's messages (hundreds within a millisecond) can overflow a DDS subscriber's
        # shared-memory queue on a loaded machine; reliability repairs the loss only at Fast DDS's next
        # heartbeat, seconds later (seen: a separate recorder missing one message of a 1.5 s run). So
        # bursts only where no DDS subscriber takes the per-step topics (a composed recorder takes them
        # from the tap); paced, a block's states go out one at a time. A controller's control_odom carries
        # at most every BURST_CONTROL_ODOM_EVERY-th state, a few of a burst: no queue overflows for them
        heard = self._heard()
        if self.params['control_odom_every'] >= BURST_CONTROL_ODOM_EVERY:
            heard.discard(topics.CONTROL_ODOM)
        return self.noise is None and not (burst and heard)

    def prepare_block(self, block: StepBlock) -> list[PreparedState]:
        heard = self._heard()  # once a block: a subscriber matched within it misses at most its few states
        every_state = bool(heard - {topics.CONTROL_ODOM})
        prepared = []
        for encoded, t in zip(self.encoder.encode_rows(block), block.t.tolist()):
            stamp_ns = codec.to_nanoseconds(t)
            controller = self._to_controller(heard, stamp_ns)
            prepared.append(PreparedState(
                lambda clock, ahead, encoded=encoded, stamp_ns=stamp_ns, controller=controller: self._send(
                    encoded, clock, stamp_ns, heard, controller, ahead),
                every_state or controller))
        return prepared

    def _heard(self) -> set[topics.Topic]:
        # a per-step message nobody is matched to would only cost its write into Fast DDS
        # (in a composed run, with nothing else subscribed: a tenth of the process)
        heard = {topic for topic, publisher in self.publishers_.items()
                 if topic is not topics.CLOCK and publisher.get_subscription_count()}
        if self.control_odom_pub.get_subscription_count():
            heard.add(topics.CONTROL_ODOM)
        return heard

    def _to_controller(self, heard: set[topics.Topic], stamp_ns: int) -> bool:
        """Whether the state at ``stamp_ns`` goes out on control_odom: subscribed, and a control instant."""
        every = self.params['control_odom_every']
        return (topics.CONTROL_ODOM in heard and every > 0
                and round(stamp_ns * 1e-9 * self.params['rate_hz']) % every == 0)

    def _send(self, encoded: Sequence[tuple[topics.Topic, bytes]], clock: bool, stamp_ns: int,
              heard: set[topics.Topic], controller: bool, ahead: float) -> None:
        """Publish one state's messages (/clock if ``clock``, the others where ``heard``, odom on control_odom if
        ``controller``: ``_to_controller``); hand them to the tap, ``ahead`` seconds before the state is due (the
        loop does so only for a state nobody outside hears)."""
        for topic, data in encoded:
            if topic is not topics.CLOCK:
                if topic in heard:
                    self.publishers_[topic].publish(data)
                if topic is topics.ODOM and controller:
                    self.control_odom_pub.publish(data)
            elif clock:
                self.publishers_[topic].publish(data)
                if self.domain_clock_pub is not None:
                    self.domain_clock_pub.publish(data)
        if self.tap is not None:
            self.tap.put(encoded, clock, stamp_ns, ahead)

    def publish_snapshot(self, snapshot: DynamicsSnapshot) -> None:
        self.snapshot_pub.publish(encode_snapshot(snapshot))

    def recorder_present(self) -> bool:
        return self.count_publishers(self.progress_topic) > 0

    def recorder_listening(self) -> bool:
        tapped = self.tap.names if self.tap is not None else {}
        return self.recorder_present() and all(topic in tapped or pub.get_subscription_count() > 0
                                               for topic, pub in self.publishers_.items())

    def keeper_seen(self) -> bool:
        return self.count_publishers(self.resume_topic) > 0

    def controller_listening(self) -> bool:
        # and every discovered command publisher is matched here: its answer to the first state
        # must not be sent before (the other direction is the controller's to check)
        return (any(heard_by_every(self, publisher, self.command_topic)
                    for publisher in (self.publishers_[topics.ODOM], self.control_odom_pub))
                and self.command_sub.get_publisher_count() >= self.count_publishers(self.command_topic))

    def _run_loop(self) -> None:
        try:
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
    def _publish_diagnostics(self) -> None:
        loop = self.loop
        window = loop.take_window()
        sim, out, status = loop.sim, loop.last_outputs, loop.status
        elapsed = max(time.perf_counter() - window.started, 1e-9)
        t = sim.t if sim is not None else 0.0
        rate = window.steps / elapsed
        dt = sim.dt if sim is not None else 1.0 / self.params['rate_hz']
        figures = messages.LoopFigures(
            rate, rate * dt, float(self.params['real_time_factor']), 1e3 * window.step_time_sum / max(window.steps, 1),
            1e3 * window.step_time_max, 1e3 * window.lateness_max, window.late,
            loop.pacer.policy)
        report = messages.simulation_status(
            self.get_fully_qualified_name(), str(status), loop.in_error, loop.command_state(), t, figures,
            float(out.residual) if out is not None else math.nan, window.residual_max,
            sim.selection.label() if sim is not None else 'none yet', loop.robot.adsorption,
            detached=loop.detached is not None,
            contact=messages.contact_values(self.params['contact_model'], sim is None or sim.coulomb_applies,
                                            out.contact if out is not None else None),
            sliding=unheld_slip(loop.robot, sim.selection, out) if sim is not None and out is not None else {},
            slipping=messages.slipping_channels(out.contact) if out is not None else ())
        self.diagnostics_pub.publish(codec.diagnostics(t, [report]))

    def close(self) -> None:
        """Stop the loop thread (called by main on shutdown, before what was published is delivered:
        a recorder may be up to ``backpressure_window`` steps behind, see ``common.deliver_published``)."""
        self.loop.stop()
        self.loop_thread.join(timeout=2.0)


def main(args: list[str] | None = None) -> None:
    sys.setswitchinterval(SWITCH_INTERVAL)
    sys.exit(run(started_node, args))


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
