"""What the viewer draws (wallbot_sim.view) and how it is encoded (wallbot_msgs_py.view_cdr), without DDS.

The encodings are checked against an independent encoder (rosbags' Jazzy typestore), the geometry
against the URDF read by an independent parser (yourdfpy) and rotations against scipy's.
"""

from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cli_helpers import simulate
from message_fields import odometry_cdr, typestore_header
from wallbot_msgs_py import bagio, codec, topics, view_cdr
from wallbot_sim.bag.reader import messages
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.urdf import RobotFrames, robot_urdf, wheel_link
from wallbot_sim.view import FORCE_SCALE, TRAIL_SPACING, Pose, Scene, margin_color

yourdfpy = pytest.importorskip('yourdfpy')
MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
TF_MESSAGE = 'tf2_msgs/msg/TFMessage'
WALL, BASE = topics.WALL_FRAME, topics.BASE_FRAME
SECOND_ROBOT = RobotFrames('map', 'chassis', 'robot2/')
"""Every frame parameter set otherwise than by default (a second robot's)."""


@pytest.fixture(scope='module')
def params():
    return load_robot_parameters()


def pose(t: float, x: float, y: float, theta: float) -> Pose:
    return Pose(round(t * 1e9), WALL, BASE, x, y, theta)


def driven_scene(params, theta: float = 0.7, frames: RobotFrames = RobotFrames()) -> Scene:
    """A scene of a robot whose odometry and viewer have ``frames``'s frame parameters."""
    scene = Scene(params, frame_prefix=frames.prefix)
    scene.update_pose(Pose(1_250_000_000, frames.odom, frames.base_link, 0.3, -0.4, theta))
    scene.update_wheels([0.1, -2.0, 3.5, 7.0])
    scene.update_contact(*CONTACT)
    scene.set_reference_path([(math.cos(a), math.sin(a)) for a in np.linspace(0, 2 * math.pi, 50)])
    return scene


CONTACT = ([60.0, 40.0, 55.0, 45.0], [0.3, 0.5, 0.2, 0.4], [False] * 4, [7.2, 4.8, -4.4, -3.6],
           [9.0, 6.0, 8.25, 6.75])
"""A wheel_contact: loads, use, slip flags, forces along x_p and along y_p."""


def rotation(q) -> Rotation:
    return Rotation.from_quat(q)  # scipy's order is (x, y, z, w) too


# --- encodings --------------------------------------------------------------------------------------
def test_a_marker_array_is_what_rosbags_serializes(params):
    scene = driven_scene(params)
    specs = scene.markers()
    data = view_cdr.marker_array(1_250_000_000, WALL, specs)
    msg = bagio.deserialize(data, MARKER_ARRAY)
    assert bagio.serialize(msg, MARKER_ARRAY) == data
    assert len(msg.markers) == len(specs)
    for marker, spec in zip(msg.markers, specs):
        assert (marker.header.frame_id, marker.header.stamp.sec, marker.header.stamp.nanosec) == (WALL, 1, 250_000_000)
        assert (marker.ns, marker.id, marker.type, marker.action) == (spec.ns, spec.id, spec.type, spec.action)
        p, q, s = marker.pose.position, marker.pose.orientation, marker.scale
        assert (p.x, p.y, p.z, q.x, q.y, q.z, q.w) == (*spec.position, *spec.orientation)
        assert (s.x, s.y, s.z) == spec.scale
        assert (marker.color.r, marker.color.g, marker.color.b, marker.color.a) == pytest.approx(spec.color, abs=1e-7)
        assert [(pt.x, pt.y, pt.z) for pt in marker.points] == [tuple(row) for row in spec.points]


def test_a_tf_message_is_what_rosbags_serializes(params):
    scene = driven_scene(params)
    data = view_cdr.tf_message(1_250_000_000, scene.transforms())
    msg = bagio.deserialize(data, TF_MESSAGE)
    assert bagio.serialize(msg, TF_MESSAGE) == data
    assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == (
        [(WALL, BASE)] + [(BASE, wheel_link(joint)) for joint in topics.WHEEL_JOINTS])


