"""Shared pytest fixtures for wallbot_sim.

* ``session_domain`` (session, autouse): claims a ROS_DOMAIN_ID for the worker's
  session and exports it (plus ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) in
  os.environ, for the module- and class-scoped fixtures.
* ``ros_domain`` (function, autouse): each test claims a ROS_DOMAIN_ID of its own and
  exports it while it runs, so every child process and in-process rclpy context is
  isolated from other tests, concurrent or earlier (a node a test killed stays in
  DDS discovery for its lease; ``wallbot_sim.domain`` chooses a just-released id last).
* ``process_runner`` (function): starts child processes with the test's environment
  (``wallbot_sim.graph.ChildProcesses``, as ``wallbot-sim run`` starts its nodes), logs their
  output to files in tmp_path and always stops them at teardown. A test that fails reports the
  end of each of its processes' logs (``pytest_runtest_makereport``), so that a failure seen once,
  in CI on a loaded machine, says what the nodes were doing.
"""
from __future__ import annotations

import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
if str(REPO_ROOT) not in sys.path:  # allow running the tests without installing
    sys.path.insert(0, str(REPO_ROOT))

from wallbot_sim.domain import DomainClaim, claim_domain_id, isolated_ros_env  # noqa: E402
from wallbot_sim.graph import ChildProcesses  # noqa: E402
from wallbot_sim.graph_monitor import temporary_environment  # noqa: E402

pytest_plugins = ('wallbot_sim.testing.plugin',)
"""The ``wallbot`` fixture, which the ``pytest11`` entry point gives a session where wallbot_sim is installed."""

_ENV_KEYS = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')
LOG_TAIL = 3000
"""Characters of each child process's log a failed test reports."""


@contextmanager
def exported_domain() -> Iterator[DomainClaim]:
    """A claimed ROS_DOMAIN_ID exported in os.environ while the block runs, the previous values restored after."""
    with claim_domain_id() as claim, temporary_environment(
            {k: v for k, v in isolated_ros_env(claim.domain_id).items() if k in _ENV_KEYS}):
        yield claim


@pytest.fixture(scope='session', autouse=True)
def session_domain() -> Iterator[DomainClaim]:
    """The worker session's ROS_DOMAIN_ID, exported: the module- and class-scoped fixtures' domain."""
    with exported_domain() as claim:
        yield claim


@pytest.fixture(autouse=True)
def ros_domain(session_domain: DomainClaim) -> Iterator[DomainClaim]:
    """The test's own ROS_DOMAIN_ID, exported while it runs."""
    with exported_domain() as claim:
        yield claim


@pytest.fixture(scope='session', autouse=True)
def test_process_heartbeat(session_domain: DomainClaim) -> None:
    """This process's writers (commands, parameter requests) send Fast DDS heartbeats as the nodes' do
    (``NODE_HEARTBEAT``), so a ``wait_for_all_acked`` or a lost request's repair takes about 0.1 s, not up
    to the default 3 s. Fast DDS reads the profile once, at the process's first participant: made here,
    before any test's, and the variable removed again so that child processes choose their own."""
    try:
        import rclpy
    except ImportError:
        return
    from wallbot_sim.heartbeat import NODE_HEARTBEAT, PROFILES_ENV, PROFILES_ENVS, install_heartbeat
    if any(os.environ.get(name) for name in PROFILES_ENVS):
        return  # the developer's own profile file
    install_heartbeat(NODE_HEARTBEAT)
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        rclpy.create_node('heartbeat_profile_loader', context=context).destroy_node()
    finally:
        rclpy.shutdown(context=context)
        os.environ.pop(PROFILES_ENV)


@pytest.fixture
def process_runner(tmp_path: Path, ros_domain: DomainClaim) -> Iterator[ChildProcesses]:
    """The product's ChildProcesses with the test's isolated ROS env and unbuffered Python
    output; logs in ``tmp_path/logs``; every process stopped at teardown."""
    runner = ChildProcesses(tmp_path / 'logs', {**isolated_ros_env(ros_domain.domain_id), 'PYTHONUNBUFFERED': '1'},
                            stop_timeout=5.0)
    try:
        yield runner
    finally:
        runner.stop_all()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item):
    report = (yield).get_result()
    runner = getattr(item, 'funcargs', {}).get('process_runner')
    if report.failed and report.when == 'call' and runner is not None:
        for log in sorted(runner.log_dir.glob('*.log')):
            report.sections.append((f'{log.stem} log (end)', log.read_text(errors='replace')[-LOG_TAIL:]))


