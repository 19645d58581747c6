"""``wallbot-sim sweep``: the spec, results.csv against single simulate runs, resumption, figures (drawn by painter
processes: as this process draws them, none outliving the command), Dask."""

from __future__ import annotations

import io
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable

import matplotlib
import numpy as np
import pytest
import yaml

import two_hosts
from cli_helpers import WALLBOT, assert_one_line_error, simulate, wallbot
from wallbot_sim.cli.sweep import SweepProgress
from wallbot_sim.config import load_robot_parameters
from wallbot_sim.model import ParameterError
from wallbot_sim.rundata import load_run, summarize
from wallbot_sim.rundata.motors import motor_report
from wallbot_sim.sweep import SweepError, parse_spec
from wallbot_sim.sweep.compute import (
    OUTPUTS, batch_supports, chunk_results, result_row, single_robot_run, tabulates)
from wallbot_sim.sweep.figures import SweepTable, write_figure
from wallbot_sim.sweep.store import read_results

BATCH_SPEC = {'scenario': 'circle', 'constraints': 'belt,non_lateral,nonslip', 'duration': 0.3,
              'grid': {'body_mass': [6.0, 12.0]}, 'vary': {'com_height': [0.03, 0.08]}, 'samples': 2, 'seed': 4,
              'chunk_size': 2}
"""Four robots on simulate's compiled blocks (ideal contact, no controller)."""
CONTROLLER_SPEC = {'scenario': 'circle', 'contact': 'coulomb', 'controller': True, 'controller_mass_scale': 1.2,
                   'duration': 0.3, 'grid': {'adhesion_force': [200.0], 'com_height': [0.05, 0.4]}, 'chunk_size': 1}
"""Two robots on the batch core under the controller: the robot file's slides a wheel and holds, the one with
the higher CoM tips off the wall at once."""
IDEAL_CONTROLLER_SPEC = {'scenario': 'circle', 'contact': 'ideal', 'controller': True, 'controller_mass_scale': 0.8,
                         'duration': 0.3, 'grid': {'adhesion_force': [100.0, 200.0]}, 'chunk_size': 2}
"""Two robots under the controller with every constraint held: the weaker adhesion's loads go negative (an ideal
run's lift-off, found in its rows)."""
ONE_CHUNK_SPEC = {**BATCH_SPEC, 'chunk_size': 4}
"""BATCH_SPEC in one chunk: computed in the command's process."""
ROUND_OFF = {'max_residual': 1e-9}
"""Absolute tolerances of outputs that are round-off (the constraint residual: each engine's own round-off)."""
POLL = 0.05
DASK = Path(sys.executable).with_name('dask')
STALL = 120.0
"""Seconds after which a sweep that should have ended is stuck (not a timing requirement)."""


def write_spec(folder: Path, values: dict, name: str = 'spec.yaml') -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(values), encoding='utf-8')
    return path


def run_sweep(spec: Path, out: Path, *args: object, figures: bool = False) -> None:
    result = wallbot('sweep', spec, '--out', out, '--quiet', *args, *(() if figures else ('--no-figures',)))
    assert result.returncode == 0, result.stderr


@pytest.fixture(scope='module')
def batch_sweep(tmp_path_factory) -> Path:
    """BATCH_SPEC swept on a local cluster of two workers: its output directory."""
    folder = tmp_path_factory.mktemp('batch_sweep')
    run_sweep(write_spec(folder, BATCH_SPEC), folder / 'out', '--workers', 2, figures=True)
    return folder / 'out'


