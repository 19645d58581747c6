"""The robot's URDF (wallbot_sim.urdf), read by an independent parser (yourdfpy), and its
``robot_description`` topic as a late subscriber (RViz, a controller_manager) receives it."""

from __future__ import annotations

import dataclasses
import io
import math
import re
import sys
import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
import yaml

from wallbot_msgs_py import topics
from wallbot_sim import paths
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.graph_description import describe_driven_graph
from wallbot_sim.model import Robot
from wallbot_sim.model.parameters import RobotParameters
from wallbot_sim.urdf import RobotFrames, robot_urdf, wheel_radius

yourdfpy = pytest.importorskip('yourdfpy')

OFFSET_ROBOT = RobotParameters(body_mass=7.3, wheel_mass=0.31, body_yaw_inertia=0.083, wheel_yaw_inertia=1.3e-4,
                               wheel_spin_inertia=2.2e-4, wheel_radius=0.045, half_wheelbase=0.11, half_track=0.13,
                               com_offset=(0.012, -0.007), com_height=0.06)
"""Unlike the installed file in every number that reaches the URDF, with an offset centre of mass."""


def parse(text: str):
    return yourdfpy.URDF.load(io.StringIO(text), build_scene_graph=True, load_meshes=False)


def planar_mass_matrix(model, theta: float) -> np.ndarray:
    """The 7 x 7 mass matrix of q = [x, y, th, p1..p4] (docs/model.md section 1) written from the
    URDF alone: each link's kinetic energy with its centre of mass and inertia placed by the URDF's
    transforms, the chassis turned by ``theta`` in the wall plane, each wheel spinning about its
    joint's axis."""
    mass = np.zeros((7, 7))
    turn = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    for link in model.robot.links:
        if link.inertial is None:
            continue
        placed = model.get_transform(link.name, topics.BASE_FRAME) @ link.inertial.origin
        rotation = placed[:3, :3]
        inertia = rotation @ link.inertial.inertia @ rotation.T  # in base_link axes
        m = link.inertial.mass
        px, py = turn @ placed[:2, 3]
        # velocity of the centre of mass: (xd - thd py, yd + thd px)
        mass[:3, :3] += m * np.array([[1.0, 0.0, -py], [0.0, 1.0, px], [-py, px, px * px + py * py]])
        mass[2, 2] += inertia[2, 2]
        joint = next((j for j in model.robot.joints if j.child == link.name and j.type == 'continuous'), None)
        if joint is not None:
            spin = 3 + topics.WHEEL_JOINTS.index(joint.name)
            axis = rotation @ np.asarray(joint.axis)
            mass[spin, spin] = axis @ inertia @ axis
    return mass


@pytest.mark.parametrize('radius', [0.04, 0.1 / 3, 0.0525])
def test_the_wheel_radius_reads_back_exactly_from_the_urdf(radius):
    """What a bag's reader takes from robot_description for a side's torque (r F_side plus its wheels' efforts)."""
    assert wheel_radius(robot_urdf(RobotParameters(wheel_radius=radius))) == radius
    with pytest.raises(ValueError, match='no wheel cylinder'):
        wheel_radius('<robot name="empty"/>')
    with pytest.raises(ValueError, match='not XML'):
        wheel_radius('<robot')


@pytest.mark.parametrize('params', [load_robot_parameters(), OFFSET_ROBOT], ids=['robot.yaml', 'offset'])
def test_the_urdf_has_the_robot_files_masses_inertias_and_geometry(params):
    model = parse(robot_urdf(params))
    assert model.validate()
    assert model.base_link == topics.WALL_FRAME
    joints = {j.name: j for j in model.robot.joints}
    assert joints['wall_to_base_link'].type == 'floating'
    assert (joints['wall_to_base_link'].parent, joints['wall_to_base_link'].child) == (topics.WALL_FRAME,
                                                                                   topics.BASE_FRAME)
    wheels = [j for j in model.robot.joints if j.type == 'continuous']
    assert [j.name for j in wheels] == list(topics.WHEEL_JOINTS)
    a, b, r = params.half_wheelbase, params.half_track, params.wheel_radius
    for joint, side, end in zip(wheels, (1, 1, -1, -1), (1, -1, 1, -1)):
        assert joint.parent == topics.BASE_FRAME
        assert np.array_equal(joint.axis, [0.0, 1.0, 0.0])
        assert np.allclose(joint.origin, np.array([[1, 0, 0, end * a], [0, 1, 0, side * b], [0, 0, 1, r],
                                                   [0, 0, 0, 1]]), rtol=0, atol=1e-15)

    links = {link.name: link for link in model.robot.links}
    chassis = links[topics.BASE_FRAME].inertial
    assert chassis.mass == params.body_mass
    assert np.array_equal(chassis.origin[:3, 3], [*params.com_offset, params.com_height])
    assert np.array_equal(chassis.origin[:3, :3], np.eye(3))
    ixx, iyy, izz = np.diag(chassis.inertia)
    assert izz == params.body_yaw_inertia and np.count_nonzero(chassis.inertia - np.diag(np.diag(chassis.inertia))) == 0
    # the roll and pitch inertias the planar model lacks: a flat 2a x 2b plate in the wall plane
    assert ixx + iyy == pytest.approx(izz, rel=1e-15) and ixx / iyy == pytest.approx(b * b / (a * a), rel=1e-12)
    for joint in wheels:
        wheel = links[joint.child].inertial
        assert wheel.mass == params.wheel_mass
        assert np.array_equal(wheel.inertia, np.diag([params.wheel_yaw_inertia, params.wheel_spin_inertia,
                                                      params.wheel_yaw_inertia]))
    total = sum(link.inertial.mass for link in model.robot.links if link.inertial is not None)
    assert total == pytest.approx(Robot(params).total_mass, rel=1e-15)


