"""The README's five-minute tour, run as a user would: the scene block saved as my_chain.yaml,
then every command of the tour's sh blocks in order (simulate, deployment-figure, the demo node
with its controller, compare), in a scratch directory. `.venv/bin/rod-sim` and
`.venv/bin/python` are this interpreter (`-m rod_sim.tools.cli`), the ROS domain comes from
ros_domains. The numbers the README quotes from the run are checked against the run."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from ros_domains import next_domains
from procs import ros_env
from rod_sim.io.log_reader import LogReader

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
TOUR = "## A five-minute tour"
DOMAIN_TOUR, DOMAIN_STIFF = next_domains(2)


def tour() -> str:
    text = README.read_text(encoding="utf-8")
    start = text.index(TOUR)
    return text[start:text.index("\n## ", start + len(TOUR))]


def blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", text, re.M | re.S)


def commands() -> list[str]:
    """The tour's shell commands in order (continuation lines joined, comments dropped)."""
    out = []
    for block in blocks(tour(), "sh"):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.split("#")[0].strip()
            if line:
                out.append(" ".join(line.split()))
    return out


def as_run_here(command: str) -> list[str]:
    """A tour command as an argument list run by this interpreter."""
    words = command.split()
    if words[0] == ".venv/bin/rod-sim":
        return [sys.executable, "-m", "rod_sim.tools.cli", *words[1:]]
    if words[0] == ".venv/bin/python":
        return [sys.executable, *words[1:]]
    return words


def test_the_readme_blocks_are_the_ones_these_tests_run():
    """A block added to the README (or one changed in kind) fails here until a test runs it:
    the tour's blocks below, the two-commands block in test_docs.py, the Python block in
    test_python_api.py."""
    text = README.read_text(encoding="utf-8")
    assert len(blocks(text, "yaml")) == 1 and blocks(text, "yaml") == blocks(tour(), "yaml")
    assert len(blocks(text, "python")) == 1           # run by test_python_api
    fences = re.findall(r"^```(\w*)$", text, re.M)              # opening, closing, ...
    assert fences[0::2] == ["sh", "yaml", "sh", "sh", "sh", "python"]
    assert not any(fences[1::2])
    assert [c.split()[0] for c in commands()] == [
        "mkdir", ".venv/bin/rod-sim", ".venv/bin/rod-sim", ".venv/bin/python", ".venv/bin/rod-sim"]
    assert "simulate my_chain.yaml" in commands()[1]
    assert "rod_sim.ros.demo --scene my_chain.yaml" in commands()[3]
    assert commands()[4].startswith(".venv/bin/rod-sim compare out/tour.mcap")


def run(command: str, cwd: Path, domain: int, timeout: float = 240.0):
    return subprocess.run(as_run_here(command), cwd=cwd, env=ros_env(domain), text=True,
                          capture_output=True, timeout=timeout)


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(600)
def test_the_tour_runs_and_says_what_the_readme_says(tmp_path):
    (tmp_path / "my_chain.yaml").write_text(blocks(tour(), "yaml")[0])
    mkdir, simulate, figure, demo, compare = commands()
    assert run(mkdir, tmp_path, DOMAIN_TOUR).returncode == 0
    done = run(simulate, tmp_path, DOMAIN_TOUR)
    assert done.returncode == 0, done.stderr
    with LogReader(tmp_path / "out" / "mine.mcap") as reader:
        assert reader.complete
        assert sum(t == "/rod_states" for t, _, _ in reader.messages()) == 301   # 0..3 s, 100 Hz
    done = run(figure, tmp_path, DOMAIN_TOUR)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "out" / "mine.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    done = run(demo, tmp_path, DOMAIN_TOUR)
    assert done.returncode == 0, done.stderr
    assert "300 commands, 0 rejected" in done.stdout + done.stderr
    done = run(compare, tmp_path, DOMAIN_TOUR)
    assert done.returncode == 0, done.stdout + done.stderr
    quoted = re.search(r"It ends with `(PASS: [^`]+)`", tour()).group(1)
    assert quoted in done.stdout, done.stdout          # lockstep: the same log on any machine
    assert (tmp_path / "out" / "tour_compare.png").is_file()


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(600)
def test_the_demo_default_gains_on_the_tour_chain_fail_compare(tmp_path):
    """The tour says so: the gains made for the paper's chain excite the light chain far beyond
    small bending, and compare says FAIL (exit 1)."""
    assert "--kp 2000 --kd 200" in tour() and "compare says FAIL" in tour()
    (tmp_path / "my_chain.yaml").write_text(blocks(tour(), "yaml")[0])
    (tmp_path / "out").mkdir()
    demo = re.sub(r"--kp \S+ --kd \S+", "--kp 2000 --kd 200", commands()[3])
    done = run(demo, tmp_path, DOMAIN_STIFF)
    assert done.returncode == 0, done.stderr
    done = run(commands()[4], tmp_path, DOMAIN_STIFF)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "FAIL" in done.stdout
