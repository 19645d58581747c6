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
a layout engine measures them: measuring draws every tick label once more, which doubled the drawing.
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
        outputs = [name for name in OUTPUTS if name != 'feasible']
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


def draw_figure(plt: Any, table: SweepTable, file: str) -> Any:
    """The figure ``file`` (one of ``table.files()``), laid out."""
    kind, _, name = file.removesuffix('.png').partition('_vs_' if file.startswith('outputs_vs_') else '_')
    if kind == 'outputs':
        return _outputs_figure(plt, table, name)
    return _map_figure(plt, table, name)


def write_figure(plt: Any, table: SweepTable, file: str, out_dir: Path) -> Path:
    """Draw the figure ``file`` into ``out_dir``."""
    fig = draw_figure(plt, table, file)
    path = out_dir / file
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _outputs_figure(plt: Any, table: SweepTable, parameter: str) -> Any:
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
    fig = plt.figure(figsize=(width, height))
    left, right, below, above = PANEL_MARGINS
    x = table.column[parameter]
    for index, output in enumerate(table.drawn):
        row, col = divmod(index, columns)
        bottom = height - title - PANEL[1] * (row + 1) + below
        ax = fig.add_axes((((col * PANEL[0]) + left) / width, bottom / height,
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
    return fig


def _map_figure(plt: Any, table: SweepTable, output: str) -> Any:
    from matplotlib.tri import Triangulation

    first, second = table.parameters
    x, y, value, feasible = table.column[first], table.column[second], table.column[output], table.feasible
    finite = np.isfinite(value)
    fig = plt.figure(figsize=(7, 5.8))
    ax = fig.add_axes((0.12, 0.19, 0.64, 0.74))
    colorbar = fig.add_axes((0.8, 0.19, 0.035, 0.74), label='<colorbar>')
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
    return fig


def _triangulation(triangulation: type, x: np.ndarray, y: np.ndarray) -> object | None:
    """A Delaunay triangulation of the points, or None when they do not span an area."""
    if len(x) < 3:
        return None
    try:
        triangles = triangulation(x, y)
    except (ValueError, RuntimeError):  # collinear or repeated points
        return None
    return triangles if len(triangles.triangles) else None
