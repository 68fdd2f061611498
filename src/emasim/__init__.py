"""emasim: electromechanical actuation system simulation.

A PMSM drives a gearbox and a planetary roller screw, which moves a control-surface
linkage; friction and backlash act on the way. The package holds the plant models
(:mod:`emasim.plant`), the discrete-time controllers (:mod:`emasim.control`), the
compiled sampled-data engine (:mod:`emasim.sim`), the paper's experiments
(:mod:`emasim.scenarios`) and the metrics (:mod:`emasim.analysis`).
"""

from .errors import EmasimError, EmasimWarning, InputError, PhysicalLimitWarning
from .numba_cache import configure as _configure_numba_cache

NUMBA_CACHE_DIR = _configure_numba_cache()  # keyed by the source: never stale (numba_cache.py)
# the public names, the ones loaded on first use too
__all__ = [
    "NUMBA_CACHE_DIR",
    "EmasimError",
    "EmasimWarning",
    "InputError",
    "PhysicalLimitWarning",
    "__version__",
    "identify",
    "linearize",
    "run",
]


def __getattr__(name: str):
    """``__version__`` (:mod:`emasim.version`, read when first asked for), ``run``
    (:func:`emasim.experiments.batch.run`), ``linearize`` (:func:`emasim.linear.linearize`)
    and ``identify`` (:func:`emasim.identification.identify.identify`), loaded when first used
    (they load the compiled core, and python-control)."""
    if name == "__version__":
        from .version import __version__

        return __version__
    if name == "linearize":
        from .linear import linearize

        return linearize
    if name == "run":
        from .experiments.batch import run

        return run
    if name == "identify":
        from .identification.identify import identify

        return identify
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    """The public API (``__all__``) with the module's own names: ``dir(emasim)`` lists ``run``,
    ``linearize`` and ``identify`` before their first use."""
    return sorted(set(globals()) | set(__all__))
