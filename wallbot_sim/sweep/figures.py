"""A sweep's figures as PNG (matplotlib, Agg backend), from its results.csv.

| file | what |
|---|---|
| outputs_vs_KEY.png | every output against the varied parameter KEY, one panel per output |
| map_OUTPUT.png | with two varied parameters: OUTPUT over both (the least adhesion force over mass and CoM height) |

Feasible robots (no slip, no detachment, friction use within 1) are drawn in blue, the others
in red; a map outlines the feasible region, rings the feasible robots and crosses out the others
(with ideal contact, those whose friction use exceeds 1: they would slip on a real wall). Every
axis carries its unit; an output without a value for any robot (``peak_err_after_5s`` of runs
shorter than 5 s) gets no panel, nor does one that is the same for every robot (``applied_adhesion_force``
of a sweep that does not vary it): the title names both; legends stand outside the data.

The panels stand where fixed margins put them (room for the tick labels and the axis labels), not where
a layout engine measures them: measuring draws every tick label once more, which doubled the drawing. A
figure is sketched (its axes and their ticks made) before it is finished with the data, so a painter
process can sketch while the chunks compute.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from wallbot_sim.model.parameters import UNITS
from wallbot_sim.sweep.compute import OUTPUT_UNITS, OUTPUTS

MAP_OUTPUTS = ('least_adhesion_force', 'peak_motor_torque_left', 'peak_motor_torque_right', 'final_err')
"""The outputs drawn as maps over two varied parameters."""
PANEL_COLUMNS = 4
INFEASIBLE = 'not feasible: slips, lifts off or friction use > 1'
DPI = 110
PANEL = (4.0, 3.0)
"""Width and height (inches) of an output's panel: its axes and the room for its labels."""
PANEL_MARGINS = (0.85, 0.15, 0.6, 0.3)
"""Inches of a panel left of its axes (tick and axis labels), right, below (tick and axis labels) and above (an
axis's offset, such as 1e-14)."""
TITLE_LINE = 0.3
"""Inches of one line of a figure's title."""
LEGEND_ROOM = 0.45
"""Inches below the panels for the legend."""
TICKS = 5
"""Intervals between a panel's ticks at most (each tick label costs its drawing)."""
SKETCH_TICKS = TICKS + 3
"""Ticks a sketch makes on each axis: up to TICKS + 1 within the data, one beyond each end."""
PANEL_OUTPUTS = tuple(name for name in OUTPUTS if name != 'feasible')
"""The outputs that may get a panel (feasibility colours the points)."""
MAP_SIZE = (7.0, 5.8)
MAP_AXES = (0.12, 0.19, 0.64, 0.74)
MAP_COLORBAR = (0.8, 0.19, 0.035, 0.74)
"""A map's size (inches) and where its axes and its colour bar stand (fractions of it)."""
UNITLESS = ('-', '0 or 1')
"""Units a note of a value leaves out."""


def axis_label(name: str) -> str:
    """A results column with its unit: ``body_mass (kg)``."""
    unit = OUTPUT_UNITS.get(name) or UNITS.get(name.split('[')[0], '')
    return f'{name} ({unit})' if unit else name


def value_note(name: str, value: float) -> str:
    """An output's value with its unit: ``applied_adhesion_force = 150 N``."""
    unit = OUTPUT_UNITS.get(name, '')
    return f'{name} = {value:.4g}' + (f' {unit}' if unit and unit not in UNITLESS else '')


@dataclass(frozen=True)
class SweepTable:
    """A results table as its figures see it."""

    robots: int
    column: dict[str, np.ndarray]
    feasible: np.ndarray
    parameters: list[str]
    """The varied parameters that take more than one value (a key the spec fixes is no axis)."""
    drawn: list[str]
    """The outputs that differ between robots: a panel each."""
    without: list[str]
    """The outputs without a value for any robot."""
    same: dict[str, float]
    """The outputs with one value for every robot."""

    @classmethod
    def of(cls, names: list[str], rows: list[list[float]], parameters: list[str]) -> SweepTable:
        """The table of results (``names``: the header, ``rows``) over those ``parameters`` columns."""
        table = np.array(rows, dtype=float).reshape(len(rows), len(names))
        column = {name: table[:, i] for i, name in enumerate(names)}
        outputs = PANEL_OUTPUTS
        without = [name for name in outputs if not np.isfinite(column[name]).any()]
        same = {name: float(column[name][0]) for name in outputs
                if np.isfinite(column[name]).all() and np.ptp(column[name]) == 0.0}
        return cls(len(rows), column, column['feasible'] > 0.5,
                   [name for name in parameters if len(np.unique(column[name])) > 1],
                   [name for name in outputs if name not in without and name not in same], without, same)

    def files(self) -> list[str]:
        """The figures' file names, the larger first."""
        files = [f'outputs_vs_{parameter}.png' for parameter in self.parameters if self.drawn]
        if len(self.parameters) == 2:
            files += [f'map_{output}.png' for output in MAP_OUTPUTS if np.isfinite(self.column[output]).any()]
        return files


def sweep_figures(plt: Any, names: list[str], rows: list[list[float]], parameters: list[str]) -> Iterator[tuple[Any, str]]:
    """Each figure of the results (``names``: the header, ``rows``) over those ``parameters`` columns, with its
    file name."""
    table = SweepTable.of(names, rows, parameters)
    for file in table.files():
        yield draw_figure(plt, table, file), file


def sketches(plt: Any, parameters: list[str]) -> dict[str, Any]:
    """The sketch of every figure that results over those ``parameters`` columns may have, by file name."""
    files = [f'outputs_vs_{parameter}.png' for parameter in parameters]
    if len(parameters) >= 2:
        files += [f'map_{output}.png' for output in MAP_OUTPUTS]
    return {file: sketch(plt, file) for file in files}


