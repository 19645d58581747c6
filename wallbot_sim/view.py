"""What the viewer draws, from the graph's topics decoded into plain numbers: markers and transforms.

ROS-free (the viewer node feeds it and publishes what it returns; tests drive it directly). All
geometry follows the URDF of ``wallbot_sim.urdf``: ``base_link`` at the chassis' geometric
centre on the wall (Z out of the wall), wheel joints at (+-a, +-b, r) turning about y, the
left wheels at +b.

Markers, all in the odometry's frame (``wall``), so a viewer needs no tf tree:

* ``chassis``: a box, coloured by the adhesion margin 1 - the largest friction use of the four
  wheels (green: far from slipping, yellow: half used, red: at the limit or slipping, or a wheel
  off the wall);
* ``wheels``: the four wheels, and ``wheel_marks``: a bar across each wheel turned by its spin
  angle, so the wheels are seen turning;
* ``reference_path``: the reference trajectory's path; ``travelled``: the centre's path, its
  newest ``trail_points`` points, one every ``TRAIL_SPACING`` metres or more;
* ``contact_forces``: the tangential force the wall exerts on the robot at each wheel (``wheel_contact``,
  docs/model.md 11.2), an arrow from the wheel's contact point, green while the wheel sticks, red while it
  slides;
* ``friction_patches`` and ``seams`` of a world file (docs/model.md 13.1): each patch a flat box on the
  wall, the more opaque the lower its friction against the robot file's, each seam a line as wide as the gap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from wallbot_msgs_py import topics
from wallbot_msgs_py.view_cdr import ARROW, CUBE, CYLINDER, DELETE, LINE_STRIP, MarkerSpec, Quaternion, TransformSpec
from wallbot_sim.model import RobotParameters
from wallbot_sim.model.world import World
from wallbot_sim.urdf import WHEEL_WIDTH_PER_RADIUS, wheel_link

TRAIL_SPACING = 0.002
"""Metres the centre moves before the travelled path gets a new point."""
FORCE_SCALE = 0.002
"""Metres of arrow per newton of contact force."""
LINE_WIDTH = 0.004
"""Metres: width of the path lines and of the force arrows' shafts (and the least of a seam's line)."""
PATCH_DEPTH = 0.001
"""Metres: thickness of a friction patch's box, drawn just under the wall's surface."""
PATCH_COLOR = (0.2, 0.4, 1.0)
SEAM_COLOR = (0.1, 0.1, 0.1, 1.0)
STICKING = (0.1, 0.8, 0.1, 1.0)
SLIPPING = (0.9, 0.1, 0.1, 1.0)
WHEEL_COLOR = (0.15, 0.15, 0.15, 1.0)
MARK_COLOR = (0.9, 0.9, 0.9, 1.0)
REFERENCE_COLOR = (0.2, 0.4, 1.0, 0.8)
TRAVELLED_COLOR = (1.0, 0.6, 0.0, 1.0)


def quaternion_product(p: Quaternion, q: Quaternion) -> Quaternion:
    """The rotation p after q, (x, y, z, w)."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return (pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
            pw * qw - px * qx - py * qy - pz * qz)


def axis_rotation(axis: int, angle: float) -> Quaternion:
    """A rotation by ``angle`` about x (0), y (1) or z (2)."""
    q = [0.0, 0.0, 0.0, math.cos(0.5 * angle)]
    q[axis] = math.sin(0.5 * angle)
    return tuple(q)


CYLINDER_ALONG_AXLE = axis_rotation(0, 0.5 * math.pi)
"""A marker cylinder lies along z; turned a quarter about x it lies along the axle (as in the URDF)."""


def world_markers(world: World, wall_friction: float) -> list[MarkerSpec]:
    """The friction patches (flat boxes just under the wall's surface, alpha growing as their static friction
    falls below ``wall_friction``) and the seams (lines as wide as their gap) of ``world``."""
    markers = []
    for k, patch in enumerate(world.patches):
        (x0, x1), (y0, y1) = patch.x, patch.y
        slippery = max(0.0, min(1.0, 1.0 - patch.wall_friction / wall_friction))
        markers.append(MarkerSpec('friction_patches', k, CUBE, (0.5 * (x0 + x1), 0.5 * (y0 + y1), -PATCH_DEPTH),
                                  scale=(x1 - x0, y1 - y0, PATCH_DEPTH), color=(*PATCH_COLOR, 0.2 + 0.6 * slippery)))
    for k, seam in enumerate(world.seams):
        markers.append(MarkerSpec('seams', k, LINE_STRIP, scale=(max(seam.width, LINE_WIDTH), 0.0, 0.0),
                                  color=SEAM_COLOR, points=np.array([(*seam.start, 0.0), (*seam.end, 0.0)])))
    return markers


