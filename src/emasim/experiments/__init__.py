"""The experiments layer: the only layer that starts simulations for the command line, the
tuner and the reports.

* :mod:`.runs`: one run of a scenario, with its metadata, description and metrics;
* :mod:`.batch`: many runs at once on Dask distributed, the one way to run many, and a
  scenario's comparison of controller sets;
* :mod:`.variation` and :mod:`.study`: grids and Monte Carlo over any scenario key, written run
  by run and resumable (``emasim study``);
* :mod:`.robustness` and :mod:`.wear`: the headline verdicts over the bench's plant
  uncertainty, and over its wear;
* :mod:`.ablation`: the bench comparisons as the bench's elements are added;
* :mod:`.reproduction`: the paper's experiments and the clearance sweep, rendered by
  :mod:`emasim.analysis.paper_report`.

It imports ``sim`` (time stepping), ``scenarios`` (what a run is) and ``analysis`` (metrics,
figures, reports); none of those imports it.
"""