def sketch(plt: Any, file: str) -> Any:
    """The figure ``file`` before its data: its axes with their ticks made (a third of drawing a panel), for
    :func:`draw_figure` to finish. A painter sketches while the chunks compute."""
    if file.startswith('outputs_vs_'):
        fig = plt.figure()
        for output in PANEL_OUTPUTS:
            _make_ticks(fig.add_axes((0.0, 0.0, 1.0, 1.0), label=output))
    else:
        fig = plt.figure(figsize=MAP_SIZE)
        _make_ticks(fig.add_axes(MAP_AXES))
        fig.add_axes(MAP_COLORBAR, label='<colorbar>')
    return fig


def draw_figure(plt: Any, table: SweepTable, file: str, sketched: Any = None) -> Any:
    """The figure ``file`` (one of ``table.files()``), laid out: its ``sketched`` figure finished (default: sketched
    now)."""
    fig = sketch(plt, file) if sketched is None else sketched
    if file.startswith('outputs_vs_'):
        _finish_outputs(fig, table, file.removeprefix('outputs_vs_').removesuffix('.png'))
    else:
        _finish_map(fig, table, file.removeprefix('map_').removesuffix('.png'))
    return fig


def write_figure(plt: Any, table: SweepTable, file: str, out_dir: Path, sketched: Any = None) -> Path:
    """Draw the figure ``file`` into ``out_dir`` (finishing its ``sketched`` figure)."""
    fig = draw_figure(plt, table, file, sketched)
    path = out_dir / file
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _make_ticks(ax: Any) -> None:
    ax.xaxis.get_major_ticks(SKETCH_TICKS)
    ax.yaxis.get_major_ticks(SKETCH_TICKS)


def _finish_outputs(fig: Any, table: SweepTable, parameter: str) -> None:
    notes = [f'sweep outputs against {parameter} ({table.robots} robots)']
    if table.without:
        notes.append(f'no values: {", ".join(table.without)}')
    if table.same:
        notes.append('the same for every robot: ' + ', '.join(value_note(name, value)
                                                               for name, value in table.same.items()))
    columns = min(PANEL_COLUMNS, len(table.drawn))
    rows = -(-len(table.drawn) // columns)
    title = TITLE_LINE * len(notes) + 0.1
    width, height = PANEL[0] * columns, PANEL[1] * rows + title + LEGEND_ROOM
    fig.set_size_inches(width, height)
    panels = {ax.get_label(): ax for ax in fig.axes}
    for output, ax in panels.items():
        if output not in table.drawn:
            fig.delaxes(ax)
    left, right, below, above = PANEL_MARGINS
    x = table.column[parameter]
    for index, output in enumerate(table.drawn):
        row, col = divmod(index, columns)
        bottom = height - title - PANEL[1] * (row + 1) + below
        ax = panels[output]
        ax.set_position((((col * PANEL[0]) + left) / width, bottom / height,
                         (PANEL[0] - left - right) / width, (PANEL[1] - below - above) / height))
        y = table.column[output]
        ax.plot(x[table.feasible], y[table.feasible], 'o', color='tab:blue', ms=4, label='feasible', clip_on=False)
        ax.plot(x[~table.feasible], y[~table.feasible], 'o', color='tab:red', ms=4, label=INFEASIBLE, clip_on=False)
        ax.set_xlabel(axis_label(parameter))
        ax.set_ylabel(axis_label(output))
        ax.grid(True, alpha=0.3)
        ax.locator_params(nbins=TICKS)
    fig.legend(*fig.axes[0].get_legend_handles_labels(), loc='lower center', ncol=2, fontsize='small')
    fig.suptitle('\n'.join(notes), y=1 - 0.1 / height, va='top', fontsize='medium')


def _finish_map(fig: Any, table: SweepTable, output: str) -> None:
    from matplotlib.tri import Triangulation

    first, second = table.parameters
    x, y, value, feasible = table.column[first], table.column[second], table.column[output], table.feasible
    finite = np.isfinite(value)
    ax, colorbar = fig.axes
    triangles = _triangulation(Triangulation, x, y)
    if triangles is not None and finite.all():
        shading = ax.tricontourf(triangles, value, levels=20, cmap='viridis')
        if feasible.any() and not feasible.all():
            ax.tricontour(triangles, feasible.astype(float), levels=[0.5], colors='white', linewidths=2)
    else:
        shading = ax.scatter(x[finite], y[finite], c=value[finite], cmap='viridis', s=25)
    fig.colorbar(shading, cax=colorbar, label=axis_label(output))
    ax.plot(x[feasible], y[feasible], 'o', mfc='white', mec='black', mew=0.6, ms=5, label='feasible robot',
            clip_on=False)
    ax.plot(x[~feasible], y[~feasible], 'x', color='red', ms=6, mew=1.5, label=INFEASIBLE, clip_on=False)
    ax.set_xlabel(axis_label(first))
    ax.set_ylabel(axis_label(second))
    ax.set_title(f'{output} ({table.robots} robots; white line: edge of the feasible region)', fontsize='medium')
    ax.legend(fontsize='small', loc='upper center', bbox_to_anchor=(0.5, -0.12), ncol=2)


def _triangulation(triangulation: type, x: np.ndarray, y: np.ndarray) -> object | None:
    """A Delaunay triangulation of the points, or None when they do not span an area."""
    if len(x) < 3:
        return None
    try:
        triangles = triangulation(x, y)
    except (ValueError, RuntimeError):  # collinear or repeated points
        return None
    return triangles if len(triangles.triangles) else None
