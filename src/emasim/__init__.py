"""emasim: electromechanical actuation system simulation.

A PMSM drives a gearbox and a planetary roller screw, which moves a control-surface
linkage; friction and backlash act on the way. The package holds the plant models
(:mod:`emasim.plant`), the discrete-time controllers (:mod:`emasim.control`), the
compiled sampled-data engine (:mod:`emasim.sim`), the paper's experiments
(:mod:`emasim.scenarios`) and the metrics (:mod:`emasim.analysis`).
"""

from importlib.metadata import PackageNotFoundError, version

from .numba_cache import configure as _configure_numba_cache

NUMBA_CACHE_DIR = _configure_numba_cache()  # keyed by the source: never stale (numba_cache.py)

try:
    __version__ = version("emasim")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
