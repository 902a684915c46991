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
validity, ...) recompiles nothing. The machine code is kept in a cache that every
checkout on the machine shares (:func:`shared_cache_dir`: ``~/.cache/rod_sim/numba/<stamp>``,
``ROD_SIM_CACHE_DIR`` to move it, ``off`` for the package's ``__pycache__``): a fresh clone of
sources compiled before starts warm.

Compile-time settings (measured with ``python -m rod_sim.tools.jit_profile``; README,
"Compile time"): numba's LLVM optimisation level :data:`OPT_LEVEL` (``ROD_SIM_NUMBA_OPT``, or
``NUMBA_OPT``; default numba's 3) and :data:`INLINE` (``ROD_SIM_NUMBA_INLINE``: whether the
``inline="always"`` option of the kernels' helpers is honoured; default yes). Both are part of
the cache stamp, so that code compiled with other settings is never loaded. Dropping the
inlining halves a driver's cold compile (reduced x dop853-jit: 84 -> 38 s of CPU) with
bit-identical results but costs 19-34 % of run time; NUMBA_OPT 1 saves 10-19 % of compile
time and costs up to 7 % of run time: the defaults stay.

Compiled functions release the GIL while they run (``nogil=True``): a compiled call of a
100 000-rod chain holds the main thread 0.3-1.1 s, and Python's other threads (the watchdog
that ends a start-up or a command within 1 s of Ctrl-C, :mod:`rod_sim.app.signals`; the
progress lines) run meanwhile. The release costs ~0.06 us per call from Python (0.29 ->
0.35 us for a call that reads one element).
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

CORE_DIR = Path(__file__).resolve().parent

DEFAULT_OPT_LEVEL = "3"
"""numba's optimisation level for this package unless ``ROD_SIM_NUMBA_OPT`` or ``NUMBA_OPT``
says otherwise ('0' .. '3' or 'max')."""
OPT_LEVEL = (os.environ.get("ROD_SIM_NUMBA_OPT") or os.environ.get("NUMBA_OPT")
             or DEFAULT_OPT_LEVEL)
"""The optimisation level in use (a string, as ``NUMBA_OPT`` takes it)."""
INLINE = os.environ.get("ROD_SIM_NUMBA_INLINE", "always")
"""'always': the ``inline="always"`` option of the kernels' helpers is honoured (numba
inlines their IR at every call site and types it again there); 'never': it is dropped (each
helper is compiled once and called; LLVM may still inline the machine code)."""


COMPILED_MARK = b"njit"
"""A module of rod_sim.core whose text holds this word holds compiled code (or code that
compiled code inlines) and is part of the cache stamp."""


def compiled_sources(directory: Path = CORE_DIR) -> list[Path]:
    """The ``*.py`` files of ``directory`` that hold compiled code, sorted by name."""
    return [p for p in sorted(Path(directory).glob("*.py")) if COMPILED_MARK in p.read_bytes()]


def sources_stamp(directory: Path = CORE_DIR, opt: str | None = None) -> str:
    """SHA-256 over the optimisation level ``opt`` (default :data:`OPT_LEVEL`) and the names
    and contents of :func:`compiled_sources` of ``directory``."""
    digest = hashlib.sha256(f"NUMBA_OPT={OPT_LEVEL if opt is None else opt}\0"
                            f"inline={INLINE}\0".encode())
    for path in compiled_sources(directory):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


SHARED_CACHE_ENV = "ROD_SIM_CACHE_DIR"
"""Environment variable naming the shared compile cache's root; empty or ``off``: none (the
package's own ``__pycache__`` only)."""


def shared_cache_root(environ=os.environ) -> Path | None:
    """The root of the compile cache that every checkout of this package on the machine
    shares (:data:`SHARED_CACHE_ENV`, else ``$XDG_CACHE_HOME/rod_sim/numba``, else
    ``~/.cache/rod_sim/numba``); None when switched off or no home directory is known."""
    text = environ.get(SHARED_CACHE_ENV)
    if text is not None:
        return None if text.strip().lower() in ("", "off", "0", "no") else Path(text)
    xdg = environ.get("XDG_CACHE_HOME")
    if xdg:
        return Path(xdg) / "rod_sim" / "numba"
    try:
        return Path.home() / ".cache" / "rod_sim" / "numba"
    except RuntimeError:
        return None


def shared_cache_dir(stamp: str, environ=os.environ) -> Path | None:
    """The shared cache's directory for the sources of ``stamp`` (and this numba and Python):
    two checkouts with the same compiled sources load each other's machine code, checkouts
    that differ never meet (their stamps differ)."""
    root = shared_cache_root(environ)
    if root is None:
        return None
    try:
        import numba
        numba_version = numba.__version__
    except ImportError:
        numba_version = "none"
    py = f"py{sys.version_info.major}{sys.version_info.minor}"
    return root / f"{stamp[:20]}-numba{numba_version}-{py}"


