"""Model state and outputs <-> the graph's ROS messages (plain functions, no node code).

Each ``*_message`` function builds one message from model objects and a simulation time;
the per-step messages of the dynamics node (odom, wheel_states, constraint_wrench,
drive_forces, /clock) are encoded straight to CDR bytes by ``step_cdr`` instead.

Conventions (REP 103/105): poses in frame ``wall`` (X right, Y up, Z out of the wall), the
robot's frame ``base_link`` at the geometric centre; odometry twists are expressed in the
child frame, so twist.linear = (v_long, v_lat) and twist.angular.z = thd.
"""

from __future__ import annotations

import math
from typing import Iterable, NamedTuple, Sequence

from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, Quaternion, Transform, Twist
from nav_msgs.msg import Odometry, Path
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from wallbot_msgs_py import bagio, topics
from wallbot_sim.model.constraints import BaumgarteGains
from wallbot_sim.model.constraint_set import ConstraintSelection
from wallbot_sim.model.trajectories import Plan, ReferenceSample, SampledReference, tangent_heading

NS_PER_S = 1_000_000_000


# --- time -----------------------------------------------------------------------------------
def to_nanoseconds(t: float) -> int:
    """Simulation time (s) as integer nanoseconds (rounded: k * 1 ms stamps come out exact)."""
    return round(t * 1e9)


def stamp(t: float, msg: Time | None = None) -> Time:
    """builtin_interfaces/Time of simulation time t (s); fills ``msg`` in place if given."""
    ns = to_nanoseconds(t)
    msg = msg if msg is not None else Time()
    msg.sec, msg.nanosec = divmod(ns, NS_PER_S)
    return msg


def stamp_nanoseconds(msg: Time | Duration) -> int:
    """A Time or Duration as integer nanoseconds."""
    return msg.sec * NS_PER_S + msg.nanosec


def seconds(msg: Time | Duration) -> float:
    """A Time or Duration in seconds."""
    return stamp_nanoseconds(msg) * 1e-9


def duration(ns: int) -> Duration:
    """builtin_interfaces/Duration of ``ns`` nanoseconds."""
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return Duration(sec=sec, nanosec=nanosec)


def yaw_quaternion(yaw: float, msg: Quaternion | None = None) -> Quaternion:
    """Rotation by ``yaw`` about Z."""
    msg = msg if msg is not None else Quaternion()
    msg.x, msg.y, msg.z, msg.w = 0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)
    return msg


def quaternion_yaw(q: Quaternion) -> float:
    """Yaw of a rotation about Z (the only rotation this graph uses)."""
    return 2.0 * math.atan2(q.z, q.w)


class PlanarState(NamedTuple):
    """The chassis state an ``odom`` message carries, in the wall frame."""

    stamp_ns: int
    x: float
    y: float
    theta: float
    """Yaw of the pose quaternion, in (-pi, pi] (the simulation's angle is unwrapped)."""
    xd: float
    yd: float
    thd: float

    @property
    def t(self) -> float:
        return self.stamp_ns * 1e-9


def odometry_to_state(msg: Odometry) -> PlanarState:
    """Decode ``odom``: pose in ``wall``, twist (v_long, v_lat, thd) in ``base_link`` rotated back
    to wall-frame velocities (xd, yd). ValueError if a value is not finite."""
    pose, twist = msg.pose.pose, msg.twist.twist
    theta = quaternion_yaw(pose.orientation)
    c, s = math.cos(theta), math.sin(theta)
    u, v = twist.linear.x, twist.linear.y
    state = PlanarState(stamp_nanoseconds(msg.header.stamp), pose.position.x, pose.position.y, theta,
                        c * u - s * v, s * u + c * v, twist.angular.z)
    if not all(math.isfinite(value) for value in state[1:]):
        raise ValueError(f'odometry at t = {state.t:.3f} s is not finite')
    return state


