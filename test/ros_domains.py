"""The ROS domain ids of the tests that start a ROS graph: the one place that hands them out.
A fixed id per test made two test runs on one host (two worktrees, a CI job beside a developer,
``make flake`` beside ``make test``) meet in the same domains. Here each call of
:func:`next_domain` gives the next id of this test process, counting up from a base and
wrapping inside a range:

- ``ROD_SIM_TEST_DOMAIN_BASE`` set: from it, inside :data:`FIRST` .. :data:`LAST`;
- else the process claims one of :data:`BLOCKS` blocks of ids (an exclusive ``flock`` on a lock
  file in the temporary directory, held until the process exits), so that test processes
  running at the same time on one machine (``make test`` beside ``make test-slow`` in CI)
  never share an id: their graphs cannot meet, whatever topic names they use (a replay test's
  absolute ``/joint_states`` once counted another suite's publisher); it counts inside its
  block;
- when every block is taken, from one derived from the process id, inside FIRST .. LAST.

Every test also uses its own namespace (``ros_graph.unique_namespace``), so that even two runs
that do meet in a domain do not read each other's node topics."""
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


BLOCKS = 4
"""Blocks of ids a test process may claim (SPAN // BLOCKS ids each: more than one suite uses)."""
BLOCK_SIZE = SPAN // BLOCKS
LOCK_DIR_NAME = "rod_sim_ros_domains"
LOCK_DIR_ENV = "ROD_SIM_TEST_DOMAIN_LOCKS"
"""Directory of the blocks' lock files (default: ``rod_sim_ros_domains`` in the temporary
directory; a test of the claiming gives its own)."""


def claim_block(pid: int | None = None, lock_dir: str | None = None):
    """(first id, size, open lock file) of the first block no other living process holds,
    trying from block ``pid % BLOCKS`` on; None when all are held (or flock is missing)."""
    import tempfile

    try:
        import fcntl
    except ImportError:
        return None
    pid = os.getpid() if pid is None else pid
    directory = lock_dir or os.environ.get(LOCK_DIR_ENV) or os.path.join(
        tempfile.gettempdir(), LOCK_DIR_NAME)
    os.makedirs(directory, exist_ok=True)
    for k in range(BLOCKS):
        block = (pid + k) % BLOCKS
        fh = open(os.path.join(directory, f"block_{block}.lock"), "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        return FIRST + block * BLOCK_SIZE, BLOCK_SIZE, fh
    return None


_ids = itertools.count()
_claim = None if os.environ.get(BASE_ENV, "").strip() else claim_block()
if _claim is not None:
    _base, _span, _lock = _claim
    _first = _base
else:
    _base, _span, _first = base(), SPAN, FIRST


def next_domain() -> int:
    """A domain id not handed out before in this process (until its range's ids have been:
    then they repeat, each test's graph having long ended)."""
    return _first + (_base - _first + next(_ids)) % _span


def next_domains(count: int) -> tuple[int, ...]:
    """``count`` ids of :func:`next_domain` (module constants: ``A, B = next_domains(2)``)."""
    return tuple(next_domain() for _ in range(count))
