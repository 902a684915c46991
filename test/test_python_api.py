"""The Python API (``import rod_sim``, docs/python_api.md): the guide's code blocks run as
written, in order, from a directory holding the repository's config/; and what they show holds
(the log ``rod-sim simulate`` writes is what the API computes; the API's checks refuse bad
input in one line)."""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "python_api.md"
BLOCK = re.compile(r"^```(python|bash)\n(.*?)^```", re.S | re.M)


def blocks() -> list[tuple[str, str]]:
    """(language, code) of every fenced python or bash block of the guide, in order."""
    return [(m.group(1), m.group(2)) for m in BLOCK.finditer(GUIDE.read_text(encoding="utf-8"))]


def run_block(lang: str, code: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if lang == "python":
        args = [[sys.executable, "-c", code]]
    else:           # `rod-sim ...` lines, as the installed entry point runs them
        args = [[sys.executable, "-m", "rod_sim.tools.cli", *shlex.split(line)[1:]]
                for line in code.splitlines() if line.startswith("rod-sim ")]
        assert args, code
    for argv in args:
        done = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                              timeout=900)
        if done.returncode:
            return done
    return done


@pytest.fixture(scope="module")
def guide_run(tmp_path_factory):
    """Every block of the guide run in order in one directory; their outputs."""
    work = tmp_path_factory.mktemp("guide")
    (work / "config").symlink_to(ROOT / "config")
    outputs = []
    for lang, code in blocks():
        done = run_block(lang, code, work)
        assert done.returncode == 0, f"{lang} block failed:\n{code}\n{done.stderr}"
        outputs.append(done.stdout)
    return work, outputs


def test_the_guide_has_the_examples():
    langs = [lang for lang, _ in blocks()]
    assert langs.count("python") >= 3 and "bash" in langs


@pytest.mark.slow
def test_the_guides_code_blocks_run(guide_run):
    work, outputs = guide_run
    first, _, log_block, craft = outputs
    assert "201 samples" in first and "balance residual" in first
    assert "hinge_0" in log_block and "/rod_states" in log_block and "reduced" in log_block
    assert "angular momentum about the centre of mass" in craft
    assert (work / "run.mcap").is_file()


@pytest.mark.slow
def test_the_log_of_rod_sim_simulate_is_what_the_api_computes(guide_run):
    """The command line builds its run through the API: its log (example 2) holds the states
    that ``Simulator.from_scene`` with the same (default) settings computes."""
    import rod_sim

    work, _ = guide_run
    t, phi, phi_rate = rod_sim.read_rod_states(work / "run.mcap")
    sim = rod_sim.Simulator.from_scene(ROOT / "config" / "paper_example.yaml")
    traj = sim.run(1.0, rate_hz=100.0)
    assert np.array_equal(t, traj.t)
    # simulate integrates in chunks of 0.5 s: the step sequences differ from one call's there
    assert np.max(np.abs(phi - traj.phi)) < 1e-6
    assert np.max(np.abs(phi_rate - traj.phi_rate)) < 1e-5


def test_load_scene_takes_a_path_a_dict_or_a_scene(tmp_path):
    import rod_sim

    scene = rod_sim.load_scene(ROOT / "config" / "small_chain.yaml")
    again = rod_sim.load_scene(scene.to_dict())
    assert rod_sim.load_scene(scene) is scene
    assert again.n == scene.n and np.array_equal(again.to_dict()["rods"]["length"],
                                                 scene.to_dict()["rods"]["length"])
    bad = scene.to_dict()
    bad["rods"] = {**bad["rods"], "length": -1.0}
    with pytest.raises(rod_sim.SceneError) as info:
        rod_sim.load_scene(bad)
    assert str(info.value).startswith("rods.length") and "\n" not in str(info.value)
    with pytest.raises(TypeError):
        rod_sim.load_scene(42)


def test_the_simulator_by_name_and_its_refusals(monkeypatch):
    import rod_sim
    from rod_sim.core import memory

    sim = rod_sim.Simulator.from_scene(ROOT / "config" / "small_chain.yaml", model="rigid",
                                       integrator="rk4", step=1e-3)
    assert sim.integrator.name == "rk4" and sim.integrator.step == 1e-3
    assert sim.model.name == "rigid" and sim.state.shape == (sim.model.state_size,)
    with pytest.raises(ValueError):
        sim.state[0] = 1.0                              # read-only
    with pytest.raises(ValueError, match="unknown"):
        rod_sim.make_integrator("rk5")
    with pytest.raises(rod_sim.ModelError, match="unknown model"):
        rod_sim.make_model("stiff", sim.scene)
    with pytest.raises(TypeError):
        rod_sim.Simulator(sim.model, sim.integrator, rtol=1e-6)
    monkeypatch.setattr(memory, "available_memory", lambda: 10 ** 8)   # 100 MB
    with pytest.raises(rod_sim.SceneError, match="rods.count: a chain of 3 rods needs about"):
        rod_sim.make_model("rigid", sim.scene)
    assert sim.base_state() is None


@pytest.mark.slow
def test_the_readmes_python_block_runs(guide_run):
    """README's "Python" section: its block runs after the tour's scene (its yaml block, saved
    as my_chain.yaml) and the tour's simulate command, whose log it reads."""
    work, _ = guide_run
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Python\n"):]
    code = BLOCK.search(section)
    assert code and code.group(1) == "python" and "import rod_sim" in code.group(2)
    scene = re.search(r"^```yaml\n(.*?)^```", text, re.S | re.M).group(1)
    (work / "my_chain.yaml").write_text(scene)
    (work / "out").mkdir(exist_ok=True)
    simulate = next(line for line in text.splitlines()
                    if line.startswith(".venv/bin/rod-sim simulate my_chain.yaml"))
    assert "out/mine.mcap" in simulate and "out/mine.mcap" in code.group(2)
    simulate = simulate.replace(".venv/bin/rod-sim", "rod-sim")
    for lang, block in (("bash", simulate), ("python", code.group(2))):
        done = run_block(lang, block, work)
        assert done.returncode == 0, done.stderr


def test_every_api_name_is_documented():
    """Each name ``import rod_sim`` exports is in the guide and in docs/interface.md section 7,
    and each resolves (lazily) to a documented object."""
    import rod_sim

    guide = GUIDE.read_text(encoding="utf-8")
    interface = (ROOT / "docs" / "interface.md").read_text(encoding="utf-8")
    section = interface[interface.index("## 7. Python API"):]
    for name in rod_sim.__all__:
        if name == "__version__":
            continue
        assert f"`{name}" in section, name
        assert name in guide, name
        value = getattr(rod_sim, name)
        assert isinstance(value, tuple) or (value.__doc__ or "").strip(), name
