"""Robustness: random parameter values and malformed torque commands against the real node processes.

For a bounded time the test sends the dynamics and trajectory nodes random parameter sets through
the SetParameters service (wrong types, NaN, inf, negative, huge, empty strings, unknown shapes
and names, arrays, unset values) and malformed ``wheel_torque_cmd`` messages (wrong lengths,
NaN, inf, huge, empty) while a recorder records every published step. Then it checks:

* no node crashed: the processes are alive and, once sane values are restored (valid random values
  may legitimately have been accepted: a huge real_time_factor, publish_every 10^6, stop_at 0.01,
  a radius of 10^300...), the dynamics publishes odometry again and the trajectory its reference;
* nothing non-finite was ever published on odom, wheel_states, constraint_wrench, drive_forces or
  /clock (every recorded message decoded and checked);
* every refused parameter came back with successful = false and a non-empty reason;
* no rejected command was ever integrated (in driven mode the applied torque, recovered from
  wheel_states + drive_forces with side_motor_torques, is always 0 or a valid command sent), and
  every rejected command falls within a logged rejection: the node's warning is throttled to one
  line per second, so the test checks that each rejected command was sent at most 1 s after a
  'rejected' log line (or before the next one), not one line per command.

Phase A: driven mode (trajectory task off) - commands + parameters of both nodes, max_wheel_torque
held at 5 N m so 'huge' commands are rejected by definition. Phase B: trajectory task on -
parameters of both nodes, max_wheel_torque included. FUZZ_SEED / FUZZ_SECONDS override the seed
and the total time.
"""

from __future__ import annotations

import math
import os
import random
import re
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from std_msgs.msg import Float64MultiArray, MultiArrayDimension  # noqa: E402
from rclpy.parameter import parameter_value_to_python  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from graph_helpers import STALL, Graph, ns, start_graph  # noqa: E402
from wallbot_msgs_py import bagio, topics  # noqa: E402
from wallbot_sim.bag.reader import info, messages  # noqa: E402
from wallbot_sim.model.outputs import DriveForces, side_motor_torques  # noqa: E402

SEED = int(os.environ.get('FUZZ_SEED', '20250605'))
SECONDS = float(os.environ.get('FUZZ_SECONDS', '24'))
MAX_TORQUE = 5.0

DYNAMICS_DEFAULTS = {  # the order restores cleanly whatever the fuzz left
    'real_time_factor': 1.0, 'rate_hz': 1000, 'publish_every': 1, 'command_timeout': 0.5,
    'max_wheel_torque': MAX_TORQUE, 'stop_at': 0.0, 'backpressure_window': 200, 'initial_x': 0.8,
    'initial_y': 0.0, 'initial_theta': 0.0, 'initial_at_rest': True, 'use_sim_time': False}
TRAJECTORY_DEFAULTS = {
    'use_sim_time': True, 'shape': 'circle', 'radius': 1.0, 'amplitude': 1.0, 'period': 20.0, 'center_x': 0.0,
    'center_y': 0.0, 'duration': 0.0, 'stop_time': 2.0, 'publish_rate_hz': 100.0, 'horizon': 10.0,
    'sample_dt': 0.05}
EXTRA_NAMES = ('robot_file', 'wait_for_recorder', 'engine', 'no_such_parameter', 'shape ', 'radius.x', 'qos_overrides')
STEP_TOPICS = ('odom', 'wheel_states', 'constraint_wrench', 'drive_forces', 'clock')
LOG_LINE = re.compile(r'\[(?:WARN|WARNING)\] \[(\d+\.\d+)\] \[[^\]]*\]: rejected')


# --- random inputs ------------------------------------------------------------------------------
def random_double(rng: random.Random) -> float:
    return rng.choice([math.nan, math.inf, -math.inf, 0.0, -0.0, -1.0, 1e308, -1e308, 5e-324, 1e-300,
                       1e300, rng.uniform(-10, 10), rng.uniform(0, 2), 10 ** rng.uniform(-8, 8),
                       -10 ** rng.uniform(-8, 8)])


def random_integer(rng: random.Random) -> int:
    return rng.choice([0, 1, -1, 2, 10, 1000, 100000, 100001, 2 ** 31, -2 ** 31, 2 ** 63 - 1, -2 ** 63,
                       rng.randint(-10 ** 6, 10 ** 6), rng.randint(1, 5000)])