# --- the reference ----------------------------------------------------------------------------
def reference_odometry_message(sample: ReferenceSample, t: float, fallback_yaw: float = 0.0) -> Odometry:
    """``reference``: the reference point at time t in ``wall``, child frame ``reference``.

    The child frame points along the path (the tangent heading; ``fallback_yaw`` while the
    reference is at rest), so the twist is (speed, 0, turning rate) in that frame, like an
    odometry of a robot driving the path exactly.
    """
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = topics.WALL_FRAME, topics.REFERENCE_FRAME
    stamp(t, msg.header.stamp)
    heading = tangent_heading(sample)
    yaw = heading.angle if heading is not None else fallback_yaw
    (vx, vy), c, s = sample.velocity, math.cos(yaw), math.sin(yaw)
    msg.pose.pose.position.x, msg.pose.pose.position.y = map(float, sample.position)
    yaw_quaternion(yaw, msg.pose.pose.orientation)
    msg.twist.twist.linear.x, msg.twist.twist.linear.y = c * vx + s * vy, -s * vx + c * vy
    msg.twist.twist.angular.z = heading.rate if heading is not None else 0.0
    return msg


def plan_sample_times(plan: Plan) -> list[float]:
    """The sample times of a plan as the dynamics node sees them (through integer nanoseconds)."""
    return [to_nanoseconds(t) * 1e-9 for t in plan.times]


def sampled_reference(plan: Plan) -> SampledReference:
    """The reference the dynamics node interpolates from ``plan``: identical to
    ``reference_from_trajectory(trajectory_message(plan))``, without building the message."""
    return SampledReference(plan_sample_times(plan), plan.positions, plan.velocities, plan.accelerations)


def _headings(plan: Plan, fallback_yaw: float) -> list[tuple[float, float, float]]:
    """Tangent heading, rate, acceleration at each sample (carried over where at rest)."""
    result, yaw = [], fallback_yaw
    for p, v, a in zip(plan.positions, plan.velocities, plan.accelerations):
        heading = tangent_heading(ReferenceSample(p, v, a, (0.0, 0.0)))
        if heading is None:
            result.append((yaw, 0.0, 0.0))
        else:
            yaw = heading.angle
            result.append((yaw, heading.rate, heading.acceleration))
    return result


def trajectory_message(plan: Plan, fallback_yaw: float = 0.0) -> MultiDOFJointTrajectory:
    """``reference_trajectory``: the plan as one MultiDOFJointTrajectory.

    header.stamp = the first sample time, frame ``wall``; one joint (``base_link``) whose
    points carry the position (transforms[0].translation), velocity (velocities[0].linear)
    and acceleration (accelerations[0].linear) of the centre at
    header.stamp + time_from_start. The rotation and angular parts hold the tangent heading
    for display only (the jerk-free heading rate acceleration omits the jerk term); the
    dynamics interpolates positions with quintic Hermite segments from p, v, a alone.
    """
    start_ns = to_nanoseconds(plan.times[0])
    msg = MultiDOFJointTrajectory()
    msg.header.frame_id = topics.WALL_FRAME
    msg.header.stamp = stamp(plan.times[0])
    msg.joint_names = [topics.BASE_FRAME]
    points = []
    for t, p, v, a, (yaw, rate, _acc) in zip(plan.times, plan.positions, plan.velocities,
                                             plan.accelerations, _headings(plan, fallback_yaw)):
        point = MultiDOFJointTrajectoryPoint()
        transform, velocity, acceleration = Transform(), Twist(), Twist()
        transform.translation.x, transform.translation.y = float(p[0]), float(p[1])
        yaw_quaternion(yaw, transform.rotation)
        velocity.linear.x, velocity.linear.y, velocity.angular.z = float(v[0]), float(v[1]), rate
        acceleration.linear.x, acceleration.linear.y = float(a[0]), float(a[1])
        point.transforms, point.velocities, point.accelerations = [transform], [velocity], [acceleration]
        point.time_from_start = duration(to_nanoseconds(t) - start_ns)
        points.append(point)
    msg.points = points
    return msg


