"""What every ``rod-sim`` subcommand shares: exit statuses, the usage error, argument types.

A subcommand lives in its own module (under ``rod_sim/tools``, or the ``command`` module of
``rod_sim/compare``, ``rod_sim/sweep``, ``rod_sim/bench``), listed in
:data:`rod_sim.tools.cli.COMMANDS`, and defines

- ``HELP`` (one line for ``rod-sim --help``) and optionally ``DESCRIPTION``,
- ``configure(parser)`` adding its arguments to an ``argparse`` subparser,
- ``run(args) -> int`` returning an exit status.

Modules import their heavy dependencies (ROS, matplotlib, dask, ...) inside ``run`` so that
``rod-sim --help`` stays fast and works without the optional extras.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from rod_sim.core.quote import quote

EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT = 0, 1, 2
PAPER_EXAMPLE = Path(__file__).resolve().parents[2] / "config" / "paper_example.yaml"


class UsageError(ValueError):
    """Bad command-line input that argparse cannot see (e.g. an existing output file).
    ``rod-sim`` prints its first line and exits with status 2."""


def _checked(text: str, convert, noun: str, valid, rule: str):
    """``convert(text)`` if it parses (else "not NOUN: 'TEXT'") and ``valid`` holds (else
    "must be RULE (got TEXT)"), as argparse's ArgumentTypeError."""
    try:
        value = convert(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not {noun}: {quote(text)}") from None
    if not valid(value):
        raise argparse.ArgumentTypeError(f"must be {rule} (got {quote(text, plain=True)})")
    return value


def positive_int(text: str, largest: int = 1000) -> int:
    """argparse type: a whole number 1 .. ``largest``."""
    return _checked(text, int, "a whole number", lambda v: 1 <= v <= largest,
                    f"1 .. {largest}")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    return _checked(text, float, "a number", lambda v: math.isfinite(v) and v > 0,
                    "a positive finite number")


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    return _checked(text, float, "a number", lambda v: math.isfinite(v) and v >= 0,
                    "a finite number >= 0")


def port_number(text: str) -> int:
    """argparse type: a TCP port 1..65535."""
    return _checked(text, int, "a port number", lambda v: 1 <= v <= 65535,
                    "a port 1..65535")


def load_scene(path: str):
    """Read a scene YAML file (raises SceneError/UsageError with a one-line reason)."""
    from rod_sim.io.scene_yaml import load_scene as _load

    return _load(path)


def new_output_path(text: str, option: str = "--out") -> Path:
    """A file path that does not exist yet, in an existing directory (UsageError otherwise),
    registered as this command's unfinished output (:func:`rod_sim.app.signals.done`)."""
    out = Path(text)
    if out.exists():
        raise UsageError(f"{option}: {out} exists; refusing to overwrite it")
    if not out.parent.is_dir():
        raise UsageError(f"{option}: directory {out.parent} does not exist")
    from .signals import unfinished

    unfinished(out)         # removed if a signal's watchdog must end the command before done()
    return out


from rod_sim.core.compile_watch import COMPILE_NOTICE  # noqa: E402,F401  (tests filter by it)


def watch_compiles(prefix: str = "rod-sim"):
    """Say on stderr what numba compiles, why and how long it takes, when it does (a driver
    not in the cache compiles on first use): :mod:`rod_sim.core.compile_watch`."""
    from .signals import write_line
    from rod_sim.core.compile_watch import watch_compiles as _watch

    return _watch(lambda line: write_line(f"{prefix}: {line}", sys.stderr))


def largest(values, k: int) -> list[int]:
    """The indices (0-based, ascending) of the ``k`` largest of ``values`` (every index when
    there are at most ``k``); a NaN counts as the largest, ties go to the lower index. What a
    report or a figure of a long chain shows of it (the rods of the largest error, the hinges
    of the largest range)."""
    import numpy as np

    key = np.nan_to_num(np.asarray(values, dtype=float), nan=np.inf)
    return sorted(int(i) for i in np.argsort(-key, kind="stable")[:k])


def importable(module: str) -> bool:
    """True when ``module`` can be imported (optional peers and extras)."""
    import importlib

    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True
