"""The dynamics node's per-step messages as CDR bytes, encoded without ROS.

Every step publishes odom, wheel_states, constraint_wrench, drive_forces, wheel_contact, and /clock at
the dynamics' clock_rate_hz (the encoder encodes it for every step; the publisher picks). Their
strings (frames, joint names) and array lengths never change, so each message is a fixed
byte template whose numbers are overwritten in place: encoding a step costs a few
``struct.pack_into`` calls instead of filling rclpy message objects and having rclpy convert
and serialize them (measured: bench/bench_node.py, README). The bytes are what rclpy itself
serializes for the same message (XCDR1, little endian; checked by test_step_cdr.py), so the
node publishes them as serialized messages, and ``simulate --bag`` writes them unchanged with
or without a ROS install.

Field meanings (REP 103/105, as ``codec`` documents them): odom pose of the centre in the
odom frame (``wall`` by default), twist (v_long, v_lat, thd) in the base frame (``base_link``),
covariance diagonals the sensor noise's variances (zero: the exact simulated state); wheel_states position / velocity /
effort per wheel in WHEEL_JOINTS order, effort = constraint torque + motor torque;
constraint_wrench Q_c on the chassis (F_X, F_Y, M_Z) in the odom frame; drive_forces effort
(F_L, F_R, F_lat) of DRIVE_JOINTS; wheel_contact as topics.WHEEL_CONTACT says; every stamp the
simulation time.
"""

from __future__ import annotations

import math
import struct
from typing import Any, Protocol, Sequence

import numpy as np

from wallbot_msgs_py import topics


class StepState(Protocol):
    """What a step's messages carry (``wallbot_sim.model.StepOutputs`` is one): numpy arrays
    q, qd (7), wheel_torques (4), chassis_wrench (3), drive forces left, right, lateral."""

    t: float
    q: Any
    qd: Any
    wheel_torques: Any
    chassis_wrench: Any
    drive: Any


class StepRows(Protocol):
    """What the messages of consecutive steps carry, as arrays, row k the k-th step
    (``wallbot_sim.model.outputs.StepBlock`` is one): t (T,), q and qd (T, 7), wheel_torques (T, 4),
    chassis_wrench (T, 3), drive (T, 3: left, right, lateral), use (T, 3), slipping (T, 3), loads (T, 4),
    limits (T, 3)."""

    t: Any
    q: Any
    qd: Any
    wheel_torques: Any
    chassis_wrench: Any
    drive: Any
    use: Any
    slipping: Any
    loads: Any
    limits: Any


class SensedState(Protocol):
    """What a sensor reports of a step's state: q, qd (7 each) as the robot measures them."""

    q: Any
    qd: Any


ENCAPSULATION = b'\x00\x01\x00\x00'
"""CDR, little endian (what rmw_fastrtps writes)."""
NS_PER_S = 1_000_000_000

_STAMP = struct.Struct('<iI')
_TWO = struct.Struct('<2d')
_THREE = struct.Struct('<3d')
_ONE = struct.Struct('<d')


class _Template:
    """A message's bytes built field by field with CDR alignment; offsets of the fields that change."""

    def __init__(self) -> None:
        self.data = bytearray(ENCAPSULATION)

    def _align(self, size: int) -> None:
        self.data += bytes(-(len(self.data) - len(ENCAPSULATION)) % size)

    def uint32(self, value: int) -> int:
        self._align(4)
        offset = len(self.data)
        self.data += struct.pack('<I', value)
        return offset

    def stamp(self) -> int:
        """builtin_interfaces/Time (int32 sec, uint32 nanosec), zero for now; its offset."""
        offset = self.uint32(0)
        self.uint32(0)
        return offset

    def string(self, text: str) -> None:
        encoded = text.encode()
        self.uint32(len(encoded) + 1)
        self.data += encoded + b'\x00'

    def strings(self, texts: tuple[str, ...]) -> None:
        self.uint32(len(texts))
        for text in texts:
            self.string(text)

    def doubles(self, count: int) -> int:
        """``count`` float64 fields (zero for now); the offset of the first."""
        if count:
            self._align(8)
        offset = len(self.data)
        self.data += bytes(8 * count)
        return offset

    def double_sequence(self, count: int) -> int:
        self.uint32(count)
        return self.doubles(count)

    def header(self, frame: str) -> int:
        """std_msgs/Header; the offset of its stamp."""
        offset = self.stamp()
        self.string(frame)
        return offset


