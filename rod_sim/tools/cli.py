"""The ``rod-sim`` command line: one entry point, one subcommand per job.

:data:`COMMANDS` is the list of subcommands: each is a module (of ``rod_sim.tools``, or the
``command`` module of the packages ``rod_sim.compare``, ``rod_sim.sweep``, ``rod_sim.bench``),
imported only when the parser is built or the command runs, with

- ``HELP`` (one line for ``rod-sim --help``; ``DESCRIPTION``, if defined, for its own --help),
- ``configure(parser)`` adding its arguments to an ``argparse`` subparser,
- ``run(args) -> int`` returning an exit status (0 success, 1 a check failed or the run
  stopped, 2 bad input).

``build_parser()`` builds the parser, ``run(args) -> int`` does the work, ``main()`` wraps both
and turns library errors into one-line messages on stderr.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import signal
import sys
from types import ModuleType

from ..version import __version__
from .commands import COMMANDS, NEVER_COMPILES

from rod_sim.app import signals
from rod_sim.app.common import (EXIT_BAD_INPUT, EXIT_CHECK_FAILED, EXIT_OK, PAPER_EXAMPLE,
                                UsageError)
from rod_sim.app.signals import Terminated, handle_sigterm
from rod_sim.app.signals import reset as reset_signals

__all__ = ["EXIT_OK", "EXIT_CHECK_FAILED", "EXIT_BAD_INPUT", "PAPER_EXAMPLE", "UsageError",
           "COMMANDS", "command_module", "build_parser", "run", "main"]


def command_module(name: str) -> ModuleType:
    """The module implementing subcommand ``name`` (imported on first use; KeyError if none)."""
    module = COMMANDS[name]
    return importlib.import_module(module if module.startswith("rod_sim.")
                                   else f"{__package__}.{module}")


def plugin_modules() -> dict[str, ModuleType]:
    """``{name: module}`` of every subcommand (imports them all)."""
    return {name: command_module(name) for name in COMMANDS}


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``rod-sim`` parser. ``only``: the subcommand being run, the only one whose module
    is imported and whose arguments are configured (the others stay bare subparsers: a start
    does not import every tool, ~0.1-0.2 s); None: all of them (``rod-sim --help``)."""
    parser = argparse.ArgumentParser(
        prog="rod-sim", description="Plane chains of elastic rods with visco-elastic hinges.")
    parser.add_argument("--version", action="version", version=f"rod-sim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    parser.subcommands = {}
    """Each subcommand's parser by name (its usage goes with its errors)."""
    for name in COMMANDS:
        if only is not None and name != only:
            sub.add_parser(name)
            continue
        module = command_module(name)
        parser.subcommands[name] = sub.add_parser(
            name, help=module.HELP, description=getattr(module, "DESCRIPTION", module.HELP))
        module.configure(parser.subcommands[name])
    return parser


def parse(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.Namespace:
    """``argv`` parsed; arguments the subcommand does not know are an error with the
    subcommand's usage (argparse gives them the top-level usage, which lists no option)."""
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        parser.subcommands[args.command].error(
            f"unrecognized arguments: {' '.join(unknown)}")
    return args


READS_LOGS = ("compare", "replay", "deployment-figure", "repair")
"""Commands that open logs: a long integrity pass of one is said on stderr
(:func:`rod_sim.app.progress.log_check_progress`)."""


def run(args: argparse.Namespace) -> int:
    """Run a parsed command; library errors propagate (``main`` reports them)."""
    from rod_sim.app.progress import log_check_progress

    with (log_check_progress(f"rod-sim {args.command}") if args.command in READS_LOGS
          else contextlib.nullcontext()):
        return command_module(args.command).run(args)


def _error(command: str, err, status: int) -> int:
    """Print the first line of ``err`` as ``rod-sim COMMAND: error: ...``; return ``status``."""
    message = str(err).splitlines()[0] if str(err) else type(err).__name__
    print(f"rod-sim {command}: error: {message}", file=sys.stderr)
    return status


def main(argv: list[str] | None = None) -> int:
    """Run ``rod-sim`` with ``argv`` (default: the command line); returns the exit status.
    Ctrl-C / SIGTERM at any moment, from here on (the command table's imports included): one
    line, exit 130 / 143 (:mod:`rod_sim.app.signals`)."""
    entry_point = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    name = argv[0] if argv and argv[0] in COMMANDS else ""
    reset_signals(f"rod-sim {name}".strip())
    handle_sigterm()
    status = None
    try:
        status = _main(argv)
    except KeyboardInterrupt as err:
        status = _interrupted(err)
    except Exception as err:
        # a signal handler's exception raised inside a compiled (numba) call comes back as
        # "SystemError: ... returned a result with an exception set", inside a C extension's
        # initialization (numpy's, during an import) as "ImportError: initialization
        # failed", and inside a descriptor's __set_name__ while a class is made (numba's
        # import, CI) as "RuntimeError: Error calling __set_name__ ...", each caused by it
        stop = _interruption(err)
        if stop is None and isinstance(err, ImportError) and signals.received() is not None:
            stop = Terminated() if signals.received() == signal.SIGTERM else KeyboardInterrupt()
        if stop is None:
            raise
        status = _interrupted(stop)
    finally:
        if status is not None and signals.received() is not None and status not in (
                signals.EXIT_SIGINT, signals.EXIT_SIGTERM):
            # the signal's exception was swallowed (e.g. raised inside a finalizer) and the
            # command ran on: still an interrupted command
            status = _interrupted(Terminated() if signals.received() == signal.SIGTERM
                                  else KeyboardInterrupt())
        signals.finished()
        if entry_point:         # the process ends now: a signal from here on ends it at once
            signals.exit_quietly_on_signal()
    if entry_point and status in (signals.EXIT_SIGINT, signals.EXIT_SIGTERM):
        # interrupted: the outputs are closed; tearing down a large heap (a 100 000-rod
        # node's) took ~2 s more, past the 1 s a stop may take
        signals.exit_now(status)
    return status


def _main(argv: list[str]) -> int:
    from ..core.scene import SceneError

    log_module = sys.modules.get("rod_sim.io.log_reader")
    if log_module is not None:          # a log's damage warnings: once per command
        log_module._reported.clear()
    if argv[:1] == ["node"]:
        # argparse cannot hand "--ros-args ..." through a subparser untouched; the node has
        # its own parser (for --help and typos) and reports bad parameters with status 2.
        return command_module("node").forward(argv[1:])
    parser = build_parser(argv[0] if argv and argv[0] in COMMANDS else None)
    args = parse(parser, argv)
    if args.command not in NEVER_COMPILES:
        from rod_sim.app.common import watch_compiles

        watch_compiles()
    try:
        return run(args)
    except (SceneError, UsageError, FileExistsError, ValueError) as err:   # ModelError too
        _raise_interruption(err)
        return _error(args.command, err, EXIT_BAD_INPUT)
    except OSError as err:                  # a file that cannot be read or written
        _raise_interruption(err)
        where = f"{err.filename}: " if err.filename else ""
        return _error(args.command, f"{where}{err.strerror or err}", EXIT_BAD_INPUT)
    except MemoryError:
        return _error(args.command, "out of memory", EXIT_CHECK_FAILED)
    except RuntimeError as err:             # IntegrationError: the run could not go on
        _raise_interruption(err)
        return _error(args.command, err, EXIT_CHECK_FAILED)


def _raise_interruption(err: BaseException) -> None:
    """Raise the KeyboardInterrupt (Ctrl-C or SIGTERM) that ``err`` was raised from, if any:
    an interrupted command is reported as interrupted, not as its error."""
    stop = _interruption(err)
    if stop is not None:
        raise stop from None


def _interruption(err: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt (Ctrl-C or SIGTERM) that ``err`` was raised from, if any."""
    seen = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


def _interrupted(err: KeyboardInterrupt) -> int:
    """Remove the outputs the interrupted command had not finished (an output is whole or
    absent), print its one line; its exit status (130, or 143 for SIGTERM)."""
    signum = signal.SIGTERM if isinstance(err, Terminated) else signal.SIGINT
    signals.write_line(signals.ended_line(signum), sys.stderr)
    return signals.exit_status(signum)


if __name__ == "__main__":
    sys.exit(main())
