"""The dynamics node's per-step messages out: a state's topics (odometry, wheel states, wrench, drive forces, wheel
contact, /clock; ground_truth/odom and the robot file's sensors where on), control_odom at the control instants,
the domain's /clock, and the in-process tap; each message written only where a subscriber hears it."""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable, Sequence

from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import FluidPressure, Imu, JointState

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_msgs_py.step_cdr import StepEncoder
from wallbot_sim.loop import PreparedState
from wallbot_sim.model import Robot, StepOutputs
from wallbot_sim.model.outputs import StepBlock
from wallbot_sim.nodes.sensor_noise import NoiseLevels, SensorNoise
from wallbot_sim.nodes.step_tap import StepTap
from wallbot_sim.sensors import SensorSuite
from wallbot_sim.settings.dynamics import NOISE_PARAMETERS
from wallbot_sim.urdf import RobotFrames

if TYPE_CHECKING:
    from wallbot_sim.nodes.dynamics import DynamicsNode

BURST_CONTROL_ODOM_EVERY = 10
"""Smallest control_odom_every at which the loop publishes a block's states at once (factor 0) to a DDS
subscriber of control_odom: five of its messages at most in a burst of 50 states."""
MESSAGE_TYPES = {topics.ODOM: Odometry, topics.WHEEL_STATES: JointState,
                 topics.CONSTRAINT_WRENCH: WrenchStamped, topics.DRIVE_FORCES: JointState,
                 topics.WHEEL_CONTACT: JointState,
                 topics.CLOCK: ClockMsg}
"""The per-step topics; published as CDR bytes from ``step_cdr`` (rclpy's publish takes bytes as serialized)."""
SENSOR_TYPES = {topics.IMU: Imu, topics.JOINT_STATES: JointState, topics.CHAMBER_PRESSURE: FluidPressure}
"""The robot file's sensors (``wallbot_sim.sensors``), published where its ``sensors`` block has them."""
STEP_TOPICS = (*MESSAGE_TYPES, topics.GROUND_TRUTH_ODOM, *SENSOR_TYPES)
"""Every topic ``prepare``'s send may publish (ground_truth/odom while the sensor noise is on, the sensors)."""