def plan_from_trajectory(msg: MultiDOFJointTrajectory) -> Plan:
    """The plan in a ``reference_trajectory`` message; ValueError if it is not a usable plan."""
    if len(msg.points) < 2:
        raise ValueError(f'a reference trajectory needs >= 2 points, got {len(msg.points)}')
    start_ns = stamp_nanoseconds(msg.header.stamp)
    times, positions, velocities, accelerations = [], [], [], []
    for i, point in enumerate(msg.points):
        if not (point.transforms and point.velocities and point.accelerations):
            raise ValueError(f'reference trajectory point {i} lacks a transform, velocity or acceleration')
        p, v, a = point.transforms[0].translation, point.velocities[0].linear, point.accelerations[0].linear
        times.append((start_ns + stamp_nanoseconds(point.time_from_start)) * 1e-9)
        positions.append((p.x, p.y))
        velocities.append((v.x, v.y))
        accelerations.append((a.x, a.y))
    return Plan(times, positions, velocities, accelerations)


def plan_from_cdr(data: bytes) -> Plan:
    """The plan in a serialized ``reference_trajectory`` (what a raw subscription takes).

    Decoding in Python (rosbags) instead of rclpy's C conversion costs a third of the time and,
    unlike the C conversion, yields the GIL: the dynamics node's 1 kHz loop thread is never
    held up for the milliseconds a plan of a few hundred points takes to convert.
    """
    try:
        msg = bagio.deserialize(data, topics.REFERENCE_TRAJECTORY.type)
    except Exception as error:  # noqa: BLE001 - any decoding failure is a malformed message
        raise ValueError(f'malformed reference_trajectory ({type(error).__name__}: {error})') from None
    return plan_from_trajectory(msg)


def reference_from_trajectory(msg: MultiDOFJointTrajectory) -> SampledReference:
    """The SampledReference (quintic Hermite) of a ``reference_trajectory`` message.

    ValueError (with the reason) for fewer than 2 points, missing parts, times that do not
    increase, or non-finite values.
    """
    try:
        return SampledReference(*plan_from_trajectory(msg))
    except ValueError:
        raise
    except Exception as error:  # ParameterError from the model
        raise ValueError(str(error)) from None


def plan_is_final(plan: Plan, tolerance: float = 1e-12) -> bool:
    """True if the plan ends at rest (zero velocity and acceleration at its last sample).

    Holding the last point after such a plan is the exact continuation of the reference, so
    the dynamics may run past its end; a plan that ends moving only covers up to its end.
    """
    (vx, vy), (ax, ay) = plan.velocities[-1], plan.accelerations[-1]
    return max(abs(vx), abs(vy), abs(ax), abs(ay)) <= tolerance


def path_message(plan: Plan, max_poses: int = 2000, fallback_yaw: float = 0.0) -> Path:
    """``reference_path``: the plan's points as poses (tangent heading), at most ``max_poses``."""
    msg = Path()
    msg.header.frame_id = topics.WALL_FRAME
    msg.header.stamp = stamp(plan.times[0])
    stride = max(1, math.ceil(len(plan.times) / max_poses))
    headings = _headings(plan, fallback_yaw)
    poses = []
    indices = list(range(0, len(plan.times), stride))
    if indices[-1] != len(plan.times) - 1:
        indices.append(len(plan.times) - 1)
    for i in indices:
        pose = PoseStamped()
        pose.header.frame_id = topics.WALL_FRAME
        stamp(plan.times[i], pose.header.stamp)
        pose.pose.position.x, pose.pose.position.y = map(float, plan.positions[i])
        yaw_quaternion(headings[i][0], pose.pose.orientation)
        poses.append(pose)
    msg.poses = poses
    return msg


# --- the constraint set -----------------------------------------------------------------------
CONSTRAINTS_STATUS_NAME = 'wallbot constraints'
SWITCHES = ('trajectory_task', 'belt', 'non_lateral', 'nonslip', 'tangent_heading')
GAINS = ('baumgarte_alpha', 'baumgarte_beta')


