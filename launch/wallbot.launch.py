"""Launch the wallbot simulation graph: the same nodes with the same parameters as ``wallbot-sim run``.

Arguments (defaults as ``wallbot-sim run``):
  scenario:=circle|figure8|PATH.yaml   the scenario: reference path and initial state (default circle)
  constraints:=belt,non_lateral,nonslip  comma list of belt, non_lateral, nonslip, or none
  duration:=0                          simulated seconds before the dynamics stops; 0 = until stopped
  real_time_factor:=1.0                simulation speed relative to wall clock; 0 = as fast as possible
  realtime_priority:=0                 SCHED_FIFO priority of the dynamics loop thread (0 = normal)
  record:=                             bag directory to record into (empty: no recorder)
  controller:=false                    true: closed loop under tracking_controller_node (driven robot)
  controller_mass_scale:=1.0           the controller's robot mass relative to the simulator's

Example:
  ros2 launch wallbot_sim wallbot.launch.py scenario:=figure8 constraints:=belt,nonslip record:=/tmp/fig8
"""
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from wallbot_msgs_py import topics
from wallbot_sim.config import load_scenario
from wallbot_sim.graph_description import EXECUTABLES, describe_graph
from wallbot_sim.model import ConstraintSelection

PACKAGE = 'wallbot_sim'
ARGUMENTS = {
    'scenario': ('circle', 'circle, figure8, or a scenario YAML path'),
    'constraints': ('belt,non_lateral,nonslip', 'comma list of belt, non_lateral, nonslip, or none'),
    'duration': ('0', 'simulated seconds before the dynamics stops (0 = until stopped)'),
    'real_time_factor': ('1.0', 'simulation speed relative to wall clock (0 = as fast as possible)'),
    'realtime_priority': ('0', 'SCHED_FIFO priority of the dynamics loop thread (0 = normal scheduling)'),
    'record': ('', 'bag directory to record into (empty: no recorder)'),
    'controller': ('false', 'true: closed loop under tracking_controller_node'),
    'controller_mass_scale': ('1.0', "the controller's robot mass relative to the simulator's"),
}


def _graph(context, *args, **kwargs):
    def arg(name):
        return LaunchConfiguration(name).perform(context)

    closed_loop = arg('controller').strip().lower() == 'true'
    specs = describe_graph(
        load_scenario(arg('scenario')), ConstraintSelection.parse(arg('constraints')),
        duration=float(arg('duration')), real_time_factor=float(arg('real_time_factor')),
        bag=Path(arg('record')) if arg('record') else None,
        controller_mass_scale=float(arg('controller_mass_scale')) if closed_loop else None,
        realtime_priority=int(arg('realtime_priority')))
    return [Node(package=PACKAGE, executable=EXECUTABLES[spec.module], name=spec.name, namespace=topics.NAMESPACE,
                 output='screen', parameters=[dict(spec.parameters)])
            for spec in specs]


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, (default, description) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_graph)])
