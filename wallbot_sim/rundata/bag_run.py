"""A run's data from a recorded bag.

Odometry stamps define the time base, and the state is the simulated one: ``ground_truth/odom``
when the bag has it (a run with sensor noise), with the noisy ``odom`` kept as ``RunData.sensed``;
wheel states, constraint wrench and drive forces are matched by header stamp (NaN where a stamp has no message); the
reference at those stamps is the recorded plan (``reference_trajectory``, quintic Hermite as the dynamics node
follows it) when present, else the ``reference`` topic (exact stamps, or linear interpolation between them). The
residual comes from ``/diagnostics`` (key ``topics.DIAGNOSTIC_RESIDUAL_MAX``: the largest residual
of every step since the previous diagnostics message), NaN at the other stamps: of the dynamics in
the odometry's namespace only (``/diagnostics`` is one topic for every robot of a domain); the residual after the
start likewise (key ``topics.DIAGNOSTIC_RESIDUAL_SETTLED``). A robot file's motor block (its diagnostics' motor
entries) gives the side torques applied, r F_side plus the side's wheels' efforts (``side_motor_torques``, r from
``robot_description``), and commanded, ``wheel_torque_cmd`` at the simulation time of the newest odometry the bag
logged at or before it (``command_stamps``: a recorder logs a command at its receive time). When simulation time
jumps back on a topic (the dynamics node was reset or restarted), only what follows the last jump is kept: a bag may
hold several runs, and the figures show the last one (``RunData.restarts`` counts the jumps).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from wallbot_msgs_py import codec, topics
from wallbot_sim.model.vacuum import ATMOSPHERE
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.rundata.run_data import RunData


class _LastRun(dict):
    """Messages by header stamp, forgetting everything earlier when the stamp jumps back."""

    def __init__(self) -> None:
        super().__init__()
        self.latest = -1
        self.restarts = 0

    def put(self, stamp: int, value: object) -> None:
        if stamp < self.latest:
            self.clear()
            self.restarts += 1
        self.latest = stamp
        self[stamp] = value


LEAVES = ('odom', 'wheel_states', 'constraint_wrench', 'drive_forces', 'wheel_contact', 'reference', 'reference_path',
          'reference_trajectory', 'diagnostics', 'chamber_pressure', 'wheel_torque_cmd', 'robot_description')
"""The topics a run is read from, by their last name component; ``ground_truth`` is ground_truth/odom."""


def bag_topics(bag: Any) -> dict[str, str]:
    """The bag topic of each leaf of LEAVES (and ``ground_truth`` when it has messages); RunDataError
    without odometry."""
    truth_suffix = f'/{topics.GROUND_TRUTH_ODOM.name}'
    by_leaf = {t.name.rsplit('/', 1)[-1]: t.name for t in bag.topics if not t.name.endswith(truth_suffix)}
    found = {leaf: by_leaf[leaf] for leaf in LEAVES if leaf in by_leaf}
    truth = next((t.name for t in bag.topics if t.name.endswith(truth_suffix) and t.count), None)
    if truth is not None:
        found['ground_truth'] = truth
    if 'odom' not in found:
        raise RunDataError(f'{bag.path} has no odom topic: not a wallbot run')
    return found


def namespace_of(topic: str) -> str:
    """The namespace of a bag topic, e.g. /wallbot of /wallbot/odom."""
    return topic.rsplit('/', 1)[0] or '/'


def simulation_values(data: bytes, namespace: str) -> tuple[int, dict[str, str]]:
    """(stamp, values) of a ``/diagnostics`` message: the values of the dynamics' status in ``namespace`` (empty
    when the message has none)."""
    diagnostics = codec.decode_diagnostics(data)
    status = codec.simulation_status(diagnostics.statuses, namespace)
    return diagnostics.stamp_ns, {} if status is None else status.value_map()


def residual_max(data: bytes, namespace: str) -> tuple[int, float, float] | None:
    """(stamp, residual max, residual max after the start) of a ``/diagnostics`` message from the dynamics in
    ``namespace``, or None (the latter NaN when the message lacks it)."""
    stamp_ns, values = simulation_values(data, namespace)
    value = values.get(topics.DIAGNOSTIC_RESIDUAL_MAX)
    try:
        return None if value is None else (stamp_ns, float(value),
                                           float(values.get(topics.DIAGNOSTIC_RESIDUAL_SETTLED, math.nan)))
    except ValueError:
        return None


def _state(data: bytes) -> tuple[int, tuple[float, ...]]:
    state = codec.decode_odometry(data).planar_state()
    return state.stamp_ns, (state.t, *state[1:])


def _wheels(data: bytes) -> tuple[int, tuple[float, ...]]:
    joints = codec.decode_joint_state(data)
    return joints.stamp_ns, sum((joints.values(topics.WHEEL_JOINTS, field) for field in codec.JOINT_FIELDS), ())


def _wrench(data: bytes) -> tuple[int, tuple[float, ...]]:
    wrench = codec.decode_wrench(data)
    return wrench.stamp_ns, (wrench.fx, wrench.fy, wrench.mz)


def _drive(data: bytes) -> tuple[int, tuple[float, ...]]:
    joints = codec.decode_joint_state(data)
    return joints.stamp_ns, joints.values(topics.DRIVE_JOINTS, 'effort')


def _contact(data: bytes) -> tuple[int, tuple[float, ...]]:
    contact = codec.decode_wheel_contact(data)
    return contact.stamp_ns, (*contact.loads, *contact.use, *contact.slipping, *contact.force_x, *contact.force_y)


def _reference(data: bytes) -> tuple[int, tuple[float, ...]]:
    pose = codec.decode_odometry(data)
    return pose.stamp_ns, (pose.x, pose.y)


STAMPED_SERIES: dict[str, tuple[Callable[[bytes], tuple[int, tuple[float, ...]]], int]] = {
    'odom': (_state, 7), 'ground_truth': (_state, 7), 'wheel_states': (_wheels, 12), 'constraint_wrench': (_wrench, 3),
    'drive_forces': (_drive, 3), 'wheel_contact': (_contact, 20), 'reference': (_reference, 2)}
"""How each per-stamp topic is read: its decoder to (stamp, values), and how many values."""


def command_stamps(odom_log_ns: np.ndarray, odom_stamps_ns: np.ndarray, command_log_ns: np.ndarray) -> np.ndarray:
    """The simulation time (ns) of each command logged at ``command_log_ns``: the stamp of the newest odometry logged
    at or before it (``odom_log_ns`` ascending, with its ``odom_stamps_ns``), the state the dynamics had reached
    when the command was recorded; the first odometry's for a command logged before any."""
    newest = np.searchsorted(odom_log_ns, command_log_ns, side='right') - 1
    return odom_stamps_ns[np.maximum(newest, 0)]