FAST_MODULES = frozenset({
    'test_batch', 'test_batch_contact', 'test_batch_control', 'test_compiled_contact', 'test_compiled_simulation',
    'test_constraint_table', 'test_control_tracking', 'test_controller_testing', 'test_doc_examples', 'test_docs',
    'test_dynamics_loop', 'test_figures', 'test_input_files', 'test_kernel_frame', 'test_launch_description',
    'test_messages',
    'test_model_contact',
    'test_model_parameters', 'test_model_robot', 'test_model_simulation', 'test_model_solver',
    'test_model_trajectories', 'test_model_wheel_contact', 'test_pacing', 'test_peer_mujoco', 'test_resume',
    'test_sizes', 'test_step_cdr', 'test_step_tap', 'test_suite_waits', 'test_view', 'test_wheel_speed',
})
"""The model and the units (no node processes, no DDS graph): ``make test-fast``, ``pytest -m fast``."""


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line('markers', 'fast: the model and the units, no node processes (make test-fast)')
    if not hasattr(config, 'workerinput'):  # once, before any xdist worker or node process starts
        _compile_kernels()


def _compile_kernels() -> None:
    """The numba kernels compiled here, once, into numba's cache (in the checkout): a fresh clone's
    test processes would otherwise each compile them on first use, several at once, for minutes. The
    single robot's runs (every numba node and simulate) and the batch's (the batch tests, sweeps) compile
    side by side, one process each, then the sweep's screen of the rows in the first to finish."""
    from wallbot_sim.model.batch import kernel
    if not kernel.available():
        return
    from wallbot_sim.model.compiled import compile_coulomb, compile_ideal
    from wallbot_sim.sweep.screen import compile_screen
    started = time.monotonic()
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context('spawn')) as pool:
        for compiled in [pool.submit(compile_coulomb), pool.submit(compile_ideal), pool.submit(compile_screen)]:
            compiled.result()
    took = time.monotonic() - started
    if took > 5.0:
        print(f'\nnumba kernels compiled into the cache in {took:.0f} s (later runs load them)', file=sys.stderr)


SHARED_FIXTURE_MODULES = frozenset({
    'test/test_cli_motors.py', 'test/test_cli_tools.py', 'test/test_constraint_table.py', 'test/test_layering.py',
    'test/test_packaging.py', 'test/test_parameter_ranges.py', 'test/test_peer_mujoco.py', 'test/test_sweep.py',
    'test/test_sweep_reduce.py',
    'test/test_view.py',
})
"""The modules whose tests share a module-scoped fixture (a colcon build, a sweep, MuJoCo's runs): ``make test``
keeps each on one worker, which runs the fixture once."""
SHARED_FIXTURE_CLASSES = frozenset({'test/test_batch_contact.py', 'test/test_doc_examples.py',
                                    'test/test_doc_graph_examples.py'})
"""The modules whose classes each share a class-scoped fixture (a page's commands run once): one worker a class."""


def scheduling_scope(nodeid: str) -> str:
    """The tests ``make test`` keeps on one worker: a test's module or class when they share a fixture, else the
    test alone."""
    module, _, rest = nodeid.partition('::')
    if module in SHARED_FIXTURE_MODULES:
        return module
    if module in SHARED_FIXTURE_CLASSES:
        return f'{module}::{rest.partition("::")[0]}'
    return nodeid


@pytest.hookimpl(tryfirst=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):  # noqa: ANN201 (xdist's types, imported only here)
    """``--dist loadgroup`` (``make test``): each test goes to whichever worker is free, but a group of
    ``scheduling_scope`` to one worker. xdist's own loadgroup reads ``xdist_group`` marks from test ids that
    pytest 9 no longer lets it change, so it would scatter the groups."""
    if config.getvalue('dist') != 'loadgroup':
        return None
    from xdist.scheduler import LoadScopeScheduling

    class SharedFixtureScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return scheduling_scope(nodeid)

    return SharedFixtureScheduling(config, log)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    shared: dict[str, set[str]] = {}
    for item in items:
        if item.module is not None and item.module.__name__.rpartition('.')[2] in FAST_MODULES:
            item.add_marker(pytest.mark.fast)
        group = shared_fixture_group(item)
        if group is not None:
            shared.setdefault(group, set()).add(scheduling_scope(item.nodeid))
    scattered = sorted(group for group, scopes in shared.items() if len(scopes) > 1)
    if scattered:
        raise pytest.UsageError(f'the tests of {scattered[0]} share a module- or class-scoped fixture: list their '
                                'module in SHARED_FIXTURE_MODULES or SHARED_FIXTURE_CLASSES (test/conftest.py)')
    if hasattr(config, 'workerinput'):
        # Workers take the tests in this order: the node-process tests (many of them tens of seconds) first, the
        # model and units (mostly under a second) last, so that neither worker is left waiting at the end for the
        # other's last long test.
        items.sort(key=lambda item: item.get_closest_marker('fast') is not None)


def shared_fixture_group(item: pytest.Item) -> str | None:
    """The module (or class) of a test that uses a module-scoped (or class-scoped) fixture."""
    fixture_info = getattr(item, '_fixtureinfo', None)
    if fixture_info is None:
        return None
    scopes = {definitions[-1].scope for definitions in fixture_info.name2fixturedefs.values() if definitions}
    module_file = item.nodeid.partition('::')[0]
    if 'module' in scopes:
        return module_file
    cls = getattr(item, 'cls', None)
    if 'class' in scopes and cls is not None:
        return f'{module_file}::{cls.__name__}'
    return None