class _OdometryTemplate:
    """nav_msgs/Odometry bytes: the pose of the centre in ``frame``, the twist in ``child``, the
    covariances' diagonals fixed (row-major 6 x 6, x y z roll pitch yaw)."""

    def __init__(self, frame: str, child: str, pose_variances: Sequence[float],
                 twist_variances: Sequence[float]) -> None:
        odom = _Template()
        self.stamp = odom.header(frame)
        odom.string(child)
        self.position = odom.doubles(3)
        self.orientation = odom.doubles(4)
        _diagonal(odom, odom.doubles(36), pose_variances)
        self.twist = odom.doubles(6)
        _diagonal(odom, odom.doubles(36), twist_variances)
        self.data = odom.data
        self._rows = _Rows(self.data, _stamped(
            self.stamp, position=(self.position, _doubles(2)), orientation=(self.orientation + 16, _doubles(2)),
            twist=(self.twist, _doubles(2)), turn=(self.twist + 40, '<f8')))

    def encode(self, sec: int, nanosec: int, q: list[float], qd: list[float]) -> bytes:
        data = self.data
        x, y, theta = q[0], q[1], q[2]
        xd, yd, thd = qd[0], qd[1], qd[2]
        c, s = math.cos(theta), math.sin(theta)
        _STAMP.pack_into(data, self.stamp, sec, nanosec)
        _TWO.pack_into(data, self.position, x, y)
        _TWO.pack_into(data, self.orientation + 16, math.sin(0.5 * theta), math.cos(0.5 * theta))
        _TWO.pack_into(data, self.twist, c * xd + s * yd, -s * xd + c * yd)
        _ONE.pack_into(data, self.twist + 40, thd)
        return bytes(data)

    def encode_rows(self, sec: np.ndarray, nanosec: np.ndarray, q: np.ndarray, qd: np.ndarray) -> list[bytes]:
        """``encode`` of each row of q, qd (T, 7), the same bytes."""
        theta = q[:, 2].tolist()
        # math's sin and cos, as encode calls them: NumPy's may differ in the last bit
        c = np.array([math.cos(angle) for angle in theta])
        s = np.array([math.sin(angle) for angle in theta])
        half = np.array([(math.sin(0.5 * angle), math.cos(0.5 * angle)) for angle in theta])
        xd, yd = qd[:, 0], qd[:, 1]
        return self._rows.fill(len(theta), sec=sec, nanosec=nanosec, position=q[:, :2], orientation=half,
                               twist=np.stack((c * xd + s * yd, -s * xd + c * yd), axis=1), turn=qd[:, 2])


class _Rows:
    """The messages of many steps from one template at once: a structured view of copies of its bytes,
    one field per number that changes (``fields``: name -> (offset, numpy format))."""

    def __init__(self, template: bytearray, fields: dict[str, tuple[int, Any]]) -> None:
        self._template = np.frombuffer(bytes(template), dtype=np.uint8)
        self._dtype = np.dtype({'names': list(fields), 'formats': [form for _offset, form in fields.values()],
                                'offsets': [offset for offset, _form in fields.values()], 'itemsize': len(template)})

    def fill(self, count: int, **values: Any) -> list[bytes]:
        """``count`` messages, field ``name`` of message k ``values[name][k]``."""
        raw = np.tile(self._template, count)
        rows = raw.view(self._dtype)
        for name, value in values.items():
            rows[name] = value
        data, size = raw.tobytes(), len(self._template)
        return [data[start:start + size] for start in range(0, count * size, size)]


def _stamped(stamp: int, **fields: tuple[int, Any]) -> dict[str, tuple[int, Any]]:
    return {'sec': (stamp, '<i4'), 'nanosec': (stamp + 4, '<u4'), **fields}


def _doubles(count: int) -> tuple[str, tuple[int]]:
    return ('<f8', (count,))


def _diagonal(template: _Template, offset: int, variances: Sequence[float]) -> None:
    for i, variance in enumerate(variances):
        _ONE.pack_into(template.data, offset + 8 * (6 * i + i), variance)


NO_VARIANCE = (0.0,) * 6
"""The covariance diagonal of an exact state: the simulation's own (ground truth, or odometry without noise)."""


