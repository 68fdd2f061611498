"""``python -m emasim`` and the ``emasim`` command: the command line (:mod:`emasim.cli`).

Its imports take a second or more (typer, rich, numpy); a Ctrl-C or a SIGTERM while they run
ends as one during a command does, with the one line ``error: interrupted`` and exit 130 or
143 (128 + the signal), never a traceback. From there on the command line handles both.
"""

import signal
import sys


def main() -> None:
    """Import the command line, then run it."""
    received = []

    def interrupt(signum, frame):
        received.append(signum)
        raise KeyboardInterrupt

    before = signal.signal(signal.SIGTERM, interrupt)
    try:
        from .cli import program
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        sys.exit(128 + (received[0] if received else signal.SIGINT))
    signal.signal(signal.SIGTERM, before)
    program()


if __name__ == "__main__":
    main()