def expected_row(robot_values: dict, spec_values: dict, folder: Path) -> dict[str, float]:
    """What simulate and the run summary / motor analysis give for one robot alone."""
    params = load_robot_parameters().replace(**robot_values)
    robot_file = folder / 'robot.yaml'
    robot_file.write_text(yaml.safe_dump({key: list(value) if isinstance(value, tuple) else value
                                          for key, value in params.__dict__.items()}), encoding='utf-8')
    csv_path = folder / 'run.csv'
    args = ['--scenario', spec_values['scenario'], '--duration', spec_values['duration'], '--robot', robot_file,
            '--csv', csv_path, '--quiet', '--contact', spec_values.get('contact', 'ideal')]
    if 'world' in spec_values:
        args += ['--world', folder / spec_values['world']]
    if not batch_supports(parse_spec(spec_values, folder).settings):
        args += ['--engine', 'python']  # such a sweep runs robot by robot on it: the same round-off
    if spec_values.get('controller'):
        args += ['--controller', '--controller-mass-scale', spec_values['controller_mass_scale']]
    else:
        args += ['--constraints', spec_values['constraints']]
    result = simulate(*args)
    assert result.returncode in (0, 3), result.stderr  # 3: detached (a coulomb run ends there)
    summary = summarize(csv_path)
    run = load_run(csv_path)
    report = motor_report(run, params)
    contact = report.contact  # None when no step had finite friction use (a wheel off the wall at once)
    use = contact.peak_use if contact is not None else (math.nan,) * 4
    lift_off = summary.lift_off
    if result.returncode == 3:  # simulate's verdict: "detached: wheel W, normal load L N, t = T s"
        found = re.search(r'detached: wheel (\d), normal load (\S+) N, t = (\S+) s', result.stderr)
        assert found, result.stderr
        lift_off = lift_off or (float(found[3]), int(found[1]), float(found[2]))
    slipped, detached = summary.first_slip is not None, lift_off is not None
    return {'final_err': summary.final_tracking_error, 'peak_err_after_5s': summary.peak_tracking_error_after_5s,
            'peak_abs_F_left': summary.peak_drive_force_left, 'peak_abs_F_right': summary.peak_drive_force_right,
            'peak_abs_F_lateral': summary.peak_lateral_force, 'peak_motor_torque_left': report.left.peak_torque,
            'peak_motor_torque_right': report.right.peak_torque,
            'min_normal_load': min(float(np.min(run.loads)), lift_off[2] if detached else math.inf),
            **{f'max_use{wheel}': value for wheel, value in enumerate(use, 1)},
            'least_adhesion_force': report.adsorption.needed,
            'applied_adhesion_force': report.adsorption.applied, 'slipped': float(slipped),
            'detached': float(detached), 't_detached': lift_off[0] if detached else math.nan,
            'max_residual': summary.max_residual,
            'feasible': float(not slipped and not detached and all(value <= 1.0 for value in use))}


def assert_rows_match_simulate(out: Path, spec_values: dict, folder: Path, rtol: float,
                               printed: tuple[str, ...] = ()) -> None:
    """Every row against its robot's simulate run; the ``printed`` columns to simulate's 0.01 of their unit."""
    names, rows = read_results(out / 'results.csv')
    spec = parse_spec(spec_values, folder)
    assert [row[0] for row in rows] == list(range(len(spec.robots)))
    for row, robot_values in zip(rows, spec.robots):
        got = dict(zip(names, row))
        for key, value in robot_values.items():
            assert got[key] == value
        want = expected_row(robot_values, spec_values, folder)
        assert set(want) == set(OUTPUTS)
        for name in OUTPUTS:
            tolerance = dict(rel=0.0, abs=0.005) if name in printed else dict(rel=rtol, abs=ROUND_OFF.get(name, 1e-12))
            assert got[name] == pytest.approx(want[name], **tolerance, nan_ok=True), (name, robot_values)


def test_batch_rows_agree_with_single_simulate_runs(batch_sweep, tmp_path):
    assert tabulates(parse_spec(BATCH_SPEC).settings)
    assert_rows_match_simulate(batch_sweep, BATCH_SPEC, tmp_path, rtol=1e-9)


@pytest.mark.parametrize('values, slipped, detached', [(CONTROLLER_SPEC, [1.0, 1.0], [0.0, 1.0]),
                                                       (IDEAL_CONTROLLER_SPEC, [0.0, 0.0], [1.0, 0.0])])
def test_controller_rows_agree_with_simulate_runs(values, slipped, detached, tmp_path):
    """Coulomb or ideal contact under the controller, on the batch core: each row simulate's run of its robot to
    1e-9 on every column, a robot that slides and holds and one that lifts off included."""
    assert batch_supports(parse_spec(values).settings) and not tabulates(parse_spec(values).settings)
    run_sweep(write_spec(tmp_path, values), tmp_path / 'out', '--workers', 1)
    assert_rows_match_simulate(tmp_path / 'out', values, tmp_path, rtol=1e-9)
    names, rows = read_results(tmp_path / 'out' / 'results.csv')
    assert [dict(zip(names, row))['slipped'] for row in rows] == slipped
    assert [dict(zip(names, row))['detached'] for row in rows] == detached


