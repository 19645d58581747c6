"""The robot as URDF, generated from its robot file: what RViz, Foxglove and ros2_control read.

    text = robot_urdf(load_robot_parameters())

Frames follow docs/model.md section 1: ``base_link`` is the chassis' geometric centre on the
wall (x forward, y to the left, z out of the wall); the wall frame ``wall`` is the root, joined
to ``base_link`` by a floating joint whose pose the simulation publishes (robot_state_publisher
publishes no transform for a floating joint). The four wheels are continuous joints named as in
``wheel_states``, axles along y at (+-a, +-b, r). Masses and the inertias about each body's own
centre of mass are the robot file's; what the planar model does not define is derived and said
so below. Geometry is for display only. The links are named by ``RobotFrames``, the nodes' frame
parameters, so that a second robot's model names its own frames:

    robot_urdf(params, RobotFrames(prefix='robot2/'))  # wall -> robot2/base_link -> robot2/wheel_..._link

ROS-free.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass

from wallbot_msgs_py import topics
from wallbot_sim.model.parameters import RobotParameters

ROBOT_NAME = 'wallbot'
FLOATING_JOINT = f'{topics.WALL_FRAME}_to_{topics.BASE_FRAME}'
"""The floating joint's name, whatever the frames (a joint name is no frame: tf never sees it)."""
WHEEL_WIDTH_PER_RADIUS = 0.5
"""Drawn wheel width / wheel radius (display only: the model's wheels have no width)."""


def wheel_link(joint: str, prefix: str = '') -> str:
    """The link a wheel joint turns (a JointState names joints, tf names links), after ``prefix``."""
    return f'{prefix}{joint}_link'


@dataclass(frozen=True)
class RobotFrames:
    """The frame names of one robot: the nodes' ``odom_frame_id``, ``base_frame_id`` and ``frame_prefix``.

    ``odom`` is the wall, the URDF's root and the odometry's frame; it is not prefixed, so robots
    sharing a domain can share it as the fixed frame they are all drawn in. ``prefix`` comes
    before every link of the robot's own body (``base_link`` and the wheel links), as
    robot_state_publisher's ``frame_prefix`` comes before the frames it publishes; joint names are
    never prefixed (a JointState in the robot's namespace names them). The defaults are the
    single robot's frames.
    """

    odom: str = topics.WALL_FRAME
    base: str = topics.BASE_FRAME
    prefix: str = ''

    @property
    def base_link(self) -> str:
        """The chassis' frame: the odometry's child frame, the URDF's floating joint's child."""
        return self.prefix + self.base

    def wheel_link(self, joint: str) -> str:
        """The link the wheel joint ``joint`` turns."""
        return wheel_link(joint, self.prefix)

    def reasons(self) -> list[str]:
        """What makes these frames unusable, one reason each (none: usable). tf2 refuses a frame
        that starts with '/' and RViz one with white space; the odometry's frame and child differ."""
        reasons = []
        for name, value in (('odom_frame_id', self.odom), ('base_frame_id', self.base), ('frame_prefix', self.prefix)):
            if not value and name != 'frame_prefix':
                reasons.append(f'{name} is empty')
            elif value.startswith('/') or any(c.isspace() for c in value):
                reasons.append(f'{name} {value!r}: a tf frame starts with no "/" and holds no white space')
        if not reasons and self.base_link == self.odom:
            reasons.append(f'the odometry\'s frame and child frame are both {self.odom!r} (odom_frame_id, '
                           f'frame_prefix + base_frame_id)')
        return reasons


def chassis_roll_pitch_inertia(params: RobotParameters) -> tuple[float, float]:
    """(I_xx, I_yy) of the chassis about its centre of mass.

    The planar model has only the yaw inertia J_b. The chassis is taken as a flat plate in the
    wall plane shaped like the wheelbase-by-track rectangle: by the perpendicular-axis theorem
    I_xx + I_yy = J_b, split as a uniform 2a x 2b rectangle splits it (I_xx ~ b^2, I_yy ~ a^2).
    """
    a2, b2 = params.half_wheelbase ** 2, params.half_track ** 2
    return params.body_yaw_inertia * b2 / (a2 + b2), params.body_yaw_inertia * a2 / (a2 + b2)


def robot_urdf(params: RobotParameters, frames: RobotFrames = RobotFrames()) -> str:
    """The URDF document (a string) of the robot ``params`` describes, its links named by ``frames``.

    ValueError if ``frames`` are unusable (``RobotFrames.reasons``)."""
    reasons = frames.reasons()
    if reasons:
        raise ValueError('; '.join(reasons))
    a, b, r = params.half_wheelbase, params.half_track, params.wheel_radius
    width = WHEEL_WIDTH_PER_RADIUS * r
    robot = ElementTree.Element('robot', name=ROBOT_NAME)
    ElementTree.SubElement(robot, 'link', name=frames.odom)
    floating = ElementTree.SubElement(robot, 'joint', name=FLOATING_JOINT, type='floating')
    ElementTree.SubElement(floating, 'parent', link=frames.odom)
    ElementTree.SubElement(floating, 'child', link=frames.base_link)

    chassis = ElementTree.SubElement(robot, 'link', name=frames.base_link)
    roll, pitch = chassis_roll_pitch_inertia(params)
    _inertial(chassis, params.body_mass, (*params.com_offset, params.com_height),
              (roll, pitch, params.body_yaw_inertia))
    _visual(chassis, (0.0, 0.0, r), (0.0, 0.0, 0.0), 'box', size=_numbers(2 * a, 2 * b - width, r))

    for joint_name, (x, y) in zip(topics.WHEEL_JOINTS, ((a, b), (-a, b), (a, -b), (-a, -b))):
        joint = ElementTree.SubElement(robot, 'joint', name=joint_name, type='continuous')
        ElementTree.SubElement(joint, 'parent', link=frames.base_link)
        ElementTree.SubElement(joint, 'child', link=frames.wheel_link(joint_name))
        ElementTree.SubElement(joint, 'origin', xyz=_numbers(x, y, r), rpy=_numbers(0.0, 0.0, 0.0))
        ElementTree.SubElement(joint, 'axis', xyz=_numbers(0.0, 1.0, 0.0))
        wheel = ElementTree.SubElement(robot, 'link', name=frames.wheel_link(joint_name))
        # axisymmetric about its axle (y): the inertia about x equals the yaw one about z
        _inertial(wheel, params.wheel_mass, (0.0, 0.0, 0.0),
                  (params.wheel_yaw_inertia, params.wheel_spin_inertia, params.wheel_yaw_inertia))
        # a URDF cylinder lies along z: turned a quarter about x to lie along the axle
        _visual(wheel, (0.0, 0.0, 0.0), (1.5707963267948966, 0.0, 0.0), 'cylinder',
                radius=_numbers(r), length=_numbers(width))
    ElementTree.indent(robot)
    return '<?xml version="1.0"?>\n' + ElementTree.tostring(robot, encoding='unicode') + '\n'


def wheel_radius(urdf: str) -> float:
    """The wheel radius (m) of a URDF ``robot_urdf`` wrote: its wheels' cylinders' radius, exact. ValueError if the
    document is not XML or has no cylinder."""
    try:
        cylinder = ElementTree.fromstring(urdf).find('.//cylinder')
    except ElementTree.ParseError as error:
        raise ValueError(f'the robot description is not XML: {error}') from None
    if cylinder is None or cylinder.get('radius') is None:
        raise ValueError('the robot description has no wheel cylinder')
    return float(cylinder.get('radius'))


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