def margin_color(margin: float) -> tuple[float, float, float, float]:
    """Green at margin 1, yellow at 0.5, red at 0 or below."""
    m = min(1.0, max(0.0, margin))
    return (min(1.0, 2.0 * (1.0 - m)), min(1.0, 2.0 * m), 0.0, 1.0)


@dataclass(frozen=True)
class Pose:
    """The robot's planar pose from the odometry: its frames, the stamp, the centre and heading."""

    stamp_ns: int
    frame: str
    child: str
    x: float
    y: float
    theta: float

    def to_wall(self, point: Sequence[float]) -> tuple[float, float, float]:
        """A point given in the robot frame, in the wall frame."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (self.x + c * point[0] - s * point[1], self.y + s * point[0] + c * point[1], point[2])

    def rotate(self, vector: Sequence[float]) -> tuple[float, float]:
        """A planar vector given in the robot frame, in the wall frame."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (c * vector[0] - s * vector[1], s * vector[0] + c * vector[1])


class Trail:
    """The newest ``capacity`` points of a path, kept in a ring buffer (drawn every frame without
    converting thousands of Python objects)."""

    def __init__(self, capacity: int) -> None:
        self.buffer = np.zeros((capacity, 3))
        self.count = 0
        self.next = 0

    def __len__(self) -> int:
        return self.count

    def last(self) -> np.ndarray:
        return self.buffer[self.next - 1]

    def append(self, point: Sequence[float]) -> None:
        self.buffer[self.next] = point
        self.next = (self.next + 1) % len(self.buffer)
        self.count = min(self.count + 1, len(self.buffer))

    def clear(self) -> None:
        self.count = self.next = 0

    def points(self) -> np.ndarray:
        """The points, oldest first (count x 3)."""
        if self.count < len(self.buffer):
            return self.buffer[:self.count]
        return np.concatenate((self.buffer[self.next:], self.buffer[:self.next]))

    def resized(self, capacity: int) -> Trail:
        """A trail of ``capacity`` holding the newest of these points."""
        trail = Trail(capacity)
        for point in self.points()[-capacity:]:
            trail.append(point)
        return trail