@pytest.mark.parametrize('theta', [0.0, 0.7, -2.4])
@pytest.mark.parametrize('params', [load_robot_parameters(), OFFSET_ROBOT], ids=['robot.yaml', 'offset'])
def test_the_urdf_assembles_to_the_models_mass_matrix(params, theta):
    """The URDF's bodies, put together as a planar robot on the wall, have the model's M(q)."""
    expected = Robot(params).mass_matrix(np.array([0.3, -0.2, theta, 0.1, 0.2, 0.3, 0.4]))
    assert np.allclose(planar_mass_matrix(parse(robot_urdf(params)), theta), expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize('frames', [RobotFrames(prefix='robot2/'), RobotFrames('map', 'chassis', 'r2_')],
                         ids=['prefix', 'every_parameter'])
def test_the_urdf_names_its_links_by_the_frame_parameters(frames):
    """The root is odom_frame_id, the chassis frame_prefix + base_frame_id, each wheel link
    frame_prefix + <joint>_link; the joints keep their names (wheel_states names them); nothing
    else differs from the single robot's document."""
    params = load_robot_parameters()
    text = robot_urdf(params, frames)
    model = parse(text)
    assert model.validate()
    assert model.base_link == frames.odom
    joints = {j.name: j for j in model.robot.joints}
    assert (joints['wall_to_base_link'].parent, joints['wall_to_base_link'].child) == (frames.odom, frames.base_link)
    for joint in topics.WHEEL_JOINTS:
        assert (joints[joint].parent, joints[joint].child) == (frames.base_link, frames.prefix + f'{joint}_link')
    renamed = {topics.WALL_FRAME: frames.odom, topics.BASE_FRAME: frames.base_link,
               **{f'{joint}_link': frames.prefix + f'{joint}_link' for joint in topics.WHEEL_JOINTS}}
    single = ElementTree.fromstring(robot_urdf(params))
    for element in single.iter():
        for attribute in ('name', 'link') if element.tag in ('link', 'parent', 'child') else ():
            if attribute in element.attrib:
                element.set(attribute, renamed[element.get(attribute)])
    assert ElementTree.tostring(single) == ElementTree.tostring(ElementTree.fromstring(text))


@pytest.mark.parametrize('frames, reason', [
    (RobotFrames(odom=''), 'odom_frame_id is empty'),
    (RobotFrames(base=''), 'base_frame_id is empty'),
    (RobotFrames(prefix='/robot2/'), "frame_prefix '/robot2/': a tf frame starts with no"),
    (RobotFrames(base='base link'), "base_frame_id 'base link': a tf frame starts with no"),
    (RobotFrames(odom='wall', base='wall'), "the odometry's frame and child frame are both 'wall'"),
])
def test_unusable_frames_are_refused_naming_what_is_wrong(frames, reason):
    assert reason in frames.reasons()[0] and len(frames.reasons()) == 1
    with pytest.raises(ValueError, match=re.escape(reason)):
        robot_urdf(load_robot_parameters(), frames)


def test_a_late_subscriber_receives_the_robot_description(tmp_path, process_runner):
    """constraint_config publishes the URDF of its robot_file once; a subscription made after that
    (transient-local, as RViz's) still receives it, and it is that file's robot."""
    from std_msgs.msg import String

    from graph_helpers import Graph
    from wallbot_msgs_py.qos import qos_profile

    robot_file = tmp_path / 'robot.yaml'
    values = yaml.safe_load(paths.robot_yaml().read_text())
    values.update(body_mass=6.5, wheel_mass=0.3, half_track=0.14)
    robot_file.write_text(yaml.safe_dump(values))
    graph = Graph(process_runner)
    try:
        graph.start('constraint_config', f'robot_file:={robot_file}')
        graph.wait_for(lambda: graph.messages(topics.CONSTRAINTS.name), 30, 'the constraints')
        graph.wait_for(lambda: 'robot_description:' in process_runner.output('constraint_config'), 30,
                       'the robot_description published')
        received = []
        graph.node.create_subscription(String, topics.ROBOT_DESCRIPTION.resolve(), received.append,
                                       qos_profile(topics.ROBOT_DESCRIPTION))
        graph.wait_for(lambda: received, 30, 'the robot_description')
    finally:
        graph.close()
    assert received[0].data == robot_urdf(load_robot_parameters(robot_file))
    links = {link.name: link for link in parse(received[0].data).robot.links}
    assert links[topics.BASE_FRAME].inertial.mass == 6.5
    assert links['wheel_left_front_link'].inertial.mass == 0.3


def test_a_bad_robot_file_ends_constraint_config_with_one_line(tmp_path, process_runner):
    missing = tmp_path / 'missing.yaml'
    node = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.constraint_config', '--ros-args',
                                 '-p', f'robot_file:={missing}'], 'constraint_config')
    assert node.wait(timeout=60) == 1
    output = process_runner.output('constraint_config')
    assert output.count('\n') == 1 and f'cannot read {missing}: No such file' in output


