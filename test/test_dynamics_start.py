"""A dynamics node's start: one that cannot be made says what it waits for, then exits (a real process); the
numba engine's kernel loaded and frozen while it starts."""

from __future__ import annotations

import sys
import time

import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from wallbot_msgs_py import codec, topics  # noqa: E402
from wallbot_msgs_py.qos import qos_profile  # noqa: E402
from wallbot_sim import messages  # noqa: E402
from wallbot_sim.bag.reader import info  # noqa: E402
from wallbot_sim.control.tracking import DRIVEN  # noqa: E402
from wallbot_sim.model import BaumgarteGains  # noqa: E402


@pytest.mark.parametrize('composed', [False, True], ids=['dynamics_node', 'dynamics_recorder_node'])
def test_a_start_waiting_for_a_missing_controller_warns_then_exits_with_status_1_naming_it(process_runner, tmp_path,
                                                                                           composed):
    """wait_for_command with no controller: /diagnostics says WARN, waiting for a controller; after
    command_wait_timeout one error line names what was missing, the diagnostics turn ERROR and the
    process exits 1 (as for a start it cannot make otherwise), instead of never starting. Composed
    with its recorder, the process closes its bag on the way out."""
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('start_probe', namespace=topics.NAMESPACE, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    statuses: list[DiagnosticStatus] = []
    try:
        node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS.name,
                                 lambda msg: statuses.extend(s for s in msg.status if s.name.endswith('simulation')),
                                 qos_profile(topics.DIAGNOSTICS))
        # transient-local: the driven set reaches the dynamics whenever it comes up
        constraints = node.create_publisher(DiagnosticStatus, topics.CONSTRAINTS.name, qos_profile(topics.CONSTRAINTS))
        constraints.publish(messages.constraints_message(messages.switches_from_selection(DRIVEN),
                                                         BaumgarteGains(5.0, 5.0)))
        bag = tmp_path / 'bag'
        module, recording = ('dynamics_recorder', ['-p', f'output:={bag}']) if composed else ('dynamics', [])
        proc = process_runner.start([sys.executable, '-m', f'wallbot_sim.nodes.{module}', '--ros-args',
                                     '-p', 'wait_for_command:=true', '-p', 'command_wait_timeout:=3.0',
                                     '-p', 'resume_wait:=0.0', *recording], 'dynamics')
        deadline = time.monotonic() + 60.0
        while proc.poll() is None:
            assert time.monotonic() < deadline, f'still running:\n{process_runner.output("dynamics")}'
            executor.spin_once(timeout_sec=0.05)
        output = process_runner.output('dynamics')
        assert proc.returncode == 1, output
        errors = [line for line in output.splitlines() if 'ERROR' in line or 'error' in line.lower()]
        assert len(errors) == 1, output
        assert ('no controller (a wheel_torque_cmd publisher subscribing odom, matched both ways) within '
                'command_wait_timeout 3 s (wall) with wait_for_command set' in errors[0])
        # the node waited for its last diagnostics to be acknowledged: they are here, maybe not taken yet
        deadline = time.monotonic() + 10.0
        while not (statuses and statuses[-1].level == level('error')) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        waiting = [s for s in statuses if s.message.startswith('waiting for a controller')]
        assert waiting and all(s.level == level('warn') for s in waiting)
        assert 'giving up after 3 s (command_wait_timeout)' in waiting[-1].message
        assert statuses[-1].level == level('error') and statuses[-1].message.startswith('gave up: no controller')
        if composed:
            assert 'Traceback' not in output
            assert info(bag).message_count > 0  # closed: its metadata and summary written (diagnostics, constraints)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def level(name: str) -> bytes:
    """A diagnostic level as rclpy gives a received DiagnosticStatus's (a byte)."""
    return bytes([codec.LEVELS[name]])


FROZEN_KERNEL_PROBE = '''
import gc, sys, time
import rclpy
from rclpy.parameter import Parameter
from wallbot_sim.loop.status import RunState
from wallbot_sim.model.batch import kernel
from wallbot_sim.nodes.dynamics import started_node
context = rclpy.Context()
rclpy.init(context=context)
contact = sys.argv[1]
node = started_node(context=context, parameter_overrides=[Parameter('engine', value='numba'),
                                                          Parameter('contact_model', value=contact)])
run = kernel.robot_run
deadline = time.monotonic() + 100
while not (run.overloads and node.loop.status.state is not RunState.LOADING_KERNEL):  # loaded by the loop thread
    assert time.monotonic() < deadline, 'the kernel did not load'
    time.sleep(0.01)
loaded = list(run.overloads.values())
tracked = {id(o) for o in gc.get_objects()}
print(len(loaded), sum(id(o) in tracked for o in loaded), node.loop.stepped)
'''


@pytest.mark.parametrize('contact', ['ideal', 'coulomb'])
def test_on_the_numba_engine_the_kernel_is_loaded_at_start_and_frozen_with_it(process_runner, contact):
    """Loading the kernel makes many objects; loaded by the first step, they cost the loop thread a full
    collection of 12 ms seconds later. The node's loop thread loads it before its first tick (the executor
    meanwhile discovers the graph) and freezes them (``gc.freeze``) as the start-up's: out of every
    collection's reach."""
    pytest.importorskip('numba')
    from wallbot_sim.model.compiled import compile_run
    compile_run(contact)  # numba's cache: the node loads instead of compiling for up to a minute
    proc = process_runner.start([sys.executable, '-c', FROZEN_KERNEL_PROBE, contact], 'probe')
    assert proc.wait(timeout=120) == 0, process_runner.output('probe')
    loaded, tracked, stepped = process_runner.output('probe').split()[-3:]
    assert int(loaded) >= 1 and int(tracked) == 0 and stepped == 'False', process_runner.output('probe')


def test_a_stop_is_reported_on_diagnostics_once_when_the_loop_stops():
    """The diagnostics of a stop close the run's last window of residuals, which ``wallbot-sim run`` waits for:
    the node publishes them when it sees the loop stopped, once per stop (again after a run that went on stops)."""
    from types import SimpleNamespace

    from wallbot_sim.loop.status import RunState, Status
    from wallbot_sim.nodes.dynamics import DynamicsNode
    published = []
    node = SimpleNamespace(loop=SimpleNamespace(status=Status(RunState.RUNNING)), _stop_reported=False,
                           _publish_diagnostics=lambda: published.append(str(node.loop.status)))
    looks = [RunState.RUNNING, RunState.STOPPED, RunState.STOPPED, RunState.STOPPED, RunState.RUNNING,
             RunState.STOPPED, RunState.STOPPED]
    for state in looks:
        node.loop.status = Status(state, t=1.0)
        DynamicsNode._report_stop(node)
    assert published == [str(Status(RunState.STOPPED, t=1.0))] * 2
