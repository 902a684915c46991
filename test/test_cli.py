"""The rod-sim command line: offline runs, logs, and bad input (exit 2, one line, no log)."""
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rod_sim.core.integrators import make_integrator
from rod_sim.core.models import make_model
from rod_sim.core.simulator import Simulator
from rod_sim.io.log_reader import LogReader
from rod_sim.io.series import read_rod_states
from rod_sim.io.scene_yaml import load_scene, scene_from_yaml_text
from rod_sim.tools import cli

ROOT = Path(__file__).resolve().parents[1]
GOOD = """
name: t
rods: {count: 3, length: 1.0, mass_per_length: 2.0, bending_stiffness: 1.0e4}
nodes: {mass: 1.0}
hinges: {stiffness: 20.0, damping: 0.1}
loads:
  - {node: 3, axis: y, shape: raised_cosine_pulse, amplitude: 30.0, duration: 0.4}
"""


def rod_sim(*args):
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("model", ["reduced", "full", "rigid"])
def test_simulate_writes_the_run_it_claims(tmp_path, model):
    scene_file = tmp_path / "s.yaml"
    scene_file.write_text(GOOD)
    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(scene_file), "--model", model, "--t-end", "1.0",
                     "--out", str(out), "--rate", "50", "--rtol", "1e-10"]) == 0
    t, phi, phi_rate = read_rod_states(out)
    assert np.allclose(t, np.arange(51) / 50.0, atol=1e-12)
    traj = Simulator(make_model(model, load_scene(scene_file)),
                     make_integrator("dop853-jit", rtol=1e-10)).run(1.0, 50.0)
    assert np.max(np.abs(phi - traj.phi)) < 1e-9
    assert np.max(np.abs(phi_rate - traj.phi_rate)) < 1e-9
    with LogReader(out) as log:
        meta = log.metadata()
        assert meta["model"] == model
        assert "dop853-jit" in meta["integrator"]
        assert scene_from_yaml_text(meta["scene"]).to_dict() == load_scene(scene_file).to_dict()
        topics = log.topics()
    for topic in ("/joint_states", "/rod_states", "/bending", "/node_poses", "/applied_forces"):
        assert topic in topics


def test_simulate_refuses_to_overwrite(tmp_path, capsys):
    scene_file = tmp_path / "s.yaml"
    scene_file.write_text(GOOD)
    out = tmp_path / "run.mcap"
    out.write_bytes(b"keep me")
    assert cli.main(["simulate", str(scene_file), "--t-end", "0.1", "--out", str(out)]) == 2
    assert out.read_bytes() == b"keep me"
    err = capsys.readouterr().err
    assert "exists" in err and len(err.strip().splitlines()) == 1


BAD_SCENES = {
    "unknown key": ("rods: {count: 2, length: 1, mass_per_length: 1, bending_stiffness: 1, colour: red}\n"
                    "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: 0}", "rods.colour"),
    "wrong length": ("rods: {count: 2, length: [1, 2, 3], mass_per_length: 1, bending_stiffness: 1}\n"
                     "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: 0}", "rods.length"),
    "non-finite": ("rods: {count: 2, length: 1, mass_per_length: .nan, bending_stiffness: 1}\n"
                   "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: 0}", "rods.mass_per_length"),
    "l <= 0": ("rods: {count: 2, length: [1, 0], mass_per_length: 1, bending_stiffness: 1}\n"
               "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: 0}", "rods.length"),
    "m < 0": ("rods: {count: 2, length: 1, mass_per_length: -1, bending_stiffness: 1}\n"
              "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: 0}", "rods.mass_per_length"),
    "EI <= 0": ("rods: {count: 2, length: 1, mass_per_length: 1, bending_stiffness: 0}\n"
                "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: 0}", "rods.bending_stiffness"),
    "kappa < 0": ("rods: {count: 2, length: 1, mass_per_length: 1, bending_stiffness: 1}\n"
                  "nodes: {mass: 1}\nhinges: {stiffness: -1, damping: 0}", "hinges.stiffness"),
    "nu < 0": ("rods: {count: 2, length: 1, mass_per_length: 1, bending_stiffness: 1}\n"
               "nodes: {mass: 1}\nhinges: {stiffness: 1, damping: -0.5}", "hinges.damping"),
    "no inertia": ("rods: {count: 2, length: 1, mass_per_length: 0, bending_stiffness: 1}\n"
                   "nodes: {mass: 0}\nhinges: {stiffness: 1, damping: 0}", "nodes.mass"),
    "yaml syntax": ("rods: {count: 2, length: [1, 2\n", "scene"),
}


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scene_exit_2_one_line_no_log(tmp_path, capsys, case):
    text, key = BAD_SCENES[case]
    scene_file = tmp_path / "bad.yaml"
    scene_file.write_text(text)
    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(scene_file), "--t-end", "0.1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and key in err, err
    assert not out.exists()


def test_full_model_rejects_massless_rod(tmp_path, capsys):
    scene_file = tmp_path / "s.yaml"
    scene_file.write_text(GOOD.replace("mass_per_length: 2.0", "mass_per_length: [2.0, 0.0, 1.0]"))
    out = tmp_path / "run.mcap"
    assert cli.main(["simulate", str(scene_file), "--model", "full", "--t-end", "0.1",
                     "--out", str(out)]) == 2
    assert "rod 2" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("args", [
    ["simulate", "config/paper_example.yaml", "--t-end", "-1", "--out", "x.mcap"],
    ["simulate", "config/paper_example.yaml", "--t-end", "1", "--out", "x.mcap", "--integrator", "nope"],
    ["simulate", "config/paper_example.yaml", "--t-end", "1", "--out", "x.mcap", "--model", "nope"],
    ["simulate", "missing.yaml", "--t-end", "1", "--out", "x.mcap"],
    ["simulate", "config/paper_example.yaml", "--t-end", "1", "--out", "no/such/dir/x.mcap"],
])
def test_bad_arguments_in_a_real_process(args):
    proc = rod_sim(*args)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip() and not os.path.exists(ROOT / "x.mcap")