def test_a_world_sweep_runs_robot_by_robot_as_simulate_world_runs_each_robot(tmp_path):
    """On the floor (inclination 0) the batch, which computes the vertical wall only, is left for the single-robot
    path: every row is simulate --world's run of its robot, and its loads carry the weight too (their sum is
    F_ad + m_t g, section 13.1, so the least one is above the vertical wall's)."""
    (tmp_path / 'floor.yaml').write_text('inclination: 0\n')
    values = {'scenario': 'circle', 'constraints': 'belt,non_lateral,nonslip', 'duration': 0.05,
              'grid': {'body_mass': [6.0, 12.0]}, 'world': 'floor.yaml'}
    spec_path = write_spec(tmp_path, values)
    spec = parse_spec(values, tmp_path)
    assert not batch_supports(spec.settings) and spec.settings.world is not None
    run_sweep(spec_path, tmp_path / 'out', '--workers', 1)
    assert_rows_match_simulate(tmp_path / 'out', values, tmp_path, rtol=0.0)
    names, rows = read_results(tmp_path / 'out' / 'results.csv')
    wall = expected_row({'body_mass': 12.0}, {key: value for key, value in values.items() if key != 'world'}, tmp_path)
    floor = dict(zip(names, rows[1]))
    params = load_robot_parameters().replace(body_mass=12.0)
    weight = (params.body_mass + 4 * params.wheel_mass) * params.gravity
    assert floor['min_normal_load'] > wall['min_normal_load'] + 0.2 * weight


def test_results_do_not_depend_on_workers_chunking_or_resumption(batch_sweep, tmp_path):
    spec = write_spec(tmp_path, {**BATCH_SPEC, 'chunk_size': 3})
    run_sweep(spec, tmp_path / 'rechunked', '--workers', 1)
    rechunked = (tmp_path / 'rechunked' / 'results.csv').read_text()
    names, rows = read_results(batch_sweep / 'results.csv')
    assert read_results(tmp_path / 'rechunked' / 'results.csv')[0] == names
    # other batches, other round-off: a robot's numbers do not depend on its batch beyond that
    assert np.array(read_results(tmp_path / 'rechunked' / 'results.csv')[1]) == pytest.approx(
        np.array(rows), rel=1e-12, abs=1e-15, nan_ok=True)
    chunks = sorted((tmp_path / 'rechunked' / 'chunks').glob('*.csv'))
    assert len(chunks) == 2
    kept = chunks[0].stat().st_mtime_ns
    chunks[1].unlink()
    (tmp_path / 'rechunked' / 'results.csv').unlink()
    run_sweep(spec, tmp_path / 'rechunked', '--workers', 1)
    assert chunks[0].stat().st_mtime_ns == kept  # the finished chunk was not computed again
    assert chunks[1].exists()
    assert (tmp_path / 'rechunked' / 'results.csv').read_text() == rechunked


def test_figures_show_each_output_against_each_parameter_and_the_map(batch_sweep):
    for name in ('outputs_vs_body_mass', 'outputs_vs_com_height', 'map_least_adhesion_force'):
        png = (batch_sweep / f'{name}.png').read_bytes()
        assert png.startswith(b'\x89PNG') and len(png) > 10_000


def processes_naming(text: str) -> list[int]:
    """The live processes whose command line holds ``text`` (the command and its forked painters share it)."""
    found = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode()
                state = (entry / 'stat').read_text().rsplit(')', 1)[1].split()[0]
            except OSError:  # gone meanwhile
                continue
            if text in cmdline and state != 'Z':
                found.append(int(entry.name))
    return found


def test_the_painters_draw_every_planned_figure_as_this_process_draws_it_and_end_with_the_command(tmp_path):
    out = tmp_path / 'out'
    result = wallbot('sweep', write_spec(tmp_path, ONE_CHUNK_SPEC), '--out', out)
    assert result.returncode == 0, result.stderr
    assert not processes_naming(str(out))
    names, rows = read_results(out / 'results.csv')
    table = SweepTable.of(names, rows, ['body_mass', 'com_height'])
    planned = table.files()
    assert {'outputs_vs_body_mass.png', 'outputs_vs_com_height.png', 'map_least_adhesion_force.png'} <= set(planned)
    assert sorted(path.name for path in out.glob('*.png')) == sorted(planned)
    assert f'and {len(planned)} figures' in result.stderr.splitlines()[-1]
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt

    here = tmp_path / 'here'
    here.mkdir()
    for file in planned:
        assert (out / file).read_bytes() == write_figure(plt, table, file, here).read_bytes(), file


