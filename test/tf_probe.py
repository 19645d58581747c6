"""Plays a dynamics node to the viewer and prints the /tf it answers with (needs tf2_msgs).

Run as a script in an environment where tf2_msgs is importable: it publishes odometry moving along
x and fixed wheel angles (WHEEL_ANGLES) every 20 ms, subscribes /tf, and once a TFMessage is stamped
like one of its odometry messages, prints that odometry and the transforms as one JSON line and
exits 0.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rclpy  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from odom_probe import spin_until  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from message_fields import odometry_cdr, stamp_ns  # noqa: E402
from wallbot_msgs_py import codec, topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402

WHEEL_ANGLES = (0.5, -1.0, 2.0, 4.0)


def main() -> int:
    rclpy.init()
    node = rclpy.create_node('tf_probe')
    odom_pub = node.create_publisher(Odometry, topics.ODOM.resolve(), qos_profile(topics.ODOM))
    wheels_pub = node.create_publisher(JointState, topics.WHEEL_STATES.resolve(), qos_profile(topics.WHEEL_STATES))
    sent: dict[int, tuple[float, float, float]] = {}
    answer: list[TFMessage] = []

    def on_tf(msg: TFMessage) -> None:
        # the first frames may come before the viewer has the wheel angles: then only wall -> base_link
        if len(msg.transforms) == 5 and stamp_ns(msg.transforms[0].header.stamp) in sent:
            answer.append(msg)

    def publish() -> None:
        k = len(sent) + 1
        t, pose = k * 0.02, (0.01 * k, -0.2, 0.3 + 0.01 * k)
        wheels = JointState(name=list(topics.WHEEL_JOINTS), position=list(WHEEL_ANGLES))
        wheels_pub.publish(wheels)
        odom_pub.publish(odometry_cdr(t, *pose, 0.5, 0.0, 0.5))
        sent[codec.to_nanoseconds(t)] = pose

    node.create_subscription(TFMessage, topics.TF.name, on_tf, qos_profile(topics.TF))
    node.create_timer(0.02, publish)
    spin_until(node, answer)
    transforms = answer[0].transforms
    stamp = stamp_ns(transforms[0].header.stamp)
    print(json.dumps({'odom': sent[stamp], 'wheel_angles': WHEEL_ANGLES, 'transforms': [
        {'parent': t.header.frame_id, 'child': t.child_frame_id, 'stamp': stamp_ns(t.header.stamp),
         'translation': [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
         'rotation': [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
                      t.transform.rotation.w]} for t in transforms]}), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
