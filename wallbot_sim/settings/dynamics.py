"""The dynamics node's settings (``nodes.dynamics``; its loop, ``wallbot_sim.loop``, reads them typed)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from wallbot_msgs_py import topics
from wallbot_sim import messages
from wallbot_sim.control.sampling import CONTROL_RATE_HZ, steps_per_period
from wallbot_sim.control.wheel_speed import SPEED_LOOP_RATE_HZ
from wallbot_sim.model.contact import CONTACT_MODELS, IDEAL
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.simulation import ENGINES, NUMBA
from wallbot_sim.settings.common import (COORDINATE, FRAME_PREFIX_HELP, ROBOT_FILE_HELP, WHEEL_TORQUE_LIMIT,
                                         WORLD_FILE_HELP)
from wallbot_sim.settings.table import setting, table_of

REAL_TIME_FACTOR = NumberRange(1e-3, 1e6, zero='as fast as possible')
"""The real-time factors the dynamics accepts: at the slowest a step waits dt / 1e-3 (1 s at 1 kHz)."""
REALTIME_PRIORITY = NumberRange(0, 99)
"""The loop thread's SCHED_FIFO priorities (Linux's 1-99), 0 = normal scheduling."""
COMMAND_WAIT_TIMEOUT = 30.0
"""Default command_wait_timeout (wall s). A controller started with the dynamics (``wallbot-sim run``,
the launch file) is there within seconds; ``run`` gives the whole graph 60 s to record its first
state, so a missing controller ends the run with the dynamics' reason before ``run``'s own limit. A
controller started by hand later wants more, or 0."""
CONTROL_ODOM_EVERY = math.gcd(steps_per_period(CONTROL_RATE_HZ), steps_per_period(SPEED_LOOP_RATE_HZ))
"""Default control_odom_every (steps): every state either commander acts on at its default rate
(20: the cmd_vel node's 50 Hz at 1 kHz; the tracking controller's 25 Hz is every 40th)."""
BACKPRESSURE_WINDOW = 200
"""Default backpressure_window (steps): how far the loop may run ahead of a recorder's progress, so
how many steps' messages (and, at lockstep_every 1, commands) a starved recorder may owe."""
ENGINE_HELP = ("how the steps are computed: numba (the batch's compiled kernel, ideal and coulomb contact, the same "
               "states as the model to 1e-9; a machine's first start compiles it into numba's cache, about a minute, "
               'then it loads from there), or python (the model as written, the reference)')
NO_KEEPER = 'no keeper of snapshots in this process'
"""Why the composed process (``dynamics_recorder_node``) fixes resume_wait and snapshot_period at 0."""
COMMAND_SENSORS = ('odom', 'wheel_states')
EFFICIENCY = NumberRange(0.0, 1.0)
"""A motor's delivered share of its commanded torque: 1 healthy, 0 dead."""
ADHESION_SCALE = NumberRange(1e-3, 10.0)
"""The adhesion force relative to the configured one (a suction fault below 1); the model needs a positive force."""
NOISE = NumberRange(0.0, 10.0)
RATE_NOISE = NumberRange(0.0, 100.0)