def documented_subcommands() -> dict[str, str]:
    """Subcommand -> its bullet(s) in docs/interface.md section 2 (the oracle: the document)."""
    text = (ROOT / "docs" / "interface.md").read_text()
    section = text.split("## 2. Command line")[1].split("\n## 3.")[0]
    bullets: dict[str, str] = {}
    for m in re.finditer(r"^- `rod-sim (\S+)(.*?)(?=^- `rod-sim |\Z)", section, re.S | re.M):
        bullets[m.group(1)] = bullets.get(m.group(1), "") + m.group(0)
    return bullets


HELP_OPTION = re.compile(r"^\s{2}(?:-\w(?: \S+)?, )?(--[a-z][a-z0-9-]*)", re.M)


def test_every_subcommand_has_help_and_every_option_it_shows_is_documented():
    """Each subcommand of docs/interface.md section 2 answers --help (exit 0) and every long
    option its help shows is named in that subcommand's entry of the document; the CLI has no
    subcommand the document leaves out."""
    documented = documented_subcommands()
    assert len(documented) >= 12, sorted(documented)
    shown = rod_sim("--help").stdout
    commands = shown.split("COMMAND\n", 1)[1].split("\n\n")[0]
    listed = set(re.findall(r"^ {4}([a-z0-9-]+)", commands, re.M))
    assert listed == set(documented), (listed ^ set(documented))
    for sub, entry in documented.items():
        proc = rod_sim(sub, "--help")
        assert proc.returncode == 0 and proc.stdout.startswith("usage"), (sub, proc.stderr)
        options = set(HELP_OPTION.findall(proc.stdout)) - {"--help"}
        missing = sorted(o for o in options if not re.search(re.escape(o) + r"(?![\w-])", entry))
        assert not missing, f"rod-sim {sub}: --help shows {missing}, docs/interface.md does not"


def test_light_name_lists_match_the_registries():
    """The CLI takes its choices from rod_sim.core.names (no numba/scipy import for --help)."""
    from rod_sim.core import integrators, models, names

    assert sorted(models.MODELS) == sorted(names.MODEL_NAMES)
    assert sorted(integrators.INTEGRATORS) == sorted(names.INTEGRATOR_NAMES)
    for name in names.INTEGRATOR_NAMES:
        assert integrators.make_integrator(name).name == name


def test_help_does_not_import_the_numerical_core():
    code = ("import sys; from rod_sim.tools import cli; cli.build_parser(); "
            "print(sorted(m for m in ('numba', 'scipy', 'rclpy', 'matplotlib') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0 and done.stdout.strip() == "[]", done.stdout + done.stderr


def test_simulate_reports_the_whole_run_and_its_integration_part(tmp_path, capsys):
    """The summary's real-time factor is of the run the user waited for (sampling, encoding
    and the log included), with the integration's part of it beside it: a figure of the
    integration alone once said 142x real time of a run that ran at 2.7x."""
    scene_file = tmp_path / "s.yaml"
    scene_file.write_text(GOOD)
    assert cli.main(["simulate", str(scene_file), "--t-end", "0.5", "--out",
                     str(tmp_path / "r.mcap"), "--rate", "200"]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    got = re.search(r"run ([0-9.]+) s wall, ([0-9.e+]+)x real time; integration ([0-9.]+) s "
                    r"of it", line)
    assert got, line
    run, rtf, integration = (float(x) for x in got.groups())
    assert 0.0 <= integration <= run
    assert rtf == pytest.approx(0.5 / run, rel=0.01 + 0.0005 / run)


@pytest.mark.parametrize("port, message", [("0", "must be a port 1..65535 (got 0)"),
                                           ("70000", "must be a port 1..65535 (got 70000)"),
                                           ("x", "not a port number: 'x'")])
def test_simulate_refuses_a_bad_live_view_port(port, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["simulate", "scene.yaml", "--t-end", "1", "--out", "o.mcap",
                  "--live-view", port])
    assert exc.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["simulate", "s.yaml", "--out", "o.mcap", "--t-end", "-1"],
     "argument --t-end: must be a positive finite number (got -1)"),
    (["simulate", "s.yaml", "--out", "o.mcap", "--t-end", "nan"],
     "argument --t-end: must be a positive finite number (got nan)"),
    (["simulate", "s.yaml", "--out", "o.mcap", "--t-end", "1s"],
     "argument --t-end: not a number: '1s'"),
    (["advise", "s.yaml", "--tolerance", "1e-3", "--repeats", "0"],
     "argument --repeats: must be 1 .. 1000 (got 0)"),
    (["advise", "s.yaml", "--tolerance", "1e-3", "--repeats", "2.5"],
     "argument --repeats: not a whole number: '2.5'"),
])
def test_number_options_are_refused_with_the_rule(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and message in err, err


@pytest.mark.parametrize("argv, unknown", [
    (["deployment-figure", "run.mcap", "--out", "fig.png"], "--out"),
    (["table1", "--frob"], "--frob"),
])
def test_an_unknown_option_is_refused_with_the_subcommands_usage(capsys, argv, unknown):
    """argparse reports an option the subcommand does not know with the top-level usage
    (``rod-sim [-h] [--version] COMMAND ...``), which shows none of the command's options."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"usage: rod-sim {argv[0]} "), err
    assert f"rod-sim {argv[0]}: error: unrecognized arguments: {unknown}\n" in err, err
