"""A sweep's figures as PNG (matplotlib, Agg backend), from its results.csv.

| file | what |
|---|---|
| outputs_vs_KEY.png | every output against the varied parameter KEY, one panel per output |
| map_OUTPUT.png | with two varied parameters: OUTPUT over both (the least adhesion force over mass and CoM height) |

Feasible robots (no slip, no detachment, friction use within 1) are drawn in blue, the others
in red; a map outlines the feasible region and crosses out the robots outside it (with ideal
contact, those whose friction use exceeds 1: they would slip on a real wall).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wallbot_sim.sweep.compute import OUTPUTS

MAP_OUTPUTS = ('least_adhesion_force', 'peak_motor_torque_left', 'peak_motor_torque_right', 'final_err')
"""The outputs drawn as maps over two varied parameters."""
PANEL_COLUMNS = 4
INFEASIBLE = 'not feasible: slips, lifts off or friction use > 1'


def write_sweep_figures(names: list[str], rows: list[list[float]], parameters: list[str], out_dir: Path) -> list[Path]:
    """Write the figures of results (``names``: the header, ``rows``) over those ``parameters`` columns that
    take more than one value (a key the spec fixes, e.g. a one-value grid, is no axis)."""
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    from matplotlib.tri import Triangulation

    table = np.array(rows, dtype=float).reshape(len(rows), len(names))
    column = {name: table[:, i] for i, name in enumerate(names)}
    feasible = column['feasible'] > 0.5
    parameters = [name for name in parameters if len(np.unique(column[name])) > 1]
    outputs = [name for name in OUTPUTS if name != 'feasible']
    written = []
    for parameter in parameters:
        count = len(outputs)
        height = -(-count // PANEL_COLUMNS)
        fig, axes = plt.subplots(height, PANEL_COLUMNS, figsize=(4 * PANEL_COLUMNS, 3 * height), squeeze=False)
        for ax, output in zip(axes.flat, outputs):
            x, y = column[parameter], column[output]
            ax.plot(x[feasible], y[feasible], 'o', color='tab:blue', ms=3, label='feasible')
            ax.plot(x[~feasible], y[~feasible], 'o', color='tab:red', ms=3, label=INFEASIBLE)
            ax.set_xlabel(parameter)
            ax.set_ylabel(output)
            ax.grid(True, alpha=0.3)
        for ax in list(axes.flat)[count:]:
            ax.axis('off')
        axes.flat[0].legend(fontsize='small')
        fig.suptitle(f'sweep outputs against {parameter} ({len(rows)} robots)')
        written.append(_save(fig, out_dir / f'outputs_vs_{parameter}.png'))
    if len(parameters) == 2:
        x, y = column[parameters[0]], column[parameters[1]]
        triangles = _triangulation(Triangulation, x, y)
        for output in MAP_OUTPUTS:
            value = column[output]
            fig, ax = plt.subplots(figsize=(7, 5.5))
            finite = np.isfinite(value)
            if triangles is not None and finite.all():
                shading = ax.tricontourf(triangles, value, levels=20, cmap='viridis')
                if feasible.any() and not feasible.all():
                    ax.tricontour(triangles, feasible.astype(float), levels=[0.5], colors='white', linewidths=2)
            else:
                shading = ax.scatter(x[finite], y[finite], c=value[finite], cmap='viridis', s=25)
            fig.colorbar(shading, ax=ax, label=output)
            ax.plot(x[feasible], y[feasible], '.', color='white', ms=3, label='feasible')
            ax.plot(x[~feasible], y[~feasible], 'x', color='red', ms=5, label=INFEASIBLE)
            ax.set_xlabel(parameters[0])
            ax.set_ylabel(parameters[1])
            ax.legend(fontsize='small', loc='upper right')
            ax.set_title(f'{output} ({len(rows)} robots; white line: edge of the feasible region)')
            written.append(_save(fig, out_dir / f'map_{output}.png'))
    return written


def _triangulation(triangulation: type, x: np.ndarray, y: np.ndarray) -> object | None:
    """A Delaunay triangulation of the points, or None when they do not span an area."""
    if len(x) < 3:
        return None
    try:
        triangles = triangulation(x, y)
    except (ValueError, RuntimeError):  # collinear or repeated points
        return None
    return triangles if len(triangles.triangles) else None


def _save(fig: object, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