@pytest.mark.parametrize('node, parameter, reason', [
    ('constraint_config', 'frame_prefix:=/robot2/', 'frame_prefix \'/robot2/\': a tf frame starts with no "/"'),
    ('dynamics', 'base_frame_id:=wall', "the odometry's frame and child frame are both 'wall'"),
    ('viewer', 'frame_prefix:=robot 2/', "frame_prefix 'robot 2/': a tf frame starts with no \"/\" and holds no white"),
])
def test_unusable_frames_end_each_node_naming_them_with_one_line(process_runner, node, parameter, reason):
    started = process_runner.start([sys.executable, '-m', f'wallbot_sim.nodes.{node}', '--ros-args',
                                    '-p', parameter], node)
    assert started.wait(timeout=60) == 1
    output = process_runner.output(node)
    assert output.count('\n') == 1 and reason in output, output


def test_two_robots_in_one_domain_each_describe_the_frames_of_their_own_odometry(process_runner):
    """Two robots, each in its namespace with its frames (the launch file's namespace:= and
    frame_prefix:=, and a base_frame_id of its own on the second): each robot_description's root
    and chassis are the frame and child frame of that robot's odometry, its wheel links carry its
    prefix, and the two documents name no link of the robot's own body alike."""
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String

    from graph_helpers import Graph

    robots = {'/robot1': RobotFrames(prefix='robot1/'), '/robot2': RobotFrames(base='chassis', prefix='robot2/')}
    graph = Graph(process_runner)
    try:
        for namespace, frames in robots.items():
            graph.subscribe(f'{namespace}/description', String, topics.ROBOT_DESCRIPTION.resolve(namespace),
                            topics.ROBOT_DESCRIPTION)
            graph.subscribe(f'{namespace}/odom', Odometry, topics.ODOM.resolve(namespace), topics.ODOM)
            # at a tenth of real time, so the odometry goes on (slowly, cheaply) until the test hears it
            specs = describe_driven_graph('joint_commands', real_time_factor=0.1, frame_prefix=frames.prefix)
            for spec in specs:
                if spec.name not in ('constraint_config', 'dynamics'):
                    continue
                extra = {'resume_wait': 0.0, 'domain_clock': namespace == '/robot1'} if spec.name == 'dynamics' else {}
                spec = dataclasses.replace(spec, parameters={**spec.parameters, 'base_frame_id': frames.base, **extra},
                                           remaps=(f'__ns:={namespace}',))
                name = f'{namespace[1:]}_{spec.name}'
                graph.procs[name] = process_runner.start(spec.command(), name)
        for namespace in robots:
            graph.wait_for(lambda: graph.messages(f'{namespace}/description'), 60,
                           f'the robot_description of {namespace}')
            graph.wait_for(lambda: graph.newest(f'{namespace}/odom'), 60, f'the odometry of {namespace}')
        received = {namespace: (graph.messages(f'{namespace}/description')[0].data, graph.newest(f'{namespace}/odom'))
                    for namespace in robots}
    finally:
        graph.close()
    params = load_robot_parameters()
    body_links = []
    for namespace, frames in robots.items():
        urdf, odom = received[namespace]
        assert urdf == robot_urdf(params, frames)
        model = parse(urdf)
        floating = next(j for j in model.robot.joints if j.type == 'floating')
        assert (model.base_link, floating.child) == (odom.header.frame_id, odom.child_frame_id)
        assert odom.child_frame_id == f'{namespace[1:]}/{frames.base}'
        body_links.append({link.name for link in model.robot.links} - {model.base_link})
        assert all(link.startswith(f'{namespace[1:]}/') for link in body_links[-1])
    assert len(body_links[0]) == len(body_links[1]) == 5 and not body_links[0] & body_links[1]
