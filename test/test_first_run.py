"""First-run experience: `make` installs quietly and compiles every registered driver into
numba's cache (rod_sim.tools.jit_warm), whatever the registries hold."""
import re
from pathlib import Path

from rod_sim.core import names
from rod_sim.tools import jit_warm

ROOT = Path(__file__).resolve().parents[1]


def test_warm_covers_every_registered_model_and_integrator(monkeypatch):
    monkeypatch.setattr(names, "INTEGRATOR_NAMES", names.INTEGRATOR_NAMES + ("new-driver",))
    got = set(jit_warm.drivers())
    for scene in jit_warm.SCENES:
        assert (jit_warm.CONFIG / scene).is_file()
        for model in names.MODEL_NAMES:
            for integrator in names.INTEGRATOR_NAMES:
                assert (scene, model, integrator) in got
    assert any(i == "new-driver" for _, _, i in got)


def test_warm_runs_and_skips_only_refused_combinations(monkeypatch):
    """One model (the cache is warm after the first test run, so this is ~1 s); only scipy's
    methods are refused on the hinge scene (they cannot follow stop contacts): every compiled
    integrator, radau-jit included, locates hinge events."""
    monkeypatch.setattr(names, "MODEL_NAMES", ("reduced",))
    lines = []
    ran = jit_warm.warm(log=lines.append)
    assert ran == 2 * len(names.INTEGRATOR_NAMES) - len(names.SCIPY_METHODS)
    assert f"{ran} compiled drivers" in lines[-1]
    total = len(jit_warm.drivers())
    progress = [ln for ln in lines if re.match(r"rod_sim: \[\d+/\d+\] ", ln)]
    assert [int(re.search(r"\[(\d+)/", ln).group(1)) for ln in progress] == list(
        range(1, total + 1)), "one progress line per driver, in order"
    assert all(f"/{total}]" in ln and "s left)" in ln for ln in progress)
    assert sum("skipped" in ln for ln in progress) == total - ran


def test_warm_progress_estimates_the_time_left_from_the_mean_so_far():
    line = jit_warm.progress_line(3, 12, "full x rk4 on x.yaml", 2.0, 30.0)
    assert line == ("rod_sim: [3/12] full x rk4 on x.yaml: 2.0 s (30 s so far, ~90 s left)")
    assert "~0 s left" in jit_warm.progress_line(12, 12, "a", 1.0, 40.0)
    assert "skipped" in jit_warm.progress_line(1, 2, "a", 0.0, 0.0, skipped=True)


def test_make_installs_quietly_and_warms_the_cache():
    text = (ROOT / "Makefile").read_text()
    pip_lines = [ln for ln in text.splitlines() if "pip install" in ln]
    assert pip_lines and all(" -q " in ln for ln in pip_lines)
    assert re.search(r"^venv: .*\$\(WARM\)", text, re.M)
    assert re.search(r"^\$\(WARM\): .*rod_sim/core/\*\.py", text, re.M)
    assert "-m rod_sim.tools.jit_warm" in text
