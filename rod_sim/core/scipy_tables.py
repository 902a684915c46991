"""scipy's DOP853 tables without the cost of importing ``scipy.integrate``.

The compiled integrators take their Butcher tables from scipy's
``scipy.integrate._ivp.dop853_coefficients`` (a module of numpy arrays only). Importing it
by name runs ``scipy.integrate``'s package ``__init__`` first (quadrature, ``scipy.special``,
``scipy.optimize``, ...): about 1 s of a warm start that never calls a scipy integrator
(measured: 1.4 s of 3.8 s profiled for a 10 ms ``rod-sim simulate`` of the paper's example).
:func:`light_dop853_tables` makes that one module importable alone for the duration of a
``with`` block: it loads the table file itself and registers it with two bare parent
packages, which it removes again afterwards, so that a later ``import scipy.integrate`` (the
scipy methods of ``--integrator``) imports the real package as usual.
"""
from __future__ import annotations

import contextlib
import importlib.util
import sys
import types
from pathlib import Path

TABLES = "scipy.integrate._ivp.dop853_coefficients"


@contextlib.contextmanager
def light_dop853_tables():
    """Within the block, ``from scipy.integrate._ivp import dop853_coefficients`` loads only
    that module (when ``scipy.integrate`` is not imported yet; otherwise nothing changes).
    If the file is not where scipy keeps it, the block runs with the normal import."""
    if "scipy.integrate" in sys.modules or "scipy.integrate._ivp" in sys.modules:
        yield
        return
    import scipy

    path = Path(scipy.__file__).resolve().parent / "integrate" / "_ivp" / \
        "dop853_coefficients.py"
    spec = importlib.util.spec_from_file_location(TABLES, path)
    if spec is None or spec.loader is None or not path.is_file():
        yield
        return
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    ivp = types.ModuleType("scipy.integrate._ivp")
    ivp.dop853_coefficients = tables
    stubs = {"scipy.integrate": types.ModuleType("scipy.integrate"),
             "scipy.integrate._ivp": ivp, TABLES: tables}
    for name, module in stubs.items():
        sys.modules.setdefault(name, module)
    try:
        yield
    finally:
        for name, module in stubs.items():
            if sys.modules.get(name) is module:
                del sys.modules[name]