def test_an_interrupted_sweep_ends_its_painters_and_says_one_line(tmp_path):
    """Ctrl-C reaches every process of the command (the terminal signals its process group): the command says
    'interrupted' alone, its painters print nothing and end."""
    out = tmp_path / 'out'
    # still computing when the painters are up: four robots for an hour each take minutes (a minute's took 2 s)
    spec = write_spec(tmp_path, {**ONE_CHUNK_SPEC, 'duration': 3600.0})
    sweep = subprocess.Popen([*WALLBOT, 'sweep', str(spec), '--out', str(out), '--quiet'], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + STALL
        while sweep.poll() is None and len(processes_naming(str(out))) < 2 and time.monotonic() < deadline:
            time.sleep(POLL)
        assert sweep.poll() is None and len(processes_naming(str(out))) >= 2, 'no painter started'
        os.killpg(sweep.pid, signal.SIGINT)
        _, stderr = sweep.communicate(timeout=STALL)
    finally:
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)
    assert sweep.returncode == 130, stderr
    assert stderr.strip().splitlines() == ['wallbot-sim sweep: interrupted']
    deadline = time.monotonic() + STALL
    while processes_naming(str(out)) and time.monotonic() < deadline:
        time.sleep(POLL)
    assert not processes_naming(str(out))
    assert not list((out / 'chunks').glob('*.csv')) and not list(out.glob('*.png'))


def test_another_spec_is_refused_in_a_sweep_directory(batch_sweep, tmp_path):
    spec = write_spec(tmp_path, {**BATCH_SPEC, 'seed': 5})
    assert_one_line_error(wallbot('sweep', spec, '--out', batch_sweep), 'holds another sweep')


def test_interrupted_sweep_keeps_finished_chunks_and_resumes(process_runner, tmp_path):
    values = {**CONTROLLER_SPEC, 'contact': 'ideal', 'duration': 0.5,
              'grid': {'body_mass': [6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0]}}
    spec, out = write_spec(tmp_path, values), tmp_path / 'out'
    command = [sys.executable, '-m', 'wallbot_sim.cli.main', 'sweep', spec, '--out', out, '--workers', 1,
               '--no-figures']
    sweep = process_runner.start(command, 'sweep')
    chunk_dir = out / 'chunks'
    while sweep.poll() is None and len(list(chunk_dir.glob('*.csv'))) < 1:
        time.sleep(POLL)
    assert sweep.poll() is None, process_runner.output('sweep')
    os.kill(sweep.pid, signal.SIGINT)
    assert sweep.wait(STALL) == 130, process_runner.output('sweep')
    finished = sorted(chunk_dir.glob('*.csv'))
    assert 1 <= len(finished) < 8 and not (out / 'results.csv').exists()
    assert not list(chunk_dir.glob('*.part'))
    run_sweep(spec, out, '--workers', 1)
    _names, rows = read_results(out / 'results.csv')
    assert [row[1] for row in rows] == values['grid']['body_mass']


@pytest.fixture
def lan():
    """Three hosts on one switch (network namespaces); skipped where they cannot be made."""
    reason = two_hosts.unavailable_reason()
    if reason is not None:
        pytest.skip(reason)
    with two_hosts.Lan(3) as created:
        yield created