def _install_core_locators(caching) -> tuple:
    """Put cache locators stamped with :func:`sources_stamp` in front of numba's own for the
    functions defined in this package (numba's locator classes are internal API: when they
    are missing nothing is installed and numba's defaults apply). In order: ``NUMBA_CACHE_DIR``
    when the user sets it; :func:`shared_cache_dir` (named by the sources' content, not their
    path or time: a fresh clone of the same sources finds its machine code compiled); where
    that cannot be written, the package's ``__pycache__``, then numba's user-wide place."""
    stamp = sources_stamp()
    shared = shared_cache_dir(stamp)

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
    mixin = getattr(caching, "_SourceFileBackedLocatorMixin", None)
    if shared is not None and mixin is not None:

        class CoreSharedCacheLocator(CoreSources, bases[0]):
            """numba's locator protocol with :func:`shared_cache_dir` as the directory."""

            def __init__(self, py_func, py_file):
                self._py_file = py_file
                self._lineno = py_func.__code__.co_firstlineno
                self._cache_path = str(shared)

            @classmethod
            def from_function(cls, py_func, py_file):
                if Path(py_file).resolve().parent != CORE_DIR:
                    return None
                return mixin.from_function.__func__(cls, py_func, py_file)

        mine = (mine[0], CoreSharedCacheLocator, *mine[1:])
    impl._locator_classes = [*mine, *[c for c in impl._locator_classes
                                      if not issubclass(c, CoreSources)]]
    return mine


CACHE_LOCK = ".rod_sim_cache.lock"
"""Lock file in each numba cache directory (:func:`_lock_cache_files`)."""


def _lock_cache_files(caching) -> bool:
    """Make numba's cache safe for processes compiling side by side (``make warm`` runs 2):
    numba writes an index file (signature -> data file) and the data file, each atomically,
    but a save reads the index, picks a data file number and writes both, so two processes
    saving different signatures of one function at once can lose an entry or pair one
    signature with the other's machine code. Saves hold an exclusive ``flock`` on
    :data:`CACHE_LOCK` of the cache directory, loads a shared one. Returns False (nothing
    changed) where flock or numba's internal class is missing."""
    try:
        import fcntl
    except ImportError:
        return False
    cls = getattr(caching, "IndexDataCacheFile", None)
    if cls is None or not all(hasattr(cls, name) for name in ("save", "load")):
        return False
    if getattr(cls, "_rod_sim_locked", False):
        return True

    def locked(method, mode):
        def wrapper(self, *args, **kwargs):
            try:
                fd = os.open(os.path.join(self._cache_path, CACHE_LOCK),
                             os.O_RDWR | os.O_CREAT, 0o644)
            except (OSError, AttributeError):
                return method(self, *args, **kwargs)
            try:
                fcntl.flock(fd, mode)
                return method(self, *args, **kwargs)
            finally:
                os.close(fd)                    # releases the lock
        wrapper.__wrapped__ = method
        return wrapper

    cls.save = locked(cls.save, fcntl.LOCK_EX)
    cls.load = locked(cls.load, fcntl.LOCK_SH)
    cls._rod_sim_locked = True
    return True


def names_a_function_object(signature) -> bool:
    """Whether a compiled function's signature (a tuple of numba types) takes a compiled
    function as an argument, alone or inside a tuple (numba's dispatcher type: a weak
    reference to that process's function object)."""
    from numba.core.types.functions import WeakType

    stack, seen = [signature], set()
    while stack:
        item = stack.pop()
        if id(item) in seen:
            continue
        seen.add(id(item))
        if isinstance(item, WeakType):
            return True
        if isinstance(item, (tuple, list)):
            stack.extend(item)
        elif isinstance(getattr(item, "key", None), tuple):
            stack.extend(item.key)
    return False


def _skip_function_object_signatures(caching) -> bool:
    """Keep signatures that take compiled functions as arguments (the generic drivers:
    ``dop853_run(rhs, ...)``, ``radau_run_work(fns, ...)``, their helpers) out of numba's disk
    cache. Their index keys hold the writing process's function objects: no other process
    ever matches them (each process compiled them again and added one more entry), and a
    save re-pickles every key of the index, which fails with "ReferenceError: underlying
    object has vanished" once numba's keep-alive of unpickled functions (128) has let one go
    (CI, test_radau: a _newton index of ~20 processes' entries). The named drivers
    (``dop853_reduced``, ...) take no function and are cached whole, the code of the generic
    ones inside them. Returns False (nothing changed) where numba's internal class is
    missing."""
    cls = getattr(caching, "IndexDataCacheFile", None)
    if cls is None or not all(hasattr(cls, name) for name in ("save", "load")):
        return False
    if getattr(cls, "_rod_sim_skips_function_objects", False):
        return True
    save, load = cls.save, cls.load

    def save_unless_function_object(self, key, data):
        if not names_a_function_object(key[0]):
            save(self, key, data)

    def load_unless_function_object(self, key):
        return None if names_a_function_object(key[0]) else load(self, key)

    save_unless_function_object.__wrapped__ = save
    load_unless_function_object.__wrapped__ = load
    cls.save, cls.load = save_unless_function_object, load_unless_function_object
    cls._rod_sim_skips_function_objects = True
    return True


