"""The experiments layer: the only layer that starts simulations for the command line, the
tuner and the reports.

* :mod:`.runs`: one run of a scenario, with its metadata, description and metrics;
* :mod:`.batch`: many runs at once (Dask), and a scenario's comparison of controller sets;
* :mod:`.reproduction`: the paper's experiments and the clearance sweep, rendered by
  :mod:`emasim.analysis.paper_report`.

It imports ``sim`` (time stepping), ``scenarios`` (what a run is) and ``analysis`` (metrics,
figures, reports); none of those imports it.
"""