def test_a_cluster_across_hosts_losing_a_worker_gives_the_local_result(process_runner, tmp_path, lan):
    """The scheduler and the sweep on host 0, a worker on host 1 running the chunks alone until one is done;
    then host 1's is killed with whatever of the queue it still holds and a worker on host 2 joins: those chunks
    are retried on host 2, the results equal a local run's byte for byte, and the scheduler says it lost host 1's
    worker (when it notices: that may be after the sweep ended)."""
    address = start_dask(process_runner, tmp_path, host=lan.address(0), place=lambda cmd: lan.command(0, cmd))
    assert address.startswith(f'tcp://{lan.address(0)}:')
    first = start_worker(process_runner, address, 'w1', host=lan.address(1), place=lambda cmd: lan.command(1, cmd))
    values = {**BATCH_SPEC, 'duration': 0.5, 'grid': {'body_mass': [6.0, 8.0, 10.0, 12.0]}, 'chunk_size': 1}
    spec, out = write_spec(tmp_path, values), tmp_path / 'out'
    sweep = process_runner.start(lan.command(0, [sys.executable, '-m', 'wallbot_sim.cli.main', 'sweep', spec,
                                                 '--out', out, '--scheduler', address, '--no-figures']), 'sweep')
    while sweep.poll() is None and not list((out / 'chunks').glob('*.csv')):
        time.sleep(POLL)
    assert sweep.poll() is None, process_runner.output('sweep')  # 7 of 8 chunks still to do, all on w1
    first.kill()
    second = start_worker(process_runner, address, 'w2', host=lan.address(2), place=lambda cmd: lan.command(2, cmd))
    assert sweep.wait(STALL) == 0, process_runner.output('sweep')
    assert second.poll() is None
    deadline = time.monotonic() + STALL
    while 'Remove worker' not in process_runner.output('scheduler') and time.monotonic() < deadline:
        time.sleep(POLL)
    assert 'Remove worker' in process_runner.output('scheduler')
    local = tmp_path / 'local'
    run_sweep(spec, local, '--workers', 1)
    assert (out / 'results.csv').read_text() == (local / 'results.csv').read_text()


@pytest.mark.parametrize('change, key', [
    ({'grid': {'body_mas': [6.0]}}, "'body_mas'"),
    ({'grid': {'body_mass': 6.0}}, 'grid: body_mass'),
    ({'grid': {'body_mass': [-1.0]}}, 'body_mass'),
    ({'vary': {'com_height': [0.08, 0.03]}, 'samples': 3}, 'vary: com_height'),
    ({'vary': {'com_height': [0.03, 0.08]}, 'samples': None}, 'samples'),
    ({'samples': 0, 'vary': {'com_height': [0.03, 0.08]}}, 'samples'),
    ({'contact': 'sticky'}, 'contact'),
    ({'contact': 'coulomb'}, 'contact'),
    ({'duration': -1}, 'duration'),
    ({'constraints': 'belt,wings'}, "'wings'"),
    ({'controller': True}, 'constraints'),
    ({'colour': 'red'}, "'colour'"),
    ({'seed': 'x'}, 'seed'),
    ({'grid': {'body_mass': [6.0]}, 'vary': {'body_mass': [6.0, 7.0]}, 'samples': 2}, "'body_mass'"),
])
def test_bad_spec_is_one_error_naming_the_key(change, key):
    values = {name: value for name, value in {**BATCH_SPEC, **change}.items() if value is not None}
    with pytest.raises((SweepError, ParameterError)) as error:
        parse_spec(values)
    assert key in str(error.value) and '\n' not in str(error.value)


def test_bad_spec_file_is_one_line_on_the_command_line(tmp_path):
    spec = write_spec(tmp_path, {**BATCH_SPEC, 'grid': {'wheel_count': [4]}})
    assert_one_line_error(wallbot('sweep', spec, '--out', tmp_path / 'out'), 'spec.yaml', "'wheel_count'")
    assert not (tmp_path / 'out').exists()


def test_an_unreachable_scheduler_is_one_line_and_leaves_no_output(tmp_path):
    """A port nothing listens on is refused at once, before the output directory is made (Dask's client would
    retry it for CONNECT_TIMEOUT)."""
    spec = write_spec(tmp_path, BATCH_SPEC)
    with socket.socket() as held:  # bound, never listening: connections to it are refused
        held.bind(('127.0.0.1', 0))
        address = f'tcp://127.0.0.1:{held.getsockname()[1]}'
        assert_one_line_error(wallbot('sweep', spec, '--out', tmp_path / 'out', '--quiet', '--scheduler', address),
                              f'cannot reach the Dask scheduler at {address}: Connection refused')
    assert not (tmp_path / 'out').exists()


