"""Issue 20 item 9, as a user meets it: `compare`'s FAIL says what to try next, `advise`
prints its criterion, `rod-sim node --help` lists the parameters one per line, and the limits
of docs/interface.md section 6 are one table. (The warm-up's progress lines:
test_first_run.py.)"""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from rod_sim.io.scene_yaml import load_scene
from rod_sim.ros.parameters import PARAMETERS
from rod_sim.tools import cli
from test_compare import node_like_log

REPO = Path(__file__).resolve().parents[1]
SMALL = REPO / "config" / "small_chain.yaml"


def test_compare_fail_says_what_to_try_next(tmp_path, capsys):
    log = tmp_path / "reduced.mcap"
    node_like_log(log, load_scene(SMALL), "reduced", periods=30)
    assert cli.main(["compare", str(log), "--tolerance", "1e-9"]) == 1
    lines = capsys.readouterr().out.splitlines()
    fail = next(i for i, line in enumerate(lines) if line.startswith("FAIL"))
    verdict = " ".join(line.strip() for line in lines[fail:])
    first = float(re.search(r"first at t = ([0-9.e-]+) s", verdict).group(1))
    after = " ".join(line.strip() for line in lines[fail + 1:])
    assert sum(line.startswith("next: ") for line in lines[fail:]) == 3
    assert "--model full" in after and "rod-sim advise SCENE.yaml --tolerance 1e-09" in after
    assert f"first exceeds the tolerance at t = {first:.6g} s" in after

    assert cli.main(["compare", str(log), "--tolerance", "1e-9", "--json", "--scene",
                     str(SMALL)]) == 1
    steps = json.loads(capsys.readouterr().out)["next_steps"]
    assert any(f"rod-sim advise {SMALL} --tolerance 1e-09" in s for s in steps)

    assert cli.main(["compare", str(log)]) == 0           # default tolerance: PASS, no advice
    out = capsys.readouterr().out
    assert "PASS" in out and "next:" not in out


def test_advise_prints_its_criterion_half_the_tolerance(capsys):
    code = cli.main(["advise", str(SMALL), "--tolerance", "0.002", "--t-end", "0.1",
                     "--repeats", "1"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "criterion: max phi error <= 0.5 x tolerance = 0.001 rad" in out
    header = next(line for line in out.splitlines() if line.startswith("model"))
    assert header.endswith("meets (<= 0.001 rad)")
    rows = [line.split() for line in out.splitlines()
            if line.split() and line.split()[0] in ("rigid", "reduced", "full")
            and "failed:" not in line]
    assert rows and all((float(r[2]) <= 0.001) == (r[-1] == "yes") for r in rows)


def test_node_help_lists_one_parameter_per_line():
    done = subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "node", "--help"],
                          cwd=REPO, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    for spec in PARAMETERS:
        own = [line for line in lines if line.startswith(f"  {spec.name} (")]
        assert len(own) == 1, f"{spec.name}: {own}"
    assert "  rate_hz (double, default 100.0)" in lines
    assert "  real_time_factor (double, default 1.0, settable at run time)" in lines
    assert "  sync_mode (bool, default false)" in lines


def test_the_limits_of_interface_section_6_are_one_table():
    text = (REPO / "docs" / "interface.md").read_text()
    section = text[text.index("## 6. Limits"):]
    rows = [line for line in section.splitlines() if line.startswith("|")]
    block = re.findall(r"(?:^\|.*\n)+", section, re.M)
    assert len(block) == 1, "the limits must be one contiguous table"
    assert rows[0] == "| what | limit |" and rows[1] == "|---|---|"
    assert any(row.startswith("| node: work per control period") for row in rows)
