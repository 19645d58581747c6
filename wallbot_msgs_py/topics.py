"""Topic names, message types and QoS of the wallbot graph: the one place that knows them.

Names without a leading slash are relative: they resolve in the node's namespace
(``/wallbot`` by default), so ``--ros-args -r __ns:=/robot2`` runs a second robot. That includes
the robot's simulation time, ``clock``: each robot is a simulation of its own, with a time of its
own (see CLOCK).
Types are standard common_interfaces messages, written as rosbag2 type names.
This module imports no ROS package, so bag tools can use it without an install.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

NAMESPACE = '/wallbot'
"""Default namespace of every node."""
STANDARD_PACKAGES = frozenset({
    'std_msgs', 'geometry_msgs', 'nav_msgs', 'sensor_msgs', 'diagnostic_msgs', 'trajectory_msgs',
    'visualization_msgs', 'rosgraph_msgs', 'rcl_interfaces', 'tf2_msgs'})
"""Message packages of a standard ROS 2 Jazzy install: every topic of the graph has a type from one
of them, so the ROS tools, RViz and Foxglove decode it without this project."""


class Durability(Enum):
    """Durability of a topic's QoS."""

    VOLATILE = 'volatile'
    TRANSIENT_LOCAL = 'transient_local'


@dataclass(frozen=True)
class Topic:
    """A topic of the graph: name (relative unless it starts with /), type, QoS."""

    name: str
    type: str
    durability: Durability = Durability.VOLATILE
    depth: int = 1000
    """History depth (KEEP_LAST, RELIABLE)."""
    offered: Durability | None = None
    """The durability its publishers offer where it differs from ``durability``, the one its subscribers ask for:
    a transient-local publisher serves volatile subscribers as a volatile one would (only what it publishes after
    they match), and a subscriber asking for transient-local also gets the ``depth`` newest it published before."""

    def __hash__(self) -> int:
        # the name's hash, which Python keeps: a topic keys the per-step maps of every step's messages
        return hash(self.name)

    def resolve(self, namespace: str = NAMESPACE) -> str:
        """The absolute topic name in ``namespace``."""
        if self.name.startswith('/'):
            return self.name
        return f'{namespace.rstrip("/")}/{self.name}'


ODOM = Topic('odom', 'nav_msgs/msg/Odometry')
CONTROL_ODOM = Topic('control_odom', 'nav_msgs/msg/Odometry')
"""The odometry of the states at control instants: every ``control_odom_every``-th step of the
dynamics (a parameter; 20 by default, 50 Hz at 1 kHz), the same messages as on ``odom``. A
controller acting at a fraction of the step rate subscribes it in place of ``odom`` (``-r
odom:=control_odom``; ``wallbot-sim run`` and the launch file do so for the tracking controller and
cmd_vel_node), so it wakes once per control period instead of once per step: the control instants it
sees are the same as long as its period is a multiple of ``control_odom_every`` steps. Not recorded
(its messages are on ``odom``)."""
WHEEL_STATES = Topic('wheel_states', 'sensor_msgs/msg/JointState')
CONSTRAINT_WRENCH = Topic('constraint_wrench', 'geometry_msgs/msg/WrenchStamped')
DRIVE_FORCES = Topic('drive_forces', 'sensor_msgs/msg/JointState')
WHEEL_CONTACT = Topic('wheel_contact', 'sensor_msgs/msg/JointState')
"""Wheel-wall contact per step, per wheel (docs/model.md 11.2). name: WHEEL_JOINTS, then each wheel's x_p
direction (``wheel_left_front/x``, ...), then its y_p direction (``wheel_left_front/y``, ...), body axes;
position: each wheel's friction use |f_i| / (mu_s N_i) (above 1 its friction disc cannot hold it), then 0;
velocity: 1 for a sliding wheel, 0 for a sticking one, then the wheel's contact-point velocity on the wall
along x_p and along y_p (m/s; its slip while it slides);
effort: each wheel's normal load N_i (N), then the wall's tangential force on the robot at the wheel along
x_p and along y_p (N)."""
DIAGNOSTICS = Topic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', depth=100,
                    offered=Durability.TRANSIENT_LOCAL)
