"""viewer_node (``/wallbot/viewer``): the running simulation as markers, tf and a Foxglove live view.

Publishes ``markers`` (visualization_msgs/MarkerArray, frame ``wall``: RViz2 or Foxglove with that
fixed frame draws the robot with no tf tree; what each marker shows: ``wallbot_sim.view``) at
``rate_hz`` frames per wall second, and ``/tf`` (the odometry's frame -> its child frame,
``base_link`` -> the wheel links, ``frame_prefix`` before their names) when tf2_msgs is importable.
With ``foxglove_port`` > 0 it also serves the graph's topics over the Foxglove WebSocket protocol
(``wallbot_sim.live_view``), ``/tf`` among them.

It never runs at the dynamics' 1 kHz: the per-step topics are read through a second node that no
executor spins (``_viewer_inputs``, hidden; the command line's remapping rules apply to the viewer's own
name and topics, not to it, so ``-r __node:=...`` renames the viewer alone), with subscriptions that
keep only the newest message (best effort, depth 1), and each frame takes that newest message and decodes it. So the node wakes
``rate_hz`` times a second whatever the step rate, and never slows the dynamics down (a best-effort
reader is never waited for). While nothing subscribes ``markers`` or ``/tf`` it reads only the
odometry (for the path travelled) and the reference path, and builds nothing; nor for a frame
without new odometry.
"""

from __future__ import annotations

import math

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from visualization_msgs.msg import MarkerArray

from wallbot_msgs_py import codec, topics, view_cdr
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.config import load_robot_parameters, load_world
from wallbot_sim.live_view import FoxgloveRelay
from wallbot_sim.nodes.common import ROBOT_CLOCK_ARGS, exit_process, run, steady_timer
from wallbot_sim.nodes.parameters import declare_typed, param_dict, parameter_result
from wallbot_sim.nodes.recorder import message_class
from wallbot_sim.settings.config import VIEWER, ViewerSettings
from wallbot_sim.urdf import RobotFrames
from wallbot_sim.view import Pose, Scene

THROTTLE = 5.0
"""Seconds between repeated log lines of one kind."""
NEWEST = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.VOLATILE)
"""The per-step topics: only the newest message matters, and the dynamics never waits for this reader."""
ALWAYS_READ = (topics.ODOM, topics.REFERENCE_PATH)
"""Read all the time, so a viewer opened later sees the path travelled and the reference at once."""
READ_WHILE_WATCHED = (topics.WHEEL_STATES, topics.WHEEL_CONTACT)
"""Read only while something subscribes ``markers`` or ``/tf`` (or the Foxglove relay runs): two
1 kHz streams that an unwatched viewer does not receive."""
DRAWN = ALWAYS_READ + READ_WHILE_WATCHED
"""Topics the markers are drawn from."""
RELAYED_ONLY = (topics.DRIVE_FORCES, topics.CONSTRAINT_WRENCH, topics.REFERENCE, topics.CONSTRAINTS,
                topics.ROBOT_DESCRIPTION, topics.DIAGNOSTICS)
"""Topics the Foxglove relay serves beside those drawn (the per-step ones at the frame rate)."""
EVERY_MESSAGE = (topics.DIAGNOSTICS,)
"""Relayed topics whose every message is served, not only each frame's newest."""