def selection_from_switches(trajectory_task: bool, belt: bool, non_lateral: bool, nonslip: bool,
                            tangent_heading: bool) -> ConstraintSelection:
    """The model's selection from the constraint_config switches.

    ``tangent_heading`` true keeps the model's default (heading task on whenever non_lateral is
    active with the trajectory task); false switches it off (the paper's inconsistent set).
    """
    return ConstraintSelection(bool(trajectory_task), bool(belt), bool(non_lateral), bool(nonslip),
                               None if tangent_heading else False)


def constraints_message(switches: dict[str, bool], gains: BaumgarteGains) -> DiagnosticStatus:
    """``constraints``: the switch values and gains as KeyValue pairs, plus the active modules.

    message = the active modules joined by '+', e.g. 'trajectory+belt'; values hold every
    switch ('true'/'false'), the gains (repr of the float) and 'active'.
    """
    selection = selection_from_switches(**{name: switches[name] for name in SWITCHES})
    values = [KeyValue(key=name, value='true' if switches[name] else 'false') for name in SWITCHES]
    values += [KeyValue(key='baumgarte_alpha', value=repr(float(gains.alpha))),
               KeyValue(key='baumgarte_beta', value=repr(float(gains.beta))),
               KeyValue(key='active', value=','.join(selection.active_names()))]
    return DiagnosticStatus(level=DiagnosticStatus.OK, name=CONSTRAINTS_STATUS_NAME,
                            message=selection.label(), hardware_id='wallbot_sim', values=values)


def constraints_from_message(msg: DiagnosticStatus) -> tuple[ConstraintSelection, BaumgarteGains]:
    """The selection and gains of a ``constraints`` message; ValueError naming what is wrong."""
    values = {kv.key: kv.value for kv in msg.values}
    switches = {}
    for name in SWITCHES:
        text = values.get(name, '').strip().lower()
        if text not in ('true', 'false'):
            raise ValueError(f'constraints message: {name} must be true or false, got {values.get(name)!r}')
        switches[name] = text == 'true'
    try:
        gains = BaumgarteGains(float(values.get('baumgarte_alpha', 'nan')),
                               float(values.get('baumgarte_beta', 'nan')))
    except Exception as error:
        raise ValueError(f'constraints message: {error}') from None
    return selection_from_switches(**switches), gains


# --- commands ---------------------------------------------------------------------------------
def parse_torque_command(msg, max_torque: float) -> tuple[float, float]:
    """(tau_L, tau_R) of a ``wheel_torque_cmd`` Float64MultiArray.

    ValueError with the reason for a wrong length, NaN or inf, or |tau| > max_torque.
    """
    data = list(msg.data)
    if len(data) != 2:
        raise ValueError(f'wheel_torque_cmd needs data = [tau_L, tau_R], got {len(data)} values')
    for side, value in zip(('tau_L', 'tau_R'), data):
        if not math.isfinite(value):
            raise ValueError(f'wheel_torque_cmd {side} is not finite ({value})')
        if abs(value) > max_torque:
            raise ValueError(f'wheel_torque_cmd {side} = {value:g} N m is beyond max_wheel_torque {max_torque:g} N m')
    return float(data[0]), float(data[1])


# --- diagnostics ------------------------------------------------------------------------------
LEVELS = {'ok': DiagnosticStatus.OK, 'warn': DiagnosticStatus.WARN, 'error': DiagnosticStatus.ERROR,
          'stale': DiagnosticStatus.STALE}


def diagnostic_status(name: str, level: str, message: str, values: Iterable[tuple[str, object]],
                      hardware_id: str = 'wallbot_sim') -> DiagnosticStatus:
    """A DiagnosticStatus; level one of ok, warn, error, stale; floats formatted with %.6g."""
    pairs = [KeyValue(key=str(k), value=(f'{v:.6g}' if isinstance(v, float) else str(v))) for k, v in values]
    return DiagnosticStatus(level=LEVELS[level], name=name, message=message, hardware_id=hardware_id,
                            values=pairs)


def diagnostics_message(t: float, statuses: Sequence[DiagnosticStatus]) -> DiagnosticArray:
    """``/diagnostics`` stamped with simulation time t."""
    msg = DiagnosticArray(status=list(statuses))
    stamp(t, msg.header.stamp)
    return msg