"""The dynamics' status, once a wall second and at once when it stops. Its publisher is transient-local: ROS tools'
volatile subscribers match it as any /diagnostics publisher; a transient-local subscriber (the monitor of
``wallbot-sim run``) also gets the statuses published before it matched, so a run whose monitor discovered the
dynamics late still has the stop's status at once, not a second later."""
CLOCK = Topic('clock', 'rosgraph_msgs/msg/Clock')
"""The robot's simulation time, published by its dynamics, in its namespace (``/wallbot/clock``):
two robots in one domain are two simulations whose times differ (started, paused, reset apart).
Every other node of the robot follows it: it subscribes ``clock``, and its ``use_sim_time`` time
source (rclpy's, fixed on the absolute ``/clock``) is remapped onto it (``ROBOT_CLOCK_REMAP``)."""
DOMAIN_CLOCK = Topic('/clock', 'rosgraph_msgs/msg/Clock')
"""The domain's ``/clock``, what ROS tools with ``use_sim_time`` follow (RViz, ``ros2 bag record
--use-sim-time``): the same messages as CLOCK, published by the dynamics whose ``domain_clock``
parameter is true (the default; set it false on every robot but one when several share a domain)."""
ROBOT_CLOCK_REMAP = '/clock:=clock'
"""The node-local remapping that makes a node's ``use_sim_time`` follow its robot's CLOCK."""
CONTROL_ODOM_REMAP = 'odom:=control_odom'
"""The remapping that makes a controller read CONTROL_ODOM where it reads ``odom``."""
GROUND_TRUTH_ODOM = Topic('ground_truth/odom', 'nav_msgs/msg/Odometry')
"""The simulated state itself, as ``odom`` carries it without sensor noise: published beside a
noisy ``odom`` (the dynamics' ``odom_noise_*`` parameters), so a bag keeps the truth; a run without
noise has no messages on it."""
WHEEL_TORQUE_CMD = Topic('wheel_torque_cmd', 'std_msgs/msg/Float64MultiArray')
"""The wheel torques ``[tau_L, tau_R]`` (N m), one per control instant (50 Hz of simulation time
from the tracking controller, up to one per step). Depth 1000 like the per-step topics: a
recorder starved of CPU misses what its transport queue cannot hold and has it resent from the
writer's history, and a KEEP_LAST writer has overwritten what is older than its depth. The
dynamics runs at most its backpressure_window (200 steps) ahead of the recorder, so the history
must hold that many commands (with depth 10, 83 of 200 commands reached a recorder stopped for
200 steps: test_recorder.py, 2026-12-02)."""
PUMP_COMMAND = Topic('pump_command', 'std_msgs/msg/Float64', depth=10)
"""The vacuum pump's command u in [0, 1] (1: full flow, the default; docs/model.md 13.3), applied by the dynamics
from its next step boundary and held; a value outside [0, 1] is refused with one log line and never applied, as is
any command to a robot file without the ``adhesion`` block."""
REFERENCE = Topic('reference', 'nav_msgs/msg/Odometry', depth=100)
REFERENCE_TRAJECTORY = Topic('reference_trajectory', 'trajectory_msgs/msg/MultiDOFJointTrajectory',
                             Durability.TRANSIENT_LOCAL, depth=1)
