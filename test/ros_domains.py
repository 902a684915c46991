"""The ROS domain ids of the tests that start a ROS graph: the one place that hands them out.

A fixed id per test made two test runs on one host (two worktrees, a CI job beside a developer,
``make flake`` beside ``make test``) meet in the same domains. Here each call of
:func:`next_domain` gives the next id of this test process, starting at a base: the environment's
``ROD_SIM_TEST_DOMAIN_BASE`` when set, else one derived from the process id (so runs side by side
most likely start apart), and wrapping inside :data:`FIRST` .. :data:`LAST`. Every test also uses
its own namespace (``ros_graph.unique_namespace``), so that even two runs that do meet in a domain
do not read each other's node topics."""
from __future__ import annotations

import itertools
import os

BASE_ENV = "ROD_SIM_TEST_DOMAIN_BASE"
FIRST = 1
"""Lowest id handed out: 0 is every ROS user's default domain."""
LAST = 232
"""Highest id handed out: Fast DDS cannot open the UDP ports of domain ids above 232."""
SPAN = LAST - FIRST + 1


def base(environ=os.environ, pid: int | None = None) -> int:
    """The first id of this run: ``ROD_SIM_TEST_DOMAIN_BASE`` (an integer in FIRST..LAST) or,
    unset or empty, FIRST + pid % SPAN. Raises ValueError naming the variable otherwise."""
    text = environ.get(BASE_ENV, "").strip()
    if not text:
        return FIRST + (os.getpid() if pid is None else pid) % SPAN
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not FIRST <= value <= LAST:
        raise ValueError(f"{BASE_ENV}={text!r}: expected an integer in {FIRST}..{LAST}")
    return value


_ids = itertools.count()
_base = base()


def next_domain() -> int:
    """A domain id not handed out before in this process (until SPAN ids have been: then they
    repeat, each test's graph having long ended)."""
    return FIRST + (_base - FIRST + next(_ids)) % SPAN


def next_domains(count: int) -> tuple[int, ...]:
    """``count`` ids of :func:`next_domain` (module constants: ``A, B = next_domains(2)``)."""
    return tuple(next_domain() for _ in range(count))
