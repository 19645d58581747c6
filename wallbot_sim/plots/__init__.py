"""The paper's figure set of a run (``wallbot_sim.rundata.RunData``), or several runs overlaid:
``wallbot_sim.plots.figures.write_figures`` (matplotlib is loaded only with that module)."""
