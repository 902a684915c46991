"""Optional JIT: numba's ``njit`` when numba is installed, otherwise plain Python.

Set ``ROD_SIM_NO_JIT=1`` to run the kernels as plain Python (slow; for debugging and for
checking that the compiled and interpreted code agree).

Compiled code is cached on disk (``cache=True``). numba judges a cache entry fresh by the
content of the function's own source file only, but the compiled integrators of ``erk.py``
inline the kernels of ``kernels.py``: after an edit or an upgrade that changes a kernel and
not ``erk.py``, numba would load an integrator with the old kernel inside. The functions of
this package are therefore cached under a stamp of every module of ``rod_sim.core`` that
holds compiled code (:func:`compiled_sources`: the modules that name ``njit``, including a
plain-Python function compiled elsewhere, as motion.py's ``profile_at``), so that a change to
any of them recompiles them all, and an edit of the pure-Python modules (models, scene,
validity, ...) recompiles nothing.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

CORE_DIR = Path(__file__).resolve().parent


COMPILED_MARK = b"njit"
"""A module of rod_sim.core whose text holds this word holds compiled code (or code that
compiled code inlines) and is part of the cache stamp."""


def compiled_sources(directory: Path = CORE_DIR) -> list[Path]:
    """The ``*.py`` files of ``directory`` that hold compiled code, sorted by name."""
    return [p for p in sorted(Path(directory).glob("*.py")) if COMPILED_MARK in p.read_bytes()]


def sources_stamp(directory: Path = CORE_DIR) -> str:
    """SHA-256 over the names and contents of :func:`compiled_sources` of ``directory``."""
    digest = hashlib.sha256()
    for path in compiled_sources(directory):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def _install_core_locators(caching) -> tuple:
    """Put cache locators stamped with :func:`sources_stamp` in front of numba's own for the
    functions defined in this package (numba's locator classes are internal API: when they
    are missing nothing is installed and numba's defaults apply)."""
    stamp = sources_stamp()

    class CoreSources:
        @classmethod
        def from_function(cls, py_func, py_file):
            if Path(py_file).resolve().parent != CORE_DIR:
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self):
            return stamp

    bases = [getattr(caching, name, None) for name in
             ("UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")]
    impl = getattr(caching, "CacheImpl", None)
    if impl is None or any(b is None for b in bases) or not hasattr(impl, "_locator_classes"):
        return ()
    mine = tuple(type(f"CoreSources{b.__name__}", (CoreSources, b), {"__module__": __name__})
                 for b in bases)
    impl._locator_classes = [*mine, *[c for c in impl._locator_classes
                                      if not issubclass(c, CoreSources)]]
    return mine


try:  # pragma: no cover - exercised by whichever branch the machine has
    if os.environ.get("ROD_SIM_NO_JIT"):
        raise ImportError("disabled by ROD_SIM_NO_JIT")
    import numba

    HAVE_NUMBA = True
    try:
        from numba.core import caching as _caching
        CORE_LOCATORS = _install_core_locators(_caching)
    except ImportError:
        CORE_LOCATORS = ()

    def njit(fn=None, **kwargs):
        """``numba.njit(cache=True)`` with the given options."""
        opts = {"cache": True, **kwargs}
        if fn is None:
            return lambda f: numba.njit(**opts)(f)
        return numba.njit(**opts)(fn)

except ImportError:  # pragma: no cover
    HAVE_NUMBA = False
    CORE_LOCATORS = ()

    def njit(fn=None, **kwargs):
        if fn is None:
            return lambda f: f
        return fn