@pytest.mark.parametrize('frames', [RobotFrames(), SECOND_ROBOT], ids=['default', 'second_robot'])
def test_the_tf_of_a_robot_names_the_links_of_its_robot_description(params, frames):
    """What the viewer publishes on /tf (and serves to Foxglove), from an odometry in the frames
    the dynamics' parameters give it and the viewer's frame_prefix, names exactly the frames of
    the robot_description built with the same parameters: the URDF's root, its chassis and its
    wheel links, each transform between the two links its joint joins."""
    odom = codec.decode_odometry(odometry_cdr(0.25, 0.3, -0.4, 0.7, 0.0, 0.0, 0.0, child=frames.base_link,
                                              frame=frames.odom))
    scene = Scene(params, frame_prefix=frames.prefix)
    scene.update_pose(Pose(*odom[:6]))  # as viewer_node reads odom
    scene.update_wheels([0.1, -2.0, 3.5, 7.0])
    msg = bagio.deserialize(view_cdr.tf_message(250_000_000, scene.transforms()), TF_MESSAGE)

    model = yourdfpy.URDF.load(io.StringIO(robot_urdf(params, frames)), build_scene_graph=False, load_meshes=False)
    joined = [(joint.parent, joint.child) for joint in model.robot.joints]
    assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == joined
    assert joined[0] == (frames.odom, frames.base_link)
    assert {link for pair in joined for link in pair} == {link.name for link in model.robot.links}


@pytest.mark.parametrize('little_endian', [True, False])
def test_the_per_step_messages_are_read_as_rosbags_wrote_them(little_endian):
    types = bagio.typestore().types
    odom = bagio.deserialize(odometry_cdr(12.345, 0.5, -0.25, 2.5, 1.0, 2.0, 0.3), topics.ODOM.type)
    data = bytes(bagio.typestore().serialize_cdr(odom, topics.ODOM.type, little_endian=little_endian))
    assert codec.decode_odometry(data)[:6] == (12_345_000_000, WALL, BASE, 0.5, -0.25, pytest.approx(2.5, abs=1e-15))

    names = list(topics.WHEEL_JOINTS + topics.DRIVE_JOINTS)
    joints = types['sensor_msgs/msg/JointState'](
        header=typestore_header(0.002, ''), name=names, position=np.arange(7.0), velocity=np.array([]),
        effort=np.linspace(-1.0, 1.0, 7))
    data = bytes(bagio.typestore().serialize_cdr(joints, 'sensor_msgs/msg/JointState', little_endian=little_endian))
    read = codec.decode_joint_state(data)
    assert (read.stamp_ns, read.name, read.position, read.velocity) == (2_000_000, tuple(names), tuple(range(7)), ())
    assert read.effort == tuple(np.linspace(-1.0, 1.0, 7))
    assert read.values(topics.DRIVE_JOINTS, 'effort') == tuple(np.linspace(-1.0, 1.0, 7)[4:])


def test_short_or_garbled_bytes_are_a_value_error():
    data = odometry_cdr(1.0, 0.5, -0.25, 2.5, 1.0, 2.0, 0.3)
    # cut short; not CDR; a frame name longer than the message
    for bad in (data[:40], b'\x07\x07' + data[2:], data[:12] + b'\xff\xff\xff\x7f' + data[16:]):
        with pytest.raises(ValueError, match='malformed odometry'):
            codec.decode_odometry(bad)
    with pytest.raises(ValueError, match='malformed joint_state'):
        codec.decode_joint_state(data[:30])


# --- geometry ---------------------------------------------------------------------------------------
@pytest.mark.parametrize('frames', [RobotFrames(), SECOND_ROBOT], ids=['default', 'second_robot'])
def test_the_transforms_are_the_urdfs_kinematics(params, frames):
    """base_link in the wall from the odometry pose; each wheel link from the URDF's joint origin
    and axis at the wheel's spin angle, as robot_state_publisher would compute it."""
    scene = driven_scene(params, frames=frames)
    model = yourdfpy.URDF.load(io.StringIO(robot_urdf(params, frames)), build_scene_graph=True, load_meshes=False)
    model.update_cfg(dict(zip(topics.WHEEL_JOINTS, scene.wheel_angles)))
    transforms = scene.transforms()
    base = transforms[0]
    assert base.translation == (0.3, -0.4, 0.0)
    assert rotation(base.rotation).as_euler('xyz') == pytest.approx([0.0, 0.0, 0.7], abs=1e-12)
    for transform in transforms[1:]:
        assert transform.parent == frames.base_link
        expected = model.get_transform(transform.child, frames.base_link)
        matrix = np.eye(4)
        matrix[:3, :3] = rotation(transform.rotation).as_matrix()
        matrix[:3, 3] = transform.translation
        assert matrix == pytest.approx(expected, abs=1e-12)


