"""Bad or extreme input to ``rod-sim simulate`` and the scene loader: one line naming the option
or key, exit status 2 (1 when a started run stops), no traceback, no file left behind, and
the resource limits of rod_sim/app/limits.py."""
import io
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.quote import QUOTE_LIMIT, quote
from rod_sim.core.scene import Scene, SceneError
from rod_sim.io.series import read_rod_states
from rod_sim.io.scene_yaml import MAX_SCENE_BYTES, load_scene
from rod_sim.app import limits
from rod_sim.core import memory
from rod_sim.tools import cli
from rod_sim.app.common import COMPILE_NOTICE, UsageError
from untimed import untimed_lines

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "paper_example.yaml"
SMALL = {"rods": {"count": 3, "length": 1.0, "mass_per_length": 1.0, "bending_stiffness": 100.0},
         "nodes": {"mass": 1.0}, "hinges": {"stiffness": 10.0, "damping": 0.1},
         "loads": [{"node": 3, "axis": "y", "shape": "constant", "amplitude": 1.0}]}


def scene_yaml(tmp_path, section=None, key=None, value=None, text=None) -> Path:
    """SMALL with one entry replaced (written as YAML text ``value``)."""
    lines = [
        f"rods: {{count: {value if key == 'count' else 3}, "
        f"length: {value if key == 'length' else 1.0}, mass_per_length: 1.0, "
        f"bending_stiffness: {value if key == 'bending_stiffness' else 100.0}}}",
        "nodes: {mass: 1.0}",
        f"hinges: {{stiffness: {value if key == 'stiffness' else 10.0}, damping: 0.1}}",
        f"initial: {{phi: {value if key == 'phi' else 0.0}}}",
        "loads:",
        f"  - {{node: 3, axis: y, shape: constant, "
        f"amplitude: {value if key == 'amplitude' else 1.0}}}"]
    path = tmp_path / "s.yaml"
    path.write_text(text if text is not None else "\n".join(lines) + "\n")
    return path


def simulate(tmp_path, scene, *options, out="run.mcap"):
    return cli.main(["simulate", str(scene), "--out", str(tmp_path / out), *options])


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    lines = untimed_lines(err)
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize("key, value, named", [
    ("amplitude", "1.0e300", "loads[0].amplitude"), ("length", "1.0e308", "rods.length"),
    ("length", "1.0e-308", "rods.length"), ("bending_stiffness", "1.0e308",
                                             "rods.bending_stiffness"),
    ("phi", "1.0e308", "initial.phi"), ("stiffness", "1.0e308", "hinges.stiffness"),
    ("count", "1" + "0" * 400, "rods.count")])
def test_extreme_scene_values_are_refused_with_the_key(tmp_path, capsys, key, value, named):
    scene = scene_yaml(tmp_path, key=key, value=value)
    assert simulate(tmp_path, scene, "--t-end", "0.1") == 2
    line = one_line_error(capsys)
    assert named in line and len(line) < 200, line
    assert not (tmp_path / "run.mcap").exists()


def test_a_chain_too_large_for_memory_is_refused_with_the_figure(tmp_path, capsys,
                                                                 monkeypatch):
    monkeypatch.setattr(memory, "available_memory", lambda: 1024 ** 3)
    scene = scene_yaml(tmp_path, key="count", value="100000")
    assert simulate(tmp_path, scene, "--t-end", "0.1") == 2
    line = one_line_error(capsys)
    assert "rods.count" in line and "1.92 GiB" in line           # linear: 400 MiB + 16 KiB/rod
    assert not (tmp_path / "run.mcap").exists()
    memory.check_model_memory(1000, available=10 ** 9)            # 0.41 GiB: fits
    with pytest.raises(SceneError, match="0.406 GiB"):
        memory.check_model_memory(1000, available=10 ** 8)
    # linear in n, not quadratic
    assert memory.model_memory(200_000) - memory.model_memory(100_000) == \
        memory.model_memory(100_000) - memory.model_memory(0)


@pytest.mark.timing
def test_quote_is_short_and_bounded_for_a_yaml_bomb():
    bomb = ["lol"] * 9
    for _ in range(12):                  # 9**13 leaves: repr() would never finish
        bomb = [bomb] * 9
    started = time.process_time()      # CPU time: not stretched by other processes
    assert len(quote(bomb)) <= QUOTE_LIMIT
    with pytest.raises(SceneError) as info:
        Scene.from_dict({**SMALL, "rods": {**SMALL["rods"], "length": bomb}})
    assert time.process_time() - started < 5.0
    assert "rods.length" in str(info.value) and len(str(info.value)) < 200
    assert "..." in quote("x" * 10 ** 6) and len(quote("x" * 10 ** 6)) <= QUOTE_LIMIT and len(quote(10 ** 5000)) <= QUOTE_LIMIT


