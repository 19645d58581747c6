"""Live topics over the Foxglove WebSocket protocol (the ``foxglove-sdk`` package), without ROS.

The Foxglove app connects to ``ws://HOST:PORT`` and shows the running simulation with no ROS
install: each relayed topic is a channel named by its absolute ROS name, its messages the same
CDR bytes DDS carries (encoding ``cdr``), its schema the ROS 2 message definition (``ros2msg``),
as Foxglove's own ROS bridge serves them. The viewer node feeds it.
"""

from __future__ import annotations

from typing import Iterable

from wallbot_msgs_py import bagio, topics

DEFAULT_PORT = 8765
"""The Foxglove app's default WebSocket port."""
DEFAULT_HOST = '127.0.0.1'
"""Only this machine: the protocol has no authentication."""


class FoxgloveUnavailable(ValueError):
    """The foxglove-sdk package is missing, or its server could not start."""


class FoxgloveRelay:
    """A Foxglove WebSocket server with one channel per relayed topic."""

    def __init__(self, host: str, port: int, namespace: str, relayed: Iterable[topics.Topic]) -> None:
        try:
            import foxglove
        except ImportError:
            raise FoxgloveUnavailable("serving Foxglove needs the foxglove-sdk package: "
                                      "pip install 'wallbot_sim[foxglove]'") from None
        try:
            self.server = foxglove.start_server(name='wallbot_sim', host=host, port=port)
        except Exception as error:  # noqa: BLE001 - the SDK raises its own types; any of them means no server
            raise FoxgloveUnavailable(f'cannot serve Foxglove on {host}:{port}: {error}') from None
        store = bagio.typestore()
        self.channels = {}
        for topic in relayed:
            definition, _digest = store.generate_msgdef(topic.type, ros_version=2)
            schema = foxglove.Schema(name=topic.type, encoding='ros2msg', data=definition.encode())
            self.channels[topic.name] = foxglove.Channel(topic.resolve(namespace), schema=schema,
                                                         message_encoding='cdr')

    @property
    def port(self) -> int:
        return self.server.port

    def log(self, topic: topics.Topic, data: bytes) -> None:
        """Send a serialized message of ``topic`` to every client subscribed to it."""
        self.channels[topic.name].log(data)

    def close(self) -> None:
        for channel in self.channels.values():
            channel.close()
        self.server.stop()