def test_the_wheels_are_drawn_where_the_transforms_put_them_turned_by_their_spin(params):
    scene = driven_scene(params)
    markers = {(m.ns, m.id): m for m in scene.markers()}
    heading = Rotation.from_euler('z', 0.7)
    for wheel, (joint, origin) in enumerate(zip(topics.WHEEL_JOINTS, scene.wheel_origins)):
        centre = np.array([0.3, -0.4, 0.0]) + heading.apply(origin)
        spin = Rotation.from_euler('y', scene.wheel_angles[wheel])
        mark, body = markers['wheel_marks', wheel], markers['wheels', wheel]
        assert mark.position == pytest.approx(centre, abs=1e-12) and body.position == pytest.approx(centre, abs=1e-12)
        # the mark's long side (its x) is the wheel's x turned by the spin angle about the axle
        assert rotation(mark.orientation).apply([1, 0, 0]) == pytest.approx((heading * spin).apply([1, 0, 0]), abs=1e-12)
        # the wheel cylinder's axis (its z) lies along the axle, base_link's y
        assert abs(rotation(body.orientation).apply([0, 0, 1]) @ heading.apply([0, 1, 0])) == pytest.approx(1.0)
    chassis = markers['chassis', 0]
    assert chassis.position == pytest.approx((0.3, -0.4, params.wheel_radius))
    assert chassis.scale[:2] == pytest.approx((2 * params.half_wheelbase, 2 * params.half_track - scene.width))


def test_each_wheel_s_arrow_is_its_force_and_shows_its_slip(params):
    """Each wheel's arrow starts at its contact point on the wall and is the wall's force on the robot at that
    wheel, turned from the body axes into the wall frame (FORCE_SCALE m per N); red while that wheel slides."""
    scene = driven_scene(params)
    arrows = [m for m in scene.markers() if m.ns == 'contact_forces']
    heading = Rotation.from_euler('z', 0.7)
    for arrow, origin, fx, fy in zip(arrows, scene.wheel_origins, CONTACT[3], CONTACT[4]):
        assert arrow.points[0] == pytest.approx([0.3, -0.4, 0.0] + heading.apply([origin[0], origin[1], 0.0]))
        assert (arrow.points[1] - arrow.points[0]) / FORCE_SCALE == pytest.approx(heading.apply([fx, fy, 0.0]))
    assert {a.color for a in arrows} == {(0.1, 0.8, 0.1, 1.0)}

    loads, use, _slipping, forces_x, forces_y = CONTACT
    scene.update_contact(loads, use, [False, True, False, True], forces_x, forces_y)  # the rear wheels slide
    colors = [m.color for m in scene.markers() if m.ns == 'contact_forces']
    assert colors[0] == colors[2] != colors[1] == colors[3] and colors[1][0] > colors[1][1]


def test_the_arrows_of_a_step_s_wheel_contact_are_the_model_s_wheel_forces(params):
    """A coulomb turn whose rear wheels slide: its wheel_contact bytes, decoded as the viewer decodes them, draw
    each wheel's force of the model's outputs in the wall frame, red at the sliding wheels."""
    from wallbot_msgs_py.step_cdr import StepEncoder
    from wallbot_sim.control.tracking import DRIVEN
    from wallbot_sim.model import Robot, Simulation
    simulation = Simulation(Robot(params), None, DRIVEN, np.array([0.2, 0.1, 0.4, 0, 0, 0, 0]), np.zeros(7),
                            contact='coulomb')
    simulation.set_motor_torque(-0.9, 1.2)
    simulation.run(0.05)
    out = simulation.outputs()
    contact = codec.decode_wheel_contact(dict(StepEncoder().encode(out))[topics.WHEEL_CONTACT])
    scene = Scene(params)
    scene.update_pose(pose(out.t, *out.q[:3]))
    scene.update_contact(contact.loads, contact.use, [flag > 0.5 for flag in contact.slipping], contact.force_x,
                         contact.force_y)
    arrows = [m for m in scene.markers() if m.ns == 'contact_forces']
    heading = Rotation.from_euler('z', out.q[2])
    for arrow, force in zip(arrows, out.contact.wheel_forces):
        assert (arrow.points[1] - arrow.points[0]) / FORCE_SCALE == pytest.approx(heading.apply([*force, 0.0]))
    assert out.contact.wheel_slipping == (False, True, False, True)
    assert [a.color[0] > a.color[1] for a in arrows] == [False, True, False, True]