def test_a_port_answering_otherwise_than_dask_is_one_line_and_leaves_no_output(tmp_path):
    """Dask's client may fail on anything in a handshake with a port that is no scheduler (seen: a MemoryError
    for a length it read): one line, and the output directory it made is removed."""
    spec = write_spec(tmp_path, BATCH_SPEC)
    with socket.socket() as server:
        server.bind(('127.0.0.1', 0))
        server.listen()
        address = f'tcp://127.0.0.1:{server.getsockname()[1]}'

        def answer() -> None:
            while True:  # every connection, the sweep's reachability check's and Dask's
                peer, _ = server.accept()
                peer.sendall(b'\xff' * 64)
                threading.Thread(target=peer.recv, args=(1,), daemon=True).start()  # open until the client leaves
        threading.Thread(target=answer, daemon=True).start()
        assert_one_line_error(wallbot('sweep', spec, '--out', tmp_path / 'out', '--quiet', '--scheduler', address),
                              address, 'Dask scheduler')  # which error depends on what Dask reads
    assert not (tmp_path / 'out').exists()


def test_a_single_chunk_is_computed_without_starting_a_cluster(monkeypatch):
    """One chunk is computed in this process whatever the number of workers: a local cluster (seconds to start)
    could only run it on one of them."""
    from wallbot_sim.sweep.cluster import run_chunks
    monkeypatch.setitem(sys.modules, 'dask.distributed', None)  # importing it fails
    spec = parse_spec({**BATCH_SPEC, 'chunk_size': 4, 'duration': 0.01})
    done = {}
    run_chunks(spec, [0], done.__setitem__, workers=2)
    assert list(done) == [0] and len(done[0]) == 4
    with pytest.raises(ImportError):
        run_chunks(parse_spec(BATCH_SPEC), [0, 1], done.__setitem__, workers=2)


def test_chunks_in_one_process_reuse_their_scenarios_reference_samples_and_no_other():
    """A worker's second chunk of a sweep takes the reference samples its first took (``compute._SAMPLES``), and
    its rows are those it gives sampling its own; a chunk of another scenario samples its own."""
    from wallbot_sim.sweep import compute
    figure8 = parse_spec({**BATCH_SPEC, 'scenario': 'figure8', 'duration': 0.05})
    circle = parse_spec({**BATCH_SPEC, 'duration': 0.05})
    robots = [figure8.parameters(0)], [figure8.parameters(3)]
    compute._SAMPLES.clear()
    alone = [compute.chunk_results(figure8.settings, chunk) for chunk in robots]
    compute._SAMPLES.clear()
    first = compute.chunk_results(figure8.settings, robots[0])
    kept = dict(compute._SAMPLES)
    assert kept and all(key[0] == figure8.settings.scenario.reference for key in kept)
    assert compute.chunk_results(figure8.settings, robots[1]) == alone[1] and first == alone[0]
    assert all(compute._SAMPLES[key] is sampled for key, sampled in kept.items())  # taken, not sampled again
    on_circle = compute.chunk_results(circle.settings, robots[0])
    compute._SAMPLES.clear()
    assert on_circle == compute.chunk_results(circle.settings, robots[0]) != first


def start_dask(process_runner, folder: Path, *options: object, host: str = '127.0.0.1',
               place: Callable[[list], list] = list) -> str:
    """A ``dask scheduler`` listening on ``host`` (its command through ``place``: on another host); its address."""
    scheduler_file = folder / 'scheduler.json'
    process_runner.start(place([DASK, 'scheduler', '--host', host, '--port', 0, '--no-dashboard',
                                '--scheduler-file', scheduler_file, *options]), 'scheduler')
    deadline = time.monotonic() + STALL
    while time.monotonic() < deadline:
        address = _written_address(scheduler_file)
        if address is not None:
            return address
        time.sleep(POLL)
    raise AssertionError(f'the scheduler wrote no address to {scheduler_file} in {STALL} s')


def _written_address(scheduler_file: Path) -> str | None:
    """The address in the scheduler's file once the scheduler has written it whole (it creates the file, then
    writes it: a read between the two finds it empty)."""
    try:
        return json.loads(scheduler_file.read_text())['address']
    except (FileNotFoundError, json.JSONDecodeError, KeyError):
        return None


