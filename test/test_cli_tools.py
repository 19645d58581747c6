"""info / plot / compare / bag reindex / play argument errors: output, files, one-line errors."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from cli_helpers import assert_one_line_error, wallbot
from wallbot_sim.cli.main import main as cli
from wallbot_sim.plots.figures import FIGURES


@pytest.fixture(scope='module')
def runs(tmp_path_factory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp('runs')
    out = {}
    for name, constraints in (('traj', 'none'), ('belt', 'belt')):
        bag, table = base / name, base / f'{name}.csv'
        assert cli(['simulate', '--scenario', 'circle', '--constraints', constraints, '--duration', '0.5',
                    '--bag', str(bag), '--csv', str(table), '--quiet']) == 0
        out[name], out[f'{name}_csv'] = bag, table
    return out


def test_info_lists_topics_types_counts_rates(runs):
    result = wallbot('info', runs['traj'])
    assert result.returncode == 0, result.stderr
    assert 'mcap' in result.stdout and 'Duration:  0.500 s' in result.stdout
    assert '/wallbot/odom' in result.stdout and 'nav_msgs/msg/Odometry' in result.stdout
    assert '501 msgs' in result.stdout and '1000.0 Hz' in result.stdout


@pytest.mark.parametrize('source', ['traj', 'traj_csv'])
def test_plot_writes_the_figure_set(runs, tmp_path, source):
    out = tmp_path / 'plots'
    assert cli(['plot', str(runs[source]), '--out', str(out)]) == 0
    files = sorted(out.glob('*.png'))
    assert [f.stem for f in files] == sorted(set(FIGURES) - {'machine'}) and len(files) == 9  # no motor or vacuum
    assert all(f.stat().st_size > 10_000 for f in files)


def test_compare_overlays_runs(runs, tmp_path):
    out = tmp_path / 'cmp'
    assert cli(['compare', str(runs['traj']), str(runs['belt_csv']), '--out', str(out),
                '--labels', 'trajectory,belt']) == 0
    assert sorted(p.stem for p in out.glob('*.png')) == sorted(set(FIGURES) - {'machine'})  # no motor or vacuum


def test_bad_inputs_get_one_line_errors(runs, tmp_path):
    not_a_bag = tmp_path / 'nobag'
    not_a_bag.mkdir()
    blocker = tmp_path / 'file'
    blocker.write_text('x')
    assert_one_line_error(wallbot('info', tmp_path / 'missing'), 'does not exist')
    assert_one_line_error(wallbot('info', not_a_bag), 'not a rosbag2 bag')
    for verb in ('plot', 'motors'):  # verbs that read a run take a CSV too, and say so
        assert_one_line_error(wallbot(verb, blocker), 'neither a simulate CSV (.csv) nor a rosbag2 bag')
    assert_one_line_error(wallbot('play', runs['traj'], '--rate', '-1'), 'argument --rate: must be > 0, got -1.0')
    assert_one_line_error(wallbot('play', runs['traj'], '--topics', 'no_such_topic'), 'no_such_topic')
    assert_one_line_error(wallbot('play', tmp_path / 'missing'), 'does not exist')
    assert_one_line_error(wallbot('plot', runs['traj'], '--out', blocker / 'sub'), 'output directory')
    assert_one_line_error(wallbot('simulate', '--duration', '0.1', '--bag', runs['traj']), 'exists already')
    assert_one_line_error(wallbot('bag', 'reindex', not_a_bag), 'no .mcap')
    assert_one_line_error(wallbot('compare', runs['traj']), 'at least two')


def test_missing_metadata_points_at_reindex_and_reindex_repairs(runs, tmp_path):
    import shutil
    bag = tmp_path / 'copy'
    shutil.copytree(runs['traj'], bag)
    (bag / 'metadata.yaml').unlink()
    assert_one_line_error(wallbot('info', bag), 'bag reindex')
    old_names = sorted(path.name for path in bag.glob('*.mcap'))
    result = wallbot('bag', 'reindex', bag)
    assert result.returncode == 0, result.stderr
    assert wallbot('info', bag).returncode == 0
    new_names = sorted(path.name for path in bag.iterdir())
    assert result.stdout.strip().endswith(f'{", ".join(old_names)} replaced by {", ".join(new_names)}')


def test_info_rates_each_topic_over_its_own_span(tmp_path):
    """A topic recorded over part of the bag is rated over its own span, not the bag's."""
    from wallbot_msgs_py import cdr, codec, topics
    from wallbot_sim.bag.writer import BagWriter

    def clock(ns: int) -> bytes:
        return codec.ClockEncoder().encode(*cdr.split_stamp(ns))

    bag = tmp_path / 'spans'
    writer = BagWriter(bag)
    fast = writer.add_graph_topic(topics.CLOCK, topics.NAMESPACE)
    slow = writer.add_graph_topic(topics.RECORD_PROGRESS, topics.NAMESPACE)
    for k in range(1001):  # 1 kHz over 1 s
        writer.write(fast, k * 1_000_000, clock(k * 1_000_000))
    for k in range(11):  # 100 Hz over the last 0.1 s only
        writer.write(slow, 900_000_000 + k * 10_000_000, clock(k))
    writer.close()
    result = wallbot('info', bag)
    assert result.returncode == 0, result.stderr
    lines = {line.split()[0]: line for line in result.stdout.splitlines() if line.startswith('  /')}
    assert '1000.0 Hz' in lines['/wallbot/clock'] and '1001 msgs' in lines['/wallbot/clock']
    assert '100.0 Hz' in lines['/wallbot/record_progress'] and '11 msgs' in lines['/wallbot/record_progress']