class _BagSeries:
    """Everything a bag says about its last run, message by message."""

    def __init__(self, namespace: str) -> None:
        self.namespace = namespace
        self.tables = {leaf: _LastRun() for leaf in (*STAMPED_SERIES, 'diagnostics', 'chamber_pressure')}
        self.plan: dict[int, tuple] = {}
        self.path_xy: tuple[list[float], list[float]] = ([], [])
        self.odom_log: list[tuple[int, int]] = []
        """(log time, stamp) of each odometry message, in log order."""
        self.commands: list[tuple[int, tuple[float, float]]] = []
        """(log time, (tau_L, tau_R)) of each wheel_torque_cmd, in log order."""
        self.motor = False
        """Whether the dynamics' diagnostics carry a motor block's entries."""
        self.wheel_radius: float | None = None
        """r of the recorded robot_description."""

    def put(self, leaf: str, data: bytes, log_ns: int) -> None:
        if leaf in STAMPED_SERIES:
            self.tables[leaf].put(*STAMPED_SERIES[leaf][0](data))
            if leaf == 'odom':
                self.odom_log.append((log_ns, self.tables[leaf].latest))
        elif leaf == 'wheel_torque_cmd':
            self.commands.append((log_ns, codec.decode_wheel_torque_cmd(data, math.inf)))
        elif leaf == 'robot_description':
            from wallbot_sim.urdf import wheel_radius
            self.wheel_radius = wheel_radius(codec.decode_robot_description(data))
        elif leaf == 'reference_trajectory':  # later plans override earlier samples at the same time
            try:
                samples = codec.decode_plan(data)
            except ValueError:
                return
            for sample in zip(*samples):
                self.plan[codec.to_nanoseconds(sample[0])] = sample[1:]
        elif leaf == 'reference_path':
            poses = codec.decode_path(data).poses
            self.path_xy = ([x for _t, x, _y, _yaw in poses], [y for _t, _x, y, _yaw in poses])
        elif leaf == 'diagnostics':
            residual = residual_max(data, self.namespace)
            if residual is not None:
                self.tables['diagnostics'].put(residual[0], residual[1:])
            self.motor = self.motor or topics.DIAGNOSTIC_MOTOR_APPLIED.format(side='left') in simulation_values(
                data, self.namespace)[1]
        elif leaf == 'chamber_pressure':  # its own sample times (the sensor's rate), as the pressure difference
            pressure = codec.decode_fluid_pressure(data)
            self.tables[leaf].put(pressure.stamp_ns, ATMOSPHERE - pressure.pressure)


def _plan_reference(plan: dict):
    """The SampledReference of the recorded plan samples, or None."""
    if len(plan) < 2:
        return None
    from wallbot_sim.model import SampledReference
    times = sorted(plan)
    try:
        return SampledReference([k * 1e-9 for k in times], [plan[k][0] for k in times],
                                [plan[k][1] for k in times], [plan[k][2] for k in times])
    except Exception:
        return None


def load_bag_run(path: Path, label: str) -> RunData:
    from wallbot_sim.bag.reader import info, messages

    names = {topic: leaf for leaf, topic in bag_topics(info(path)).items()}
    series = _BagSeries(namespace_of(next(topic for topic, leaf in names.items() if leaf == 'odom')))
    for raw in messages(path, list(names)):
        try:
            series.put(names[raw.topic], raw.data, raw.timestamp)
        except ValueError as error:
            raise RunDataError(f'{path}: {raw.topic}: {error}') from None
    return _run_data(series, label, path)