def start_worker(process_runner, address: str, name: str, *options: object, host: str = '127.0.0.1',
                 place: Callable[[list], list] = list):
    """A single-threaded ``dask worker`` without a nanny (killing it kills the worker) listening on ``host``."""
    return process_runner.start(place([DASK, 'worker', address, '--host', host, '--nthreads', 1, '--no-nanny',
                                       '--no-dashboard', '--name', name, *options]), name)


def test_a_tls_cluster_runs_the_sweep_for_a_client_with_its_certificate(process_runner, tmp_path):
    openssl = shutil.which('openssl')
    if openssl is None:
        pytest.skip('no openssl command to make a self-signed certificate')
    cert, key = tmp_path / 'cert.pem', tmp_path / 'key.pem'
    subprocess.run([openssl, 'req', '-x509', '-newkey', 'rsa:2048', '-nodes', '-keyout', key, '-out', cert,
                    '-days', '1', '-subj', '/CN=wallbot-sweep-test', '-addext', 'basicConstraints=critical,CA:TRUE'],
                   check=True, capture_output=True)
    tls = ['--protocol', 'tls', '--tls-ca-file', cert, '--tls-cert', cert, '--tls-key', key]
    address = start_dask(process_runner, tmp_path, *tls[2:])
    start_worker(process_runner, address, 'w0', *tls[2:])
    assert address.startswith('tls://')
    security = tmp_path / 'tls.yaml'
    security.write_text(yaml.safe_dump({'tls_ca_file': str(cert), 'tls_client_cert': str(cert),
                                        'tls_client_key': str(key)}), encoding='utf-8')
    values = {**BATCH_SPEC, 'grid': {'body_mass': [6.0]}, 'samples': 1}
    spec = write_spec(tmp_path, values)
    assert_one_line_error(wallbot('sweep', spec, '--out', tmp_path / 'refused', '--quiet', '--scheduler',
                                  address.replace('tls://', 'tcp://')), 'cannot reach the Dask scheduler')
    run_sweep(spec, tmp_path / 'out', '--scheduler', address, '--security', security)
    run_sweep(spec, tmp_path / 'local', '--workers', 1)
    assert (tmp_path / 'out' / 'results.csv').read_text() == (tmp_path / 'local' / 'results.csv').read_text()


def test_progress_shows_robots_done_throughput_and_time_left():
    stream = io.StringIO()
    progress = SweepProgress(robots=10, done=2, steps=1001, stream=stream)
    progress.update(3, force=True)
    line = stream.getvalue()
    assert line.startswith('  5 / 10 robots') and line.endswith('s left\n')
    rate = float(line.split('robots')[1].split('robot-steps/s')[0].replace(',', ''))
    left = float(line.split('robot-steps/s')[1].split('s left')[0].replace(',', ''))
    assert rate > 0 and left == pytest.approx(5 * 1001 / rate, abs=1.0)  # the 5 robots to do at that rate


def test_a_robot_lifted_by_the_command_answered_at_its_last_row_counts_as_detached(tmp_path):
    """simulate exits 3 for a robot whose wheel the controller's command at 0.12 s lifts (its spin-up unloads
    the front wheels), although the CSV row of that instant (written before that command) has every load
    positive: the sweep says detached too, with that load, and not feasible."""
    spec = {**CONTROLLER_SPEC, 'grid': {'adhesion_force': [100.0], 'com_height': [0.05]}}
    run_sweep(write_spec(tmp_path, spec), tmp_path / 'out', '--workers', 1)
    names, rows = read_results(tmp_path / 'out' / 'results.csv')
    got = dict(zip(names, rows[0]))
    assert (got['detached'], got['feasible'], got['t_detached']) == (1.0, 0.0, 0.12)
    assert got['min_normal_load'] < 0.0
    # simulate (numba) prints the lifted wheel's load to 0.01 N: that column agrees to its print, the others to the
    # engines' 1e-9
    assert_rows_match_simulate(tmp_path / 'out', spec, tmp_path, rtol=1e-9, printed=('min_normal_load',))
    # the single-robot model's lift-off (python engine, its DetachedError) to 1e-9, that load included
    params = load_robot_parameters().replace(adhesion_force=100.0, com_height=0.05)
    alone = result_row(single_robot_run(parse_spec(spec).settings, params), params)
    assert chunk_results(parse_spec(spec).settings, [params])[0] == pytest.approx(alone, rel=1e-9, abs=1e-9,
                                                                                 nan_ok=True)
