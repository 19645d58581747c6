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
  engine:=numba|python                 how the dynamics computes its steps and the controller its law
                                       (numba: the compiled kernel; python: the model as written)
  viewer:=false                        true: viewer_node publishes markers (and /tf with tf2_msgs installed)
  compose:=true                        with record: dynamics and recorder in one process,
                                       dynamics_recorder_node, the per-step topics recorded in process;
                                       false: two processes (a restarted dynamics resumes from the
                                       snapshot the recorder keeps)
  drive:=cmd_vel|joint_commands        the robot at rest at the origin driven by you, as `wallbot-sim run rest
                                       --drive`: cmd_vel_node or joint_bridge_node instead of the trajectory
                                       (scenario, constraints and controller left at their defaults); default
                                       empty: the scenario's graph
  namespace:=/wallbot                  the namespace of every node: a second robot in the domain runs in its own
  frame_prefix:=                       before the robot's own frames (base_link, the wheel links) in its
                                       odometry, robot_description and tf, as robot_state_publisher's frame_prefix
                                       (e.g. robot2/); the wall is not prefixed
  domain_clock:=true                   the dynamics also publishes the domain's /clock (which RViz and other
                                       tools with use_sim_time follow): false on every robot but one in a domain

Examples:
  ros2 launch wallbot_sim wallbot.launch.py scenario:=figure8 constraints:=belt,nonslip record:=/tmp/fig8
  ros2 launch wallbot_sim wallbot.launch.py drive:=cmd_vel record:=/tmp/teleop
  ros2 launch wallbot_sim wallbot.launch.py namespace:=/robot2 frame_prefix:=robot2/ domain_clock:=false \
      scenario:=figure8
"""
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from wallbot_msgs_py import topics
from wallbot_sim.config import load_scenario
from wallbot_sim.graph_description import DRIVES, EXECUTABLES, describe_driven_graph, describe_graph, launch_name
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
    'engine': ('numba', "how the dynamics computes its steps and the controller its law: numba (the batch's "
                        "compiled kernel; a machine's first start compiles it, about a minute), or python (the "
                        'model as written)'),
    'viewer': ('false', 'true: viewer_node publishes markers (and /tf where tf2_msgs is installed)'),
    'compose': ('true', 'with record: the dynamics and the recorder in one process (dynamics_recorder_node), the '
                        'per-step topics recorded in process; false: two processes (a restarted dynamics resumes '
                        'from the snapshot the recorder keeps)'),
    'drive': ('', f'{" or ".join(DRIVES)}: the robot at rest at the origin driven by you, as wallbot-sim run rest '
                  '--drive (scenario, constraints and controller stay at their defaults); empty: the scenario'),
    'namespace': (topics.NAMESPACE, 'the namespace of every node (a second robot in the domain: its own, '
                                    'e.g. /robot2)'),
    'frame_prefix': ('', "before the robot's own frames (base_link, the wheel links) in its odometry, "
                         "robot_description and tf, as robot_state_publisher's frame_prefix (e.g. robot2/); the wall "
                         'is not prefixed'),
    'domain_clock': ('true', "the dynamics also publishes the domain's /clock, which tools with use_sim_time "
                             'follow (false on every robot but one in a domain)'),
}


def _graph(context, *args, **kwargs):
    def arg(name):
        return LaunchConfiguration(name).perform(context)

    def true(name):
        return arg(name).strip().lower() == 'true'

    common = dict(
        duration=float(arg('duration')), real_time_factor=float(arg('real_time_factor')),
        bag=Path(arg('record')) if arg('record') else None, realtime_priority=int(arg('realtime_priority')),
        robot_file=Path(arg('robot')).resolve() if arg('robot') else None, contact_model=arg('contact'),
        adhesion_force=float(arg('adhesion_force')) if arg('adhesion_force') else None,
        viewer=true('viewer'), engine=arg('engine'), compose=true('compose'), frame_prefix=arg('frame_prefix'),
        domain_clock=true('domain_clock'))
    if arg('drive'):
        scenario_arguments = [name for name in ('scenario', 'constraints', 'controller_mass_scale')
                              if arg(name) != ARGUMENTS[name][0]] + (['controller'] if true('controller') else [])
        if scenario_arguments:
            raise ValueError(f'drive:= runs the driven robot at rest at the origin (no trajectory, no tracking '
                             f'controller): drop {", ".join(scenario_arguments)}')
        specs = describe_driven_graph(arg('drive'), **common)
    else:
        specs = describe_graph(
            load_scenario(arg('scenario')), ConstraintSelection.parse(arg('constraints')),
            controller_mass_scale=float(arg('controller_mass_scale')) if true('controller') else None, **common)
    return [Node(package=PACKAGE, executable=EXECUTABLES[spec.module], **launch_name(spec), namespace=arg('namespace'),
                 output='screen', parameters=[dict(spec.parameters)],
                 remappings=[tuple(remap.split(':=')) for remap in spec.remaps])
            for spec in specs]


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, (default, description) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_graph)])