class Scene:
    """The newest state of the graph as the viewer knows it; markers and transforms of it."""

    def __init__(self, params: RobotParameters, trail_points: int = 3000, frame_prefix: str = '',
                 world: World | None = None) -> None:
        a, b, r = params.half_wheelbase, params.half_track, params.wheel_radius
        self.surface = world_markers(world, params.wall_friction) if world is not None else []
        """The world's patches and seams (fixed)."""
        self.wheel_links = tuple(wheel_link(joint, frame_prefix) for joint in topics.WHEEL_JOINTS)
        """The wheels' tf frames, the URDF's wheel links after the robot's ``frame_prefix``."""
        self.radius = r
        self.width = WHEEL_WIDTH_PER_RADIUS * r
        self.wheel_origins = ((a, b, r), (-a, b, r), (a, -b, r), (-a, -b, r))
        """Each wheel joint's origin in base_link, in topics.WHEEL_JOINTS order."""
        self.chassis_size = (2 * a, 2 * b - self.width, r)
        self.pose: Pose | None = None
        self.wheel_angles: tuple[float, ...] | None = None
        """Spin angles of the wheels; None while unknown (no wheel marks or wheel transforms then)."""
        self.loads: tuple[float, ...] | None = None
        self.use: tuple[float, ...] | None = None
        self.slipping: tuple[bool, ...] = ()
        self.forces: tuple[tuple[float, float], ...] | None = None
        self.forget_wheels_and_contact()
        self.reference_path = np.zeros((0, 3))
        self.trail = Trail(trail_points)

    # --- inputs ----------------------------------------------------------------------------------
    def set_trail_points(self, count: int) -> None:
        self.trail = self.trail.resized(count)

    def update_pose(self, pose: Pose) -> None:
        """A new odometry pose; time going back (a reset) starts the travelled path afresh."""
        if self.pose is not None and pose.stamp_ns < self.pose.stamp_ns:
            self.trail.clear()
        self.pose = pose
        if not self.trail or math.hypot(pose.x - self.trail.last()[0], pose.y - self.trail.last()[1]) >= TRAIL_SPACING:
            self.trail.append((pose.x, pose.y, 0.0))

    def update_wheels(self, angles: Sequence[float]) -> None:
        """Spin angles (rad) of the wheels, in topics.WHEEL_JOINTS order."""
        self.wheel_angles = tuple(float(angle) for angle in angles)

    def update_contact(self, loads: Sequence[float], use: Sequence[float], slipping: Sequence[bool],
                       forces_x: Sequence[float], forces_y: Sequence[float]) -> None:
        """Per wheel (topics.WHEEL_JOINTS order): normal load (N), friction use, whether it slides, and the
        wall's force on the robot along the body axes x_p and y_p (N)."""
        self.loads = tuple(float(load) for load in loads)
        self.use = tuple(float(u) for u in use)
        self.slipping = tuple(bool(flag) for flag in slipping)
        self.forces = tuple((float(fx), float(fy)) for fx, fy in zip(forces_x, forces_y))

    def forget_wheels_and_contact(self) -> None:
        """Back to not knowing the wheel angles and the contact (no longer read)."""
        self.wheel_angles = self.loads = self.use = self.forces = None
        self.slipping = (False,) * 4

    def set_reference_path(self, points: Sequence[Sequence[float]]) -> None:
        """The reference path's (x, y) points in the wall frame."""
        planar = np.asarray(points, dtype=float).reshape(-1, 2)
        self.reference_path = np.column_stack([planar, np.zeros(len(planar))])

    # --- outputs ---------------------------------------------------------------------------------
    def margin(self) -> float | None:
        """1 - the largest friction use of the wheels (<= 0 when a wheel has no load); None before contact."""
        if self.use is None or self.loads is None:
            return None
        if min(self.loads) <= 0.0:
            return 0.0
        return 1.0 - max(self.use)

    def wheel_rotation(self, wheel: int) -> Quaternion:
        """Orientation of a wheel link in the wall frame: heading, then its spin about the axle."""
        return quaternion_product(axis_rotation(2, self.pose.theta), axis_rotation(1, self.wheel_angles[wheel]))

    def contact_forces(self) -> list[tuple[float, float]] | None:
        """The wall's force on the robot at each wheel (N, wall frame); None before contact."""
        if self.forces is None:
            return None
        return [self.pose.rotate(force) for force in self.forces]

    def markers(self) -> list[MarkerSpec]:
        """Every marker of the current state (none before the first pose)."""
        if self.pose is None:
            return []
        pose = self.pose
        heading = axis_rotation(2, pose.theta)
        margin = self.margin()
        chassis_color = margin_color(1.0 if margin is None else margin)
        markers = [MarkerSpec('chassis', 0, CUBE, pose.to_wall((0.0, 0.0, self.radius)), heading, self.chassis_size,
                              chassis_color)]
        for wheel, origin in enumerate(self.wheel_origins):
            centre = pose.to_wall(origin)
            markers.append(MarkerSpec('wheels', wheel, CYLINDER, centre,  # axisymmetric: drawn without its spin
                                      quaternion_product(heading, CYLINDER_ALONG_AXLE),
                                      (2 * self.radius, 2 * self.radius, self.width), WHEEL_COLOR))
            if self.wheel_angles is None:
                markers.append(MarkerSpec('wheel_marks', wheel, CUBE, action=DELETE))
            else:
                markers.append(MarkerSpec('wheel_marks', wheel, CUBE, centre, self.wheel_rotation(wheel),
                                          (2 * self.radius, 1.05 * self.width, 0.2 * self.radius), MARK_COLOR))
        markers.append(self._line('reference_path', self.reference_path, REFERENCE_COLOR))
        markers.append(self._line('travelled', self.trail.points(), TRAVELLED_COLOR))
        forces = self.contact_forces()
        for wheel, origin in enumerate(self.wheel_origins):
            if forces is None:
                markers.append(MarkerSpec('contact_forces', wheel, ARROW, action=DELETE))
                continue
            start = pose.to_wall((origin[0], origin[1], 0.0))
            end = (start[0] + FORCE_SCALE * forces[wheel][0], start[1] + FORCE_SCALE * forces[wheel][1], 0.0)
            markers.append(MarkerSpec('contact_forces', wheel, ARROW, scale=(LINE_WIDTH, 2.5 * LINE_WIDTH,
                                                                              4 * LINE_WIDTH),
                                      color=SLIPPING if self.slipping[wheel] else STICKING,
                                      points=np.array([start, end])))
        return markers + self.surface

    @staticmethod
    def _line(ns: str, points: np.ndarray, color: tuple[float, float, float, float]) -> MarkerSpec:
        if len(points) < 2:  # a line strip needs two points; delete what an earlier frame drew
            return MarkerSpec(ns, 0, LINE_STRIP, action=DELETE)
        return MarkerSpec(ns, 0, LINE_STRIP, scale=(LINE_WIDTH, 0.0, 0.0), color=color, points=points)

    def transforms(self) -> list[TransformSpec]:
        """The odometry's frame -> its child frame (base_link), and base_link -> each wheel link (as
        robot_state_publisher would give them from the URDF and wheel_states; only once the angles
        are known); none before the first pose. The frames are the odometry's and ``wheel_links``,
        so a robot whose frame parameters are set publishes its own."""
        if self.pose is None:
            return []
        pose = self.pose
        transforms = [TransformSpec(pose.frame, pose.child, (pose.x, pose.y, 0.0), axis_rotation(2, pose.theta))]
        if self.wheel_angles is None:
            return transforms
        for link, origin, angle in zip(self.wheel_links, self.wheel_origins, self.wheel_angles):
            transforms.append(TransformSpec(pose.child, link, origin, axis_rotation(1, angle)))
        return transforms