def test_scene_files_must_be_small_regular_files(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text("# " + "x" * MAX_SCENE_BYTES + "\n")
    with pytest.raises(SceneError, match=f"at most {MAX_SCENE_BYTES} bytes"):
        load_scene(big)
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)                       # opening it would block until a writer comes
    with pytest.raises(SceneError, match="not a regular file"):
        load_scene(fifo)
    with pytest.raises(SceneError, match="not a regular file"):
        load_scene("/dev/zero")


@pytest.mark.parametrize("options, named", [
    (["--t-end", "1", "--rtol", "1e-15"], "--rtol"),
    (["--t-end", "1", "--rtol", "0.1"], "--rtol"),
    (["--t-end", "1", "--rate", "2e9"], "--rate"),
    (["--t-end", "1e308"], "--t-end"),
    (["--t-end", "1", "--rate", "1e9"], "--rate x --t-end"),
    (["--t-end", "1", "--integrator", "rk4", "--step", "1e-300"], "step"),
    (["--t-end", "100", "--integrator", "rk4", "--step", "1e-7"], "--step"),
    (["--t-end", "1", "--frame-id", ""], "--frame-id: must not be empty"),   # as the node
])
def test_simulate_option_limits(tmp_path, capsys, options, named):
    assert simulate(tmp_path, PAPER, *options) == 2
    line = one_line_error(capsys)
    assert named in line, line
    assert not (tmp_path / "run.mcap").exists()


@pytest.mark.parametrize("repeats", ["0", "-1", "1001", "two"])
def test_advise_refuses_a_repeat_count_outside_1_to_1000(capsys, repeats):
    with pytest.raises(SystemExit) as exc:          # argparse: exit 2, one line of usage error
        cli.main(["advise", str(PAPER), "--tolerance", "1e-3", "--repeats", repeats])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "argument --repeats:" in err.splitlines()[-1] and "Traceback" not in err


def test_rates_below_2_hz_are_honoured_exactly(tmp_path, capsys):
    assert simulate(tmp_path, PAPER, "--t-end", "3.2", "--rate", "0.5") == 0
    t, _, _ = read_rod_states(tmp_path / "run.mcap")
    assert np.array_equal(t, [0.0, 2.0, 3.2])


def test_a_run_failing_at_its_first_step_logs_t0_and_says_so(tmp_path, capsys):
    status = simulate(tmp_path, PAPER, "--model", "full", "--integrator", "euler", "--step",
                      "0.05", "--t-end", "3", "--rate", "1")
    assert status == 1
    err = capsys.readouterr().err
    assert "the log holds 1 samples, t = 0..0 s" in err and "Traceback" not in err
    t, _, _ = read_rod_states(tmp_path / "run.mcap")
    assert list(t) == [0.0]


def test_out_in_a_directory_without_permission(tmp_path, capsys):
    assert simulate(tmp_path, PAPER, "--t-end", "0.1", out="/sys/rod_sim_test.mcap") == 2
    line = one_line_error(capsys)
    assert "--out" in line and "Permission denied" in line


def simulate_on_a_small_disk(tmp_path, budget: int) -> subprocess.CompletedProcess:
    """``rod-sim simulate`` of 4 s of the paper example at 1 kHz in a process whose files may
    not grow past ``budget`` bytes (RLIMIT_FSIZE, inherited by its log writer process: a
    write there takes what fits, then fails with EFBIG, as a full disk fails with ENOSPC)."""
    import resource

    def small_disk():
        resource.setrlimit(resource.RLIMIT_FSIZE, (budget, budget))

    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(PAPER),
                           "--t-end", "4", "--rate", "1000", "--out", str(tmp_path / "run.mcap")],
                          preexec_fn=small_disk, capture_output=True, text=True, timeout=300)


def test_full_disk_before_the_first_chunk_removes_the_log(tmp_path):
    done = simulate_on_a_small_disk(tmp_path, 8 * 1024)
    assert done.returncode == 1, done.stderr
    assert "File too large" in done.stderr and "removed" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "run.mcap").exists()


def test_full_disk_later_keeps_the_complete_chunks_and_says_so(tmp_path):
    done = simulate_on_a_small_disk(tmp_path, 1024 * 1024)
    assert done.returncode == 1, done.stderr
    assert "File too large" in done.stderr and "keeps the" in done.stderr, done.stderr
    t, _, _ = read_rod_states(tmp_path / "run.mcap")
    assert t.size > 100 and t[0] == 0.0 and f"keeps the {t.size} samples" in done.stderr
    assert (tmp_path / "run.mcap").stat().st_size <= 1024 * 1024


