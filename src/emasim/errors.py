"""Errors and warnings meant for the user: the command line prints an error's message as one
line, exit code 2, and a warning as one ``warning:`` line; from Python they are exceptions and
``warnings`` of emasim's own categories (``emasim.InputError``, ``emasim.PhysicalLimitWarning``),
to catch, filter or escalate as any library's."""


class EmasimError(Exception):
    """Base of every error whose message is written for the user."""


class InputError(EmasimError):
    """A scenario, option or argument is invalid; the message names the field and the range."""


class SimulationDiverged(EmasimError):
    """The simulation produced NaN/inf or a state beyond its physical bound."""


class LawFailed(SimulationDiverged):
    """A controller law raised or returned a non-finite command; the run stopped there."""


class DamagedResult(EmasimError):
    """A saved result cannot be read back whole: a file is missing, truncated, changed since
    emasim wrote it, or not emasim's; the message names the file and what is wrong."""


class OutputError(EmasimError):
    """A target cannot be written without losing someone's data, or cannot be written at all
    (emasim.output's rules)."""


class EmasimWarning(UserWarning):
    """Base of emasim's warnings: ``warnings.simplefilter("error", emasim.EmasimWarning)``
    turns every one into an exception, ``"ignore"`` silences them."""


class PhysicalLimitWarning(EmasimWarning):
    """A run touched a stop or went past a physical limit (rated speed, current, stroke): one
    warning a line of its meta.json's ``warnings``, prefixed with the controller set's label."""