REFERENCE_PATH = Topic('reference_path', 'nav_msgs/msg/Path', Durability.TRANSIENT_LOCAL, depth=1)
CONSTRAINTS = Topic('constraints', 'diagnostic_msgs/msg/DiagnosticStatus', Durability.TRANSIENT_LOCAL, depth=1)
INITIALPOSE = Topic('initialpose', 'geometry_msgs/msg/PoseWithCovarianceStamped', depth=10)
"""Where to put the robot, at rest (what RViz's "2D Pose Estimate" publishes), in frame ``wall``;
the dynamics places it there at its next step boundary."""
ROBOT_DESCRIPTION = Topic('robot_description', 'std_msgs/msg/String', Durability.TRANSIENT_LOCAL, depth=1)
"""The robot's URDF, generated from the robot file, published once by constraint_config; transient-local
like robot_state_publisher's, so RViz, Foxglove or a controller_manager started later receive it."""
CMD_VEL = Topic('cmd_vel', 'geometry_msgs/msg/TwistStamped', depth=10)
"""Velocity command of the robot (base_link: linear.x m/s, angular.z rad/s) for cmd_vel_node; a
geometry_msgs/msg/Twist instead when its ``use_stamped_vel`` is false."""
CMD_VEL_UNSTAMPED_TYPE = 'geometry_msgs/msg/Twist'
JOINT_STATES = Topic('joint_states', 'sensor_msgs/msg/JointState')
"""The four wheel joints (WHEEL_JOINTS) as joint_state_broadcaster publishes them. With the robot file's
``sensors.encoders`` the dynamics publishes them in every drive mode, as the encoders read them: position (rad)
quantized to ``counts_per_rev``, velocity (rad/s) the count's change over the sample period, no effort, at the
encoders' ``rate`` of simulation time. Without it, joint_bridge_node (``--drive joint_commands``) republishes
wheel_states at its ``rate_hz``: position, velocity, effort (N m). Depth 1000 like the per-step topics (a recorder
starved of CPU is resent what the writer's history holds)."""
IMU = Topic('imu', 'sensor_msgs/msg/Imu')
"""The robot file's ``sensors.imu`` (published by the dynamics at its ``rate``): REP 145, frame ``base_link``,
linear_acceleration the specific force (on a vertical wall at rest facing +X, y = +g; on the floor, z = +g),
angular_velocity (0, 0, turning rate), each with the sensor's noise and bias; orientation_covariance[0] = -1."""
CHAMBER_PRESSURE = Topic('chamber_pressure', 'sensor_msgs/msg/FluidPressure')
"""The robot file's ``sensors.pressure`` (published by the dynamics at its ``rate``): the vacuum chamber's absolute
pressure, 101325 Pa - dp, with the sensor's noise and bias, frame ``base_link``."""
SENSORS = (IMU, JOINT_STATES, CHAMBER_PRESSURE)
"""The robot's sensors the dynamics publishes (each where the robot file's ``sensors`` block has it)."""
JOINT_COMMANDS = Topic('joint_commands', 'sensor_msgs/msg/JointState', depth=10)
"""Effort per wheel joint (topic_based_ros2_control's command topic), summed per side into the side
motor torques by joint_bridge_node (wallbot_sim.control.joint_interface)."""
MARKERS = Topic('markers', 'visualization_msgs/msg/MarkerArray', Durability.TRANSIENT_LOCAL, depth=1)
"""Published by the viewer at its frame rate (never per step): the robot, its paths and contact
forces, all in the odometry's frame (``wall``), so RViz or Foxglove needs no tf tree (wallbot_sim/view.py
says what each marker shows). Transient-local, so a viewer opened later gets the latest frame."""
TF = Topic('/tf', 'tf2_msgs/msg/TFMessage', depth=100)
"""Published by the viewer at its frame rate where tf2_msgs is installed: ``wall`` -> ``base_link``
(the odometry's frames) and ``base_link`` -> each wheel link (``<wheel joint>_link``, as the URDF names them)."""
RECORD_PROGRESS = Topic('record_progress', 'rosgraph_msgs/msg/Clock', Durability.TRANSIENT_LOCAL, depth=1)
"""Published by a recorder: the newest stamp up to which it has written /clock and every message
of STEP_STAMPED.
The dynamics node does not run more than its ``backpressure_window`` steps ahead of it (waiting a
bounded time for it to move), so a recorder that falls behind slows the simulation instead of
losing data. Transient-local, so a restarted dynamics learns the progress at once."""
STATE_SNAPSHOT = Topic('state_snapshot', 'std_msgs/msg/Float64MultiArray', Durability.TRANSIENT_LOCAL, depth=1)
"""Published by the dynamics: its state every ``snapshot_period`` and at every event (layout: snapshot.py)."""
RESUME_STATE = Topic('resume_state', 'std_msgs/msg/Float64MultiArray', Durability.TRANSIENT_LOCAL, depth=1)
"""Published by a keeper (the recorder): the newest snapshot it holds, which outlives a killed dynamics;
a restarted dynamics continues from it."""
FAULTS = Topic('faults', 'diagnostic_msgs/msg/DiagnosticArray', Durability.TRANSIENT_LOCAL, depth=100)
"""Published by the dynamics when its fault settings change (a motor's efficiency, the adhesion scale, a sensor
dropout; set with ``ros2 param set`` or scheduled by ``fault_schedule``): stamped with the simulation time the
change applies from, naming what changed and why, with every fault setting's value from then on.
Transient-local, so a recorder matched late still records every event of the run."""
STEP_STAMPED = (ODOM, WHEEL_STATES, CONSTRAINT_WRENCH, DRIVE_FORCES, WHEEL_CONTACT)
"""The dynamics' per-step topics in its namespace; each message starts with a std_msgs/Header."""

