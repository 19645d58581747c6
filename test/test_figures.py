"""The run and sweep figures read at a glance, checked on matplotlib's Figure objects: every axis with its
unit, no panel without data, runs named by their folder, references drawn only where a run had one, legends
beside the data, compared runs' slides each in its run's colour."""

from __future__ import annotations

import re

import matplotlib
import numpy as np
import pytest

matplotlib.use('Agg', force=True)
import matplotlib.pyplot as plt  # noqa: E402

from wallbot_sim.plots.figures import FIGURES, run_figures  # noqa: E402
from wallbot_sim.rundata.csv_format import CSV_COLUMNS  # noqa: E402
from wallbot_sim.rundata.load import RunData, run_from_columns, run_label  # noqa: E402
from wallbot_sim.sweep.compute import OUTPUTS  # noqa: E402
from wallbot_sim.sweep.figures import sweep_figures  # noqa: E402

UNIT = re.compile(r'\([^()]+\)$')


def synthetic_run(label: str, reference: bool, sliding_wheel: int | None = None) -> RunData:
    """A 1 s run in CSV columns: a circle's arc with (``reference``) its reference, each wheel's use, one wheel
    sliding in the second half."""
    t = np.linspace(0.0, 1.0, 101)
    col = {name: np.zeros_like(t) for name in CSV_COLUMNS}
    col.update(t=t, x=np.cos(t), y=np.sin(t), theta=t + np.pi / 2, Fx=10 * t, Fy=-5 * t, Mz=t, F_left=t, F_right=-t)
    for wheel in range(1, 5):
        col[f'N{wheel}'] = np.full_like(t, 20.0)
        col[f'use{wheel}'] = 0.5 + 0.1 * wheel * t
    if sliding_wheel is not None:
        col[f'slip{sliding_wheel}'] = (t > 0.5).astype(float)
    if reference:
        col.update(ref_x=np.cos(t) + 0.01, ref_y=np.sin(t), err=np.full_like(t, 0.01))
    else:
        col.update(ref_x=np.full_like(t, np.nan), ref_y=np.full_like(t, np.nan), err=np.full_like(t, np.nan))
    return run_from_columns(np.column_stack([col[name] for name in CSV_COLUMNS]), label)


def with_machine(run: RunData, names: tuple[str, ...]) -> RunData:
    """``run`` with the machine series ``names`` (a motor block's applied torques, a vacuum block's dp and F_ad)."""
    shapes = {'tau_L_applied': 2.0 - run.t, 'tau_R_applied': 1.5 - run.t, 'tau_L_cmd': np.full_like(run.t, 3.0),
              'tau_R_cmd': np.full_like(run.t, -1.0), 'dp': 10000.0 - 100 * run.t, 'F_ad': 200.0 - 2 * run.t}
    run.machine = {name: (run.t, shapes[name]) for name in names}
    return run


def drawn(runs: list[RunData]) -> dict:
    figures = dict(run_figures(plt, runs, 0.1, 0.12))
    yield_figures.extend(figures.values())
    return figures


yield_figures: list = []


@pytest.fixture(autouse=True)
def close_figures():
    yield
    for fig in yield_figures:
        plt.close(fig)
    yield_figures.clear()


def data_axes(fig) -> list:
    return [ax for ax in fig.axes if ax.get_label() != '<colorbar>']


def has_data(ax) -> bool:
    lines = [line for line in ax.get_lines() if np.isfinite(np.asarray(line.get_ydata(), float)).any()
             and len(line.get_xdata()) > 1]
    return bool(lines or ax.collections)


def test_every_axis_of_a_run_figure_has_its_unit_and_data():
    for many in (False, True):
        runs = [with_machine(synthetic_run('first', True, 2), ('tau_L_applied', 'tau_R_applied', 'tau_L_cmd', 'tau_R_cmd', 'dp', 'F_ad'))]
        runs += [synthetic_run('second', True, 3)] if many else []
        for name, fig in drawn(runs).items():
            for ax in data_axes(fig):
                assert has_data(ax), f'{name}: a panel without data'
                assert UNIT.search(ax.get_ylabel()), f'{name}: y axis {ax.get_ylabel()!r} without a unit'
                if ax.get_xlabel() or ax in fig.axes[-1:]:
                    assert UNIT.search(ax.get_xlabel()), f'{name}: x axis {ax.get_xlabel()!r} without a unit'


def test_a_run_without_a_reference_has_no_tracking_error_and_lists_no_reference():
    figures = drawn([synthetic_run('rest_run', False)])
    assert 'tracking_error' not in figures
    assert list(figures) == [name for name in FIGURES if name not in ('tracking_error', 'machine')]
    for name in ('path', 'position'):
        labels = [text for ax in figures[name].axes for text in ax.get_legend_handles_labels()[1]]
        assert not any('reference' in text for text in labels), f'{name} lists a reference: {labels}'
    assert 'tracking_error' in drawn([synthetic_run('circle', True)])


def test_titles_name_the_run_by_its_folder(tmp_path):
    bag = tmp_path / 'runs' / 'first' / 'bag'
    bag.mkdir(parents=True)
    (bag / 'metadata.yaml').write_text('')
    (bag / 'bag.mcap').write_text('')
    (tmp_path / 'lone.mcap').write_text('')
    assert run_label(bag) == run_label(bag / 'bag.mcap') == 'first'
    assert run_label(tmp_path / 'runs' / 'first') == 'first'
    assert run_label(tmp_path / 'F_ad_300N.csv') == 'F_ad_300N' and run_label(tmp_path / 'lone.mcap') == 'lone'
    for name, fig in drawn([synthetic_run('first', True)]).items():
        titles = [fig.get_suptitle()] + [ax.get_title() for ax in fig.axes]
        assert any('(first)' in title for title in titles), f'{name}: {titles}'