class StepEncoder:
    """Encodes the messages of one step; ``encode`` returns (Topic, bytes) in publishing order.

    The order is odom, wheel_states, constraint_wrench, drive_forces, wheel_contact, then
    ground_truth/odom when it is published, /clock last (so a subscriber that has seen a clock
    stamp knows the step's other messages were sent before it).

    ``odom_frame`` and ``base_frame`` name the frames of every message that has one (odom, the
    wrench); ``pose_variances`` and ``twist_variances`` (6 each) are the odometry covariance's
    diagonal. With ``ground_truth`` the exact odometry is encoded too, as ``topics.GROUND_TRUTH_ODOM``.
    """

    def __init__(self, odom_frame: str = topics.WALL_FRAME, base_frame: str = topics.BASE_FRAME,
                 pose_variances: Sequence[float] = NO_VARIANCE, twist_variances: Sequence[float] = NO_VARIANCE,
                 ground_truth: bool = False) -> None:
        self._odom = _OdometryTemplate(odom_frame, base_frame, pose_variances, twist_variances)
        self._truth = (_OdometryTemplate(odom_frame, base_frame, NO_VARIANCE, NO_VARIANCE) if ground_truth
                       else None)

        wheels = _Template()
        self._wheels_stamp = wheels.header('')
        wheels.strings(topics.WHEEL_JOINTS)
        count = len(topics.WHEEL_JOINTS)
        self._wheels_position = wheels.double_sequence(count)
        self._wheels_velocity = wheels.double_sequence(count)
        self._wheels_effort = wheels.double_sequence(count)

        wrench = _Template()
        self._wrench_stamp = wrench.header(odom_frame)
        self._wrench_force = wrench.doubles(3)
        self._wrench_torque = wrench.doubles(3)

        drive = _Template()
        self._drive_stamp = drive.header('')
        drive.strings(topics.DRIVE_JOINTS)
        drive.double_sequence(0)
        drive.double_sequence(0)
        self._drive_effort = drive.double_sequence(len(topics.DRIVE_JOINTS))

        contact = _Template()
        self._contact_stamp = contact.header('')
        contact.strings(topics.WHEEL_JOINTS + topics.DRIVE_JOINTS)
        entries = len(topics.WHEEL_JOINTS) + len(topics.DRIVE_JOINTS)
        self._contact_position = contact.double_sequence(entries)
        self._contact_velocity = contact.double_sequence(entries)
        self._contact_effort = contact.double_sequence(entries)
        self._contact = contact.data

        clock = _Template()
        self._clock_stamp = clock.stamp()

        self._wheels, self._wrench = wheels.data, wrench.data
        self._drive, self._clock = drive.data, clock.data
        self._wheel_values = struct.Struct(f'<{count}d')
        self._rows = {
            topics.WHEEL_STATES: _Rows(wheels.data, _stamped(
                self._wheels_stamp, position=(self._wheels_position, _doubles(count)),
                velocity=(self._wheels_velocity, _doubles(count)), effort=(self._wheels_effort, _doubles(count)))),
            topics.CONSTRAINT_WRENCH: _Rows(wrench.data, _stamped(
                self._wrench_stamp, force=(self._wrench_force, _doubles(2)), torque=(self._wrench_torque + 16, '<f8'))),
            topics.DRIVE_FORCES: _Rows(drive.data, _stamped(
                self._drive_stamp, effort=(self._drive_effort, _doubles(3)))),
            topics.WHEEL_CONTACT: _Rows(contact.data, _stamped(
                self._contact_stamp, use=(self._contact_position + 32, _doubles(3)),
                slipping=(self._contact_velocity + 32, _doubles(3)), loads=(self._contact_effort, _doubles(count)),
                limits=(self._contact_effort + 32, _doubles(3)))),
            topics.CLOCK: _Rows(clock.data, _stamped(self._clock_stamp))}

    def encode(self, out: StepState, sensed: SensedState | None = None) -> list[tuple[topics.Topic, bytes]]:
        """The messages of ``out`` as CDR bytes (new bytes objects, safe to keep); odom and
        wheel_states carry ``sensed`` when given (a measurement of ``out``), else ``out``'s state."""
        sec, nanosec = divmod(round(out.t * 1e9), NS_PER_S)
        true_q, true_qd = out.q.tolist(), out.qd.tolist()
        q, qd = (sensed.q.tolist(), sensed.qd.tolist()) if sensed is not None else (true_q, true_qd)
        encoded = [(topics.ODOM, self._odom.encode(sec, nanosec, q, qd))]

        wheels, values = self._wheels, self._wheel_values
        _STAMP.pack_into(wheels, self._wheels_stamp, sec, nanosec)
        values.pack_into(wheels, self._wheels_position, *q[3:])
        values.pack_into(wheels, self._wheels_velocity, *qd[3:])
        values.pack_into(wheels, self._wheels_effort, *out.wheel_torques.tolist())

        wrench = self._wrench
        fx, fy, mz = out.chassis_wrench.tolist()
        _STAMP.pack_into(wrench, self._wrench_stamp, sec, nanosec)
        _TWO.pack_into(wrench, self._wrench_force, fx, fy)
        _ONE.pack_into(wrench, self._wrench_torque + 16, mz)

        drive = self._drive
        _STAMP.pack_into(drive, self._drive_stamp, sec, nanosec)
        _THREE.pack_into(drive, self._drive_effort, out.drive.left, out.drive.right, out.drive.lateral)

        contact, state = self._contact, out.contact
        _STAMP.pack_into(contact, self._contact_stamp, sec, nanosec)
        _THREE.pack_into(contact, self._contact_position + 32, *state.use)
        _THREE.pack_into(contact, self._contact_velocity + 32, *(float(flag) for flag in state.slipping))
        values.pack_into(contact, self._contact_effort, *state.loads.tolist())
        _THREE.pack_into(contact, self._contact_effort + 32, *state.limits)

        _STAMP.pack_into(self._clock, self._clock_stamp, sec, nanosec)
        encoded += [(topics.WHEEL_STATES, bytes(wheels)), (topics.CONSTRAINT_WRENCH, bytes(wrench)),
                    (topics.DRIVE_FORCES, bytes(drive)), (topics.WHEEL_CONTACT, bytes(contact))]
        if self._truth is not None:
            encoded.append((topics.GROUND_TRUTH_ODOM, self._truth.encode(sec, nanosec, true_q, true_qd)))
        encoded.append((topics.CLOCK, bytes(self._clock)))
        return encoded

    def encode_rows(self, rows: StepRows) -> list[list[tuple[topics.Topic, bytes]]]:
        """``encode`` of consecutive steps without sensed states at once: for each row, the same bytes
        in the same order (a few array assignments per topic instead of a dozen pack_into per step)."""
        stamps = np.array([round(t * 1e9) for t in rows.t.tolist()], dtype=np.int64)
        sec, nanosec = stamps // NS_PER_S, stamps % NS_PER_S
        count, q, qd = len(stamps), rows.q, rows.qd
        wrench, by_topic = rows.chassis_wrench, self._rows
        columns = [
            (topics.ODOM, self._odom.encode_rows(sec, nanosec, q, qd)),
            (topics.WHEEL_STATES, by_topic[topics.WHEEL_STATES].fill(
                count, sec=sec, nanosec=nanosec, position=q[:, 3:], velocity=qd[:, 3:], effort=rows.wheel_torques)),
            (topics.CONSTRAINT_WRENCH, by_topic[topics.CONSTRAINT_WRENCH].fill(
                count, sec=sec, nanosec=nanosec, force=wrench[:, :2], torque=wrench[:, 2])),
            (topics.DRIVE_FORCES, by_topic[topics.DRIVE_FORCES].fill(count, sec=sec, nanosec=nanosec,
                                                                     effort=rows.drive)),
            (topics.WHEEL_CONTACT, by_topic[topics.WHEEL_CONTACT].fill(
                count, sec=sec, nanosec=nanosec, use=rows.use, slipping=rows.slipping.astype(float),
                loads=rows.loads, limits=rows.limits))]
        if self._truth is not None:
            columns.append((topics.GROUND_TRUTH_ODOM, self._truth.encode_rows(sec, nanosec, q, qd)))
        columns.append((topics.CLOCK, by_topic[topics.CLOCK].fill(count, sec=sec, nanosec=nanosec)))
        names = [topic for topic, _messages in columns]
        return [list(zip(names, step)) for step in zip(*(messages for _topic, messages in columns))]
