"""Design sweeps: many robots over varied parameters, each run summarized as one row of results.csv.

    spec = load_spec('sweep.yaml')                 # SweepSpec (SweepError naming a bad key)
    rows = chunk_results(spec.settings, [spec.parameters(i) for i in spec.chunks()[0]])

``wallbot-sim sweep`` runs the chunks on Dask (``wallbot_sim.sweep.cluster``), stores them in the
output directory (``wallbot_sim.sweep.store``) and draws the figures (``wallbot_sim.sweep.figures``) in
a painter process started while the chunks compute (``wallbot_sim.sweep.painters``).
"""

from wallbot_sim.sweep.compute import OUTPUTS, RunSettings, chunk_results
from wallbot_sim.sweep.errors import SweepError
from wallbot_sim.sweep.spec import SweepSpec, load_spec, parse_spec

__all__ = ['OUTPUTS', 'RunSettings', 'SweepError', 'SweepSpec', 'chunk_results', 'load_spec', 'parse_spec']