def test_the_machine_figure_has_a_panel_for_each_series_a_run_has_and_only_for_such_runs():
    """A motor block's CSV: a torque panel a side, its applied and commanded torque; a bag with chamber_pressure
    only: the dp panel alone; a run without the blocks: no machine figure."""
    run = with_machine(synthetic_run('motor', False), ('tau_L_applied', 'tau_R_applied', 'tau_L_cmd', 'tau_R_cmd'))
    left, right = drawn([run])['machine'].axes
    for ax, side, name in ((left, 'L', 'left'), (right, 'R', 'right')):
        assert ax.get_ylabel() == f'{name} side torque (N m)'
        assert ax.get_legend_handles_labels()[1] == ['applied', 'commanded']
        applied, commanded = ax.get_lines()
        assert list(applied.get_ydata()) == list(run.machine[f'tau_{side}_applied'][1])
        assert list(commanded.get_ydata()) == list(run.machine[f'tau_{side}_cmd'][1])
        assert commanded.get_linestyle() == '--' and commanded.get_drawstyle() == 'steps-post'
    [pressure] = drawn([with_machine(synthetic_run('bag', False), ('dp',))])['machine'].axes
    assert pressure.get_ylabel() == 'chamber pressure difference dp (Pa)' and has_data(pressure)
    both = drawn([with_machine(synthetic_run('a', False), ('dp', 'F_ad')), synthetic_run('b', False)])['machine']
    assert [ax.get_ylabel() for ax in both.axes] == ['chamber pressure difference dp (Pa)', 'adhesion force F_ad (N)']
    assert 'machine' not in drawn([synthetic_run('plain', False)])


def test_legends_stand_beside_the_data():
    runs = [with_machine(synthetic_run('a', True, 1), ('tau_L_applied', 'tau_R_applied', 'tau_L_cmd', 'tau_R_cmd', 'dp', 'F_ad')),
            synthetic_run('b', True, 2)]
    for name, fig in drawn(runs).items():
        renderer = fig.canvas.get_renderer()
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is not None:
                assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer)), \
                    f'{name}: legend on the data'


def test_compared_runs_shade_their_slides_each_in_its_colour():
    runs = [synthetic_run('a', True, 1), synthetic_run('b', True, 1)]
    fig = drawn(runs)['friction_use']
    ax = fig.axes[0]  # the left front wheel
    line_colours = {line.get_label().split(':')[0]: matplotlib.colors.to_rgb(line.get_color())
                    for line in ax.get_lines() if line.get_label().endswith(': use')}
    shades = {collection.get_label().split(':')[0]: matplotlib.colors.to_rgb(collection.get_facecolor()[0])
              for collection in ax.collections if collection.get_label().endswith(': sliding')}
    assert shades == line_colours and len(set(shades.values())) == 2


def sweep_table(with_slip: bool) -> tuple[list[str], list[list[float]]]:
    names = ['robot', 'body_mass', 'com_height', *OUTPUTS]
    rows = []
    for index, (mass, height) in enumerate(((6.0, 0.03), (12.0, 0.03), (6.0, 0.08), (12.0, 0.08), (9.0, 0.05))):
        outputs = {name: mass * 10 + height for name in OUTPUTS}
        outputs.update(peak_err_after_5s=np.nan, t_detached=np.nan, feasible=float(mass < 10), slipped=0.0,
                       detached=0.0)
        rows.append([index, mass, height, *(outputs[name] for name in OUTPUTS)])
    return names, rows


def test_sweep_figures_have_units_no_empty_panels_visible_robots_and_legends_beside_the_data():
    names, rows = sweep_table(False)
    figures = dict((file, fig) for fig, file in sweep_figures(plt, names, rows, ['body_mass', 'com_height']))
    yield_figures.extend(figures.values())
    assert {'outputs_vs_body_mass.png', 'outputs_vs_com_height.png', 'map_least_adhesion_force.png'} <= set(figures)
    for file, fig in figures.items():
        renderer = fig.canvas.get_renderer()
        for ax in data_axes(fig):
            assert has_data(ax), f'{file}: a panel without data'
            assert UNIT.search(ax.get_xlabel()) and UNIT.search(ax.get_ylabel()), \
                f'{file}: {ax.get_xlabel()!r}, {ax.get_ylabel()!r} without units'
            legend = ax.get_legend()
            assert legend is None or not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer)), file
        if file.startswith('outputs_vs'):
            assert 'no values: peak_err_after_5s, t_detached' in fig.get_suptitle()
        else:
            feasible = [line for line in fig.axes[0].get_lines() if line.get_label() == 'feasible robot']
            assert feasible and matplotlib.colors.to_rgb(feasible[0].get_markeredgecolor()) != (1.0, 1.0, 1.0)


def test_sweep_outputs_the_same_for_every_robot_are_named_in_the_title_not_drawn_flat():
    names, rows = sweep_table(False)
    figures = dict((file, fig) for fig, file in sweep_figures(plt, names, rows, ['body_mass', 'com_height']))
    yield_figures.extend(figures.values())
    fig = figures['outputs_vs_body_mass.png']
    assert 'the same for every robot: slipped = 0, detached = 0' in fig.get_suptitle()
    drawn = {ax.get_ylabel().split(' (')[0] for ax in data_axes(fig)}
    assert drawn == set(OUTPUTS) - {'feasible', 'peak_err_after_5s', 't_detached', 'slipped', 'detached'}
