"""Issue 20 item 6: the node's ``scene_file`` is found relative to the params file that sets it
(or as ``package://rod_sim/...`` or an absolute path), from any working directory; a missing
one is one line naming the directory searched; package.xml lists every runtime dependency of
setup.py. ROS domain ids from ros_domains (LOCALHOST)."""
from __future__ import annotations

import ast
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from ros_domains import next_domains  # noqa: E402
from procs import ros_env
from rod_sim.ros.scene_path import (ScenePathError, params_file_value, resolve_scene_file)

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "config" / "paper_example.yaml"
DOMAIN_START, DOMAIN_MISSING = next_domains(2)


def write_params(path: Path, scene_file: str, key: str = "/**") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"{key}:\n  ros__parameters:\n    scene_file: {scene_file}\n"
                    "    sync_mode: true\n", encoding="utf-8")
    return path


def test_relative_to_the_params_file_not_the_working_directory(tmp_path):
    params = write_params(tmp_path / "cfg" / "node.yaml", "scenes/chain.yaml")
    scene = tmp_path / "cfg" / "scenes" / "chain.yaml"
    scene.parent.mkdir()
    scene.write_text(PAPER.read_text())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    found, note = resolve_scene_file("scenes/chain.yaml", "/rod_sim", [str(params)],
                                     cwd=elsewhere)
    assert found == scene and note == ""


def test_params_file_keys_match_as_ros_matches_them(tmp_path):
    p = tmp_path / "p.yaml"
    p.write_text("/arm1/rod_sim:\n  ros__parameters: {scene_file: a.yaml}\n"
                 "/arm2:\n  rod_sim:\n    ros__parameters: {scene_file: b.yaml}\n"
                 "/**/other:\n  ros__parameters: {scene_file: c.yaml}\n")
    assert params_file_value(p, "/arm1/rod_sim", "scene_file") == "a.yaml"
    assert params_file_value(p, "/arm2/rod_sim", "scene_file") == "b.yaml"
    assert params_file_value(p, "/x/y/other", "scene_file") == "c.yaml"
    assert params_file_value(p, "/rod_sim", "scene_file") is None


def test_a_value_from_the_command_line_is_relative_to_the_working_directory(tmp_path):
    params = write_params(tmp_path / "cfg" / "node.yaml", "other.yaml")
    (tmp_path / "mine.yaml").write_text(PAPER.read_text())
    found, _ = resolve_scene_file("mine.yaml", "/rod_sim", [str(params)], cwd=tmp_path)
    assert found == tmp_path / "mine.yaml"


def test_an_old_params_file_relative_to_the_working_directory_still_works_with_a_warning(
        tmp_path):
    params = write_params(tmp_path / "cfg" / "node.yaml", "config/paper_example.yaml")
    found, note = resolve_scene_file("config/paper_example.yaml", "/rod_sim", [str(params)],
                                     cwd=REPO)
    assert found == PAPER
    assert str(tmp_path / "cfg") in note and "relative to the params file" in note


def test_not_found_names_the_directory_searched(tmp_path):
    params = write_params(tmp_path / "cfg" / "node.yaml", "nope.yaml")
    with pytest.raises(ScenePathError, match=re.escape(f"searched {tmp_path / 'cfg'}")):
        resolve_scene_file("nope.yaml", "/rod_sim", [str(params)], cwd=tmp_path)
    with pytest.raises(ScenePathError, match=re.escape(f"searched {tmp_path}")):
        resolve_scene_file("nope.yaml", "/rod_sim", [], cwd=tmp_path)


def test_package_urls_find_the_config_of_rod_sim(tmp_path):
    found, _ = resolve_scene_file("package://rod_sim/config/paper_example.yaml", "/rod_sim",
                                  cwd=tmp_path)
    assert found.read_text() == PAPER.read_text()
    with pytest.raises(ScenePathError, match="no config/none.yaml in the share directory"):
        resolve_scene_file("package://rod_sim/config/none.yaml", "/rod_sim", cwd=tmp_path)
    with pytest.raises(ScenePathError, match="expected package://PACKAGE/PATH"):
        resolve_scene_file("package://rod_sim", "/rod_sim", cwd=tmp_path)


def node_args(*ros_args: str) -> list[str]:
    return [sys.executable, "-m", "rod_sim.tools.cli", "node", "--ros-args", *ros_args]


