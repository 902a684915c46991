"""Optional JIT: numba's ``njit`` when numba is installed, otherwise plain Python.

Set ``ROD_SIM_NO_JIT=1`` to run the kernels as plain Python (slow; for debugging and for
checking that the compiled and interpreted code agree).
"""
from __future__ import annotations

import os

try:  # pragma: no cover - exercised by whichever branch the machine has
    if os.environ.get("ROD_SIM_NO_JIT"):
        raise ImportError("disabled by ROD_SIM_NO_JIT")
    import numba

    HAVE_NUMBA = True

    def njit(fn=None, **kwargs):
        """``numba.njit(cache=True)`` with the given options."""
        opts = {"cache": True, **kwargs}
        if fn is None:
            return lambda f: numba.njit(**opts)(f)
        return numba.njit(**opts)(fn)

except ImportError:  # pragma: no cover
    HAVE_NUMBA = False

    def njit(fn=None, **kwargs):
        if fn is None:
            return lambda f: f
        return fn