def test_the_chassis_colour_is_the_adhesion_margin(params):
    scene = driven_scene(params)
    chassis = next(m for m in scene.markers() if m.ns == 'chassis')
    assert scene.margin() == pytest.approx(0.5) and chassis.color == margin_color(0.5) == (1.0, 1.0, 0.0, 1.0)
    loads, _use, slipping, forces_x, forces_y = CONTACT
    scene.update_contact(loads, [0.0, 0.05, 0.0, 0.01], slipping, forces_x, forces_y)
    assert next(m for m in scene.markers() if m.ns == 'chassis').color == margin_color(0.95)
    assert margin_color(0.95)[1] == 1.0 and margin_color(0.95)[0] == pytest.approx(0.1)
    scene.update_contact([60.0, -1.0, 55.0, 45.0], [0.0] * 4, slipping, forces_x, forces_y)  # a wheel off the wall
    assert scene.margin() == 0.0 and next(m for m in scene.markers() if m.ns == 'chassis').color == (1.0, 0.0, 0.0, 1.0)
    assert margin_color(-0.3) == (1.0, 0.0, 0.0, 1.0)


def test_the_travelled_path_is_bounded_spaced_and_starts_again_after_a_reset(params):
    scene = Scene(params, trail_points=100)
    step = 0.75 * TRAIL_SPACING  # clear of the spacing both ways: every second pose makes a point
    for k in range(1000):
        scene.update_pose(pose(k * 1e-3, k * step, 0.0, 0.0))
    trail = scene.trail.points()
    assert len(trail) == 100 and trail[-1, 0] == pytest.approx(998 * step)
    assert np.diff(trail[:, 0]) == pytest.approx(np.full(99, 2 * step))
    travelled = next(m for m in scene.markers() if m.ns == 'travelled')
    assert travelled.type == view_cdr.LINE_STRIP and travelled.points == pytest.approx(trail)

    scene.update_pose(pose(0.0, 5.0, 5.0, 0.0))  # time went back: the path starts afresh
    assert scene.trail.points().tolist() == [[5.0, 5.0, 0.0]]
    travelled = next(m for m in scene.markers() if m.ns == 'travelled')
    assert travelled.action == view_cdr.DELETE  # one point is no line: what was drawn goes
    scene.set_trail_points(3)
    for k in range(1, 10):
        scene.update_pose(pose(k, 5.0 + k, 5.0, 0.0))
    assert scene.trail.points()[:, 0].tolist() == [12.0, 13.0, 14.0]
    scene.set_trail_points(5)  # keeps what it has
    scene.update_pose(pose(10, 15.0, 5.0, 0.0))
    assert scene.trail.points()[:, 0].tolist() == [12.0, 13.0, 14.0, 15.0]


def test_a_scene_that_forgets_the_wheels_and_contact_draws_no_arrows_nor_wheel_turns(params):
    scene = driven_scene(params)
    scene.forget_wheels_and_contact()
    markers = scene.markers()
    assert scene.margin() is None and next(m for m in markers if m.ns == 'chassis').color == margin_color(1.0)
    assert all(m.action == view_cdr.DELETE for m in markers if m.ns == 'contact_forces')
    assert [m.action for m in markers if m.ns == 'wheel_marks'] == [view_cdr.DELETE] * 4  # angles unknown
    assert len(scene.transforms()) == 1  # wall -> base_link only
    assert sum(m.action == view_cdr.ADD for m in markers if m.ns == 'wheels') == 4
    assert len(scene.trail) == 1 and len(next(m for m in markers if m.ns == 'reference_path').points) == 50


def test_nothing_is_drawn_before_the_first_pose_and_no_turns_or_arrows_before_their_topics(params):
    scene = Scene(params)
    assert scene.markers() == [] and scene.transforms() == []
    scene.update_pose(pose(0.0, 0.0, 0.0, 0.0))
    markers = scene.markers()
    assert {m.ns for m in markers if m.action == view_cdr.DELETE} == {'reference_path', 'travelled', 'contact_forces',
                                                                      'wheel_marks'}
    assert next(m for m in markers if m.ns == 'chassis').color == margin_color(1.0)


