"""First-run experience: `make` installs quietly; `make demo` compiles what the demo runs,
`make test` every registered driver into numba's cache (rod_sim.tools.jit_warm), whatever the
registries hold, in 2 processes (one model each at a time)."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rod_sim.core import jit, names
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


def test_warm_progress_line():
    line = jit_warm.progress_line(3, 12, "full x rk4 on x.yaml", 2.0, 30.0, 90.0)
    assert line == ("rod_sim: [3/12] full x rk4 on x.yaml: 2.0 s (30 s so far, ~90 s left)")
    assert "skipped" in jit_warm.progress_line(1, 2, "a", 0.0, 0.0, 0.0, skipped=True)


def test_warm_groups_are_models_and_the_costliest_run_first():
    plan = jit_warm.groups(jit_warm.drivers())
    models = [g[0][1] for g in plan]
    assert sorted(models) == sorted(names.MODEL_NAMES), "one group per model"
    for group, model in zip(plan, models):
        assert {m for _, m, _ in group} == {model}
    costs = [jit_warm.estimate(g) for g in plan]
    assert costs == sorted(costs, reverse=True)
    assert sum(map(len, plan)) == len(jit_warm.drivers())
    hinge = jit_warm.SCENES[-1]       # its velocity projection is compiled by one process
    assert plan[0][0][0] == hinge and all(g[-1][0] == hinge for g in plan[1:])
    assert all(g[0][0] != hinge for g in plan[1:])


def test_warm_in_two_processes_ticks_while_nothing_finishes(monkeypatch):
    """The parent prints a line every TICK_S while the workers compile (a fake compile that
    sleeps until the parent has ticked twice: waited for, so load only slows it)."""
    import multiprocessing

    global _TICKS
    ticks = _TICKS = multiprocessing.get_context("fork").Event()   # inherited by the workers
    monkeypatch.setattr(jit_warm, "TICK_S", 0.05)
    monkeypatch.setattr(jit_warm, "START", "fork")       # the workers see the fake and _TICKS
    monkeypatch.setattr(jit_warm, "run_group", _fake_group)
    lines = []

    def log(line):
        lines.append(line)
        if sum("compiling" in ln and "so far" in ln for ln in lines) >= 2:
            ticks.set()

    todo = [("a.yaml", "full", "dop853-jit"), ("a.yaml", "reduced", "dop853-jit")]
    assert jit_warm.warm(log, todo, jobs=2) == 2
    assert lines[0].startswith("rod_sim: compiling 2 drivers") and "2 process(es)" in lines[0]
    assert sum(bool(re.match(r"rod_sim: \[\d/2\] .* x dop853-jit on a.yaml: ", ln))
               for ln in lines) == 2
    assert "2 compiled drivers ready" in lines[-1]


_TICKS = None


def _fake_group(group):
    """Stands in for run_group in a worker: waits for the parent's ticks."""
    assert _TICKS.wait(120)
    return [(f"{m} x {i} on {s}", 0.1, 0.1, False) for s, m, i in group]


def test_make_installs_quietly_and_warms_the_cache():
    text = (ROOT / "Makefile").read_text()
    pip_lines = [ln for ln in text.splitlines() if "pip install" in ln]
    assert pip_lines and all(" -q " in ln for ln in pip_lines)
    assert re.search(r"^test: .*\$\(WARM\)", text, re.M)
    assert re.search(r"^demo: .*\$\(WARM_DEMO\)", text, re.M)
    assert re.search(r"^COMPILED = .*rod_sim/core/\*\.py", text, re.M)
    assert re.search(r"^\$\(WARM\): .*\$\(COMPILED\)", text, re.M)
    assert "-m rod_sim.tools.jit_warm --demo" in text
    # rod_sim's bytecode is written ahead (PYTHONDONTWRITEBYTECODE=1 would otherwise make
    # every process compile its modules again) for every target that runs rod_sim
    assert re.search(r"^\$\(BYTECODE\): \$\(SOURCES\)", text, re.M)
    assert "-m compileall -q rod_sim" in text
    for target in ("test", "test-slow", "demo", "flake", "bench", "bench-report"):
        assert re.search(rf"^{target}: .*\$\(BYTECODE\)", text, re.M), target


def test_the_demo_warm_up_covers_what_the_demo_runs():
    """table1 runs both models with dop853-jit, the demo's node the reduced model, compare
    the full one (the Makefile's demo recipe)."""
    text = (ROOT / "Makefile").read_text()
    recipe = text[text.index("\ndemo:"):].split("\n\n")[0]
    assert "rod-sim table1" in recipe and "rod_sim.ros.demo" in recipe and "compare" in recipe
    assert set(jit_warm.DEMO) == {("paper_example.yaml", m, "dop853-jit")
                                  for m in ("full", "reduced")}


WARM_THEN_RUN = """
import sys, tempfile
from pathlib import Path
from rod_sim.tools import jit_warm


def used():
    '''rod_sim.core's compiled functions with each signature that holds machine code in
    this process (loaded from the cache or compiled): numba's own record.'''
    from numba.core.dispatcher import Dispatcher
    out = set()
    for name, module in list(sys.modules.items()):
        if name.startswith("rod_sim.core."):
            for attr, value in vars(module).items():
                if isinstance(value, Dispatcher):
                    out.update(f"{name}.{attr}{sig}" for sig in value.overloads)
    return out


jit_warm.run_group([("paper_example.yaml", sys.argv[1], "dop853-jit")])
warmed = used()
from rod_sim.tools.cli import main
out = Path(tempfile.mkdtemp()) / "run.mcap"
assert main(["simulate", str(jit_warm.CONFIG / "paper_example.yaml"), "--model", sys.argv[1],
             "--t-end", "0.01", "--out", str(out)]) == 0
print("NOT WARMED:", sorted(used() - warmed))
"""


@pytest.mark.skipif(not jit.HAVE_NUMBA, reason="numba not installed")
@pytest.mark.parametrize("model", ["reduced", "full"])
def test_a_run_after_the_warm_up_needs_no_compiled_function_it_did_not_reach(model):
    """`make demo` warms the demo's drivers; the first `simulate` after it then compiled the
    validity monitor's mass operator (the chain's lowest bending mode, called from Python:
    a 3 s compile with its notice, a 5 s start). The warm-up now runs what every run's start
    and every sample call from Python: a 10 ms run of the paper example uses no compiled
    function (or signature) the warm-up did not load (numba's record of the functions
    holding machine code)."""
    done = subprocess.run([sys.executable, "-c", WARM_THEN_RUN, model], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "NOT WARMED: []" in done.stdout, done.stdout