class _FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _drive(progress_stream, monkeypatch, duration: float = 10.0) -> str:
    from wallbot_sim.cli import progress as progress_module
    clock = _FakeClock()
    monkeypatch.setattr(progress_module.time, 'monotonic', clock)
    progress = progress_module.Progress(duration, progress_stream)
    for step in range(1001):  # 10 s of simulation in 10 s of wall time, updated every 10 ms
        clock.now += 0.01
        progress.update(step * 0.01)
    progress.update(10.0, force=True)
    return progress_stream.getvalue()


def test_progress_outside_a_terminal_prints_a_plain_line_every_few_seconds(monkeypatch):
    from wallbot_sim.cli.progress import LOG_PERIOD
    text = _drive(io.StringIO(), monkeypatch)
    assert '\r' not in text
    lines = text.splitlines()
    assert len(lines) == int(10.0 / LOG_PERIOD) + 1  # one per period, and the final one
    assert all(line.startswith('  t = ') and 'real-time factor' in line for line in lines)
    assert lines[-1].startswith('  t =  10.000 / 10.000 s')


def test_progress_in_a_terminal_redraws_one_line(monkeypatch):
    text = _drive(_Terminal(), monkeypatch)
    assert text.count('\n') == 1 and text.endswith('\n')
    assert text.count('\r') > 20  # redrawn a few times a second


def test_progress_of_a_run_until_stopped_shows_no_end(monkeypatch):
    lines = _drive(io.StringIO(), monkeypatch, duration=0.0).splitlines()
    assert lines[-1].startswith('  t =  10.000 s (until stopped)   real-time factor   1.00')
    assert not any(' / ' in line for line in lines)


def test_progress_after_a_reset_measures_the_factor_from_it(monkeypatch):
    """``~/reset`` sends simulation time back to 0: the line follows it, and the factor is that of the
    run since then, not a negative one over the whole."""
    from wallbot_sim.cli import progress as progress_module
    clock = _FakeClock()
    monkeypatch.setattr(progress_module.time, 'monotonic', clock)
    stream = io.StringIO()
    progress = progress_module.Progress(0.0, stream)
    for step in range(400):  # 4 s at factor 1, then a reset, then 2 s at factor 0.5
        clock.now += 0.01
        progress.update(step * 0.01 if step < 200 else (step - 200) * 0.005)
    progress.update(1.0, force=True)
    assert stream.getvalue().splitlines()[-1] == '  t =   1.000 s (until stopped)   real-time factor   0.50'
