"""One BLAS thread in rod_sim's own processes (the ``rod-sim`` command, the node).

numpy and scipy each load an OpenBLAS that starts a thread per core and splits large vector
operations among them. On a machine whose cores are shared with other work that costs more
than it saves: the validity monitor's Lanczos iteration (scipy's ARPACK, at start-up of a
reduced model of up to 4096 rods) took 1.5-5 s on 4096 rods with two BLAS threads and 0.3 s
with one (2026-11-28, two shared cores); the node runs on one core by design. The limit is
OpenBLAS's own ``OPENBLAS_NUM_THREADS``, read when the library loads: :func:`one_blas_thread`
must run before numpy is imported, and a value the user set is kept."""
from __future__ import annotations

import os
import sys

VARIABLE = "OPENBLAS_NUM_THREADS"


def one_blas_thread() -> bool:
    """Set ``OPENBLAS_NUM_THREADS=1`` unless it is set already; returns whether it takes effect
    (False once numpy is loaded: its OpenBLAS has read the variable then)."""
    os.environ.setdefault(VARIABLE, "1")
    return "numpy" not in sys.modules