def _run_data(series: _BagSeries, label: str, path: Path) -> RunData:
    tables = series.tables
    odom, sensed = tables['odom'], None
    if tables['ground_truth']:
        odom, sensed = tables['ground_truth'], odom
    if not odom:
        raise RunDataError(f'{path} has no odometry messages')
    stamps = sorted(odom)
    o = np.array([odom[s] for s in stamps], dtype=float)
    t = o[:, 0]

    def matched(leaf: str | _LastRun, width: int) -> np.ndarray:
        table = tables[leaf] if isinstance(leaf, str) else leaf
        nan = (math.nan,) * width
        return np.array([table.get(s, nan) for s in stamps], dtype=float).reshape(len(stamps), width)

    w, c, d, k = (matched(leaf, width) for leaf, width in (('wheel_states', 12), ('constraint_wrench', 3),
                                                          ('drive_forces', 3), ('wheel_contact', 20)))
    ref_x, ref_y = _reference_at(t, series.plan, tables['reference'], matched('reference', 2))
    return RunData(label, t, o[:, 1], o[:, 2], o[:, 3], o[:, 4], o[:, 5], o[:, 6],
                   w[:, 0:4], w[:, 4:8], w[:, 8:12], ref_x, ref_y, np.hypot(o[:, 1] - ref_x, o[:, 2] - ref_y),
                   c[:, 0], c[:, 1], c[:, 2], d[:, 0], d[:, 1], d[:, 2], *matched('diagnostics', 2).T,
                   np.array(series.path_xy[0]), np.array(series.path_xy[1]), odom.restarts,
                   loads=k[:, 0:4], use=k[:, 4:8], slip=k[:, 8:12],
                   wheel_forces=np.stack((k[:, 12:16], k[:, 16:20]), axis=2),
                   sensed=matched(sensed, 7)[:, 1:] if sensed is not None else np.empty((0, 6)),
                   machine={**_side_torques(series, t, w[:, 8:12], d[:, :2]), **_sampled(tables['chamber_pressure'], 'dp')})


def _side_torques(series: _BagSeries, t: np.ndarray, wheel_torques: np.ndarray, drive: np.ndarray
                  ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """With a motor block (and the robot's wheel radius recorded): the side torques applied at the odometry's times
    ``t``, r F_side plus the efforts of the side's wheels (``wheel_torques`` (N, 4), ``drive`` (N, 2): F_L, F_R),
    and those commanded (``command_stamps``; of the last run where the stamps jump back); else nothing."""
    if not series.motor or series.wheel_radius is None:
        return {}
    from wallbot_sim.model.outputs import DriveForces, side_motor_torques
    applied = np.array([side_motor_torques(DriveForces(left, right, 0.0), torques, series.wheel_radius)
                        for (left, right), torques in zip(drive.tolist(), wheel_torques.tolist())]).reshape(-1, 2)
    found = {'tau_L_applied': (t, applied[:, 0]), 'tau_R_applied': (t, applied[:, 1])}
    if series.commands and series.odom_log:
        odom_log, odom_stamps = (np.array(column, dtype=np.int64) for column in zip(*series.odom_log))
        stamps = command_stamps(odom_log, odom_stamps, np.array([log for log, _ in series.commands], dtype=np.int64))
        commanded = _LastRun()
        for stamp, (_log, command) in zip(stamps.tolist(), series.commands):
            commanded.put(stamp, command)
        times = np.array(list(commanded), dtype=float) * 1e-9
        values = np.array(list(commanded.values()), dtype=float).reshape(-1, 2)
        found.update(tau_L_cmd=(times, values[:, 0]), tau_R_cmd=(times, values[:, 1]))
    return found


def _sampled(table: _LastRun, name: str) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{name: (times (s), values)}`` of a series at its own sample stamps; empty without samples."""
    stamps = sorted(table)
    if not stamps:
        return {}
    return {name: (np.array(stamps, dtype=float) * 1e-9, np.array([table[s] for s in stamps], dtype=float))}


def _reference_at(t: np.ndarray, plan: dict, ref: _LastRun, exact: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The reference position at times ``t``: the recorded plan's (quintic Hermite, as the dynamics node
    followed it), else the reference poses' (exact stamps, linear in between), else NaN."""
    plan_reference = _plan_reference(plan)
    if plan_reference is not None:
        samples = [plan_reference.sample(ti).position for ti in t]
        ref_x, ref_y = (np.array(c, dtype=float) for c in zip(*samples))
        return ref_x, ref_y
    if not ref:
        return np.full(len(t), math.nan), np.full(len(t), math.nan)
    rs = sorted(ref)
    rt = np.array(rs, dtype=float) * 1e-9
    rxy = np.array([ref[s] for s in rs], dtype=float)
    return (np.where(np.isnan(exact[:, 0]), np.interp(t, rt, rxy[:, 0]), exact[:, 0]),
            np.where(np.isnan(exact[:, 1]), np.interp(t, rt, rxy[:, 1]), exact[:, 1]))
