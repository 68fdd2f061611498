"""Errors meant for the user: the command line prints their message as one line, exit code 2."""


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
