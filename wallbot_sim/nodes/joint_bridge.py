"""joint_bridge_node (``/wallbot/joint_bridge``): the wheels in ros2_control's topic conventions.

* publishes ``joint_states`` (sensor_msgs/JointState, as joint_state_broadcaster does): the four
  wheel joints of the URDF (``wheel_left_front``, ...) with position (spin angle, rad), velocity
  (rad/s) and effort (N m: the total torque on the wheel, motor share plus constraint torque, as
  ``wheel_states`` carries it), stamped in simulation time, at ``rate_hz`` (50 by default) of
  simulation time: the ``wheel_states`` message at or after each multiple of 1 / ``rate_hz``,
  republished. A controller_manager reads states at its own update rate; 1 kHz would only load
  the graph. A robot file (``robot_file``) with ``sensors.encoders`` has the dynamics publish
  ``joint_states`` as the encoders read them (``wallbot_sim.sensors``): then this node publishes none.
* subscribes ``joint_commands`` (sensor_msgs/JointState with one effort per wheel joint, what
  topic_based_ros2_control's hardware interface publishes for effort command interfaces) and
  sends the side torques (``wallbot_sim.control.joint_interface``: each side's two efforts summed,
  the belt couples the wheels of a side) on ``wheel_torque_cmd``. A malformed message (joints
  missing, duplicated or unknown, efforts missing or not finite, a side over ``max_wheel_torque``)
  is refused with one log line and never reaches the simulation.

The dynamics holds each command for its ``command_timeout`` (0.5 s of simulation time), then
falls back to zero torque; a controller_manager writing at its update rate keeps it fresh.

With ``wait_for_recorder`` (``wallbot-sim run`` sets it when it records) the node subscribes
``joint_commands`` and ``wheel_states``, and so forwards anything, only once a recorder hears
``wheel_torque_cmd`` and ``joint_states``: the bag holds every command that reached the simulation
and every joint state, also when a loaded machine's discovery matches the recorder late.

With ``answer_commands`` (``wallbot-sim test`` sets it: a controller under test publishes joint_commands,
one answering each joint_states, and the dynamics waits for it in lockstep, its ``command_sensor``
wheel_states) it subscribes only once, besides, every joint_commands publisher hears joint_states (so
the controller gets the first state), and holds a command until the dynamics hears it.
"""

from __future__ import annotations

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.control.joint_interface import side_torques
from wallbot_sim.control.sampling import ControlInstants
from wallbot_sim.nodes.common import (ROBOT_CLOCK_ARGS, HeldCommands, WhenRecorded, exit_process, heard_by_every, run,
                                      steady_timer)
from wallbot_sim.nodes.parameters import declare_typed, param_dict, parameter_result
from wallbot_sim.settings.drives import JOINT_BRIDGE, JointBridgeSettings

THROTTLE = 1.0
"""Seconds between repeated log lines of one kind."""
COMMANDER_CHECK = 0.02
"""Wall seconds between looks for a commander hearing joint_states (answer_commands)."""


class JointBridgeNode(Node):
    """wheel_states -> joint_states at rate_hz; joint_commands -> wheel_torque_cmd."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_JOINT_BRIDGE, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS, **kwargs)
        settings: JointBridgeSettings = declare_typed(self, JointBridgeSettings, JOINT_BRIDGE)
        rate_hz, self.max_torque = settings.rate_hz, settings.max_wheel_torque
        self.answer_commands = settings.answer_commands
        self.commander_check = None
        self.instants = ControlInstants(int(rate_hz))
        sensors = load_robot_parameters(settings.robot_file or None).sensors
        self.state_pub = (None if sensors is not None and sensors.encoders is not None else
                          self.create_publisher(JointState, topics.JOINT_STATES.name, qos_profile(topics.JOINT_STATES)))
        states = [self.state_pub] if self.state_pub is not None else []
        self.command_pub = self.create_publisher(Float64MultiArray, topics.WHEEL_TORQUE_CMD.name,
                                                 qos_profile(topics.WHEEL_TORQUE_CMD))
        self.held = HeldCommands(self, self.command_pub, topics.WHEEL_STATES.name) if self.answer_commands else None
        if settings.wait_for_recorder:
            WhenRecorded(self, [self.command_pub, *states], self._subscribe, 'a recorder hears '
                         'wheel_torque_cmd and joint_states: subscribing joint_commands and wheel_states')
        else:
            self._subscribe()
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.get_logger().info((f'joint_states at {rate_hz} Hz of simulation time' if states else
                                'joint_states from the robot\'s encoders (the dynamics)')
                               + f'; joint_commands efforts -> wheel_torque_cmd (side totals within '
                                 f'+-{self.max_torque:g} N m)')

    def _subscribe(self) -> None:
        if self.answer_commands and self.state_pub is not None and not heard_by_every(self, self.state_pub,
                                                       self.resolve_topic_name(topics.JOINT_COMMANDS.name)):
            if self.commander_check is None:  # until the commander hears the states it answers
                self.commander_check = steady_timer(self, COMMANDER_CHECK, self._subscribe)
            return
        if self.commander_check is not None:
            self.commander_check.cancel()
            self.get_logger().info('the commander hears joint_states: subscribing wheel_states and joint_commands')
        # raw: of the 1 kHz wheel states only those republished are decoded
        self.create_subscription(JointState, topics.WHEEL_STATES.name, self._on_wheel_states,
                                 qos_profile(topics.WHEEL_STATES), raw=True)
        self.create_subscription(JointState, topics.JOINT_COMMANDS.name, self._on_joint_commands,
                                 qos_profile(topics.JOINT_COMMANDS), raw=True)

    def _on_wheel_states(self, data: bytes) -> None:
        stamp_ns = codec.leading_stamp_ns(data)
        if stamp_ns is None:
            self.get_logger().error('ignoring a malformed wheel_states message', throttle_duration_sec=THROTTLE)
            return
        self.instants.observe(stamp_ns)
        if self.state_pub is None or not self.instants.due(stamp_ns):
            return
        self.instants.acted(stamp_ns)
        self.state_pub.publish(data)  # the same message: wheel_states has the wheel joints, as joint_states

    def _on_joint_commands(self, data: bytes) -> None:
        try:
            commands = codec.decode_joint_state(data)
            left, right = side_torques(list(commands.name), list(commands.effort), self.max_torque)
        except ValueError as error:
            self.get_logger().warning(f'rejected: {error}', throttle_duration_sec=THROTTLE)
            return
        command = codec.wheel_torque_cmd(left, right)
        if self.held is not None:
            self.held.send(command)
        else:
            self.command_pub.publish(command)

    def _on_set(self, parameters):
        return parameter_result(JOINT_BRIDGE.reasons(param_dict(parameters)))

    def _after_set(self, parameters) -> None:
        changes = param_dict(parameters, ('max_wheel_torque',))
        if changes:
            self.max_torque = float(changes['max_wheel_torque'])


def main(args: list[str] | None = None) -> None:
    exit_process(run(JointBridgeNode, args, events=True))


if __name__ == '__main__':
    main()
