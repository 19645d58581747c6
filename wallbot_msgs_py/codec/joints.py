"""sensor_msgs/JointState (``wheel_states``, ``drive_forces``, ``joint_states``, ``joint_commands``), its
``wheel_contact`` layout, and geometry_msgs/WrenchStamped (``constraint_wrench``).

Each encoder is a byte template of fixed names and lengths whose numbers are overwritten per message
(the dynamics publishes these at every step).
"""

from __future__ import annotations

import math
import struct
from typing import NamedTuple, Sequence

import numpy as np

from wallbot_msgs_py import cdr, topics

JOINT_STATE = 'sensor_msgs/msg/JointState'
WRENCH_STAMPED = 'geometry_msgs/msg/WrenchStamped'
JOINT_FIELDS = ('position', 'velocity', 'effort')
_STAMP = struct.Struct('<iI')
_TWO = struct.Struct('<2d')
_ONE = struct.Struct('<d')


@cdr.encoder('joint_state', JOINT_STATE)
class JointStateEncoder:
    """JointState bytes of fixed ``names`` (frame ''), with a value per name in each field of ``filled``
    and the other fields empty; ``offsets[field]`` is where a field's first value is."""

    def __init__(self, names: Sequence[str], filled: Sequence[str] = JOINT_FIELDS) -> None:
        joints = cdr.Writer()
        self.stamp = joints.header(0, '')
        joints.strings(names)
        self.offsets = {field: joints.float64_sequence((0.0,) * (len(names) if field in filled else 0))
                        for field in JOINT_FIELDS}
        self.template = joints.bytes()
        self._buffer = bytearray(self.template)
        self._filled = tuple(field for field in JOINT_FIELDS if field in filled)
        self._filled_offsets = tuple(self.offsets[field] for field in self._filled)
        self._values = struct.Struct(f'<{len(names)}d')
        self._rows = cdr.Rows(self.template, cdr.stamped(
            self.stamp, **{field: (self.offsets[field], cdr.doubles(len(names))) for field in self._filled}))

    def encode(self, sec: int, nanosec: int, *values: Sequence[float]) -> bytes:
        """The message with the values of each filled field, in the order of JOINT_FIELDS."""
        data = self._buffer
        _STAMP.pack_into(data, self.stamp, sec, nanosec)
        pack = self._values.pack_into
        for offset, numbers in zip(self._filled_offsets, values):
            pack(data, offset, *numbers)
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray, *values: np.ndarray) -> list[bytes]:
        """``encode`` of each row of the filled fields' arrays (T, len(names)), the same bytes."""
        return self._rows.fill(len(sec), sec=sec, nanosec=nanosec, **dict(zip(self._filled, values)))


class JointArrays(NamedTuple):
    """A JointState's stamp, names and values (under the message's field names)."""

    stamp_ns: int
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]

    def values(self, names: Sequence[str], field: str) -> tuple[float, ...]:
        """``field`` (position, velocity or effort) for ``names`` in that order (NaN where absent)."""
        values = getattr(self, field)
        if self.name == tuple(names) and len(values) == len(names):  # as the graph publishes them
            return values
        index = {name: i for i, name in enumerate(self.name)}
        return tuple(float(values[index[n]]) if n in index and index[n] < len(values) else math.nan for n in names)


@cdr.decoder('joint_state', JOINT_STATE)
def decode_joint_state(message: cdr.Reader) -> JointArrays:
    """The stamp, names and values of a serialized JointState (its frame is not used)."""
    return _joint_arrays(message)


def _joint_arrays(message: cdr.Reader) -> JointArrays:
    stamp_ns, _frame = message.header()
    return JointArrays(stamp_ns, message.strings(), message.float64_sequence(), message.float64_sequence(),
                       message.float64_sequence())


# --- wheel_contact -------------------------------------------------------------------------------
CONTACT_NAMES = (topics.WHEEL_JOINTS + tuple(f'{wheel}/x' for wheel in topics.WHEEL_JOINTS)
                 + tuple(f'{wheel}/y' for wheel in topics.WHEEL_JOINTS))
"""The names of a ``wheel_contact`` message: the wheels, then each wheel's x_p direction, then its y_p direction."""
_WHEELS = len(topics.WHEEL_JOINTS)
_PER_WHEEL = struct.Struct(f'<{_WHEELS}d')
_PER_DIRECTION = struct.Struct(f'<{2 * _WHEELS}d')


class WheelContact(NamedTuple):
    """What a ``wheel_contact`` message says (topics.WHEEL_CONTACT), each field per wheel in the order of
    topics.WHEEL_JOINTS."""

    stamp_ns: int
    loads: tuple[float, ...]
    """Normal load N_i (N)."""
    use: tuple[float, ...]
    """Friction use |f_i| / (mu_s N_i)."""
    slipping: tuple[float, ...]
    """1.0 for a sliding wheel, 0.0 for a sticking one."""
    force_x: tuple[float, ...]
    """The wall's tangential force on the robot at the wheel along the body axis x_p (N)."""
    force_y: tuple[float, ...]
    """The same along y_p (N)."""
    velocity_x: tuple[float, ...]
    """The wheel's contact-point velocity on the wall along x_p (m/s): its slip where it slides."""
    velocity_y: tuple[float, ...]
    """The same along y_p (m/s)."""


