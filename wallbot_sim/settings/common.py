"""What several nodes' settings share."""

from __future__ import annotations

from wallbot_sim.model.numbers import NumberRange
from wallbot_sim.settings.table import setting

COORDINATE = NumberRange(-1e4, 1e4)
"""A position on the wall (m) as a parameter: no wall is 10 km wide."""
WHEEL_TORQUE_LIMIT = NumberRange(1e-3, 1e4)
"""The largest |torque| per side a wheel_torque_cmd may carry (N m): the dynamics refuses larger
commands, the controllers clamp to it."""
FRAME_PREFIX_HELP = ("comes before the robot's own frames, base_frame_id and the wheel links (e.g. robot2/ for a "
                     'second robot; the wall, odom_frame_id, is not prefixed), as '
                     "robot_state_publisher's frame_prefix; set it alike on the dynamics, constraint_config and the "
                     'viewer')
"""The ``frame_prefix`` setting of every node that names the robot's frames."""
ROBOT_FILE_HELP = 'robot parameter YAML; empty = installed config/robot.yaml'
WORLD_FILE_HELP = ('world YAML: inclination, friction patches, seams (python engine only); empty = a vertical, '
                   'uniform wall')


def sim_time() -> bool:
    """The ``use_sim_time`` field of a node that may follow its robot's clock (rclpy's parameter; ``wallbot-sim
    run`` sets it)."""
    return setting(False, "follow the robot's clock (simulation time) instead of the wall clock")


def recorder_wait(what: str) -> bool:
    """The read-only ``wait_for_recorder`` field of a node that holds back ``what`` until a recorder hears it."""
    return setting(False, f'{what} only once a recorder (record_progress) is matched on its topics, so a recording '
                          'holds everything from the start', read_only=True)