def random_string(rng: random.Random) -> str:
    return rng.choice(['', ' ', 'circle', 'figure8', 'CIRCLE', 'figure-8', 'square', 'nan', 'inf', '1.0',
                       'true', '\x00', 'é' * 50, 'x' * 10000, '/nonexistent.yaml', '${HOME}', '[1, 2]'])


def random_value(rng: random.Random) -> ParameterValue:
    """A ParameterValue of a random type (including NOT_SET and every array type)."""
    kind = rng.choice(['double'] * 5 + ['integer'] * 3 + ['string'] * 2 + ['bool', 'not_set', 'byte_array',
                      'bool_array', 'integer_array', 'double_array', 'string_array'])
    value = ParameterValue()
    if kind == 'double':
        value.type, value.double_value = ParameterType.PARAMETER_DOUBLE, random_double(rng)
    elif kind == 'integer':
        value.type, value.integer_value = ParameterType.PARAMETER_INTEGER, random_integer(rng)
    elif kind == 'string':
        value.type, value.string_value = ParameterType.PARAMETER_STRING, random_string(rng)
    elif kind == 'bool':
        value.type, value.bool_value = ParameterType.PARAMETER_BOOL, rng.random() < 0.5
    elif kind == 'not_set':
        value.type = ParameterType.PARAMETER_NOT_SET
    elif kind == 'byte_array':
        value.type, value.byte_array_value = ParameterType.PARAMETER_BYTE_ARRAY, [bytes([rng.randrange(256)])
                                                                                 for _ in range(rng.randrange(4))]
    elif kind == 'bool_array':
        value.type, value.bool_array_value = ParameterType.PARAMETER_BOOL_ARRAY, [True] * rng.randrange(3)
    elif kind == 'integer_array':
        value.type, value.integer_array_value = ParameterType.PARAMETER_INTEGER_ARRAY, [
            random_integer(rng) for _ in range(rng.randrange(3))]
    elif kind == 'double_array':
        value.type, value.double_array_value = ParameterType.PARAMETER_DOUBLE_ARRAY, [
            random_double(rng) for _ in range(rng.randrange(3))]
    else:
        value.type, value.string_array_value = ParameterType.PARAMETER_STRING_ARRAY, [
            random_string(rng) for _ in range(rng.randrange(3))]
    return value


def random_command(rng: random.Random) -> list[float]:
    """Mostly malformed (wrong length, NaN, inf, huge, empty); about one in five valid."""
    kind = rng.randrange(10)
    if kind < 2:
        return [rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)]
    if kind == 2:
        return []
    if kind == 3:
        return [random_double(rng) for _ in range(rng.choice([1, 3, 4, 100]))]
    if kind == 4:
        return [rng.choice([math.nan, math.inf, -math.inf]), rng.uniform(-1, 1)][::rng.choice([1, -1])]
    if kind == 5:
        return [rng.choice([1e308, -1e308, 1e6, MAX_TORQUE * 1.0000001, -5.5]), 0.1][::rng.choice([1, -1])]
    return [random_double(rng), random_double(rng)]


def command_is_valid(data: list[float]) -> bool:
    return len(data) == 2 and all(math.isfinite(v) and abs(v) <= MAX_TORQUE for v in data)


def parameter_msg(name: str, value) -> ParameterMsg:
    from rclpy.parameter import Parameter
    return Parameter(name, value=value).to_parameter_msg()


