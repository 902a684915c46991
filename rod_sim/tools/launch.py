"""The ``rod-sim`` console script's entry point: Ctrl-C and SIGTERM handled from its first line.

The interpreter imports this module before anything else of the command line; its first
statements install a handler that ends the process at once with the command's one line
(``rod-sim CMD: interrupted``, `` (SIGTERM)``; plain ``rod-sim`` when the first word
is not a subcommand, as the command line says it) and status 130 / 143: nothing is open yet. Then
:func:`rod_sim.tools.cli.main` installs the commands' own handler (which closes their files).
Before this module's first line (the interpreter's own start-up) Python's defaults apply."""
import os
import signal
import sys


_COMMANDS: dict = {}
"""The subcommand table (:mod:`rod_sim.tools.commands`), loaded right after the handlers."""


def _stop_at_once(signum, frame):           # pragma: no cover - timing-dependent
    name = sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] in _COMMANDS else ""
    who = f"rod-sim {name}" if name else "rod-sim"
    tail = " (SIGTERM)" if signum == signal.SIGTERM else ""
    try:
        os.write(2, f"{who}: interrupted{tail}\n".encode())
    finally:
        os._exit(128 + signum)


_stop_at_once.rod_sim_early = True          # rod_sim.app.signals replaces it
signal.signal(signal.SIGINT, _stop_at_once)
signal.signal(signal.SIGTERM, _stop_at_once)

from rod_sim.app.blas import one_blas_thread  # noqa: E402 -- after the handlers

one_blas_thread()                           # before anything loads numpy

from .commands import COMMANDS as _COMMANDS  # noqa: E402 -- after the handlers, plain data


def main() -> int:
    from .cli import main as cli_main

    return cli_main()


if __name__ == "__main__":
    sys.exit(main())
