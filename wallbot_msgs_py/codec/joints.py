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
_CHANNELS = struct.Struct(f'<{len(topics.DRIVE_JOINTS)}d')


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
CONTACT_NAMES = topics.WHEEL_JOINTS + topics.DRIVE_JOINTS
"""The names of a ``wheel_contact`` message: the wheels, then the friction channels."""


class WheelContact(NamedTuple):
    """What a ``wheel_contact`` message says (topics.WHEEL_CONTACT)."""

    stamp_ns: int
    loads: tuple[float, ...]
    """Normal load of each wheel (N), in the order of topics.WHEEL_JOINTS."""
    use: tuple[float, ...]
    """Friction use |F| / (mu_s N) of each channel (left, right, lateral)."""
    slipping: tuple[float, ...]
    """1.0 for a slipping channel, 0.0 for a sticking one."""
    limits: tuple[float, ...]
    """Friction limit mu_s N of each channel (N)."""


@cdr.encoder('wheel_contact', JOINT_STATE)
class WheelContactEncoder:
    """``wheel_contact`` bytes: the wheels' loads as effort; per channel, the use as position, 1/0 for
    slipping as velocity, the limit as effort (the wheels' positions and velocities 0)."""

    def __init__(self) -> None:
        joints = JointStateEncoder(CONTACT_NAMES)
        position, velocity, effort = (joints.offsets[field] for field in JOINT_FIELDS)
        wheels = 8 * len(topics.WHEEL_JOINTS)
        self.template, self._stamp = joints.template, joints.stamp
        self._buffer = bytearray(self.template)
        self._use, self._slipping = position + wheels, velocity + wheels
        self._loads, self._limits = effort, effort + wheels
        self._wheel_values = struct.Struct(f'<{len(topics.WHEEL_JOINTS)}d')
        self._rows = cdr.Rows(self.template, cdr.stamped(
            self._stamp, use=(self._use, cdr.doubles(3)), slipping=(self._slipping, cdr.doubles(3)),
            loads=(effort, cdr.doubles(len(topics.WHEEL_JOINTS))), limits=(self._limits, cdr.doubles(3))))

    def encode(self, sec: int, nanosec: int, loads: Sequence[float], use: Sequence[float],
               slipping: Sequence[bool], limits: Sequence[float]) -> bytes:
        data = self._buffer
        _STAMP.pack_into(data, self._stamp, sec, nanosec)
        _CHANNELS.pack_into(data, self._use, *use)
        left, right, lateral = slipping
        _CHANNELS.pack_into(data, self._slipping, float(left), float(right), float(lateral))
        self._wheel_values.pack_into(data, self._loads, *loads)
        _CHANNELS.pack_into(data, self._limits, *limits)
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray, loads: np.ndarray, use: np.ndarray,
                    slipping: np.ndarray, limits: np.ndarray) -> list[bytes]:
        """``encode`` of each row, the same bytes."""
        return self._rows.fill(len(sec), sec=sec, nanosec=nanosec, loads=loads, use=use,
                               slipping=slipping.astype(float), limits=limits)


@cdr.decoder('wheel_contact', JOINT_STATE)
def decode_wheel_contact(message: cdr.Reader) -> WheelContact:
    """The contact a serialized ``wheel_contact`` carries, by name (NaN for a name it lacks)."""
    joints = _joint_arrays(message)
    wheels = len(topics.WHEEL_JOINTS)
    count = len(CONTACT_NAMES)
    if joints.name == CONTACT_NAMES and len(joints.position) == len(joints.velocity) == len(joints.effort) == count:
        return WheelContact(joints.stamp_ns, joints.effort[:wheels], joints.position[wheels:],
                            joints.velocity[wheels:], joints.effort[wheels:])
    channels = topics.DRIVE_JOINTS
    return WheelContact(joints.stamp_ns, joints.values(topics.WHEEL_JOINTS, 'effort'),
                        joints.values(channels, 'position'), joints.values(channels, 'velocity'),
                        joints.values(channels, 'effort'))


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