# --- the test -------------------------------------------------------------------------------------
class Fuzzer:
    def __init__(self, graph: Graph, rng: random.Random) -> None:
        self.graph, self.rng = graph, rng
        self.parameter_sets = self.accepted = self.refused = 0
        self.commands_valid: list[tuple[float, float]] = []
        self.commands_rejected: list[float] = []  # wall send times
        self.clients = {node: graph.node.create_client(SetParameters, f'{graph.namespace}/{node}/set_parameters')
                        for node in ('dynamics', 'trajectory', 'constraint_config')}
        self.refusals: list[str] = []
        self.journal: list[str] = []
        self.current = {'dynamics': dict(DYNAMICS_DEFAULTS), 'trajectory': dict(TRAJECTORY_DEFAULTS)}

    def recent(self) -> str:
        return 'last inputs:\n  ' + '\n  '.join(self.journal[-8:])

    def set_parameters(self, node: str, params: list[ParameterMsg], timeout: float = 5.0):
        client = self.clients[node]
        assert client.wait_for_service(timeout_sec=timeout), f'{node}/set_parameters is gone'
        self.journal.append(f'{time.time():.3f} {node}: ' + ', '.join(
            f'{p.name} = {parameter_value_to_python(p.value)!r}'[:120] for p in params))
        future = client.call_async(SetParameters.Request(parameters=params))
        self.graph.wait_for(future.done, timeout, f'response of {node}/set_parameters; {self.recent()}')
        results = future.result().results
        assert len(results) == len(params)
        return results

    def fuzz_parameters(self, node: str, names: list[str]) -> None:
        count = self.rng.choice([1, 1, 1, 2, 3])
        params = [ParameterMsg(name=self.rng.choice(names + list(EXTRA_NAMES)), value=random_value(self.rng))
                  for _ in range(count)]
        for param, result in zip(params, self.set_parameters(node, params)):
            self.parameter_sets += 1
            if result.successful:
                self.accepted += 1
                if param.name in self.current[node]:
                    self.current[node][param.name] = parameter_value_to_python(param.value)
            else:
                self.refused += 1
                assert result.reason.strip(), f'{node} refused {param.name} = {param.value} without a reason'
                self.refusals.append(result.reason)

    def send_command(self) -> None:
        data = random_command(self.rng)
        msg = Float64MultiArray(data=data)
        if self.rng.random() < 0.2:  # a layout that does not describe the data
            msg.layout.dim = [MultiArrayDimension(label='junk' * self.rng.randrange(5), size=self.rng.randrange(2 ** 32),
                                                  stride=self.rng.randrange(2 ** 32))]
            msg.layout.data_offset = self.rng.randrange(2 ** 32)
        self.graph.torque_pub.publish(msg)
        if command_is_valid(data):
            self.commands_valid.append((float(data[0]), float(data[1])))
        else:
            self.commands_rejected.append(time.time())


def restore(fuzzer: Fuzzer) -> None:
    # plan length first (horizon >= 10 sample_dt must hold at every step), then the rest
    first = ('sample_dt', 'horizon') if fuzzer.current['trajectory']['horizon'] >= 0.5 else ('horizon', 'sample_dt')
    trajectory = {**{k: TRAJECTORY_DEFAULTS[k] for k in first}, **TRAJECTORY_DEFAULTS}
    for node, defaults in (('trajectory', trajectory), ('dynamics', DYNAMICS_DEFAULTS)):
        for name, value in defaults.items():  # one by one: each must be accepted
            if name == 'use_sim_time':  # read-only on both (each keeps its clock): the fuzz could not change it
                continue
            result = fuzzer.set_parameters(node, [parameter_msg(name, value)])[0]
            assert result.successful, f'restoring {node} {name} = {value} refused: {result.reason}'


