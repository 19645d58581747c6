"""Launch the wallbot simulation graph: the same nodes with the same parameters as ``wallbot-sim run``.

Its arguments are ``wallbot_sim.graph_options.OPTIONS`` (``ros2 launch wallbot_sim wallbot.launch.py
--show-args`` lists them with their defaults and help): the options of ``wallbot-sim run``, those that set a
node's parameter checked by that node's own rule (a refused value stops the launch with one line naming it).

Examples:
  ros2 launch wallbot_sim wallbot.launch.py scenario:=figure8 constraints:=belt,nonslip record:=/tmp/fig8
  ros2 launch wallbot_sim wallbot.launch.py drive:=cmd_vel record:=/tmp/teleop
  ros2 launch wallbot_sim wallbot.launch.py namespace:=/robot2 frame_prefix:=robot2/ domain_clock:=false \
      scenario:=figure8
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from wallbot_sim.graph_description import EXECUTABLES, launch_name
from wallbot_sim.graph_options import OPTIONS, launched_graph
from wallbot_sim.settings.table import text_of

PACKAGE = 'wallbot_sim'
ARGUMENTS = {option.name: (text_of(option.setting.default), option.setting.description()) for option in OPTIONS}
"""Every argument with its default and description (``graph_options.OPTIONS``: those setting a node's parameter
are that parameter's setting, so a value the launch file accepts is one the node accepts)."""


def _graph(context, *args, **kwargs):
    specs = launched_graph({name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS})
    return [Node(package=PACKAGE, executable=EXECUTABLES[spec.module], **launch_name(spec),
                 namespace=LaunchConfiguration('namespace').perform(context), output='screen',
                 parameters=[dict(spec.parameters)], remappings=[tuple(remap.split(':=')) for remap in spec.remaps])
            for spec in specs]


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, (default, description) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_graph)])
