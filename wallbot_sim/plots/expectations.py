"""The figure of a failing expectation of a controller test (``wallbot_sim.testing``): the quantity against time, its
limit, the worst instant and the faults of the run (PNG, matplotlib's Agg backend)."""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from wallbot_sim.plots.errors import PlotError


@dataclass(frozen=True)
class Limit:
    """A limit line: ``value`` from simulation time ``start`` on; ``mirrored``: also -``value`` (a limit on a
    magnitude)."""

    value: float
    start: float = -math.inf
    mirrored: bool = False


def write_expectation_figure(path: Path, title: str, t: np.ndarray, series: Mapping[str, np.ndarray], ylabel: str,
                             limit: Limit | None, worst_t: float, events: Sequence[tuple[float, str]] = ()) -> Path:
    """``series`` (label: values at the times ``t``) with ``limit``, the worst instant ``worst_t`` marked, and each
    event (time, label: a fault) as a vertical line; written to ``path``. PlotError if it cannot be written."""
    import matplotlib
    matplotlib.use('Agg', force=True)
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for label, values in series.items():
        ax.plot(t, values, lw=1.3, label=label)
    if limit is not None:
        shown = t >= limit.start
        if shown.any():
            span = t[shown]
            ax.plot([span[0], span[-1]], [limit.value] * 2, 'r--', lw=1.2, label=f'limit {limit.value:g}')
            if limit.mirrored:
                ax.plot([span[0], span[-1]], [-limit.value] * 2, 'r--', lw=1.2)
    if math.isfinite(worst_t):
        ax.axvline(worst_t, color='k', lw=1.0, ls=':', label=f'worst at t = {worst_t:.3f} s')
    for k, (when, label) in enumerate(events):
        ax.axvline(when, color='tab:purple', lw=1.0, alpha=0.7, label='fault' if k == 0 else None)
        ax.annotate(label, (when, 1.0), xycoords=('data', 'axes fraction'), rotation=90, va='top', ha='right',
                    fontsize='x-small', color='tab:purple')
    ax.set(xlabel='time (s)', ylabel=ylabel)
    ax.set_title(textwrap.fill(title, 90), fontsize='medium')
    ax.grid(True, alpha=0.3)
    ax.legend(loc='best', fontsize='small')
    fig.tight_layout()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    except OSError as error:
        raise PlotError(f'cannot write {path}: {error.strerror}') from None
    finally:
        plt.close(fig)
    return path
