"""The node graph of a simulated run, described once: which nodes, in which order, with which parameters.

``wallbot-sim run`` starts these as child processes (``graph.Graph``); ``launch/wallbot.launch.py``
turns the same list into launch_ros ``Node`` actions (``graph_options``), so ``ros2 launch`` and ``run``
start the same graph for the same scenario. Every node's parameters are checked by its settings table
(``wallbot_sim.settings``): a description names no parameter a node lacks, nor a value it refuses.
ROS-free.
"""

from __future__ import annotations

from pathlib import Path

from wallbot_msgs_py import topics
from wallbot_sim.control.sampling import CONTROL_RATE_HZ, steps_per_period
from wallbot_sim.control.tracking import DRIVEN
from wallbot_sim.control.wheel_speed import SPEED_LOOP_RATE_HZ
from wallbot_sim.graph import NodeSpec
from wallbot_sim.live_view import DEFAULT_HOST
from wallbot_sim.messages import switches_from_selection
from wallbot_sim.model import Circle, ConstraintSelection, FigureEight, Scenario
from wallbot_sim.model.scenario import InitialPose
from wallbot_sim.settings.config import CONSTRAINT_CONFIG
from wallbot_sim.settings.config import RECORDER as RECORDER_SETTINGS
from wallbot_sim.settings.config import VIEWER as VIEWER_SETTINGS
from wallbot_sim.settings.controller import CONTROLLER as CONTROLLER_SETTINGS
from wallbot_sim.settings.drives import CMD_VEL, JOINT_BRIDGE
from wallbot_sim.settings.dynamics import DYNAMICS
from wallbot_sim.settings.table import SettingError, SettingsTable
from wallbot_sim.settings.trajectory import TRAJECTORY

RECORDER = 'recorder'
DYNAMICS_RECORDER = 'dynamics_recorder'
"""The composed process (``compose``): the dynamics and the recorder, the per-step topics recorded in process."""
COMPOSED_MODULE = 'wallbot_sim.nodes.dynamics_recorder'
CONTROLLER = 'controller'
VIEWER = 'viewer'
EXECUTABLES = {
    'wallbot_sim.nodes.recorder': 'recorder_node',
    'wallbot_sim.nodes.constraint_config': 'constraint_config_node',
    'wallbot_sim.nodes.trajectory': 'trajectory_node',
    'wallbot_sim.nodes.controller': 'tracking_controller_node',
    'wallbot_sim.nodes.dynamics': 'dynamics_node',
    COMPOSED_MODULE: 'dynamics_recorder_node',
    'wallbot_sim.nodes.cmd_vel': 'cmd_vel_node',
    'wallbot_sim.nodes.joint_bridge': 'joint_bridge_node',
    'wallbot_sim.nodes.viewer': 'viewer_node',
}
"""Each node module's console script (setup.py entry points): what ``ros2 run`` and launch start."""
CONTROL_STEPS = steps_per_period(CONTROL_RATE_HZ)
"""Dynamics steps per control period: the controller's default rate at the dynamics' 1 kHz. The
dynamics runs in lockstep with it (``lockstep_every``): a closed-loop run does not depend on CPU load."""
CMD_VEL_STEPS = steps_per_period(SPEED_LOOP_RATE_HZ)
"""Dynamics steps per period of cmd_vel_node's wheel-speed loop (its default 50 Hz), in lockstep likewise."""
CONTROLLER_REMAPS = (topics.CONTROL_ODOM_REMAP,)
"""A commander (the tracking controller, cmd_vel_node) reads control_odom, published at its lockstep
instants (the dynamics' ``control_odom_every``), instead of every step's odom: one wake per control period."""
DRIVES = {'cmd_vel': (topics.NODE_CMD_VEL, 'wallbot_sim.nodes.cmd_vel', CMD_VEL),
          'joint_commands': (topics.NODE_JOINT_BRIDGE, 'wallbot_sim.nodes.joint_bridge', JOINT_BRIDGE)}