def tf_message_type():
    """tf2_msgs' TFMessage, or None where it is not installed (the pip wheels lack it)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        return None
    return TFMessage


class ViewerNode(Node):
    """Each frame: take the newest inputs, update the scene, publish markers (and tf, and the relay)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_VIEWER, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)
        settings: ViewerSettings = declare_typed(self, ViewerSettings, VIEWER)
        self.rate_hz = settings.rate_hz
        frame_prefix, port, host = settings.frame_prefix, settings.foxglove_port, settings.foxglove_host
        reasons = RobotFrames(prefix=frame_prefix).reasons()
        if reasons:
            raise ValueError('; '.join(reasons))
        self.scene = Scene(load_robot_parameters(settings.robot_file or None), settings.trail_points, frame_prefix,
                           load_world(settings.world_file or None))
        self.relay = None
        if port:
            self.relay = FoxgloveRelay(host, port, self.get_namespace(),
                                       DRAWN + RELAYED_ONLY + (topics.MARKERS, topics.TF))
            self.get_logger().info(f'serving Foxglove on ws://{host}:{self.relay.port}')
        self.marker_pub = self.create_publisher(MarkerArray, topics.MARKERS.name, qos_profile(topics.MARKERS))
        tf_type = tf_message_type()
        self.tf_pub = None if tf_type is None else self.create_publisher(tf_type, topics.TF.name,
                                                                         qos_profile(topics.TF))
        if self.tf_pub is None:
            self.get_logger().info('tf2_msgs is not installed: no /tf (the markers need none)')

        self.inputs = Node(f'_{self.get_name()}_inputs', namespace=self.get_namespace(), context=self.context,
                           start_parameter_services=False, use_global_arguments=False)
        self.subscriptions_ = {}
        for topic in ALWAYS_READ + ((READ_WHILE_WATCHED + RELAYED_ONLY) if self.relay is not None else ()):
            self._subscribe(topic)
        self.published_ns: int | None = None
        """The odometry stamp of the newest frame published."""
        self.timer = self._frame_timer()
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.get_logger().info(f'markers at {self.rate_hz:g} frames per second')

    def _subscribe(self, topic: topics.Topic) -> None:
        newest_only = topic.durability is topics.Durability.VOLATILE and topic not in EVERY_MESSAGE
        self.subscriptions_[topic] = self.inputs.create_subscription(
            message_class(topic.type), self.resolve_topic_name(topic.name), lambda _data: None,
            NEWEST if newest_only else qos_profile(topic), raw=True)

    def _watched(self) -> bool:
        """Whether anything takes what the viewer publishes (and so, whether to read every input)."""
        return (self.relay is not None or self.marker_pub.get_subscription_count() > 0
                or (self.tf_pub is not None and self.tf_pub.get_subscription_count() > 0))

    def _read_while_watched(self, watched: bool) -> None:
        """Subscribe the wheels' and contact topics while watched, drop them (and what they said) when not."""
        if watched and READ_WHILE_WATCHED[0] not in self.subscriptions_:
            for topic in READ_WHILE_WATCHED:
                self._subscribe(topic)
        elif not watched and READ_WHILE_WATCHED[0] in self.subscriptions_:
            for topic in READ_WHILE_WATCHED:
                self.inputs.destroy_subscription(self.subscriptions_.pop(topic))
            self.scene.forget_wheels_and_contact()

    def _frame_timer(self):
        return steady_timer(self, 1.0 / self.rate_hz, self.frame)

    # --- a frame ---------------------------------------------------------------------------------
    def _take(self, topic: topics.Topic) -> list[bytes]:
        """What arrived on ``topic`` since the last frame (its newest message only, for most topics).

        Taken from the subscription's handle, as rclpy's own ``wait_for_message`` does: the
        subscription belongs to a node no executor waits on, so no callback runs per message.
        """
        subscription = self.subscriptions_[topic]
        taken = []
        while True:
            with subscription.handle:
                message = subscription.handle.take_message(subscription.msg_type, True)
            if message is None:
                return taken
            taken.append(message[0])

    def frame(self) -> None:
        """Take the newest inputs, and publish the markers (and tf) if the robot has moved on."""
        watched = self._watched()
        self._read_while_watched(watched)
        for topic in self.subscriptions_:
            for data in self._take(topic):
                try:
                    if topic in DRAWN:
                        self._draw(topic, data)
                except (ValueError, TypeError, IndexError) as error:  # malformed: never drawn
                    self.get_logger().error(f'ignoring a {topic.name} message: {error}',
                                            throttle_duration_sec=THROTTLE)
                    continue
                if self.relay is not None:
                    self.relay.log(topic, data)
        pose = self.scene.pose
        if not watched or pose is None or pose.stamp_ns == self.published_ns:
            return
        self.published_ns = pose.stamp_ns
        if self.relay is not None or self.marker_pub.get_subscription_count() > 0:
            markers = view_cdr.marker_array(pose.stamp_ns, pose.frame, self.scene.markers())
            self.marker_pub.publish(markers)
            if self.relay is not None:
                self.relay.log(topics.MARKERS, markers)
        tf_wanted = self.tf_pub is not None and self.tf_pub.get_subscription_count() > 0
        if tf_wanted or self.relay is not None:  # Foxglove gets tf with or without tf2_msgs
            transforms = view_cdr.tf_message(pose.stamp_ns, self.scene.transforms())
            if tf_wanted:
                self.tf_pub.publish(transforms)
            if self.relay is not None:
                self.relay.log(topics.TF, transforms)

    def _draw(self, topic: topics.Topic, data: bytes) -> None:
        scene = self.scene
        if topic is topics.ODOM:
            odom = codec.decode_odometry(data)
            _finite(topic, (odom.x, odom.y, odom.yaw))
            scene.update_pose(Pose(odom.stamp_ns, odom.frame, odom.child, odom.x, odom.y, odom.yaw))
        elif topic is topics.REFERENCE_PATH:
            scene.set_reference_path([(x, y) for _stamp, x, y, _yaw in codec.decode_path(data).poses])
        elif topic is topics.WHEEL_CONTACT:
            contact = codec.decode_wheel_contact(data)
            scene.update_contact(_finite(topic, contact.loads), _finite(topic, contact.use),
                                 [flag > 0.5 for flag in _finite(topic, contact.slipping)],
                                 _finite(topic, contact.force_x), _finite(topic, contact.force_y))
        else:
            scene.update_wheels(_finite(topic, codec.decode_joint_state(data).values(topics.WHEEL_JOINTS, 'position')))

    # --- parameters ------------------------------------------------------------------------------
    def _on_set(self, parameters):
        return parameter_result(VIEWER.reasons(param_dict(parameters)))

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, ('rate_hz', 'trail_points'))
        if 'rate_hz' in changes:
            self.rate_hz = float(changes['rate_hz'])
            self.destroy_timer(self.timer)
            self.timer = self._frame_timer()
        if 'trail_points' in changes:
            self.scene.set_trail_points(int(changes['trail_points']))
        if changes:
            self.get_logger().info('parameters: ' + ', '.join(f'{k} = {v}' for k, v in changes.items()))

    def close(self) -> None:
        self.inputs.destroy_node()
        if self.relay is not None:
            self.relay.close()


def _finite(topic: topics.Topic, values: tuple[float, ...]) -> tuple[float, ...]:
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f'{topic.name}: a value is missing or not finite: {values}')
    return values


def main(args: list[str] | None = None) -> None:
    exit_process(run(ViewerNode, args))


if __name__ == '__main__':
    main()
