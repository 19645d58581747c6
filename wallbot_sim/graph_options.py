"""The options of a run of the graph, written once: the launch file's arguments (``launch/wallbot.launch.py``)
and ``wallbot-sim run``'s options come from :data:`OPTIONS`, and an option that sets a node's parameter is that
parameter's setting (``wallbot_sim.settings``: type, default, range or choices, help), renamed. So a value the
command line or ``ros2 launch`` accepts is one the node accepts. ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from wallbot_msgs_py import topics
from wallbot_sim.config import load_scenario
from wallbot_sim.graph import NodeSpec
from wallbot_sim.graph_description import DRIVES, describe_driven_graph, describe_graph
from wallbot_sim.model import SELECTION_SYNTAX, STRUCTURAL, ConstraintSelection
from wallbot_sim.settings.config import VIEWER
from wallbot_sim.settings.controller import CONTROLLER
from wallbot_sim.settings.dynamics import DYNAMICS
from wallbot_sim.settings.table import Setting, SettingError, SettingsTable, Value


@dataclass(frozen=True)
class GraphOption:
    """A launch argument (``setting``'s name), ``wallbot-sim run``'s ``flag`` if it has one, and the node's
    ``parameter`` it sets (``node``; None: the graph's own option), whose setting ``setting`` is, renamed."""

    setting: Setting
    flag: str | None = None
    node: str | None = None
    parameter: str | None = None

    @property
    def name(self) -> str:
        return self.setting.name


def node_option(node: str, table: SettingsTable, parameter: str, flag: str | None, name: str | None = None,
                help: str | None = None) -> GraphOption:
    """The option ``name`` (default: the parameter's) setting ``node``'s ``parameter`` (of its settings ``table``),
    with other ``help`` if given."""
    return GraphOption(table[parameter].renamed(name or parameter, help), flag, node, parameter)


DRIVE_HELP = (f'{" or ".join(DRIVES)}: the robot at rest at the origin driven by you (cmd_vel_node, a wheel-speed PI '
              'loop for teleop_twist_keyboard; or joint_bridge_node, the ros2_control topics joint_states and '
              'joint_commands), its command topics recorded; scenario, constraints and controller stay at their '
              'defaults; empty: the scenario')
ALL_STRUCTURAL = ','.join(STRUCTURAL)
"""The constraint set a run and a simulation start with unless told otherwise: every structural constraint."""
OPTIONS = (
    GraphOption(Setting('scenario', 'circle', 'circle, figure8, or a scenario YAML path')),
    GraphOption(Setting('constraints', ALL_STRUCTURAL, SELECTION_SYNTAX), '--constraints'),
    node_option('dynamics', DYNAMICS, 'stop_at', '--duration', 'duration',
                'simulated seconds before the dynamics stops; 0 = until stopped'),
    node_option('dynamics', DYNAMICS, 'real_time_factor', '--real-time-factor'),
    node_option('dynamics', DYNAMICS, 'realtime_priority', '--realtime-priority',
                help="SCHED_FIFO priority of the dynamics' paced loop thread (Linux; needs an rtprio limit, else a "
                     'warning and normal scheduling); 0 = normal scheduling'),
    GraphOption(Setting('record', '', 'bag directory to record into (empty: no recorder)')),
    GraphOption(Setting('controller', False, f'closed loop: the driven robot ({", ".join(STRUCTURAL)}, no '
                                             'trajectory task) under tracking_controller_node; wheel_torque_cmd is '
                                             'recorded'), '--controller'),
    node_option('controller', CONTROLLER, 'mass_scale', '--controller-mass-scale', 'controller_mass_scale',
                "with the controller: its robot's mass relative to the simulator's (model mismatch)"),
    node_option('dynamics', DYNAMICS, 'robot_file', '--robot', 'robot',
                'robot parameter YAML (empty: the installed config/robot.yaml)'),
    node_option('dynamics', DYNAMICS, 'world_file', '--world', 'world',
                'world YAML: inclination, friction patches, seams (python engine only; empty: a vertical, uniform '
                'wall)'),
    node_option('dynamics', DYNAMICS, 'contact_model', '--contact', 'contact',
                'wheel-wall contact: ideal, or coulomb (friction-limited; with the controller or a drive)'),
    node_option('dynamics', DYNAMICS, 'adhesion_force', '--adhesion-force',
                help='adhesion force pressing the robot to the wall (N)'),
    node_option('dynamics', DYNAMICS, 'engine', '--engine',
                help="how the dynamics computes its steps and the controller its law: numba (the batch's compiled "
                     "kernel, the same states as the model to 1e-9; a machine's first run compiles it, about a "
                     'minute), or python (the model as written, the reference)'),
    GraphOption(Setting('viewer', False, 'viewer_node: markers (and /tf where tf2_msgs is installed) for RViz or '
                                         'Foxglove, at 30 frames per second'), '--markers'),
    node_option('viewer', VIEWER, 'foxglove_port', '--foxglove',
                help='serve the live topics over the Foxglove WebSocket protocol on this port (needs the '
                     'foxglove-sdk package; implies the viewer); 0 = off'),
    node_option('viewer', VIEWER, 'foxglove_host', '--foxglove-host',
                help="the Foxglove server's address (127.0.0.1: this machine only)"),
    GraphOption(Setting('compose', True, 'with a recording: the dynamics and the recorder in one process '
                                         '(dynamics_recorder_node), the per-step topics recorded in process; false: '
                                         'two processes, all over DDS, a restarted dynamics resuming from the '
                                         'snapshot the recorder keeps'), '--compose'),
    GraphOption(Setting('drive', '', DRIVE_HELP), '--drive'),
    GraphOption(Setting('namespace', topics.NAMESPACE, 'the namespace of every node (a second robot in the domain: '
                                                       'its own, e.g. /robot2)')),
    node_option('dynamics', DYNAMICS, 'frame_prefix', None,
                help="before the robot's own frames (base_link, the wheel links) in its odometry, robot_description "
                     "and tf, as robot_state_publisher's frame_prefix (e.g. robot2/); the wall is not prefixed"),
    node_option('dynamics', DYNAMICS, 'domain_clock', None),
)
"""Every launch argument, in order."""
BY_NAME = {option.name: option for option in OPTIONS}
SCENARIO_ARGUMENTS = ('scenario', 'constraints', 'controller', 'controller_mass_scale')
"""What a driven graph (drive:=) leaves at its default."""


def option(name: str) -> GraphOption:
    return BY_NAME[name]


def parsed(texts: Mapping[str, str]) -> dict[str, Value]:
    """The launch arguments' texts as values (each by its setting); SettingError naming the first one refused."""
    values = {}
    for name, text in texts.items():
        try:
            values[name] = BY_NAME[name].setting.parse(text)
        except SettingError as error:
            raise SettingError(f'{name}:={text}: {error}') from None
    return values


def launched_graph(texts: Mapping[str, str]) -> list[NodeSpec]:
    """The nodes ``ros2 launch wallbot_sim wallbot.launch.py`` starts for its arguments' texts (by name, every one
    of :data:`OPTIONS`): the graph ``wallbot-sim run`` starts for the same options."""
    values = parsed(texts)
    common = dict(duration=values['duration'], real_time_factor=values['real_time_factor'],
                  bag=Path(values['record']) if values['record'] else None,
                  realtime_priority=values['realtime_priority'],
                  robot_file=Path(values['robot']).resolve() if values['robot'] else None,
                  contact_model=values['contact'], adhesion_force=values['adhesion_force'], viewer=values['viewer'],
                  foxglove_port=values['foxglove_port'], foxglove_host=values['foxglove_host'],
                  engine=values['engine'], compose=values['compose'], frame_prefix=values['frame_prefix'],
                  domain_clock=values['domain_clock'],
                  world_file=Path(values['world']).resolve() if values['world'] else None)
    if values['drive']:
        changed = [name for name in SCENARIO_ARGUMENTS if values[name] != BY_NAME[name].setting.default]
        if changed:
            raise ValueError(f'drive:= runs the driven robot at rest at the origin (no trajectory, no tracking '
                             f'controller): drop {", ".join(changed)}')
        return describe_driven_graph(values['drive'], **common)
    return describe_graph(load_scenario(values['scenario']), ConstraintSelection.parse(values['constraints']),
                          controller_mass_scale=values['controller_mass_scale'] if values['controller'] else None,
                          **common)