"""``run rest --drive NAME``: the node that turns the user's commands into wheel_torque_cmd (name, module, settings)."""
ENGINE = DYNAMICS['engine'].default
"""The engine of a run: the dynamics' (and the controller's) default."""
DRIVE_TOPICS = {'cmd_vel': (topics.WHEEL_TORQUE_CMD, topics.CMD_VEL),
                'joint_commands': (topics.WHEEL_TORQUE_CMD, topics.JOINT_COMMANDS)}
"""What a driven run records besides topics.RECORDED (wheel_torque_cmd: the torques applied)."""
TESTED_DRIVES = {'wheel_torque_cmd': (topics.WHEEL_TORQUE_CMD,), **DRIVE_TOPICS}
"""What a controller under test may publish (``describe_tested_graph``), and what its run records besides
topics.RECORDED."""
REST = InitialPose(0.0, 0.0, 0.0, True)
"""Where a driven run starts: at rest at the origin, facing +X."""
SIM_TIME = {'use_sim_time': True}
"""The nodes that are not the clock's owner (the dynamics) nor the recorder (its log time is the
receive time) follow their robot's clock, so their logs and stamps are simulation time."""


class GraphDescriptionError(ValueError):
    """A graph that the nodes cannot run (e.g. a reference shape the trajectory node does not plan)."""


def node(name: str, module: str, table: SettingsTable, parameters: dict[str, object],
         remaps: tuple[str, ...] = ()) -> NodeSpec:
    """The node ``name`` of ``module`` with ``parameters`` its settings ``table`` accepts (GraphDescriptionError
    naming the node if it does not)."""
    try:
        return NodeSpec(name, module, table.values(**parameters), remaps)
    except SettingError as error:
        raise GraphDescriptionError(f'node {name}: {error}') from None


def describe_graph(scenario: Scenario, selection: ConstraintSelection, *, duration: float = 0.0,
                   real_time_factor: float = 1.0, bag: Path | None = None,
                   controller_mass_scale: float | None = None, realtime_priority: int = 0,
                   robot_file: Path | None = None, contact_model: str = 'ideal',
                   adhesion_force: float = 0.0, viewer: bool = False, foxglove_port: int = 0,
                   foxglove_host: str = DEFAULT_HOST, engine: str = ENGINE, compose: bool = False,
                   frame_prefix: str = '', domain_clock: bool = True,
                   world_file: Path | None = None) -> list[NodeSpec]:
    """The nodes of a run of ``scenario``, in start order (the recorder first, so it misses nothing).

    ``duration`` 0 runs until stopped. Without ``bag`` there is no recorder and the dynamics does
    not wait for one. With ``controller_mass_scale`` (a closed-loop run) the selection is the driven
    set (no trajectory task); the controller starts before the dynamics, which waits for it
    (``wait_for_command``) so the loop is closed from t = 0. ``robot_file`` (the dynamics' model,
    constraint_config's gains and robot_description) None: the installed robot file;
    ``adhesion_force`` 0: the robot file's. ``viewer``: the viewer node (markers, tf), started
    before the dynamics so it draws the whole path; ``foxglove_port`` > 0 (implies the viewer):
    it serves the topics over the Foxglove WebSocket protocol on ``foxglove_host``. ``engine``: the
    dynamics' and the controller's (numba, the default, or python). ``compose`` (with ``bag``): the dynamics and the recorder in one
    process (``nodes.dynamics_recorder``), started first in the recorder's place. ``frame_prefix``
    (e.g. ``robot2/``): the robot's frames' prefix, given to every node that names them (the
    dynamics, constraint_config's robot_description, the viewer's tf); "" sets no parameter.
    ``domain_clock`` false: the dynamics leaves the domain's ``/clock`` to another robot's.
    ``world_file`` (the dynamics' surface) None: a vertical, uniform wall.
    """
    trajectory = _trajectory(scenario, bag is not None)
    closed_loop = controller_mass_scale is not None
    if closed_loop:
        selection = DRIVEN
    pose = scenario.initial
    switches = switches_from_selection(selection)
    recorder: dict[str, object] = {'output': str(bag)} if bag is not None else {}
    if bag is not None and closed_loop:
        recorder['topics'] = [t.name for t in (*topics.RECORDED, topics.WHEEL_TORQUE_CMD)]
    specs = []
    robot = {'robot_file': str(robot_file)} if robot_file is not None else {}
    frames = _frames(frame_prefix)
    specs += [
        node('constraint_config', 'wallbot_sim.nodes.constraint_config', CONSTRAINT_CONFIG,
             {**switches, **robot, **frames, 'wait_for_recorder': bag is not None, **SIM_TIME}),
        trajectory,
    ]
    if closed_loop:
        specs.append(node(CONTROLLER, 'wallbot_sim.nodes.controller', CONTROLLER_SETTINGS, {
            'mass_scale': float(controller_mass_scale), 'engine': engine, 'wait_for_recorder': bag is not None,
            **SIM_TIME}, CONTROLLER_REMAPS))
    specs += _viewer(viewer, foxglove_port, foxglove_host, {**robot, **_world(world_file)}, frames)
    dynamics = _dynamics(pose, duration, real_time_factor, bag is not None, realtime_priority,
                         {**robot, **_world(world_file)}, contact_model,
                         adhesion_force, CONTROL_STEPS if closed_loop else None, engine, frames, domain_clock)
    return _with_recorder(specs, dynamics, recorder, compose)


