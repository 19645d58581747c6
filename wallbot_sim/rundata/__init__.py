"""A run's data, from a recorded bag or a ``simulate`` CSV: loading it as one set of arrays, the
CSV format, the run summary and the motor analysis. ``wallbot_sim.bag`` reads and writes bags,
``wallbot_sim.plots`` draws; this is what lies between.

    from wallbot_sim.rundata import load_run, summarize, format_summary
    run = load_run(path)                   # RunData (RunDataError / BagError if unreadable)
    print(format_summary(summarize(path)))
"""

from wallbot_sim.rundata.csv_format import CSV_COLUMNS, csv_row
from wallbot_sim.rundata.errors import RunDataError
from wallbot_sim.rundata.load import load_run
from wallbot_sim.rundata.run_data import RunData
from wallbot_sim.rundata.summary import RunSummary, format_summary, summarize

__all__ = ['CSV_COLUMNS', 'RunData', 'RunDataError', 'RunSummary', 'csv_row', 'format_summary', 'load_run',
           'summarize']
