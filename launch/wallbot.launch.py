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
  robot:=PATH.yaml                     robot parameter file (default: the installed config/robot.yaml)
  contact:=ideal|coulomb               wheel-wall contact model (coulomb with controller:=true)
  adhesion_force:=N                    adhesion force in N (default: the robot file's)
  engine:=python|numba                 how the dynamics computes the ideal-contact steps (numba: compiled kernel)
  viewer:=false                        true: viewer_node publishes markers (and /tf with tf2_msgs installed)
  compose:=false                       true (with record): dynamics and recorder in one process,
                                       dynamics_recorder_node; the per-step topics are recorded in process

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
from wallbot_sim.graph_description import EXECUTABLES, describe_graph, launch_name
from wallbot_sim.model import SELECTION_SYNTAX, STRUCTURAL, ConstraintSelection

PACKAGE = 'wallbot_sim'
ARGUMENTS = {
    'scenario': ('circle', 'circle, figure8, or a scenario YAML path'),
    'constraints': (','.join(STRUCTURAL), SELECTION_SYNTAX),
    'duration': ('0', 'simulated seconds before the dynamics stops (0 = until stopped)'),
    'real_time_factor': ('1.0', 'simulation speed relative to wall clock (0 = as fast as possible)'),
    'realtime_priority': ('0', 'SCHED_FIFO priority of the dynamics loop thread (0 = normal scheduling)'),
    'record': ('', 'bag directory to record into (empty: no recorder)'),
    'controller': ('false', 'true: closed loop under tracking_controller_node'),
    'controller_mass_scale': ('1.0', "the controller's robot mass relative to the simulator's"),
    'robot': ('', 'robot parameter YAML (empty: the installed config/robot.yaml)'),
    'contact': ('ideal', 'wheel-wall contact model: ideal or coulomb (coulomb with controller:=true)'),
    'adhesion_force': ('', "adhesion force in N (empty: the robot file's)"),
    'engine': ('python', "how the dynamics computes the ideal-contact steps: python, or numba (the batch's compiled "
                         'kernel; it compiles on first use on a machine)'),
    'viewer': ('false', 'true: viewer_node publishes markers (and /tf where tf2_msgs is installed)'),
    'compose': ('false', 'true (with record): the dynamics and the recorder in one process (dynamics_recorder_node), '
                         'the per-step topics recorded in process'),
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
        realtime_priority=int(arg('realtime_priority')),
        robot_file=Path(arg('robot')).resolve() if arg('robot') else None, contact_model=arg('contact'),
        adhesion_force=float(arg('adhesion_force')) if arg('adhesion_force') else None,
        viewer=arg('viewer').strip().lower() == 'true', engine=arg('engine'),
        compose=arg('compose').strip().lower() == 'true')
    return [Node(package=PACKAGE, executable=EXECUTABLES[spec.module], **launch_name(spec), namespace=topics.NAMESPACE,
                 output='screen', parameters=[dict(spec.parameters)])
            for spec in specs]


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, (default, description) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_graph)])