def describe_driven_graph(drive: str, *, duration: float = 0.0, real_time_factor: float = 1.0,
                          bag: Path | None = None, realtime_priority: int = 0, robot_file: Path | None = None,
                          contact_model: str = 'ideal', adhesion_force: float = 0.0, viewer: bool = False,
                          foxglove_port: int = 0, foxglove_host: str = DEFAULT_HOST,
                          engine: str = ENGINE, compose: bool = False, frame_prefix: str = '',
                          domain_clock: bool = True, world_file: Path | None = None) -> list[NodeSpec]:
    """The nodes of a run driven by the user (``run rest --drive DRIVE``): the driven set (no
    trajectory task, no trajectory node), at rest at the origin, and the ``DRIVES`` node.

    ``cmd_vel``: cmd_vel_node, the dynamics waiting for it and in lockstep with its loop.
    ``joint_commands``: joint_bridge_node (joint_states, joint_commands); the dynamics does not
    wait, since the commands come from the user's controller_manager (zero torque until then).
    ``viewer``, ``foxglove_port``, ``foxglove_host``, ``engine``, ``compose``, ``frame_prefix``,
    ``domain_clock``, ``world_file``: as for describe_graph.
    """
    if drive not in DRIVES:
        raise GraphDescriptionError(f'unknown drive {drive!r}: use {" or ".join(DRIVES)}')
    name, module, table = DRIVES[drive]
    recorder = ({'output': str(bag), 'topics': [t.name for t in (*topics.RECORDED, *DRIVE_TOPICS[drive])]}
                if bag is not None else {})
    robot = {'robot_file': str(robot_file)} if robot_file is not None else {}
    frames = _frames(frame_prefix)
    specs = [
        node('constraint_config', 'wallbot_sim.nodes.constraint_config', CONSTRAINT_CONFIG,
             {**switches_from_selection(DRIVEN), **robot, **frames, 'wait_for_recorder': bag is not None,
              **SIM_TIME}),
        # the drive node must not forward commands before the recorder hears them (the cmd_vel node is
        # also the run's commander: the dynamics waits for it)
        node(name, module, table, {**robot, **SIM_TIME, **({'wait_for_recorder': True} if bag is not None else {})},
             CONTROLLER_REMAPS if drive == 'cmd_vel' else ()),
        *_viewer(viewer, foxglove_port, foxglove_host, {**robot, **_world(world_file)}, frames),
    ]
    dynamics = _dynamics(REST, duration, real_time_factor, bag is not None, realtime_priority,
                         {**robot, **_world(world_file)}, contact_model,
                         adhesion_force, CMD_VEL_STEPS if drive == 'cmd_vel' else None, engine, frames,
                         domain_clock)
    return _with_recorder(specs, dynamics, recorder, compose)


