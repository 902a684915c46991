"""The on-disk cache of compiled code is keyed by every module of rod_sim.core that holds
compiled code: an integrator that inlined an older kernel must not be loaded after the kernel
changed (numba alone looks only at the integrator's own file), and an edit of a pure-Python
module (models, scene, ...) must not recompile anything."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core import erk, jit, kernels


def test_stamp_changes_when_a_compiled_module_changes_and_only_then(tmp_path):
    for path in jit.CORE_DIR.glob("*.py"):
        shutil.copy(path, tmp_path / path.name)
    before = jit.sources_stamp(tmp_path)
    assert jit.sources_stamp(tmp_path) == before
    names = {p.name for p in jit.compiled_sources(tmp_path)}
    assert {"kernels.py", "erk.py", "radau.py", "newton.py", "motion.py"} <= names
    assert not names & {"models.py", "scene.py", "validity.py", "simulator.py"}
    models_file = tmp_path / "models.py"
    models_file.write_text(models_file.read_text() + "\n# edited\n")
    assert jit.sources_stamp(tmp_path) == before             # pure Python: no recompile
    for name in ("kernels.py", "motion.py"):                  # compiled, or compiled elsewhere
        path = tmp_path / name
        path.write_text(path.read_text() + "\n# edited\n")
        assert jit.sources_stamp(tmp_path) != before
        before = jit.sources_stamp(tmp_path)
    (tmp_path / "new_module.py").write_text("from .jit import njit\n")
    assert jit.sources_stamp(tmp_path) not in (before, jit.sources_stamp(jit.CORE_DIR))


def test_stamp_changes_with_the_optimisation_level():
    """Code compiled at another NUMBA_OPT is not loaded (it is recompiled)."""
    assert jit.sources_stamp(opt="3") != jit.sources_stamp(opt="1")
    assert jit.sources_stamp(opt=jit.OPT_LEVEL) == jit.sources_stamp()


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba not installed")
def test_numba_uses_the_package_optimisation_level():
    from numba.core import config

    config.reload_config()              # as numba does before each compile
    assert str(int(config.OPT)) == str(int(jit.OPT_LEVEL.replace("max", "3")))


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba not installed")
def test_compiled_integrators_and_kernels_use_the_core_stamp():
    if not jit.CORE_LOCATORS:
        pytest.skip("this numba has no cache locator API")
    stamp = jit.sources_stamp()
    for dispatcher in (erk.dop853_reduced, erk.fixed_full, kernels.reduced_rhs):
        locator = dispatcher._cache._impl.locator
        assert isinstance(locator, jit.CORE_LOCATORS), type(locator)
        assert locator.get_source_stamp() == stamp


@pytest.mark.skipif(not jit.CACHE_LOCKED, reason="no flock or no numba cache internals")
def test_two_processes_saving_one_function_side_by_side_keep_both_entries(tmp_path,
                                                                          monkeypatch):
    """numba's save reads the index, adds its entry and writes it back: two writers at once
    (make warm's 2 processes, here 2 threads with a widened window) lost an entry before
    the lock; now both signatures are in the index, each with its own data."""
    import threading
    import time

    from numba.core.caching import IndexDataCacheFile

    load_index = IndexDataCacheFile._load_index

    def slow_load_index(self):
        got = load_index(self)
        time.sleep(0.2)            # another writer would read the same index meanwhile
        return got

    monkeypatch.setattr(IndexDataCacheFile, "_load_index", slow_load_index)
    files = [IndexDataCacheFile(str(tmp_path), "f-1.py311", "stamp") for _ in range(2)]
    threads = [threading.Thread(target=f.save, args=(f"sig{i}", f"code{i}"))
               for i, f in enumerate(files)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    monkeypatch.setattr(IndexDataCacheFile, "_load_index", load_index)
    reader = IndexDataCacheFile(str(tmp_path), "f-1.py311", "stamp")
    assert reader.load("sig0") == "code0" and reader.load("sig1") == "code1"


@pytest.mark.parametrize("method", ["Radau", "BDF"])
def test_scipy_jacobians_hand_the_kernel_contiguous_states(method):
    """scipy's finite-difference Jacobian passes columns of a 2-D array; a strided state made
    numba compile the whole kernel again (66 s of CPU per model): the kernel sees only
    C-contiguous states, one specialisation."""
    from pathlib import Path

    from rod_sim.core.integrators import make_integrator
    from rod_sim.core.models import make_model
    from rod_sim.core.simulator import Simulator
    from rod_sim.io.scene_yaml import load_scene

    model = make_model("reduced", load_scene(Path(__file__).resolve().parents[1] / "config"
                                             / "paper_example.yaml"))
    kernel, layouts = model.kernel, []

    def watched(t, y, *args):
        layouts.append(y.flags.c_contiguous)
        return kernel(t, np.ascontiguousarray(y), *args)   # this test compiles nothing

    model.kernel = watched
    Simulator(model, make_integrator(method)).advance(0.01)
    assert len(layouts) > 2 * model.state_size        # a Jacobian was computed
    assert all(layouts)


SHARED_PROBE = """
import json, sys
import numpy as np
from rod_sim.core import dense_lu, jit
A = np.array([[2.0, 1.0], [1.0, 3.0]]); piv = np.zeros(2, dtype=np.int64)
dense_lu.lu_inplace(A, piv)
fn = dense_lu.lu_inplace
print(json.dumps({"path": fn._cache._impl.locator.get_cache_path(),
                  "hits": sum(fn.stats.cache_hits.values()),
                  "misses": sum(fn.stats.cache_misses.values()),
                  "file": jit.__file__}))
"""


def _probe(package_root, cache_root):
    import json
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(package_root), "ROD_SIM_CACHE_DIR": str(cache_root)}
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, "-c", SHARED_PROBE], env=env, capture_output=True,
                          text=True, timeout=300, cwd=package_root)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not jit.CORE_LOCATORS, reason="this numba has no cache locator API")
def test_a_fresh_copy_of_the_sources_loads_the_machine_code_another_copy_compiled(tmp_path):
    """Two checkouts at different paths (a fresh clone beside the first) with the same
    sources: the second loads from the shared cache what the first compiled, and the
    cache's directory is named after the sources, not the path."""
    import shutil

    repo = Path(jit.__file__).resolve().parents[2]
    copies = []
    for name in ("clone_a", "clone_b"):
        dst = tmp_path / name / "rod_sim"
        shutil.copytree(repo / "rod_sim", dst,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        copies.append(dst.parent)
    cache = tmp_path / "cache"
    first = _probe(copies[0], cache)
    second = _probe(copies[1], cache)
    assert first["file"].startswith(str(copies[0])) and second["file"].startswith(str(copies[1]))
    assert first["path"] == second["path"]
    assert Path(first["path"]).parent == cache
    assert first["misses"] >= 1 and first["hits"] == 0
    assert second["hits"] >= 1 and second["misses"] == 0
    assert not list((copies[1] / "rod_sim" / "core" / "__pycache__").glob("*.nbi"))


def test_the_shared_cache_root_comes_from_the_environment(tmp_path):
    assert jit.shared_cache_root({"ROD_SIM_CACHE_DIR": str(tmp_path)}) == tmp_path
    for off in ("", "off", "0", "no", " OFF "):
        assert jit.shared_cache_root({"ROD_SIM_CACHE_DIR": off}) is None
    assert jit.shared_cache_root({"XDG_CACHE_HOME": "/x"}) == Path("/x/rod_sim/numba")
    a = jit.shared_cache_dir("a" * 64, {"ROD_SIM_CACHE_DIR": str(tmp_path)})
    b = jit.shared_cache_dir("b" * 64, {"ROD_SIM_CACHE_DIR": str(tmp_path)})
    assert a.parent == b.parent == tmp_path and a != b


@pytest.mark.skipif(not jit.CORE_LOCATORS, reason="this numba has no cache locator API")
def test_the_shared_cache_switched_off_keeps_the_package_cache():
    repo = Path(jit.__file__).resolve().parents[2]
    got = _probe(repo, "off")
    assert got["path"] == str(repo / "rod_sim" / "core" / "__pycache__")


GENERIC_PROBE = """
import json, sys
from rod_sim.core import jit

@jit.njit
def twice(x):
    return 2.0 * x

@jit.njit
def thrice(x):
    return 3.0 * x

@jit.njit
def apply(f, x):
    return f(x)

callee = twice if sys.argv[1] == "twice" else thrice
value = apply(callee, 1.5)
twice(0.5)
print(json.dumps({"value": value, "plain_hits": sum(twice.stats.cache_hits.values())}))
"""


def test_functions_taking_compiled_functions_stay_out_of_the_disk_cache(tmp_path):
    """A signature holding a compiled function (numba's dispatcher type, a weak reference to
    the writing process's function) never matches in another process: each process added an
    index entry, and once numba's keep-alive of unpickled functions had let one go, a save
    raised "ReferenceError: underlying object has vanished" (CI, test_radau). Here the
    keep-alive is one function, so a later process failed before: now every process gives
    the right value, the generic function writes no index, and a plain function is cached
    and found again."""
    import json
    import subprocess
    import sys

    (tmp_path / "generic_probe.py").write_text(GENERIC_PROBE)
    cache = tmp_path / "cache"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1]),
           "NUMBA_CACHE_DIR": str(cache), "NUMBA_FUNCTION_CACHE_SIZE": "1"}
    results = []
    for callee in ("twice", "thrice", "twice", "thrice"):
        done = subprocess.run([sys.executable, "generic_probe.py", callee], env=env,
                              capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert done.returncode == 0, done.stderr[-2000:]
        results.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert [r["value"] for r in results] == [3.0, 4.5, 3.0, 4.5]
    indexes = sorted(p.name for p in cache.rglob("*.nbi"))
    assert not any(".apply-" in name for name in indexes), indexes
    assert any(".twice-" in name for name in indexes), indexes
    assert results[0]["plain_hits"] == 0 and results[1]["plain_hits"] == 1


def test_a_signature_names_a_function_object_inside_tuples():
    """The check behind the skip: a dispatcher type alone, in a tuple, in a named tuple;
    arrays and scalars do not."""
    import numba

    from rod_sim.core.radau import RadauFns

    @numba.njit
    def f(x):
        return x

    fn = numba.typeof(f)
    arr = numba.typeof(np.zeros(3))
    assert jit.names_a_function_object((fn, arr))
    assert jit.names_a_function_object((arr, numba.typeof((1.0, f))))
    assert jit.names_a_function_object((numba.typeof(RadauFns(f, f, f, f)),))
    assert not jit.names_a_function_object((arr, numba.float64, numba.typeof((arr, 1.0))))


LOAD_PROBE = """
import json, sys
import numpy as np
from rod_sim.core import jit

@jit.njit
def wave(x):
    return np.sum(np.sin(x) * x)

x = np.linspace(0.0, 1.0, 5)
value = wave(x)
refreshed = "numba.cpython.setobj" in sys.modules     # installed by a refresh only
out = {"value": value, "hits": sum(wave.stats.cache_hits.values()), "refreshed": refreshed}
if sys.argv[1] == "compile":                          # a function no cache holds, after a load
    @jit.njit(cache=False)
    def fresh(x):
        return np.sum(np.cos(x) ** 2)
    out["fresh"] = fresh(x)
print(json.dumps(out))
"""


@pytest.mark.skipif(not getattr(jit, "CACHE_LOADS_WITHOUT_REFRESH", False),
                    reason="numba's cache internals differ")
def test_a_cached_function_loads_without_numbas_registries_and_compiling_still_works(tmp_path):
    """numba refreshed its whole target context before every cache load: importing and
    installing every lowering module (sets, lists, complex math, ...; numpy's array math,
    which imports scipy.linalg), 0.38-0.47 s of a warm start on an idle machine. A process
    that only loads machine code now installs none of them (this probe's function still
    imports numpy's array math when its environment is rebuilt, for np.sum; set support
    comes with a refresh only), gets the same value (its arrays allocated through numba's
    runtime, which the load initializes: without it this probe segfaulted), and a function
    compiled after the load (numba's compiler refreshes the context itself) still works."""
    import json
    import subprocess
    import sys

    (tmp_path / "load_probe.py").write_text(LOAD_PROBE)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1]),
           "NUMBA_CACHE_DIR": str(tmp_path / "cache")}

    def run(what):
        done = subprocess.run([sys.executable, "load_probe.py", what], env=env,
                              capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert done.returncode == 0, done.stderr[-2000:]
        return json.loads(done.stdout.strip().splitlines()[-1])

    x = np.linspace(0.0, 1.0, 5)
    first, loaded, compiled = run("load"), run("load"), run("compile")
    assert first["hits"] == 0 and first["refreshed"]          # compiled: registries loaded
    assert loaded["hits"] == 1 and not loaded["refreshed"]
    for got in (first, loaded, compiled):
        assert got["value"] == pytest.approx(float(np.sum(np.sin(x) * x)), rel=1e-15)
    assert compiled["hits"] == 1
    assert compiled["fresh"] == pytest.approx(float(np.sum(np.cos(x) ** 2)), rel=1e-15)