def check_recorded(bag, phase_a_end_ns: int,  # wall clock (the recorder's receive time)
                   valid_commands: list[tuple[float, float]], wheel_radius: float):
    """Every recorded step message finite; in phase A every applied torque is 0 or a valid command."""
    names = {t.name.rsplit('/', 1)[-1]: t.name for t in info(bag).topics}
    wanted = {names[leaf]: leaf for leaf in STEP_TOPICS if leaf in names}
    assert set(wanted.values()) == set(STEP_TOPICS), f'recorded topics: {sorted(names)}'
    counts = dict.fromkeys(STEP_TOPICS, 0)
    wheels, drive, odom_stamps = {}, {}, []
    for raw in messages(bag, list(wanted)):
        leaf = wanted[raw.topic]
        msg = bagio.deserialize(raw.data, raw.type)
        counts[leaf] += 1
        if leaf == 'odom':
            odom_stamps.append(ns(msg))
            p, tw = msg.pose.pose, msg.twist.twist
            values = [p.position.x, p.position.y, p.position.z, p.orientation.x, p.orientation.y, p.orientation.z,
                      p.orientation.w, tw.linear.x, tw.linear.y, tw.linear.z, tw.angular.x, tw.angular.y,
                      tw.angular.z, *msg.pose.covariance, *msg.twist.covariance]
        elif leaf in ('wheel_states', 'drive_forces'):
            values = [*msg.position, *msg.velocity, *msg.effort]
            stamp = ns(msg)
            if raw.timestamp <= phase_a_end_ns:  # received before the switch to the trajectory task
                (wheels if leaf == 'wheel_states' else drive)[stamp] = msg
        elif leaf == 'constraint_wrench':
            f, m = msg.wrench.force, msg.wrench.torque
            values = [f.x, f.y, f.z, m.x, m.y, m.z]
        else:
            values = [msg.clock.sec + msg.clock.nanosec * 1e-9]
        assert all(math.isfinite(v) for v in values), f'non-finite {leaf} recorded: {msg}'
    after_reset = odom_stamps[max(i for i, stamp in enumerate(odom_stamps) if stamp == 0):]
    assert len(after_reset) > 1000 and np.all(np.diff(after_reset) == 1_000_000), \
        'consecutive 1 ms odometry steps recorded after the restore and reset'
    allowed = np.array([(0.0, 0.0)] + valid_commands)
    checked = 0
    for stamp, wheel in wheels.items():
        forces = drive.get(stamp)
        if forces is None:
            continue
        tau = side_motor_torques(DriveForces(forces.effort[0], forces.effort[1], forces.effort[2]),
                                 list(wheel.effort), wheel_radius)
        distance = np.abs(allowed - np.array(tau)).max(axis=1).min()
        assert distance < 1e-6, f'at t = {stamp * 1e-9:.3f} s the applied torque {tau} was never a valid command'
        checked += 1
    return counts, checked


def check_rejections_logged(log: str, sent: list[float]) -> int:
    """Each rejected command sent within 1 s (plus delivery slack) after a 'rejected' log line."""
    lines = sorted(float(m.group(1)) for m in LOG_LINE.finditer(log))
    assert lines, 'no rejection was logged'
    times = np.array(lines)
    for when in sent:
        # the throttle logs the first rejection of each >= 1 s window: a line at most 1 s before
        # this send, or the line this send itself produced (up to 3 s delivery slack under load)
        near = times[(times > when - 1.1) & (times < when + 3.0)]
        assert near.size, f'a command rejected at {when:.3f} has no rejection log line within 1 s'
    return len(lines)


