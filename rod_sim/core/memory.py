"""The memory a run needs and the memory this process may count on: refusing a chain that
would not fit before allocating it (the command line and the node both check it).

Figures: docs/interface.md ("Limits") and docs/reliability.md. A refusal is a
:class:`~rod_sim.core.scene.SceneError` keyed ``rods.count`` naming the figure and what limits
it.
"""
from __future__ import annotations

import os

from .scene_error import SceneError

# Peak memory of a run is linear in n (the O(n) kernels keep no n x n array): a base for the
# interpreter, numba, numpy and the log writer, plus bytes per rod for the scene, the model,
# the integrators' workspaces and one sample's messages (bounds above the peak RSS measured in
# docs/bench.md, "start-up and memory").
MODEL_MEMORY = (400 * 1024 ** 2, 16 * 1024)     # (base, per rod) [bytes]


def gib(nbytes: float) -> str:
    """``nbytes`` in GiB, 3 significant digits."""
    return f"{nbytes / 1024 ** 3:.3g} GiB"


MEMORY_LIMIT_ENV = "ROD_SIM_MEMORY_LIMIT"
"""Environment variable: a cap [bytes] on the memory rod_sim may count on (e.g. several
instances on one machine); the smaller of it and the machine's available memory is used."""


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation: Linux MemAvailable (None if unknown),
    capped by ``$ROD_SIM_MEMORY_LIMIT`` when that is a whole number of bytes."""
    return memory_budget()[0]


def memory_budget() -> tuple[int | None, str]:
    """(bytes a new allocation of this process can count on, what limits it): the smallest of
    the machine's MemAvailable, the room left under the process's cgroup memory limit (v2
    ``memory.max`` - ``memory.current``, v1 ``memory.limit_in_bytes`` - usage), under its
    address-space limit (RLIMIT_AS, ``ulimit -v``: the limit - VmSize, plus what is already
    resident, since the estimates are of resident memory) and ``$ROD_SIM_MEMORY_LIMIT``;
    (None, '') when none is known."""
    found = [(_machine_memory(), "available on the machine"),
             (_cgroup_memory(), "under the cgroup memory limit"),
             (_address_space(), "under the address-space limit (ulimit -v)")]
    cap = os.environ.get(MEMORY_LIMIT_ENV, "").strip()
    if cap.isdigit():
        found.append((int(cap), f"by ${MEMORY_LIMIT_ENV}"))
    known = [(have, why) for have, why in found if have is not None]
    return min(known, key=lambda f: f[0]) if known else (None, "")


def _machine_memory() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _read_int(path: str) -> int | None:
    try:
        with open(path, encoding="ascii") as fh:
            text = fh.read().strip()
        return int(text) if text.isdigit() else None      # 'max': no limit
    except (OSError, ValueError):
        return None


PROC_CGROUP = "/proc/self/cgroup"
CGROUP_ROOT = "/sys/fs/cgroup"
UNLIMITED = 1 << 60
"""A cgroup v1 limit at least this large means none (the kernel writes ~2^63 rounded)."""


def _cgroup_memory() -> int | None:
    """Bytes left under this process's cgroup memory limit, None without one."""
    try:
        with open(PROC_CGROUP, encoding="ascii") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return None
    for line in lines:
        _, controllers, path = line.split(":", 2)
        path = path.strip("/")
        if controllers == "":                                       # cgroup v2
            candidates = [(CGROUP_ROOT, "memory.max", "memory.current")]
        elif "memory" in controllers.split(","):                    # cgroup v1
            candidates = [(os.path.join(CGROUP_ROOT, "memory"), "memory.limit_in_bytes",
                           "memory.usage_in_bytes")]
        else:
            continue
        for root, limit_file, usage_file in candidates:
            # the process's own group, else the mount's root (a namespaced container)
            for base in (os.path.join(root, path), root):
                limit = _read_int(os.path.join(base, limit_file))
                if limit is not None and limit < UNLIMITED:
                    usage = _read_int(os.path.join(base, usage_file)) or 0
                    return max(0, limit - usage)
    return None


def _address_space() -> int | None:
    """Bytes of address space left under RLIMIT_AS (``ulimit -v``) plus this process's
    resident memory (the model estimates count resident bytes from the start of the run, and
    what is resident now is part of them); None without a limit."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError, AttributeError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    sizes = {}
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(("VmSize:", "VmRSS:")):
                    sizes[line.split(":")[0]] = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return max(0, soft - sizes.get("VmSize", 0) + sizes.get("VmRSS", 0))


_AVAILABLE_MEMORY = available_memory


def model_memory(n: int) -> int:
    """Estimated peak memory [bytes] of a run of an n-rod chain (:data:`MODEL_MEMORY`)."""
    base, per_rod = MODEL_MEMORY
    return base + per_rod * n


def check_model_memory(n: int, available: int | None = None) -> None:
    """Refuse a chain whose model would not fit in the memory this process may use (the
    machine's, its cgroup's and its address-space limit: :func:`memory_budget`), before
    allocating it."""
    need = model_memory(n)
    if available is None:
        have, why = memory_budget()
        if available_memory is not _AVAILABLE_MEMORY:     # replaced (tests): use it
            have, why = available_memory(), "available"
    else:
        have, why = available, "available"
    if have is not None and need > have:
        raise SceneError("rods.count", f"a chain of {n} rods needs about {gib(need)} of memory "
                                       f"({gib(MODEL_MEMORY[1] * 1024)} per 1024 rods); "
                                       f"{gib(have)} {why}")