# --- the Foxglove layout ------------------------------------------------------------------------------
LAYOUT = Path(__file__).resolve().parents[1] / 'config' / 'foxglove_layout.json'
PLOTTED = {'F_L': 'drive_left', 'F_R': 'drive_right', 'F_lat': 'lateral', 'use left front': 'wheel_left_front',
           'use left rear': 'wheel_left_rear', 'use right front': 'wheel_right_front',
           'use right rear': 'wheel_right_rear'}
"""Each plotted channel's series label and the joint name its array index must have in the message."""


def panels(tree) -> list[str]:
    return [tree] if isinstance(tree, str) else panels(tree['first']) + panels(tree['second'])


def field(message, path: str):
    """A Foxglove message path below the topic (``.a.b[2]``) evaluated on a decoded message."""
    value = message
    for name, index in re.findall(r'\.(\w+)(?:\[(\d+)\])?', path):
        value = getattr(value, name)
        if index:
            value = value[int(index)]
    return value


def test_the_foxglove_layout_plots_what_a_recorded_bag_holds(tmp_path):
    """Every plotted path names a recorded topic and a field its messages have, and every indexed
    series is the one its label says (a channel of drive_forces, a wheel of wheel_contact)."""
    layout = json.loads(LAYOUT.read_text())
    assert set(panels(layout['layout'])) == set(layout['configById'])
    result = simulate('--scenario', 'circle', '--duration', '0.01', '--csv', tmp_path / 'run.csv',
                      '--bag', tmp_path / 'bag')
    assert result.returncode == 0, result.stderr
    first = {}
    for raw in messages(tmp_path / 'bag'):
        first.setdefault(raw.topic, bagio.deserialize(raw.data, raw.type))
    plotted = [(series['value'], series['label']) for panel in layout['configById'].values()
               for series in panel.get('paths', [])]
    plotted += [(panel['xAxisPath']['value'], 'x') for panel in layout['configById'].values() if 'xAxisPath' in panel]
    assert len(plotted) == 10
    for value, label in plotted:
        topic, path = re.fullmatch(r'(/[\w/]+?)((?:\.\w+(?:\[\d+\])?)+)', value).groups()
        assert topic in first, f'{topic} is not recorded'
        assert isinstance(field(first[topic], path), float), value
        if label in PLOTTED:
            index = int(re.search(r'\[(\d+)\]$', path).group(1))
            assert first[topic].name[index] == PLOTTED[label], value


def test_a_world_s_patches_and_seams_are_drawn_on_the_wall(params):
    """The example world's wet patch is a flat box covering its rectangle, more opaque the lower its friction;
    its seam a line between its ends as wide as the gap (at least a path line's width); none without a world."""
    from wallbot_sim.config import load_world
    from wallbot_sim.view import LINE_WIDTH
    world = load_world(Path(__file__).resolve().parents[1] / 'config' / 'world.yaml')
    scene = Scene(params, world=world)
    scene.update_pose(pose(0.0, 0.0, 0.0, 0.0))
    drawn = scene.markers()
    [patch] = [m for m in drawn if m.ns == 'friction_patches']
    (x0, x1), (y0, y1) = world.patches[0].x, world.patches[0].y
    assert patch.position[:2] == pytest.approx(((x0 + x1) / 2, (y0 + y1) / 2)) and patch.position[2] < 0.0
    assert patch.scale[:2] == pytest.approx((x1 - x0, y1 - y0))
    drier = Scene(params.replace(wall_friction=0.35, kinetic_friction=0.3), world=world)
    drier.update_pose(pose(0.0, 0.0, 0.0, 0.0))
    [less_slippery] = [m for m in drier.markers() if m.ns == 'friction_patches']
    assert less_slippery.color[3] < patch.color[3]  # 0.3 on a 0.35 wall stands out less than on a 0.7 one
    [seam] = [m for m in drawn if m.ns == 'seams']
    assert seam.points.tolist() == [[-5.0, 1.0, 0.0], [5.0, 1.0, 0.0]]
    assert seam.scale[0] == max(world.seams[0].width, LINE_WIDTH)
    plain = Scene(params)
    plain.update_pose(pose(0.0, 0.0, 0.0, 0.0))
    assert not {m.ns for m in plain.markers()} & {'friction_patches', 'seams'}