def test_fuzz_parameters_and_commands(process_runner, tmp_path):
    from wallbot_sim.config import load_robot_parameters
    rng = random.Random(SEED)
    bag = tmp_path / 'bag'
    recorder = process_runner.start([sys.executable, '-m', 'wallbot_sim.nodes.recorder', '--ros-args',
                                     '-p', f'output:={bag}'], 'recorder')
    graph = Graph(process_runner)
    try:
        start_graph(graph, 'real_time_factor:=1.0',
                    constraints=('trajectory_task:=false', 'belt:=true', 'non_lateral:=true', 'nonslip:=true'))
        graph.procs['recorder'] = recorder
        graph.wait_sim_time(0.3, 20)
        fuzzer = Fuzzer(graph, rng)
        dynamics_names = [n for n in DYNAMICS_DEFAULTS if n != 'max_wheel_torque']

        # phase A: driven mode, commands and parameters
        end = time.monotonic() + SECONDS / 2
        while time.monotonic() < end:
            pick = rng.random()
            if pick < 0.5:
                fuzzer.send_command()
                time.sleep(0.002)
            elif pick < 0.8:
                fuzzer.fuzz_parameters('dynamics', dynamics_names)
            else:
                fuzzer.fuzz_parameters('trajectory', list(TRAJECTORY_DEFAULTS))
        commands = len(fuzzer.commands_valid) + len(fuzzer.commands_rejected)
        phase_a_end = time.time_ns()  # commands still in flight are valid ones too: no need to wait

        # phase B: trajectory task on, parameters only (max_wheel_torque too)
        result = fuzzer.set_parameters('constraint_config', [parameter_msg('trajectory_task', True)])[0]
        assert result.successful
        end = time.monotonic() + SECONDS / 2
        while time.monotonic() < end:
            if rng.random() < 0.6:
                fuzzer.fuzz_parameters('dynamics', list(DYNAMICS_DEFAULTS))
            else:
                fuzzer.fuzz_parameters('trajectory', list(TRAJECTORY_DEFAULTS))
        for name, proc in graph.procs.items():
            assert proc.poll() is None, f'{name} died during the fuzz:\n{process_runner.output(name)[-3000:]}'

        # restore sane values: the graph must run again
        restore(fuzzer)
        graph.clear(topics.ODOM.name)
        graph.clear(topics.REFERENCE.name)
        assert graph.call(Trigger, '/wallbot/dynamics/reset', Trigger.Request()).success

        def since_reset():
            stamps = [ns(m) for m in graph.messages(topics.ODOM.name)]
            zero = max((i for i, s in enumerate(stamps) if s == 0), default=None)
            return stamps[zero:] if zero is not None and stamps[-1] >= 1_000_000_000 else None

        odom = graph.wait_for(since_reset, 20, 'odometry from t = 0 to 1 s after the restore and reset')
        # this test's subscriber may drop messages on a loaded machine; the bag (lossless) is checked
        # for consecutive 1 ms steps after the reset
        assert np.all(np.diff([s for s in odom if s <= 1_000_000_000]) > 0), 'time runs on from 0 after the reset'
        graph.wait_for(lambda: len(graph.messages(topics.REFERENCE.name)) > 10, STALL, 'reference again')
        for name, proc in graph.procs.items():
            assert proc.poll() is None, f'{name} died:\n{process_runner.output(name)[-3000:]}'
        logs = {name: process_runner.output(name) for name in ('dynamics', 'trajectory', 'constraint_config')}
        for name, log in logs.items():
            assert 'Traceback' not in log, f'{name} logged a traceback:\n{log[-3000:]}'
        for name in ('dynamics', 'trajectory', 'constraint_config'):  # publishers first: the recorder drains
            assert process_runner.stop(graph.procs[name]) == 0, f'{name} did not stop cleanly'
    finally:
        graph.close()
    process_runner.stop_timeout = 30.0
    assert process_runner.stop(recorder) == 0, process_runner.output('recorder')[-2000:]
    lines = check_rejections_logged(logs['dynamics'], fuzzer.commands_rejected)
    counts, checked = check_recorded(bag, phase_a_end, fuzzer.commands_valid,
                                     load_robot_parameters().wheel_radius)
    assert checked > 100, 'the driven phase was recorded'
    print(f'\nfuzz seed {SEED}, {SECONDS:g} s: {fuzzer.parameter_sets} parameter values '
          f'({fuzzer.accepted} accepted, {fuzzer.refused} refused with a reason), {commands} torque commands '
          f'({len(fuzzer.commands_valid)} valid, {len(fuzzer.commands_rejected)} malformed, '
          f'{lines} throttled rejection log lines); recorded and checked finite: '
          + ', '.join(f'{k} {v}' for k, v in counts.items())
          + f'; applied torque checked at {checked} driven steps')
    distinct = sorted({re.sub(r"-?[\d.]+(e[-+]?\d+)?|'[^']*'|\"[^\"]*\"", '#', r)[:90] for r in fuzzer.refusals})
    print(f'{len(distinct)} distinct refusal reasons, e.g.:\n  ' + '\n  '.join(distinct[:25]))


# --- issues the fuzz found (docs/robustness.md), fixed: they stay refused --------------------------
@pytest.mark.parametrize('changes', [{'duration': 1.0, 'stop_time': 1e300}, {'horizon': 1e300},
                                     {'sample_dt': 5e-324}, {'publish_rate_hz': 1e-300}])
def test_trajectory_refuses_endless_plans(changes):
    from wallbot_sim.nodes.trajectory import check_values
    assert check_values({**TRAJECTORY_DEFAULTS, **changes}), f'{changes} accepted'


def test_trajectory_refuses_a_period_that_overflows():
    from wallbot_sim.model.trajectories import sample_plan
    from wallbot_sim.nodes.trajectory import check_values, make_reference
    values = {**TRAJECTORY_DEFAULTS, 'period': 1e-300}
    assert check_values(values)
    sample_plan(make_reference({**values, 'period': 0.01}), 0.0, 1.0, 0.05)  # the shortest period accepted
