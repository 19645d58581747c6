"""A sweep's figures as PNG (matplotlib, Agg backend), from its results.csv.

| file | what |
|---|---|
| outputs_vs_KEY.png | every output against the varied parameter KEY, one panel per output |
| map_OUTPUT.png | with two varied parameters: OUTPUT over both (the least adhesion force over mass and CoM height) |

Feasible robots (no slip, no detachment, friction use within 1) are drawn in blue, the others
in red; a map outlines the feasible region, rings the feasible robots and crosses out the others
(with ideal contact, those whose friction use exceeds 1: they would slip on a real wall). Every
axis carries its unit; an output without a value for any robot (``peak_err_after_5s`` of runs
shorter than 5 s) gets no panel, named in the title instead; legends stand outside the data.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np

from wallbot_sim.model.parameters import UNITS
from wallbot_sim.sweep.compute import OUTPUT_UNITS, OUTPUTS

MAP_OUTPUTS = ('least_adhesion_force', 'peak_motor_torque_left', 'peak_motor_torque_right', 'final_err')
"""The outputs drawn as maps over two varied parameters."""
PANEL_COLUMNS = 4
INFEASIBLE = 'not feasible: slips, lifts off or friction use > 1'


def axis_label(name: str) -> str:
    """A results column with its unit: ``body_mass (kg)``."""
    unit = OUTPUT_UNITS.get(name) or UNITS.get(name.split('[')[0], '')
    return f'{name} ({unit})' if unit else name


def write_sweep_figures(names: list[str], rows: list[list[float]], parameters: list[str], out_dir: Path) -> list[Path]:
    """Write the figures of results (``names``: the header, ``rows``) over those ``parameters`` columns that
    take more than one value (a key the spec fixes, e.g. a one-value grid, is no axis)."""
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt

    written = []
    for fig, name in sweep_figures(plt, names, rows, parameters):
        written.append(_save(fig, out_dir / name))
    return written


def sweep_figures(plt: Any, names: list[str], rows: list[list[float]], parameters: list[str]) -> Iterator[tuple[Any, str]]:
    """Each figure of the results, laid out, with its file name (``write_sweep_figures`` saves them)."""
    from matplotlib.tri import Triangulation

    table = np.array(rows, dtype=float).reshape(len(rows), len(names))
    column = {name: table[:, i] for i, name in enumerate(names)}
    feasible = column['feasible'] > 0.5
    parameters = [name for name in parameters if len(np.unique(column[name])) > 1]
    outputs = [name for name in OUTPUTS if name != 'feasible']
    with_values = [name for name in outputs if np.isfinite(column[name]).any()]
    without = [name for name in outputs if name not in with_values]
    for parameter in parameters:
        count = len(with_values)
        height = -(-count // PANEL_COLUMNS)
        fig, axes = plt.subplots(height, PANEL_COLUMNS, figsize=(4 * PANEL_COLUMNS, 3 * height + 0.8), squeeze=False)
        for ax, output in zip(axes.flat, with_values):
            x, y = column[parameter], column[output]
            ax.plot(x[feasible], y[feasible], 'o', color='tab:blue', ms=3, label='feasible')
            ax.plot(x[~feasible], y[~feasible], 'o', color='tab:red', ms=3, label=INFEASIBLE)
            ax.set_xlabel(axis_label(parameter))
            ax.set_ylabel(axis_label(output))
            ax.grid(True, alpha=0.3)
        for ax in list(axes.flat)[count:]:
            ax.remove()
        fig.legend(*axes.flat[0].get_legend_handles_labels(), loc='lower center', ncol=2, fontsize='small')
        note = f'; no values: {", ".join(without)}' if without else ''
        fig.suptitle(f'sweep outputs against {parameter} ({len(rows)} robots{note})')
        fig.tight_layout(rect=(0, 0.5 / (3 * height + 0.8), 1, 1))
        yield fig, f'outputs_vs_{parameter}.png'
    if len(parameters) == 2:
        x, y = column[parameters[0]], column[parameters[1]]
        triangles = _triangulation(Triangulation, x, y)
        for output in MAP_OUTPUTS:
            value = column[output]
            finite = np.isfinite(value)
            if not finite.any():
                continue
            fig, ax = plt.subplots(figsize=(7, 6.2))
            if triangles is not None and finite.all():
                shading = ax.tricontourf(triangles, value, levels=20, cmap='viridis')
                if feasible.any() and not feasible.all():
                    ax.tricontour(triangles, feasible.astype(float), levels=[0.5], colors='white', linewidths=2)
            else:
                shading = ax.scatter(x[finite], y[finite], c=value[finite], cmap='viridis', s=25)
            fig.colorbar(shading, ax=ax, label=axis_label(output))
            ax.plot(x[feasible], y[feasible], 'o', mfc='white', mec='black', mew=0.6, ms=4, label='feasible robot')
            ax.plot(x[~feasible], y[~feasible], 'x', color='red', ms=5, label=INFEASIBLE)
            ax.set_xlabel(axis_label(parameters[0]))
            ax.set_ylabel(axis_label(parameters[1]))
            ax.set_title(f'{output} ({len(rows)} robots; white line: edge of the feasible region)', fontsize='medium')
            ax.legend(fontsize='small', loc='upper center', bbox_to_anchor=(0.5, -0.12), ncol=2)
            fig.tight_layout()
            yield fig, f'map_{output}.png'


def _triangulation(triangulation: type, x: np.ndarray, y: np.ndarray) -> object | None:
    """A Delaunay triangulation of the points, or None when they do not span an area."""
    if len(x) < 3:
        return None
    try:
        triangles = triangulation(x, y)
    except (ValueError, RuntimeError):  # collinear or repeated points
        return None
    return triangles if len(triangles.triangles) else None


def _save(fig: Any, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