class StatePublisher:
    """The per-step publishers of ``node`` (its settings read as they are now), with the step encoder, the sensor
    noise and the sensors of ``robot``; ``tap``: a recorder in the same process also gets every state's messages."""

    def __init__(self, node: DynamicsNode, frames: RobotFrames, robot: Robot, tap: StepTap | None) -> None:
        self.node, self.tap = node, tap
        settings = node.settings
        self.publishers_ = {topic: node.create_publisher(kind, topic.name, qos_profile(topic))
                            for topic, kind in MESSAGE_TYPES.items()}
        self.control_odom_sent: bytes | None = None
        """The last state published on control_odom."""
        self.control_odom_pub = node.create_publisher(Odometry, topics.CONTROL_ODOM.name,
                                                      qos_profile(topics.CONTROL_ODOM))
        self.domain_clock_pub = (node.create_publisher(ClockMsg, topics.DOMAIN_CLOCK.name,
                                                       qos_profile(topics.DOMAIN_CLOCK))
                                 if settings.domain_clock else None)
        levels = NoiseLevels(*(getattr(settings, name) for name in NOISE_PARAMETERS))
        self.noise = SensorNoise(levels, settings.noise_seed) if levels.on else None
        truth = levels.on or settings.ground_truth
        self.encoder = StepEncoder(frames.odom, frames.base_link, levels.pose_variances(),
                                   levels.twist_variances(), ground_truth=truth)
        if truth:
            self.publishers_[topics.GROUND_TRUTH_ODOM] = node.create_publisher(
                Odometry, topics.GROUND_TRUTH_ODOM.name, qos_profile(topics.GROUND_TRUTH_ODOM))
        sensors = robot.params.sensors
        self.sensors = SensorSuite(sensors, robot, frames.base_link) if sensors is not None else None
        for topic in self.sensors.topics if self.sensors is not None else ():
            self.publishers_[topic] = node.create_publisher(SENSOR_TYPES[topic], topic.name, qos_profile(topic))

    def prepare(self, out: StepOutputs, clock: bool) -> Callable[[], None]:
        """``Graph.prepare``: ``out``'s messages encoded now, and the send that publishes them."""
        sensed = self.noise.sense(out.q, out.qd) if self.noise is not None else None
        encoded, stamp_ns = self.encoder.encode(out, sensed), codec.to_nanoseconds(out.t)
        if self.sensors is not None:
            encoded[-1:-1] = self.sensors.encode(out)  # before /clock, which goes last

        def send() -> None:
            heard = self.heard()
            self._send(encoded, clock, stamp_ns, heard, self._to_controller(heard, stamp_ns), 0.0)
        return send

    def encodes_blocks(self, burst: bool) -> bool:
        """``Graph.encodes_blocks``: whether a block's states may be encoded at once (and sent in a ``burst``)."""
        # A burst of a block's messages (hundreds within a millisecond) can overflow a DDS subscriber's
        # shared-memory queue on a loaded machine; reliability repairs the loss only at Fast DDS's next
        # heartbeat, seconds later (seen: a separate recorder missing one message of a 1.5 s run). So
        # bursts only where no DDS subscriber takes the per-step topics (a composed recorder takes them
        # from the tap); paced, a block's states go out one at a time. A controller's control_odom carries
        # at most every BURST_CONTROL_ODOM_EVERY-th state, a few of a burst: no queue overflows for them
        heard = self.heard()
        if self.node.settings.control_odom_every >= BURST_CONTROL_ODOM_EVERY:
            heard.discard(topics.CONTROL_ODOM)
        return self.noise is None and self.sensors is None and not (burst and heard)

    def prepare_block(self, block: StepBlock) -> list[PreparedState]:
        """``Graph.prepare_block``: each state of ``block`` encoded, with its send."""
        heard = self.heard()  # once a block: a subscriber matched within it misses at most its few states
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

    def heard(self) -> set[topics.Topic]:
        """The per-step topics (and control_odom) a subscriber is matched to now."""
        # a per-step message nobody is matched to would only cost its write into Fast DDS
        # (in a composed run, with nothing else subscribed: a tenth of the process)
        heard = {topic for topic, publisher in self.publishers_.items()
                 if topic is not topics.CLOCK and publisher.get_subscription_count()}
        if self.control_odom_pub.get_subscription_count():
            heard.add(topics.CONTROL_ODOM)
        return heard

    def resend_to_controller(self) -> None:
        """``Graph.resend_to_controller``: the last state sent on control_odom, again."""
        if self.control_odom_sent is not None:
            self.control_odom_pub.publish(self.control_odom_sent)

    def _to_controller(self, heard: set[topics.Topic], stamp_ns: int) -> bool:
        """Whether the state at ``stamp_ns`` goes out on control_odom: subscribed, and a control instant."""
        settings = self.node.settings
        every = settings.control_odom_every
        return (topics.CONTROL_ODOM in heard and every > 0
                and round(stamp_ns * 1e-9 * settings.rate_hz) % every == 0)

    def _send(self, encoded: Sequence[tuple[topics.Topic, bytes]], clock: bool, stamp_ns: int,
              heard: set[topics.Topic], controller: bool, ahead: float) -> None:
        """Publish one state's messages (/clock if ``clock``, the others where ``heard``, odom on control_odom if
        ``controller``: ``_to_controller``) but those a sensor dropout silences; hand them to the tap, ``ahead``
        seconds before the state is due (the loop does so only for a state nobody outside hears)."""
        silenced = self.node.loop.silenced
        if silenced:
            encoded = [(topic, data) for topic, data in encoded if topic not in silenced]
        for topic, data in encoded:
            if topic is not topics.CLOCK:
                if topic in heard:
                    self.publishers_[topic].publish(data)
                if topic is topics.ODOM and controller:
                    self.control_odom_pub.publish(data)
                    self.control_odom_sent = data
            elif clock:
                self.publishers_[topic].publish(data)
                if self.domain_clock_pub is not None:
                    self.domain_clock_pub.publish(data)
        if self.tap is not None:
            self.tap.put(encoded, clock, stamp_ns, ahead)