@cdr.encoder('wheel_contact', JOINT_STATE)
class WheelContactEncoder:
    """``wheel_contact`` bytes (CONTACT_NAMES): per wheel, the use as position, 1/0 for sliding as velocity and
    the normal load as effort; per wheel and body axis, the contact-point velocity as velocity and the wall's
    force as effort (their positions 0)."""

    def __init__(self) -> None:
        joints = JointStateEncoder(CONTACT_NAMES)
        position, velocity, effort = (joints.offsets[field] for field in JOINT_FIELDS)
        per_wheel = 8 * _WHEELS
        self.template, self._stamp = joints.template, joints.stamp
        self._buffer = bytearray(self.template)
        self._use, self._slipping, self._loads = position, velocity, effort
        self._velocities, self._forces = velocity + per_wheel, effort + per_wheel
        self._rows = cdr.Rows(self.template, cdr.stamped(
            self._stamp, use=(self._use, cdr.doubles(_WHEELS)), slipping=(self._slipping, cdr.doubles(_WHEELS)),
            velocities=(self._velocities, cdr.doubles(2 * _WHEELS)), loads=(self._loads, cdr.doubles(_WHEELS)),
            forces=(self._forces, cdr.doubles(2 * _WHEELS))))

    def encode(self, sec: int, nanosec: int, loads: Sequence[float], use: Sequence[float],
               slipping: Sequence[bool], forces: np.ndarray, velocities: np.ndarray) -> bytes:
        """``forces`` and ``velocities``: (4, 2), each wheel's (x_p, y_p) components."""
        data = self._buffer
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        _PER_WHEEL.pack_into(data, self._use, *use)
        _PER_WHEEL.pack_into(data, self._slipping, *(float(flag) for flag in slipping))
        _PER_WHEEL.pack_into(data, self._loads, *loads)
        _PER_DIRECTION.pack_into(data, self._velocities, *velocities.T.ravel().tolist())
        _PER_DIRECTION.pack_into(data, self._forces, *forces.T.ravel().tolist())
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray, loads: np.ndarray, use: np.ndarray,
                    slipping: np.ndarray, forces: np.ndarray, velocities: np.ndarray) -> list[bytes]:
        """``encode`` of each row (loads, use, slipping (T, 4); forces, velocities (T, 4, 2)), the same bytes."""
        count = len(sec)
        return self._rows.fill(count, sec=sec, nanosec=nanosec, loads=loads, use=use,
                               slipping=slipping.astype(float),
                               forces=forces.transpose(0, 2, 1).reshape(count, 2 * _WHEELS),
                               velocities=velocities.transpose(0, 2, 1).reshape(count, 2 * _WHEELS))


@cdr.decoder('wheel_contact', JOINT_STATE)
def decode_wheel_contact(message: cdr.Reader) -> WheelContact:
    """The contact a serialized ``wheel_contact`` carries, by name: NaN for what it lacks (a message that names
    the wheels but not their directions gives their loads only)."""
    joints = _joint_arrays(message)
    count = len(CONTACT_NAMES)
    if joints.name == CONTACT_NAMES and len(joints.position) == len(joints.velocity) == len(joints.effort) == count:
        position, velocity, effort = joints.position, joints.velocity, joints.effort
    elif all(name in joints.name for name in CONTACT_NAMES[_WHEELS:]):
        position, velocity, effort = (joints.values(CONTACT_NAMES, field) for field in JOINT_FIELDS)
    else:
        unknown = (math.nan,) * _WHEELS
        return WheelContact(joints.stamp_ns, joints.values(topics.WHEEL_JOINTS, 'effort'), *(unknown,) * 6)
    x, y = slice(_WHEELS, 2 * _WHEELS), slice(2 * _WHEELS, 3 * _WHEELS)
    return WheelContact(joints.stamp_ns, effort[:_WHEELS], position[:_WHEELS], velocity[:_WHEELS], effort[x],
                        effort[y], velocity[x], velocity[y])


# --- constraint_wrench ---------------------------------------------------------------------------
class Wrench(NamedTuple):
    """The planar part of a WrenchStamped: (F_X, F_Y) and M_Z in ``frame``."""

    stamp_ns: int
    frame: str
    fx: float
    fy: float
    mz: float


@cdr.encoder('wrench', WRENCH_STAMPED)
class WrenchEncoder:
    """WrenchStamped bytes of a planar wrench (F_X, F_Y, M_Z) in ``frame``."""

    def __init__(self, frame: str = topics.WALL_FRAME) -> None:
        wrench = cdr.Writer()
        self._stamp = wrench.header(0, frame)
        self._force = wrench.float64s((0.0,) * 3)
        self._torque_z = wrench.float64s((0.0,) * 3) + 16
        self.template = wrench.bytes()
        self._buffer = bytearray(self.template)
        self._rows = cdr.Rows(self.template, cdr.stamped(
            self._stamp, force=(self._force, cdr.doubles(2)), torque=(self._torque_z, '<f8')))

    def encode(self, sec: int, nanosec: int, fx: float, fy: float, mz: float) -> bytes:
        data = self._buffer
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        _TWO.pack_into(data, self._force, fx, fy)
        _ONE.pack_into(data, self._torque_z, mz)
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray, wrench: np.ndarray) -> list[bytes]:
        """``encode`` of each row of ``wrench`` (T, 3: F_X, F_Y, M_Z), the same bytes."""
        return self._rows.fill(len(sec), sec=sec, nanosec=nanosec, force=wrench[:, :2], torque=wrench[:, 2])


@cdr.decoder('wrench', WRENCH_STAMPED)
def decode_wrench(message: cdr.Reader) -> Wrench:
    stamp_ns, frame = message.header()
    fx, fy, _fz, _mx, _my, mz = message.float64s(6)
    return Wrench(stamp_ns, frame, fx, fy, mz)