def _cache_without_the_driver(tmp_path) -> dict:
    """The environment of a run whose compile cache lacks the reduced model's dop853-jit
    driver only: a copy of the warm shared cache without that function's files (its compile
    then takes ~30 s of CPU instead of ~100 s for everything). Without a warm shared cache
    (switched off, or not built), an empty cache: everything compiles."""
    from rod_sim.core import jit

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    warm = jit.shared_cache_dir(jit.sources_stamp())
    if warm is not None and any(warm.glob("erk.dop853_reduced-*.nbi")):
        root = tmp_path / "cache"
        shutil.copytree(warm, root / warm.name,
                        ignore=shutil.ignore_patterns("erk.dop853_reduced-*"))
        assert not any((root / warm.name).glob("erk.dop853_reduced-*"))
        return {**env, jit.SHARED_CACHE_ENV: str(root)}
    return {**env, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}


@pytest.mark.slow
def test_first_run_with_a_cold_cache_says_it_compiles(tmp_path):
    env = _cache_without_the_driver(tmp_path)

    def run(name):
        return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(PAPER),
                               "--t-end", "0.1", "--out", str(tmp_path / name)],
                              env=env, capture_output=True, text=True, timeout=600)

    cold, warm = run("a.mcap"), run("b.mcap")
    assert cold.returncode == 0 and warm.returncode == 0
    # compiling takes tens of seconds, the notice comes after 2 s: what, why, how long
    assert COMPILE_NOTICE in cold.stderr and "not in numba's cache" in cold.stderr
    assert "dop853-jit" in cold.stderr and "cached for later runs" in cold.stderr
    # a cache load fires no compile event, however slow the machine: no notice at all
    assert COMPILE_NOTICE not in warm.stderr


def test_a_failure_during_the_jit_warm_up_is_no_traceback(tmp_path, capsys, monkeypatch):
    """The warm-up integration (1 ms, before the clock starts) may fail where the run itself
    fails; the run then reports it (here the run succeeds: only the warm-up is made to fail)."""
    from rod_sim.core.integrators import IntegrationError
    from rod_sim.core.simulator import Simulator

    def fail(self, dt):
        raise IntegrationError("step size fell below the minimum", 0.0)

    monkeypatch.setattr(Simulator, "advance", fail)
    assert simulate(tmp_path, PAPER, "--t-end", "0.2") == 0
    assert "Traceback" not in capsys.readouterr().err
    t, _, _ = read_rod_states(tmp_path / "run.mcap")
    assert t.size == 21


def _address_space(limit: int):
    def preexec():
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    return preexec


def test_the_memory_check_honours_the_address_space_limit(tmp_path):
    """Issue 27, item 10: `simulate` at n = 1e6 under `ulimit -v 6 GB` was accepted (the check
    saw only the machine's memory) and did not finish a step in 400 s. Now the room under
    RLIMIT_AS counts: refused at once, one line naming the limit."""
    scene = scene_yaml(tmp_path, key="count", value="1000000")
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate", str(scene),
                           "--t-end", "0.01", "--out", str(tmp_path / "run.mcap")],
                          capture_output=True, text=True, timeout=120,
                          preexec_fn=_address_space(6 * 1024 ** 3))
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr.strip().splitlines()[-1].startswith(
        "rod-sim simulate: error: rods.count: a chain of 1000000 rods needs about 15.6 GiB"), \
        done.stderr
    assert "under the address-space limit (ulimit -v)" in done.stderr
    assert time.monotonic() - started < 60 and not (tmp_path / "run.mcap").exists()


@pytest.mark.parametrize("version", [1, 2])
def test_the_memory_check_honours_the_cgroup_limit(tmp_path, monkeypatch, version):
    """The room left under the process's cgroup memory limit counts (v1 and v2 layouts, read
    from a copy of /proc/self/cgroup and /sys/fs/cgroup written here)."""
    root = tmp_path / "cgroup"
    if version == 2:
        group = root / "jobs" / "rod"
        group.mkdir(parents=True)
        (group / "memory.max").write_text(f"{3 * 1024 ** 3}\n")
        (group / "memory.current").write_text(f"{1024 ** 3}\n")
        proc = "0::/jobs/rod\n"
    else:
        group = root / "memory" / "jobs" / "rod"
        group.mkdir(parents=True)
        (group / "memory.limit_in_bytes").write_text(f"{3 * 1024 ** 3}\n")
        (group / "memory.usage_in_bytes").write_text(f"{1024 ** 3}\n")
        proc = "4:memory:/jobs/rod\n1:cpu:/\n"
    (tmp_path / "cgroup.txt").write_text(proc)
    monkeypatch.setattr(memory, "PROC_CGROUP", str(tmp_path / "cgroup.txt"))
    monkeypatch.setattr(memory, "CGROUP_ROOT", str(root))
    assert memory._cgroup_memory() == 2 * 1024 ** 3
    with pytest.raises(SceneError, match=r"2 GiB under the cgroup memory limit"):
        memory.check_model_memory(200_000)                       # 3.45 GiB
    memory.check_model_memory(50_000)                            # 1.15 GiB: fits
    (group / ("memory.max" if version == 2 else "memory.limit_in_bytes")).write_text(
        "max\n" if version == 2 else "9223372036854771712\n")
    assert memory._cgroup_memory() is None


