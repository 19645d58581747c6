"""The two ends of test_node_common's delivery test.

``delivery_probe.py send N``: a node run by ``wallbot_sim.nodes.common.run``, as every node of the
package is, that logs ``matched`` once subscribers of ``delivery`` and ``delivery_last`` appear; when it
gets SIGUSR1 it publishes N numbered messages on ``delivery`` at once, then one on ``delivery_last``
(its writer sends nothing after it, as a controller's last command), and logs ``sent N``; it runs until
SIGINT / SIGTERM.

``delivery_probe.py listen``: a plain rclpy subscriber of both that prints ``received K`` for the
message numbered K and ``received last`` for the last one.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rclpy  # noqa: E402
from rclpy.executors import ExternalShutdownException  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from wallbot_sim.nodes.common import run, steady_timer  # noqa: E402

TOPIC, LAST_TOPIC = 'delivery', 'delivery_last'
PADDING = 'x' * 1000
"""Makes each message about 1 kB, so that a burst fills a stopped listener's queue."""


def qos(depth: int) -> QoSProfile:
    """Reliable, keeping the last ``depth`` messages (0: all of them)."""
    if depth == 0:
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1, reliability=ReliabilityPolicy.RELIABLE)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=ReliabilityPolicy.RELIABLE)


class Sender(Node):
    def __init__(self, count: int) -> None:
        super().__init__('delivery_sender')
        self.count, self.asked, self.matched = count, False, False
        self.publisher = self.create_publisher(String, TOPIC, qos(count))
        self.last_publisher = self.create_publisher(String, LAST_TOPIC, qos(1))
        signal.signal(signal.SIGUSR1, lambda *_: setattr(self, 'asked', True))
        self.timer = steady_timer(self, 0.01, self._check)

    def _check(self) -> None:
        if not self.matched and all(p.get_subscription_count() for p in (self.publisher, self.last_publisher)):
            self.matched = True
            self.get_logger().info('matched')
        if self.asked:
            self.asked = False
            for number in range(1, self.count + 1):
                self.publisher.publish(String(data=f'{number} {PADDING}'))
            self.last_publisher.publish(String(data='last'))
            self.get_logger().info(f'sent {self.count}')


def listen() -> int:
    rclpy.init()
    node = rclpy.create_node('delivery_listener')
    node.create_subscription(String, TOPIC, lambda msg: print(f'received {msg.data.split()[0]}', flush=True),
                             qos(0))
    node.create_subscription(String, LAST_TOPIC, lambda msg: print(f'received {msg.data}', flush=True), qos(1))
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):  # Ctrl-C, or SIGTERM's shutdown
        pass
    return 0


if __name__ == '__main__':
    if sys.argv[1] == 'send':
        sys.exit(run(lambda: Sender(int(sys.argv[2])), sys.argv))
    sys.exit(listen())