def describe_tested_graph(scenario: Scenario | None, drive: str, control_steps: int, *, stop_at: float, bag: Path,
                          robot_file: Path | None = None, contact_model: str = 'ideal', adhesion_force: float = 0.0,
                          controller_timeout: float = 5.0, start_timeout: float = 30.0, fault_schedule: str = '',
                          ground_truth: bool = False, engine: str = ENGINE,
                          world_file: Path | None = None) -> list[NodeSpec]:
    """The graph ``wallbot-sim test`` (and the pytest fixture) runs a controller under test in, without it (the test
    starts it as a process of its own): the driven robot (no trajectory task) of ``scenario``, with its trajectory
    node publishing the reference to track (None: at rest at the origin, no reference), recorded (composed).

    The dynamics runs as fast as the controller answers (factor 0) in strict lockstep: it publishes every
    ``control_steps``-th state on control_odom and takes no step before the answer to it, at most
    ``controller_timeout`` wall seconds (longer ends the run, the dynamics exiting 1 naming the state); it starts
    once the controller hears it and gives up after ``start_timeout``; it stops at ``stop_at`` (s, the fixture moves
    it). ``drive``: what the controller publishes, wheel_torque_cmd itself, or cmd_vel or joint_commands to the drive
    node (``DRIVES``), which answers in lockstep with the controller. ``fault_schedule``: the dynamics' faults at
    simulation times (``loop.faults``). ``ground_truth``: the exact state on ground_truth/odom too, so the bag keeps
    every state while a fault silences odom. ``world_file``: as for describe_graph. The bag leaves out /diagnostics, the dynamics' status at 1 Hz of wall
    time with its wall-clock figures: so a spec run twice records the same messages.
    """
    if drive not in TESTED_DRIVES:
        raise GraphDescriptionError(f'unknown drive {drive!r}: use {", ".join(TESTED_DRIVES)}')
    robot = {'robot_file': str(robot_file)} if robot_file is not None else {}
    specs = [node('constraint_config', 'wallbot_sim.nodes.constraint_config', CONSTRAINT_CONFIG,
                  {**switches_from_selection(DRIVEN), **robot, 'wait_for_recorder': True, **SIM_TIME})]
    if scenario is not None:
        specs.append(_trajectory(scenario, True))
    if drive in DRIVES:
        name, module, table = DRIVES[drive]
        rate = {'rate_hz': round(DYNAMICS['rate_hz'].default / control_steps)}
        specs.append(node(name, module, table, {**robot, **SIM_TIME, 'wait_for_recorder': True, 'answer_commands': True,
                                                **rate}, CONTROLLER_REMAPS if drive == 'cmd_vel' else ()))
    pose = scenario.initial if scenario is not None else REST
    dynamics = _dynamics(pose, stop_at, 0.0, True, 0, {**robot, **_world(world_file)}, contact_model, adhesion_force,
                         control_steps, engine, {}, True)
    dynamics = node(dynamics.name, dynamics.module, DYNAMICS, {
        **dynamics.parameters, 'strict_lockstep': True, 'lockstep_timeout': float(controller_timeout),
        'command_wait_timeout': float(start_timeout),
        **({'command_sensor': 'wheel_states'} if drive == 'joint_commands' else {}),
        **({'fault_schedule': fault_schedule} if fault_schedule else {}),
        **({'ground_truth': True} if ground_truth else {})})
    recorded = [t.name for t in (*topics.RECORDED, *TESTED_DRIVES[drive]) if t is not topics.DIAGNOSTICS]
    return _with_recorder(specs, dynamics, {'output': str(bag), 'topics': recorded}, compose=True)


