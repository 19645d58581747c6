"""The paper's figure set from a run (bag or simulate CSV), or several runs overlaid."""

from wallbot_sim.plots.data import RunData, RunDataError, load_run
from wallbot_sim.plots.figures import FIGURES, write_figures

__all__ = ['FIGURES', 'RunData', 'RunDataError', 'load_run', 'write_figures']
