"""The dynamics node's per-step messages as CDR bytes, encoded without ROS.

Every step publishes odom, wheel_states, constraint_wrench, drive_forces, wheel_contact, and /clock at
the dynamics' clock_rate_hz (the encoder encodes it for every step; the publisher picks). Their
strings (frames, joint names) and array lengths never change, so each message is a copy of a fixed
byte template (``codec``'s encoder of its family) with its numbers overwritten: encoding a step costs a few
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

from typing import Any, Protocol, Sequence

import numpy as np

from wallbot_msgs_py import cdr, topics
from wallbot_msgs_py.codec import clock, joints, odometry


class StepState(Protocol):
    """What a step's messages carry (``wallbot_sim.model.StepOutputs`` is one): numpy arrays
    q, qd (7), wheel_torques (4), chassis_wrench (3), drive forces left, right, lateral, and the contact per
    wheel: contact.loads, contact.wheel_use (4), contact.wheel_slipping (4 flags), contact.wheel_forces and
    contact.slip_velocity (4, 2)."""

    t: float
    q: Any
    qd: Any
    wheel_torques: Any
    chassis_wrench: Any
    drive: Any
    contact: Any


class StepRows(Protocol):
    """What the messages of consecutive steps carry, as arrays, row k the k-th step
    (``wallbot_sim.model.outputs.StepBlock`` is one): t (T,), q and qd (T, 7), wheel_torques (T, 4),
    chassis_wrench (T, 3), drive (T, 3: left, right, lateral), and per wheel loads, wheel_use, wheel_slipping
    (T, 4), wheel_forces and slip_velocity (T, 4, 2)."""

    t: Any
    q: Any
    qd: Any
    wheel_torques: Any
    chassis_wrench: Any
    drive: Any
    loads: Any
    wheel_use: Any
    wheel_slipping: Any
    wheel_forces: Any
    slip_velocity: Any


class SensedState(Protocol):
    """What a sensor reports of a step's state: q, qd (7 each) as the robot measures them."""

    q: Any
    qd: Any


NO_VARIANCE = odometry.NO_VARIANCE


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
        self._odom = odometry.OdometryEncoder(odom_frame, base_frame, pose_variances, twist_variances)
        self._truth = odometry.OdometryEncoder(odom_frame, base_frame) if ground_truth else None
        self._wheels = joints.JointStateEncoder(topics.WHEEL_JOINTS)
        self._wrench = joints.WrenchEncoder(odom_frame)
        self._drive = joints.JointStateEncoder(topics.DRIVE_JOINTS, filled=('effort',))
        self._contact = joints.WheelContactEncoder()
        self._clock = clock.ClockEncoder()

    def encode(self, out: StepState, sensed: SensedState | None = None) -> list[tuple[topics.Topic, bytes]]:
        """The messages of ``out`` as CDR bytes (new bytes objects, safe to keep); odom and
        wheel_states carry ``sensed`` when given (a measurement of ``out``), else ``out``'s state."""
        sec, nanosec = cdr.split_stamp(round(out.t * 1e9))
        true_q, true_qd = out.q.tolist(), out.qd.tolist()
        q, qd = (sensed.q.tolist(), sensed.qd.tolist()) if sensed is not None else (true_q, true_qd)
        drive, contact = out.drive, out.contact
        encoded = [
            (topics.ODOM, self._odom.encode(sec, nanosec, q, qd)),
            (topics.WHEEL_STATES, self._wheels.encode(sec, nanosec, q[3:], qd[3:], out.wheel_torques.tolist())),
            (topics.CONSTRAINT_WRENCH, self._wrench.encode(sec, nanosec, *out.chassis_wrench.tolist())),
            (topics.DRIVE_FORCES, self._drive.encode(sec, nanosec, (drive.left, drive.right, drive.lateral))),
            (topics.WHEEL_CONTACT, self._contact.encode(sec, nanosec, contact.loads.tolist(),
                                                        contact.wheel_use.tolist(), contact.wheel_slipping,
                                                        contact.wheel_forces, contact.slip_velocity))]
        if self._truth is not None:
            encoded.append((topics.GROUND_TRUTH_ODOM, self._truth.encode(sec, nanosec, true_q, true_qd)))
        encoded.append((topics.CLOCK, self._clock.encode(sec, nanosec)))
        return encoded

    def encode_rows(self, rows: StepRows) -> list[list[tuple[topics.Topic, bytes]]]:
        """``encode`` of consecutive steps without sensed states at once: for each row, the same bytes
        in the same order (a few array assignments per topic instead of a dozen pack_into per step)."""
        stamps = np.array([round(t * 1e9) for t in rows.t.tolist()], dtype=np.int64)
        sec, nanosec = stamps // cdr.NS_PER_S, stamps % cdr.NS_PER_S
        q, qd = rows.q, rows.qd
        columns = [
            (topics.ODOM, self._odom.encode_rows(sec, nanosec, q, qd)),
            (topics.WHEEL_STATES, self._wheels.encode_rows(sec, nanosec, q[:, 3:], qd[:, 3:], rows.wheel_torques)),
            (topics.CONSTRAINT_WRENCH, self._wrench.encode_rows(sec, nanosec, rows.chassis_wrench)),
            (topics.DRIVE_FORCES, self._drive.encode_rows(sec, nanosec, rows.drive)),
            (topics.WHEEL_CONTACT, self._contact.encode_rows(sec, nanosec, rows.loads, rows.wheel_use,
                                                             rows.wheel_slipping, rows.wheel_forces,
                                                             rows.slip_velocity))]
        if self._truth is not None:
            columns.append((topics.GROUND_TRUTH_ODOM, self._truth.encode_rows(sec, nanosec, q, qd)))
        columns.append((topics.CLOCK, self._clock.encode_rows(sec, nanosec)))
        names = [topic for topic, _messages in columns]
        return [list(zip(names, step)) for step in zip(*(messages for _topic, messages in columns))]
