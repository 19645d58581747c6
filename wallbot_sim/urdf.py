"""The robot as URDF, generated from its robot file: what RViz, Foxglove and ros2_control read.

    text = robot_urdf(load_robot_parameters())

Frames follow docs/model.md section 1: ``base_link`` is the chassis' geometric centre on the
wall (x forward, y to the left, z out of the wall); the wall frame ``wall`` is the root, joined
to ``base_link`` by a floating joint whose pose the simulation publishes (robot_state_publisher
publishes no transform for a floating joint). The four wheels are continuous joints named as in
``wheel_states``, axles along y at (+-a, +-b, r). Masses and the inertias about each body's own
centre of mass are the robot file's; what the planar model does not define is derived and said
so below. Geometry is for display only. ROS-free.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

from wallbot_msgs_py import topics
from wallbot_sim.model.parameters import RobotParameters

ROBOT_NAME = 'wallbot'
FLOATING_JOINT = f'{topics.WALL_FRAME}_to_{topics.BASE_FRAME}'
WHEEL_WIDTH_PER_RADIUS = 0.5
"""Drawn wheel width / wheel radius (display only: the model's wheels have no width)."""


def wheel_link(joint: str) -> str:
    """The link a wheel joint turns (a JointState names joints, tf names links)."""
    return f'{joint}_link'


def chassis_roll_pitch_inertia(params: RobotParameters) -> tuple[float, float]:
    """(I_xx, I_yy) of the chassis about its centre of mass.

    The planar model has only the yaw inertia J_b. The chassis is taken as a flat plate in the
    wall plane shaped like the wheelbase-by-track rectangle: by the perpendicular-axis theorem
    I_xx + I_yy = J_b, split as a uniform 2a x 2b rectangle splits it (I_xx ~ b^2, I_yy ~ a^2).
    """
    a2, b2 = params.half_wheelbase ** 2, params.half_track ** 2
    return params.body_yaw_inertia * b2 / (a2 + b2), params.body_yaw_inertia * a2 / (a2 + b2)


def robot_urdf(params: RobotParameters) -> str:
    """The URDF document (a string) of the robot ``params`` describes."""
    a, b, r = params.half_wheelbase, params.half_track, params.wheel_radius
    width = WHEEL_WIDTH_PER_RADIUS * r
    robot = ElementTree.Element('robot', name=ROBOT_NAME)
    ElementTree.SubElement(robot, 'link', name=topics.WALL_FRAME)
    floating = ElementTree.SubElement(robot, 'joint', name=FLOATING_JOINT, type='floating')
    ElementTree.SubElement(floating, 'parent', link=topics.WALL_FRAME)
    ElementTree.SubElement(floating, 'child', link=topics.BASE_FRAME)

    chassis = ElementTree.SubElement(robot, 'link', name=topics.BASE_FRAME)
    roll, pitch = chassis_roll_pitch_inertia(params)
    _inertial(chassis, params.body_mass, (*params.com_offset, params.com_height),
              (roll, pitch, params.body_yaw_inertia))
    _visual(chassis, (0.0, 0.0, r), (0.0, 0.0, 0.0), 'box', size=_numbers(2 * a, 2 * b - width, r))

    for joint_name, (x, y) in zip(topics.WHEEL_JOINTS, ((a, b), (-a, b), (a, -b), (-a, -b))):
        joint = ElementTree.SubElement(robot, 'joint', name=joint_name, type='continuous')
        ElementTree.SubElement(joint, 'parent', link=topics.BASE_FRAME)
        ElementTree.SubElement(joint, 'child', link=wheel_link(joint_name))
        ElementTree.SubElement(joint, 'origin', xyz=_numbers(x, y, r), rpy=_numbers(0.0, 0.0, 0.0))
        ElementTree.SubElement(joint, 'axis', xyz=_numbers(0.0, 1.0, 0.0))
        wheel = ElementTree.SubElement(robot, 'link', name=wheel_link(joint_name))
        # axisymmetric about its axle (y): the inertia about x equals the yaw one about z
        _inertial(wheel, params.wheel_mass, (0.0, 0.0, 0.0),
                  (params.wheel_yaw_inertia, params.wheel_spin_inertia, params.wheel_yaw_inertia))
        # a URDF cylinder lies along z: turned a quarter about x to lie along the axle
        _visual(wheel, (0.0, 0.0, 0.0), (1.5707963267948966, 0.0, 0.0), 'cylinder',
                radius=_numbers(r), length=_numbers(width))
    ElementTree.indent(robot)
    return '<?xml version="1.0"?>\n' + ElementTree.tostring(robot, encoding='unicode') + '\n'


def _numbers(*values: float) -> str:
    """Space-separated, each float written so that it reads back exactly."""
    return ' '.join(repr(float(v)) for v in values)


def _inertial(link: ElementTree.Element, mass: float, com: tuple[float, float, float],
              principal: tuple[float, float, float]) -> None:
    inertial = ElementTree.SubElement(link, 'inertial')
    ElementTree.SubElement(inertial, 'origin', xyz=_numbers(*com), rpy=_numbers(0.0, 0.0, 0.0))
    ElementTree.SubElement(inertial, 'mass', value=_numbers(mass))
    ixx, iyy, izz = principal
    ElementTree.SubElement(inertial, 'inertia', ixx=_numbers(ixx), ixy='0.0', ixz='0.0', iyy=_numbers(iyy),
                           iyz='0.0', izz=_numbers(izz))


def _visual(link: ElementTree.Element, xyz: tuple[float, float, float], rpy: tuple[float, float, float],
            shape: str, **size: str) -> None:
    visual = ElementTree.SubElement(link, 'visual')
    ElementTree.SubElement(visual, 'origin', xyz=_numbers(*xyz), rpy=_numbers(*rpy))
    geometry = ElementTree.SubElement(visual, 'geometry')
    ElementTree.SubElement(geometry, shape, **size)
