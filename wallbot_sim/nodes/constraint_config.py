"""constraint_config_node: the constraint switches as parameters, published on ``constraints``, and
the robot model on ``robot_description``.

``ros2 param set /wallbot/constraint_config nonslip true`` switches the dynamics at its next
step boundary (the dynamics node projects the velocities onto newly added constraints). The
robot file (``robot_file``, the same the dynamics simulates) gives the default Baumgarte gains
and the URDF, published once (transient-local) as robot_state_publisher does. The URDF's links
are named by the frame parameters ``odom_frame_id``, ``base_frame_id`` and ``frame_prefix``, set as
on the dynamics, so the model's links are the odometry's and tf's frames.

With ``wait_for_recorder`` (set by ``wallbot-sim run`` when it records) the first set goes out only
once a recorder is matched on ``constraints``: the dynamics starts with it, and a short run can
otherwise end before a loaded machine's discovery has matched the recorder to this node, leaving
the bag without the set it ran under.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.node import Node
from std_msgs.msg import String

from wallbot_msgs_py import codec, topics
from wallbot_msgs_py.constraint_modules import CONSTRAINT_SWITCHES
from wallbot_msgs_py.qos import qos_profile
from wallbot_sim import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import BaumgarteGains
from wallbot_sim.nodes.common import ROBOT_CLOCK_ARGS, WhenRecorded, exit_process, run
from wallbot_sim.nodes.parameters import declare_setting, declare_settings, param_dict, parameter_result
from wallbot_sim.settings.config import CONSTRAINT_CONFIG, ROBOT_GAINS
from wallbot_sim.urdf import RobotFrames, robot_urdf


class ConstraintConfigNode(Node):
    """Owns the switches; publishes the active set (transient-local) at start and on every change."""

    def __init__(self, **kwargs) -> None:
        super().__init__(topics.NODE_CONSTRAINT_CONFIG, namespace=topics.NAMESPACE, cli_args=ROBOT_CLOCK_ARGS,
                         **kwargs)
        robot_file = declare_setting(self, CONSTRAINT_CONFIG['robot_file'], '')[0]  # first: it gives defaults
        params = load_robot_parameters(robot_file or None)
        values = declare_settings(self, CONSTRAINT_CONFIG, {'baumgarte_alpha': params.baumgarte_alpha,
                                                            'baumgarte_beta': params.baumgarte_beta})
        self.switches = {name: values[name] for name in CONSTRAINT_SWITCHES}
        frames = RobotFrames(values['odom_frame_id'], values['base_frame_id'], values['frame_prefix'])
        urdf = robot_urdf(params, frames)  # before anything is published: unusable frames stop the node here
        self.gains = {name: values[name] for name in ROBOT_GAINS}
        self.publisher = self.create_publisher(DiagnosticStatus, topics.CONSTRAINTS.name,
                                               qos_profile(topics.CONSTRAINTS))
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._after_set)
        self.held = values['wait_for_recorder']
        if self.held:
            WhenRecorded(self, [self.publisher], self._release, 'a recorder hears constraints: publishing the set')
        else:
            self.publish()
        self.description_publisher = self.create_publisher(String, topics.ROBOT_DESCRIPTION.name,
                                                           qos_profile(topics.ROBOT_DESCRIPTION))
        self.description_publisher.publish(codec.robot_description(urdf))
        self.get_logger().info(f'robot_description: {len(urdf)} characters of URDF from '
                               f'{robot_file or "the installed robot file"}, links {frames.odom} -> '
                               f'{frames.base_link} -> {frames.wheel_link(topics.WHEEL_JOINTS[0])}, ...')

    def _on_set(self, parameters):
        return parameter_result(CONSTRAINT_CONFIG.reasons(param_dict(parameters)))

    def _after_set(self, parameters) -> None:
        changed = False
        for name, value in param_dict(parameters).items():
            if name in self.switches:
                self.switches[name], changed = bool(value), True
            elif name in self.gains:
                self.gains[name], changed = float(value), True
        if changed and not self.held:
            self.publish()

    def _release(self) -> None:
        self.held = False
        self.publish()

    def publish(self) -> None:
        """Publish the current set and log it."""
        self.publisher.publish(messages.constraints_message(
            self.switches, BaumgarteGains(self.gains['baumgarte_alpha'], self.gains['baumgarte_beta'])))
        label = messages.selection_from_switches(self.switches).label()
        self.get_logger().info(f'constraints: {label} (alpha {self.gains["baumgarte_alpha"]:g}, '
                               f'beta {self.gains["baumgarte_beta"]:g})')


def main(args: list[str] | None = None) -> None:
    exit_process(run(ConstraintConfigNode, args, events=True))


if __name__ == '__main__':
    main()
