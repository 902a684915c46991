"""Compiled calls whose argument types are known ahead: the overload looked up, not typed.

numba's dispatcher types every argument on every call. For the kernels' named tuples of
arrays (:class:`~rod_sim.core.kernels.Chain`, ``Extra``, ``Loads``: some 60 arrays, all inside
a driver's ``Problem``) that is most of a small call: ``reduced_rhs`` at n = 8 took 11 us
through the dispatcher and 3.6 us through the entry point of its compiled overload (the C
wrapper that unboxes the arguments; 2026-11-26). A model's ``Chain`` and ``Loads`` and a
:class:`~rod_sim.core.models.ModelData`'s ``Extra`` tuples are built once and never change
type (immutable tuples of arrays whose dtype, rank, layout and writeability nobody changes),
so their types are found once (:func:`typeof`, ~0.1 ms) and kept by their owner; an array
made at the call site is typed by :func:`array_type` from a small table. :func:`call` looks
the whole signature up among the function's compiled overloads (numba's own table, keyed by
argument types: the overload its dispatcher picks for an exact match) and calls that
overload's entry point. When the function has no overload for exactly these types yet, or is
not compiled (``ROD_SIM_NO_JIT``, or numba missing), it is called as usual: the dispatcher then
types the arguments (and compiles), so the result never depends on this module.

Memory: the cache holds one entry per (function, signature), each keeping its numba types
alive (numba interns types, so equal types are the same object: the cache's key is their
ids).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

try:
    import numba as _numba
    from numba.core import types as _types
except ImportError:             # plain Python kernels (rod_sim.core.jit without numba)
    _numba = None
    _types = None

FLOAT64 = None if _types is None else _types.float64
"""The type of a Python float argument (numba types a float and an np.float64 alike)."""
INT64 = None if _types is None else _types.int64
"""The type of a Python int argument that fits int64."""

_ARRAYS: dict[tuple, Any] = {}
"""(dtype, ndim, writeable) of an aligned C-contiguous array -> its numba type."""
_ENTRIES: dict[tuple, tuple] = {}
"""(function, ids of the signature's types) -> (the types, the overload's entry point)."""
MAX_ENTRIES = 256
"""Entries kept at most (the cache is emptied beyond it: a new entry costs one lookup)."""


def typeof(value) -> Any:
    """numba's type of ``value`` (None without numba): once per long-lived argument."""
    return None if _numba is None else _numba.typeof(value)


def array_type(a: np.ndarray) -> Any:
    """numba's type of the array ``a`` (None without numba): from a table for aligned
    C-contiguous arrays (~0.2 us), else by :func:`typeof`."""
    if _numba is None:
        return None
    flags = a.flags
    if not (flags.c_contiguous and flags.aligned):
        return _numba.typeof(a)
    key = (a.dtype, a.ndim, flags.writeable)
    found = _ARRAYS.get(key)
    if found is None:
        found = _ARRAYS[key] = _numba.typeof(a)
    return found


def call(fn: Callable, signature: tuple, *args):
    """``fn(*args)`` through the entry point of ``fn``'s compiled overload for
    ``signature`` (the numba types of ``args``, in order: the caller vouches for them), or
    through ``fn`` itself when it has none for exactly these types (or is not compiled)."""
    key = (fn, *map(id, signature))
    hit = _ENTRIES.get(key)
    if hit is not None:
        return hit[1](*args)
    overloads = getattr(fn, "overloads", None)
    out = fn(*args)             # types the arguments and compiles when it must
    if overloads is not None and None not in signature:
        found = overloads.get(tuple(signature))
        if found is not None:
            if len(_ENTRIES) >= MAX_ENTRIES:
                _ENTRIES.clear()
            _ENTRIES[key] = (tuple(signature), found.entry_point)
    return out