def _trajectory(scenario: Scenario, recorded: bool) -> NodeSpec:
    """The trajectory node playing ``scenario``'s reference; GraphDescriptionError for a shape it does not plan."""
    reference = scenario.reference
    if isinstance(reference, Circle):
        shape = {'shape': 'circle', 'radius': reference.radius}
    elif isinstance(reference, FigureEight):
        shape = {'shape': 'figure8', 'amplitude': reference.amplitude}
    else:
        raise GraphDescriptionError(f'scenario {scenario.name!r}: the trajectory node plays circles and figure-8s only')
    return node('trajectory', 'wallbot_sim.nodes.trajectory', TRAJECTORY, {
        **shape, 'period': reference.period, 'center_x': reference.center[0], 'center_y': reference.center[1],
        'wait_for_recorder': recorded, **SIM_TIME})


def _with_recorder(specs: list[NodeSpec], dynamics: NodeSpec, recorder: dict[str, object],
                   compose: bool) -> list[NodeSpec]:
    """``specs`` with the dynamics last and the recorder (its parameters ``recorder``; none: no
    recorder) first, or, with ``compose``, the two as one process first."""
    if not recorder:
        return [*specs, dynamics]
    recorder_spec = node(RECORDER, 'wallbot_sim.nodes.recorder', RECORDER_SETTINGS, recorder)
    if compose:
        return [NodeSpec(DYNAMICS_RECORDER, COMPOSED_MODULE, {**dynamics.parameters, **recorder_spec.parameters}),
                *specs]
    return [recorder_spec, *specs, dynamics]


def launch_name(spec: NodeSpec) -> dict[str, str]:
    """The ``name`` a launch_ros Node action gives the process of ``spec``: none for the composed
    process, whose two nodes keep their own names (a launch name renames every node of a process)."""
    return {} if spec.module == COMPOSED_MODULE else {'name': spec.name}


def _world(world_file: Path | None) -> dict[str, str]:
    """The world_file parameter of the dynamics and the viewer (none for a vertical, uniform wall)."""
    return {'world_file': str(world_file)} if world_file is not None else {}


def _frames(frame_prefix: str) -> dict[str, str]:
    """The frame parameters of the nodes that name the robot's frames (none for the default frames)."""
    return {'frame_prefix': frame_prefix} if frame_prefix else {}


def _viewer(viewer: bool, foxglove_port: int, foxglove_host: str, files: dict[str, str],
            frames: dict[str, str]) -> list[NodeSpec]:
    """The viewer node if asked for (``viewer``, or a Foxglove port), else nothing; ``files`` its robot and world
    file parameters."""
    if not (viewer or foxglove_port):
        return []
    foxglove = {'foxglove_port': int(foxglove_port), 'foxglove_host': foxglove_host} if foxglove_port else {}
    return [node(VIEWER, 'wallbot_sim.nodes.viewer', VIEWER_SETTINGS, {**files, **frames, **foxglove, **SIM_TIME})]


def _dynamics(pose: InitialPose, duration: float, real_time_factor: float, recorded: bool, realtime_priority: int,
              robot: dict[str, str], contact_model: str, adhesion_force: float,
              lockstep_every: int | None, engine: str, frames: dict[str, str], domain_clock: bool) -> NodeSpec:
    """The dynamics node; ``lockstep_every`` set: it waits for its controller and runs in lockstep."""
    return node('dynamics', 'wallbot_sim.nodes.dynamics', DYNAMICS, {
        'initial_x': pose.x, 'initial_y': pose.y, 'initial_theta': pose.theta,
        'initial_at_rest': pose.at_rest, 'real_time_factor': float(real_time_factor), 'stop_at': float(duration),
        'wait_for_recorder': recorded, 'realtime_priority': int(realtime_priority),
        **robot, **frames, **({} if domain_clock else {'domain_clock': False}),
        'contact_model': contact_model, 'engine': engine,
        **({'adhesion_force': float(adhesion_force)} if adhesion_force else {}),
        **({'wait_for_command': True, 'lockstep_every': lockstep_every, 'control_odom_every': lockstep_every}
           if lockstep_every else {})})
