"""The settings of the nodes that describe or record the robot: constraint_config_node (``nodes.constraint_config``),
viewer_node (``nodes.viewer``) and recorder_node (``nodes.recorder``)."""

from __future__ import annotations

from dataclasses import dataclass

from wallbot_msgs_py import topics
from wallbot_msgs_py.constraint_modules import CONSTRAINT_MODULES
from wallbot_sim.live_view import DEFAULT_HOST
from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.settings.common import FRAME_PREFIX_HELP, recorder_wait, sim_time
from wallbot_sim.settings.table import Setting, SettingsTable, setting, table_of

GAIN_RANGE = NumberRange(1e-6, 1e4)
"""What each Baumgarte gain accepts (1/s): the model's "> 0" written as a range a descriptor can
carry (1e-6 1/s is no stabilization in any run's time)."""
ROBOT = RobotParameters()
ROBOT_GAINS = ('baumgarte_alpha', 'baumgarte_beta')
"""constraint_config_node's settings whose default is the robot file's (``robot_file``)."""


@dataclass(frozen=True)
class ConstraintConfigSettings:
    """constraint_config_node's parameters besides the switches (``SWITCHES``)."""

    robot_file: str = setting('', 'robot parameter YAML ("" = the installed config/robot.yaml): the default gains '
                                  'and the robot_description', read_only=True)
    odom_frame_id: str = setting(topics.WALL_FRAME, "the URDF's root link: the odometry's frame (the wall)",
                                 read_only=True)
    base_frame_id: str = setting(topics.BASE_FRAME, "the URDF's chassis link, after frame_prefix: the odometry's "
                                                    'child frame', read_only=True)
    frame_prefix: str = setting('', FRAME_PREFIX_HELP, read_only=True)
    baumgarte_alpha: float = setting(ROBOT.baumgarte_alpha, "Baumgarte gain alpha (1/s; default: the robot file's)",
                                     GAIN_RANGE)
    baumgarte_beta: float = setting(ROBOT.baumgarte_beta, "Baumgarte gain beta (1/s; default: the robot file's)",
                                    GAIN_RANGE)
    wait_for_recorder: bool = recorder_wait('publish the first constraint set')
    use_sim_time: bool = sim_time()


SWITCHES = tuple(Setting(switch.parameter, switch.default, switch.description)
                 for switch in CONSTRAINT_MODULES.values())
"""The constraint switches, one bool each (``wallbot_msgs_py.constraint_modules``' table)."""
CONSTRAINT_CONFIG = SettingsTable((*SWITCHES, *table_of(ConstraintConfigSettings)))


@dataclass(frozen=True)
class ViewerSettings:
    """viewer_node's parameters."""

    rate_hz: float = setting(30.0, 'frames per wall second', NumberRange(1.0, 100.0))
    trail_points: int = setting(3000, 'points kept of the path travelled (one every 2 mm or more)',
                                NumberRange(2, 1_000_000))
    robot_file: str = setting('', 'robot parameter YAML ("" = the installed config/robot.yaml): the sizes drawn',
                              read_only=True)
    world_file: str = setting('', 'world YAML ("" = a vertical, uniform wall): its friction patches and seams drawn',
                              read_only=True)
    frame_prefix: str = setting('', FRAME_PREFIX_HELP, read_only=True)
    foxglove_port: int = setting(0, 'serve the topics over the Foxglove WebSocket protocol on this port (0 = off)',
                                 NumberRange(0, 65535), read_only=True)
    foxglove_host: str = setting(DEFAULT_HOST, 'address the Foxglove server binds to', read_only=True)
    use_sim_time: bool = sim_time()


VIEWER = table_of(ViewerSettings)


@dataclass(frozen=True)
class RecorderSettings:
    """recorder_node's parameters (and, composed with the dynamics, dynamics_recorder_node's beside the dynamics')."""

    output: str = setting('', 'bag directory to create (it must not exist, or be empty)', read_only=True)
    topics: tuple = setting(tuple(topic.name for topic in topics.RECORDED),
                            'topics to record (relative names resolve in the namespace)', read_only=True)


RECORDER = table_of(RecorderSettings)
