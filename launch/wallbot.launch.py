"""Launch the wallbot simulation nodes in namespace /wallbot.

Arguments:
  scenario:=circle|figure8           trajectory shape (default circle)
  constraints:=belt,non_lateral,...  comma list of belt, non_lateral, nonslip (default none)
  real_time_factor:=1.0              simulation speed relative to wall clock
  realtime_priority:=0               SCHED_FIFO priority of the dynamics loop thread (0 = normal)

Example:
  ros2 launch wallbot_sim wallbot.launch.py scenario:=figure8 constraints:=belt,nonslip
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

PACKAGE = 'wallbot_sim'
NAMESPACE = 'wallbot'
SCENARIOS = ('circle', 'figure8')
CONSTRAINTS = ('belt', 'non_lateral', 'nonslip')


def parse_constraints(text):
    """Parse a comma list of constraint names into {name: bool} for every known constraint."""
    names = {c.strip() for c in text.split(',') if c.strip()}
    unknown = names - set(CONSTRAINTS)
    if unknown:
        raise ValueError(f'unknown constraints {sorted(unknown)}; choose from {CONSTRAINTS}')
    return {c: c in names for c in CONSTRAINTS}


def _constraint_node(context, *args, **kwargs):
    flags = parse_constraints(LaunchConfiguration('constraints').perform(context))
    return [Node(
        package=PACKAGE,
        executable='constraint_config_node',
        name='constraint_config',
        namespace=NAMESPACE,
        output='screen',
        parameters=[flags],
    )]


def generate_launch_description():
    scenario = LaunchConfiguration('scenario')
    real_time_factor = LaunchConfiguration('real_time_factor')
    realtime_priority = LaunchConfiguration('realtime_priority')
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='circle', choices=list(SCENARIOS),
                              description='Trajectory scenario'),
        DeclareLaunchArgument('constraints', default_value='',
                              description='Comma list of: ' + ', '.join(CONSTRAINTS)),
        DeclareLaunchArgument('real_time_factor', default_value='1.0',
                              description='Simulation speed relative to wall clock'),
        DeclareLaunchArgument('realtime_priority', default_value='0',
                              description='SCHED_FIFO priority of the dynamics loop thread (0 = normal scheduling)'),
        Node(
            package=PACKAGE,
            executable='dynamics_node',
            name='dynamics',
            namespace=NAMESPACE,
            output='screen',
            parameters=[{'real_time_factor': ParameterValue(real_time_factor, value_type=float),
                         'realtime_priority': ParameterValue(realtime_priority, value_type=int)}],
        ),
        Node(
            package=PACKAGE,
            executable='trajectory_node',
            name='trajectory',
            namespace=NAMESPACE,
            output='screen',
            parameters=[{'shape': ParameterValue(scenario, value_type=str)}],
        ),
        OpaqueFunction(function=_constraint_node),
    ])