@dataclass(frozen=True)
class DynamicsSettings:
    """The dynamics node's parameters. Any sensor noise above 0 also publishes the exact state on
    ground_truth/odom."""

    initial_x: float = setting(0.8, 'initial X of the centre (m); applies at start and reset', COORDINATE)
    initial_y: float = setting(0.0, 'initial Y of the centre (m); applies at start and reset', COORDINATE)
    initial_theta: float = setting(0.0, 'initial heading (rad); applies at start and reset', NumberRange(-1e4, 1e4))
    initial_at_rest: bool = setting(True, 'start at rest; false: with the reference velocity at t = 0, wheels '
                                          'rolling')
    robot_file: str = setting('', ROBOT_FILE_HELP, read_only=True)
    world_file: str = setting('', WORLD_FILE_HELP, read_only=True)
    rate_hz: int = setting(1000, 'integration rate (RK4 steps per second of simulation time)',
                           NumberRange(1, 100_000))
    publish_every: int = setting(1, 'publish every N steps', NumberRange(1, 1_000_000))
    clock_rate_hz: float = setting(messages.CLOCK_RATE_HZ, 'clock messages per second of simulation time (at most '
                                   'one per published step, and always the state before a stop); the per-step '
                                   'topics carry every published step', NumberRange(1e-3, 1e6), read_only=True)
    control_odom_every: int = setting(CONTROL_ODOM_EVERY, "publish every Nth step's odometry on control_odom too, "
                                      'for controllers acting every N steps or a multiple of N; 0 = never',
                                      NumberRange(0, 1_000_000))
    real_time_factor: float = setting(1.0, 'simulation seconds per wall second; 0 = as fast as possible',
                                      REAL_TIME_FACTOR)
    command_timeout: float = setting(0.5, 'seconds of simulation time a wheel_torque_cmd is held',
                                     NumberRange(1e-3, 3600.0))
    max_wheel_torque: float = setting(5.0, 'largest accepted |torque| per side in wheel_torque_cmd (N m)',
                                      WHEEL_TORQUE_LIMIT)
    stop_at: float = setting(0.0, 'pause when simulation time reaches this (s); 0 = never',
                             NumberRange(0.0, 1e9, low_open=True, zero='never'))
    wait_for_recorder: bool = setting(False, 'do not start until a recorder (record_progress) hears every topic',
                                      read_only=True)
    wait_for_command: bool = setting(False, 'driven mode: start (or resume) once a wheel_torque_cmd publisher hears '
                                            'odom, and take the first step only after its answer to the first state '
                                            'published (a closed loop from t = 0, or from the resumed state)',
                                     read_only=True)
    command_wait_timeout: float = setting(COMMAND_WAIT_TIMEOUT, 'wall seconds a start (or resume) with '
                                          'wait_for_command waits for the controller, and then for its first command; '
                                          'after that the node logs what was missing and exits with status 1 '
                                          '(0 = wait for ever)', NumberRange(0.0, 3600.0), read_only=True)
    lockstep_every: int = setting(0, 'driven mode: after publishing every Nth step, wait for the command answering '
                                     'that state before stepping on (at most lockstep_timeout); 0 = off',
                                  NumberRange(0, 1_000_000))
    command_sensor: str = setting('odom', 'the topic the commander answers in driven mode: odom (or control_odom), or '
                                          'wheel_states (joint_bridge_node, ros2_control); a start waits for a commander '
                                          'subscribing it, and while a dropout silences it lockstep waits for no answer',
                                  choices=COMMAND_SENSORS, read_only=True)
    lockstep_timeout: float = setting(2.0, 'wall seconds lockstep waits for a command before stepping on without it '
                                           'until commands return (a dead controller costs this once)',
                                      NumberRange(0.01, 60.0))
    realtime_priority: int = setting(0, 'SCHED_FIFO priority of the paced loop thread for steps it sleeps before '
                                        '(Linux; needs an rtprio limit, else a warning); 0 = normal scheduling',
                                     REALTIME_PRIORITY)
    contact_model: str = setting(IDEAL, 'wheel-wall contact: ideal, or coulomb (channels stick or slip, a wheel '
                                        'lifting off pauses the run; acts while the trajectory task is off)',
                                 choices=CONTACT_MODELS)
    engine: str = setting(NUMBA, ENGINE_HELP, choices=ENGINES, read_only=True)
    adhesion_force: float = setting(0.0, 'force pressing the robot to the wall (N)',
                                    NumberRange(0.0, 1e6, low_open=True, zero="the robot file's"))
    adhesion_scale: float = setting(1.0, "a suction fault: the adhesion force relative to adhesion_force (or the robot "
                                         "file's)", ADHESION_SCALE)
    motor_efficiency_left: float = setting(1.0, 'a motor fault: the share of the commanded left side torque the left '
                                                'motor delivers (0: dead)', EFFICIENCY)
    motor_efficiency_right: float = setting(1.0, 'a motor fault: the share of the commanded right side torque the '
                                                 'right motor delivers (0: dead)', EFFICIENCY)
    drop_odom: bool = setting(False, 'a sensor fault: odom and control_odom go silent (ground_truth/odom, where '
                                     'published, keeps the state)')
    drop_wheel_states: bool = setting(False, 'a sensor fault: wheel_states goes silent')
    drop_imu: bool = setting(False, "a sensor fault: imu goes silent (the robot file's sensors.imu)")
    fault_schedule: str = setting('', 'faults at simulation times: entries "at=T NAME=VALUE ..." separated by ";", '
                                      'each NAME a fault parameter (adhesion_scale, motor_efficiency_left, '
                                      'motor_efficiency_right, drop_odom, drop_wheel_states, drop_imu) set at the step boundary '
                                      'at T s; empty = none', read_only=True)
    strict_lockstep: bool = setting(False, 'a lockstep wait that reaches lockstep_timeout ends the run (the node exits '
                                           '1 naming the state left unanswered) instead of stepping on',
                                    read_only=True)
    backpressure_window: int = setting(BACKPRESSURE_WINDOW, "max steps ahead of a recorder's record_progress "
                                                            '(any factor)', NumberRange(1, 1_000_000))
    snapshot_period: float = setting(0.01, 'simulation seconds between state snapshots (kept by the recorder for a '
                                           'restart); 0 = only at events (start, reset, pause, switch, plan)',
                                     NumberRange(0.0, 1e6))
    step_count: int = setting(1, 'steps one ~/step call takes while paused', NumberRange(1, 1_000_000))
    domain_clock: bool = setting(True, "also publish the robot's clock on the domain's /clock, which ROS tools with "
                                       'use_sim_time follow; false for every robot but one in a domain', read_only=True)
    resume_wait: float = setting(2.0, 'wall seconds from the first constraint set to wait for a keeper of snapshots '
                                      '(resume_state) to continue from; 0 = always start from the initial state',
                                 NumberRange(0.0, 60.0), read_only=True)
    odom_frame_id: str = setting(topics.WALL_FRAME, 'frame of the odometry pose, the constraint wrench and '
                                                    'initialpose (the wall)', read_only=True)
    base_frame_id: str = setting(topics.BASE_FRAME, "the odometry's child frame (the robot's centre), in which its "
                                                    'twist is given, after frame_prefix', read_only=True)
    frame_prefix: str = setting('', FRAME_PREFIX_HELP, read_only=True)
    odom_noise_position: float = setting(0.0, 'standard deviation of the Gaussian noise on the published odometry X '
                                              'and Y (m); 0 = exact', NOISE, read_only=True)
    odom_noise_heading: float = setting(0.0, 'standard deviation of the noise on the published odometry yaw (rad); '
                                             '0 = exact', NOISE, read_only=True)
    odom_noise_linear: float = setting(0.0, 'standard deviation of the noise on each linear velocity of the '
                                            'published odometry (m/s); 0 = exact', RATE_NOISE, read_only=True)
    odom_noise_angular: float = setting(0.0, 'standard deviation of the noise on the published odometry turning rate '
                                             '(rad/s); 0 = exact', RATE_NOISE, read_only=True)
    encoder_noise: float = setting(0.0, 'standard deviation of the noise on each wheel angle in wheel_states (rad); '
                                        '0 = exact', NOISE, read_only=True)
    encoder_velocity_noise: float = setting(0.0, 'standard deviation of the noise on each wheel speed in '
                                                 'wheel_states (rad/s); 0 = exact', NumberRange(0.0, 1000.0),
                                            read_only=True)
    ground_truth: bool = setting(False, 'also publish the exact state on ground_truth/odom (as any sensor noise does): a '
                                        'bag then keeps every state while odom is silent or noisy', read_only=True)
    noise_seed: int = setting(0, 'seed of the sensor noise (the same seed, the same noise)',
                              NumberRange(0, 2**31 - 1), read_only=True)
    use_sim_time: bool = setting(False, "rclpy's: follow a clock topic instead of the wall clock",
                                 fixed='the dynamics owns the simulation clock: it publishes clock, it follows none')


DYNAMICS = table_of(DynamicsSettings)
NOISE_PARAMETERS = ('odom_noise_position', 'odom_noise_heading', 'odom_noise_linear', 'odom_noise_angular',
                    'encoder_noise', 'encoder_velocity_noise')
"""The sensor noise settings, in the order of ``NoiseLevels``' fields."""
FAULT_PARAMETERS = ('adhesion_scale', 'motor_efficiency_left', 'motor_efficiency_right', 'drop_odom', 'drop_wheel_states',
                    'drop_imu')
"""The fault settings (``loop.faults``): changed while running, or at simulation times by ``fault_schedule``."""
COMPOSED = DYNAMICS.fixing({'resume_wait': (0.0, NO_KEEPER), 'snapshot_period': (0.0, NO_KEEPER)})
"""The dynamics' settings in the composed process (``dynamics_recorder_node``): with no keeper of snapshots there,
a start never waits for one, and a snapshot is published only at events."""