def test_compare_over_a_folder_of_many_logs_is_refused_up_front(tmp_path):
    """Issue 27, item 10: `compare` over a folder of 10 000 files had no bound (every file is
    opened and checked, all at once, to merge their messages). Past MAX_LOG_FILES (1000) the
    folder is refused before any file is read: one line, exit 2, in seconds."""
    from rod_sim.io.log_open import MAX_LOG_FILES

    log = tmp_path / "one.mcap"
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "simulate",
                           str(ROOT / "config" / "small_chain.yaml"), "--t-end", "0.05",
                           "--out", str(log)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "many"
    folder.mkdir()
    for k in range(10_000):
        os.link(log, folder / f"part_{k:05d}.mcap")
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "compare", str(folder)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    assert f"more than {MAX_LOG_FILES} log files in one bag" in done.stderr
    assert time.monotonic() - started < 30


def test_urdf_of_a_long_chain_is_written_in_bounded_time_and_memory(tmp_path):
    """Issue 27, item 10: `rod-sim urdf` at n = 1e6 wrote nothing in 300 s (an ElementTree of
    19 elements per rod, serialised at the end). Written as text, 1000 rods at a time: 300 000
    rods here (n = 1e6 measured: 24 s, 0.9 GB file, 206 MB max RSS)."""
    scene = scene_yaml(tmp_path, key="count", value="300000")
    out = tmp_path / "chain.urdf"
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "urdf", str(scene),
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    took = time.monotonic() - started
    assert done.returncode == 0, done.stderr
    assert took < 45, f"{took:.1f} s"
    with open(out, "rb") as f:
        joints = sum(line.count(b"<joint ") for line in f)
        f.seek(-10, 2)
        tail = f.read()
    assert joints == 300_001 and tail.endswith(b"</robot>\n")


def test_a_slow_simulate_says_what_it_is_doing_and_how_long_it_will_take(tmp_path, capsys,
                                                                         monkeypatch):
    """Issue 27, item 10: radau-jit at rtol 1e-12 on the EI = 1e12 deployment variant ran
    past 60 s with no line. A run says every PROGRESS_EVERY_S (10 s; 0.2 s here) the simulated
    time reached, the integrator, its steps and rhs evaluations and the time left at its
    pace (measured on that case: "t = 0 of 0.2 s after 10 s (radau-jit rtol=1e-12 ...:
    347967 steps of ~2.4e-09 s ...; ~41 min more at this pace)")."""
    from rod_sim.tools import cli, simulate

    monkeypatch.setattr(simulate._LoggedRun, "PROGRESS_EVERY_S", 0.2)
    monkeypatch.setattr(simulate._LoggedRun, "CHUNK_SECONDS", 0.05)
    assert cli.main(["simulate", str(ROOT / "config" / "paper_example.yaml"), "--t-end", "2",
                     "--rate", "1000", "--out", str(tmp_path / "run.mcap")]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines()
             if line.startswith("rod-sim simulate: t = ")]
    assert lines, "no progress line"
    assert " of 2 s after " in lines[-1] and "dop853-jit rtol=1e-08" in lines[-1]
    assert "rhs evaluations" in lines[-1] and ("more at this pace" in lines[-1]
                                               or "no estimate yet" in lines[-1])


def test_a_slow_simulate_start_up_says_what_it_is_doing(tmp_path, capsys, monkeypatch):
    """Every start-up shows progress after 2 s: a 1e6-rod paper example took ~25 s in
    simulate's start-up (the log's sizing, the model, 1 ms of warm-up integration) with no
    line. The step is named (here a sizing made slow: 2 s, the notices every 0.05 s)."""
    from rod_sim.app import startup
    from rod_sim.tools import simulate

    sizes = simulate.log_sample_bytes

    def slow_sizes(*args):
        time.sleep(2.0)
        return sizes(*args)

    monkeypatch.setattr(startup, "NOTICE_AFTER_S", 0.05)
    monkeypatch.setattr(startup, "NOTICE_EVERY_S", 0.05)
    monkeypatch.setattr(simulate, "log_sample_bytes", slow_sizes)
    assert cli.main(["simulate", str(PAPER), "--t-end", "0.01", "--out",
                     str(tmp_path / "run.mcap")]) == 0
    err = capsys.readouterr().err
    assert "rod-sim simulate: starting: sizing the log (" in err, err