def linked_at_load(target_context) -> None:
    """Provide what machine code loaded from the cache links against and numba's context
    refresh would have provided: the NRT runtime's functions (array allocation;
    ``rtsys.initialize``, which ``load_additional_registries`` calls: without it a loaded
    function that allocates an array crashed) and the hash secret's symbols (added when
    ``numba.cpython.hashing`` is imported). The other symbols numba adds (its C helpers,
    the math library, exception classes) come with the context's ``init``."""
    from numba.core.runtime import rtsys
    import numba.cpython.hashing  # noqa: F401 - its import adds the hash secret's symbols

    rtsys.initialize(target_context)


REFRESH_FREE_NUMBA = ("0.68.",)
"""numba versions whose cache load :func:`_load_without_refresh` was checked against (its
internals may change in any release; other versions keep numba's own load)."""


def _load_without_refresh(caching, version: str) -> bool:
    """Load machine code from numba's disk cache without refreshing the target context first.
    numba's ``Cache.load_overload`` calls ``target_context.refresh()`` before every load; the
    first refresh of a process imports and installs every lowering and typing registry (sets,
    lists, strings, complex math, random, numpy's array math with its scipy.linalg check):
    0.38-0.47 s here, of which a load needs only :func:`linked_at_load` (0.07-0.09 s). A
    warm 10 ms run of the paper example took 1.92-2.37 s against 1.57-1.89 s (4 alternating
    pairs, idle machine). Whatever compiles still refreshes: numba's compiler does so itself
    (``CompilerBase.__init__``), and so does ``BaseContext.get_function`` on a first miss.
    Returns False (numba's method stays) for a numba version not in
    :data:`REFRESH_FREE_NUMBA` or where the helpers it calls are missing."""
    if not version.startswith(REFRESH_FREE_NUMBA):
        return False
    cls = getattr(caching, "Cache", None)
    if cls is None or not all(hasattr(cls, name) for name in (
            "load_overload", "_load_overload", "_guard_against_spurious_io_errors")):
        return False
    if getattr(cls, "_rod_sim_loads_without_refresh", False):
        return True
    original = cls.load_overload

    def load_overload(self, sig, target_context):
        linked_at_load(target_context)
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)

    load_overload.__wrapped__ = original
    cls.load_overload = load_overload
    cls._rod_sim_loads_without_refresh = True
    return True


try:  # pragma: no cover - exercised by whichever branch the machine has
    if os.environ.get("ROD_SIM_NO_JIT"):
        raise ImportError("disabled by ROD_SIM_NO_JIT")
    # numba reads NUMBA_OPT at import and again whenever a NUMBA_ variable changes
    # (config.reload_config before each compile): set both, before anything compiles
    os.environ["NUMBA_OPT"] = OPT_LEVEL
    import numba
    from numba.core import config as _config

    _config.OPT = _config._process_opt_level(OPT_LEVEL)

    HAVE_NUMBA = True
    try:
        from numba.core import caching as _caching
        CORE_LOCATORS = _install_core_locators(_caching)
        CACHE_LOCKED = _lock_cache_files(_caching)
        CACHE_SKIPS_FUNCTION_OBJECTS = _skip_function_object_signatures(_caching)
        CACHE_LOADS_WITHOUT_REFRESH = _load_without_refresh(_caching, numba.__version__)
    except ImportError:
        CORE_LOCATORS, CACHE_LOCKED, CACHE_SKIPS_FUNCTION_OBJECTS = (), False, False
        CACHE_LOADS_WITHOUT_REFRESH = False

    def njit(fn=None, **kwargs):
        """``numba.njit(cache=True, nogil=True)`` with the given options."""
        opts = {"cache": True, "nogil": True, **kwargs}
        if INLINE == "never":
            opts.pop("inline", None)
        if fn is None:
            return lambda f: numba.njit(**opts)(f)
        return numba.njit(**opts)(fn)

except ImportError:  # pragma: no cover
    HAVE_NUMBA = False
    CORE_LOCATORS, CACHE_LOCKED, CACHE_SKIPS_FUNCTION_OBJECTS = (), False, False
    CACHE_LOADS_WITHOUT_REFRESH = False

    def njit(fn=None, **kwargs):
        if fn is None:
            return lambda f: f
        return fn