RECORDED = (ODOM, WHEEL_STATES, CONSTRAINT_WRENCH, DRIVE_FORCES, WHEEL_CONTACT, REFERENCE, REFERENCE_TRAJECTORY,
            REFERENCE_PATH, CONSTRAINTS, ROBOT_DESCRIPTION, CLOCK, DIAGNOSTICS, GROUND_TRUTH_ODOM, FAULTS, *SENSORS, PUMP_COMMAND)
"""Topics a run records, in this order (robot_description too: a bag replayed in RViz or Foxglove
has the robot model)."""
NOISELESS_RECORDED = tuple(topic for topic in RECORDED
                           if topic not in (GROUND_TRUTH_ODOM, FAULTS, *SENSORS, PUMP_COMMAND))
"""Topics with messages in a run without sensor noise, faults, sensors and pump commands (what ``simulate --bag``
writes): its odom is the truth, ground_truth/odom is not published, no fault event is, and no sensor of the robot
file's."""

WALL_FRAME = 'wall'
BASE_FRAME = 'base_link'
REFERENCE_FRAME = 'reference'
"""Child frame of the ``reference`` odometry: at the reference point, along the path."""
WHEEL_JOINTS = ('wheel_left_front', 'wheel_left_rear', 'wheel_right_front', 'wheel_right_rear')
DRIVE_JOINTS = ('drive_left', 'drive_right', 'lateral')

DIAGNOSTIC_RESIDUAL_MAX = 'constraint residual max'
"""Key of the dynamics' /diagnostics value: the largest constraint residual |A qdd - b| of every
state published since the previous diagnostics message (so a run's peak is never missed)."""
RESIDUAL_SETTLED_AFTER = 0.1
"""Simulation seconds after which a state counts into DIAGNOSTIC_RESIDUAL_SETTLED: a start off the
constraints is pulled onto them over about this time, with a large residual meanwhile."""
DIAGNOSTIC_RESIDUAL_SETTLED = f'constraint residual max after {RESIDUAL_SETTLED_AFTER:g} s'
"""Key of the dynamics' /diagnostics value: DIAGNOSTIC_RESIDUAL_MAX of the states at or after
RESIDUAL_SETTLED_AFTER of simulation time (nan when the window has none)."""

DIAGNOSTIC_MOTOR_COMMANDED = '{side} motor commanded (N m)'
DIAGNOSTIC_MOTOR_APPLIED = '{side} motor applied (N m)'
"""Keys (``side``: left or right) of the dynamics' /diagnostics values with a robot file's motor block: the side's
torque commanded and applied over the step from the newest state; absent without the block."""

NODE_DYNAMICS = 'dynamics'
NODE_TRAJECTORY = 'trajectory'
NODE_CONSTRAINT_CONFIG = 'constraint_config'
NODE_RECORDER = 'recorder'
NODE_CMD_VEL = 'cmd_vel_controller'
NODE_JOINT_BRIDGE = 'joint_bridge'
NODE_VIEWER = 'viewer'


def by_name(name: str) -> Topic:
    """The graph topic called ``name`` (relative or absolute, e.g. 'odom' or '/wallbot/odom')."""
    known = RECORDED + (CONTROL_ODOM, WHEEL_TORQUE_CMD, CMD_VEL, JOINT_COMMANDS)
    for topic in known:
        if name in (topic.name, topic.resolve()):
            return topic
    # a name in another namespace (/robot2/odom); the longest match (ground_truth/odom, not odom)
    for topic in sorted(known, key=lambda topic: -len(topic.name)):
        if name.endswith(f'/{topic.name.lstrip("/")}'):
            return topic
    raise KeyError(name)
