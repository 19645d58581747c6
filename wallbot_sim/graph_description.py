"""The node graph of a simulated run, described once: which nodes, in which order, with which parameters.

``wallbot-sim run`` starts these as child processes (``graph.Graph``); ``launch/wallbot.launch.py``
turns the same list into launch_ros ``Node`` actions, so ``ros2 launch`` and ``run`` start the same
graph for the same scenario. ROS-free.
"""

from __future__ import annotations

from pathlib import Path

from wallbot_msgs_py import topics
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.graph import NodeSpec
from wallbot_sim.messages import switches_from_selection
from wallbot_sim.model import Circle, ConstraintSelection, FigureEight, Scenario

RECORDER = 'recorder'
CONTROLLER = 'controller'
EXECUTABLES = {
    'wallbot_sim.nodes.recorder': 'recorder_node',
    'wallbot_sim.nodes.constraint_config': 'constraint_config_node',
    'wallbot_sim.nodes.trajectory': 'trajectory_node',
    'wallbot_sim.nodes.controller': 'tracking_controller_node',
    'wallbot_sim.nodes.dynamics': 'dynamics_node',
}
"""Each node module's console script (setup.py entry points): what ``ros2 run`` and launch start."""
CONTROL_STEPS = 5
"""Dynamics steps per control period: the controller's default 200 Hz at the dynamics' 1 kHz. The
dynamics runs in lockstep with it (``lockstep_every``): a closed-loop run does not depend on CPU load."""


class GraphDescriptionError(ValueError):
    """A graph that the nodes cannot run (e.g. a reference shape the trajectory node does not plan)."""


def describe_graph(scenario: Scenario, selection: ConstraintSelection, *, duration: float = 0.0,
                   real_time_factor: float = 1.0, bag: Path | None = None,
                   controller_mass_scale: float | None = None, realtime_priority: int = 0,
                   robot_file: Path | None = None, contact_model: str = 'ideal',
                   adhesion_force: float | None = None) -> list[NodeSpec]:
    """The nodes of a run of ``scenario``, in start order (the recorder first, so it misses nothing).

    ``duration`` 0 runs until stopped. Without ``bag`` there is no recorder and the dynamics does
    not wait for one. With ``controller_mass_scale`` (a closed-loop run) the selection is the driven
    set (no trajectory task); the controller starts before the dynamics, which waits for it
    (``wait_for_command``) so the loop is closed from t = 0. ``robot_file`` (the dynamics' model,
    constraint_config's gains and robot_description) None: the installed robot file;
    ``adhesion_force`` None: the robot file's.
    """
    reference = scenario.reference
    if isinstance(reference, Circle):
        shape = {'shape': 'circle', 'radius': reference.radius}
    elif isinstance(reference, FigureEight):
        shape = {'shape': 'figure8', 'amplitude': reference.amplitude}
    else:
        raise GraphDescriptionError(f'scenario {scenario.name!r}: the trajectory node plays circles and figure-8s only')
    closed_loop = controller_mass_scale is not None
    if closed_loop:
        selection = DRIVEN
    pose = scenario.initial
    switches = switches_from_selection(selection)
    specs = []
    if bag is not None:
        recorder: dict[str, object] = {'output': str(bag)}
        if closed_loop:
            recorder['topics'] = [t.name for t in (*topics.RECORDED, topics.WHEEL_TORQUE_CMD)]
        specs.append(NodeSpec(RECORDER, 'wallbot_sim.nodes.recorder', recorder))
    robot = {'robot_file': str(robot_file)} if robot_file is not None else {}
    specs += [
        NodeSpec('constraint_config', 'wallbot_sim.nodes.constraint_config', {**switches, **robot}),
        NodeSpec('trajectory', 'wallbot_sim.nodes.trajectory', {
            **shape, 'period': reference.period, 'center_x': reference.center[0], 'center_y': reference.center[1],
            'wait_for_recorder': bag is not None}),
    ]
    if closed_loop:
        specs.append(NodeSpec(CONTROLLER, 'wallbot_sim.nodes.controller', {
            'mass_scale': float(controller_mass_scale), 'wait_for_recorder': bag is not None}))
    specs.append(NodeSpec('dynamics', 'wallbot_sim.nodes.dynamics', {
        'initial_x': pose.x, 'initial_y': pose.y, 'initial_theta': pose.theta,
        'initial_at_rest': pose.at_rest, 'real_time_factor': float(real_time_factor), 'stop_at': float(duration),
        'wait_for_recorder': bag is not None, 'realtime_priority': int(realtime_priority),
        **robot,
        'contact_model': contact_model,
        **({'adhesion_force': float(adhesion_force)} if adhesion_force is not None else {}),
        **({'wait_for_command': True, 'lockstep_every': CONTROL_STEPS} if closed_loop else {})}))
    return specs
