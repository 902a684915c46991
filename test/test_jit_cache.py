"""The on-disk cache of compiled code is keyed by every module of rod_sim.core that holds
compiled code: an integrator that inlined an older kernel must not be loaded after the kernel
changed (numba alone looks only at the integrator's own file), and an edit of a pure-Python
module (models, scene, ...) must not recompile anything."""
from __future__ import annotations

import shutil

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