@pytest.mark.slow
@pytest.mark.ros
@pytest.mark.timeout(90)
def test_the_shipped_params_file_starts_the_node_from_another_directory(tmp_path):
    """The user's path: `rod-sim node --ros-args --params-file .../sim_node.params.yaml` from
    their own directory; then a scene next to their own params file, and package://."""
    for i, extra in enumerate([
            ["--params-file", str(REPO / "config" / "sim_node.params.yaml")],
            ["--params-file", str(write_params(tmp_path / "mine" / "p.yaml", "chain.yaml"))],
            ["-p", "scene_file:=package://rod_sim/config/small_chain.yaml"]]):
        (tmp_path / "mine" / "chain.yaml").parent.mkdir(exist_ok=True)
        (tmp_path / "mine" / "chain.yaml").write_text(PAPER.read_text())
        err = tmp_path / f"node{i}.err"
        with open(err, "w") as stderr:
            proc = subprocess.Popen(node_args(*extra, "-p", "sync_mode:=true"), cwd=tmp_path,
                                    env=ros_env(DOMAIN_START), stdout=subprocess.DEVNULL,
                                    stderr=stderr)
        try:
            deadline = time.monotonic() + 60
            while "commands on" not in err.read_text():
                assert proc.poll() is None, err.read_text()
                assert time.monotonic() < deadline, err.read_text()
                time.sleep(0.1)
        finally:
            proc.kill()
            proc.wait(timeout=10)
        expected = "small_chain" if i == 2 else "paper_example"
        assert f"scene '{expected}'" in err.read_text(), err.read_text()


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_a_missing_scene_exits_2_naming_the_directory_searched(tmp_path):
    params = write_params(tmp_path / "cfg" / "node.yaml", "missing.yaml")
    done = subprocess.run(node_args("--params-file", str(params)), cwd=tmp_path,
                          env=ros_env(DOMAIN_MISSING), capture_output=True, text=True,
                          timeout=50)
    assert done.returncode == 2, done.stderr
    errors = [line for line in done.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1 and "Traceback" not in done.stderr, done.stderr
    assert f"searched {tmp_path / 'cfg'}" in errors[0] and "missing.yaml" in errors[0]


def test_package_xml_lists_every_runtime_dependency_of_setup_py():
    tree = ast.parse((REPO / "setup.py").read_text())
    setup = next(node for node in ast.walk(tree) if isinstance(node, ast.Call)
                 and getattr(node.func, "id", "") == "setup")
    kwargs = {k.arg: ast.literal_eval(k.value) for k in setup.keywords
              if k.arg in ("install_requires", "extras_require")}
    depends = {e.text for e in ET.parse(REPO / "package.xml").getroot()
               if e.tag in ("exec_depend", "depend")}
    rosdep = {"pyyaml": "python3-yaml"}     # rosdep's key differs from the PyPI name

    def key(requirement: str) -> str:
        name = re.split(r"[\[<>=!~ ]", requirement)[0].lower()
        return rosdep.get(name, "python3-" + name)

    missing = [r for r in kwargs["install_requires"] if key(r) not in depends]
    assert not missing, f"package.xml lacks exec_depend for {missing}"
    # the ROS extra's wheels are the message and client packages the node imports
    used = set(re.findall(r"^from (\w+_msgs|\w+_srvs|\w+_interfaces|rclpy)\b",
                          "\n".join(p.read_text() for p in (REPO / "rod_sim").rglob("*.py")),
                          re.M))
    assert used and used <= depends, f"package.xml lacks {sorted(used - depends)}"


def test_package_urls_never_lead_outside_the_share_directory(tmp_path, monkeypatch):
    """Issue 27, item 4: `package://rod_sim/../../../../etc/passwd` read a file outside the
    package. '..' above the share folder, an absolute path and a symbolic link whose target is
    outside the package are refused naming the URL; a link inside the share folder, or into
    another of the package's directories (colcon --symlink-install links share/ into the
    source tree), is followed."""
    from rod_sim.ros import scene_path

    share, src, outside = tmp_path / "share", tmp_path / "src", tmp_path / "outside"
    for d in (share / "config", src, outside):
        d.mkdir(parents=True)
    (share / "config" / "ok.yaml").write_text("ok")
    (src / "linked.yaml").write_text("linked")
    (outside / "secret.yaml").write_text("secret")
    (share / "config" / "in.yaml").symlink_to(share / "config" / "ok.yaml")
    (share / "config" / "src.yaml").symlink_to(src / "linked.yaml")
    (share / "config" / "out.yaml").symlink_to(outside / "secret.yaml")
    (share / "config" / "dir").symlink_to(outside, target_is_directory=True)
    monkeypatch.setattr(scene_path, "package_share_dirs", lambda package: [share, src])

    def read(url: str) -> str:
        return resolve_scene_file(url, "/rod_sim", cwd=tmp_path)[0].read_text()

    assert read("package://p/config/ok.yaml") == "ok"
    assert read("package://p/config/in.yaml") == "ok"
    assert read("package://p/config/src.yaml") == "linked"
    assert read("package://p/config/../config/ok.yaml") == "ok"
    for url in ("package://p/../outside/secret.yaml", "package://p/config/../../outside/secret.yaml",
                f"package://p/{outside / 'secret.yaml'}", "package://p/config/out.yaml",
                "package://p/config/dir/secret.yaml"):
        with pytest.raises(ScenePathError, match="refused: .* leads outside the share directory"):
            read(url)
    monkeypatch.undo()
    with pytest.raises(ScenePathError, match="refused"):
        resolve_scene_file("package://rod_sim/../../../../../../../../etc/passwd", "/rod_sim",
                           cwd=tmp_path)
