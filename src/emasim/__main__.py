"""``python -m emasim`` runs the command line."""

from .cli import program

program()
