"""Issue 27, item 5: scene names. A name with a control character (``name: "a\\0b"``) was
accepted and ``rod-sim urdf`` wrote XML that does not parse. The scene checks its name once
(printable text, at most 200 characters; :func:`rod_sim.core.scene._check_name`), so every
writer gets a name it can carry: checked here with parsers that are not rod_sim's (the
standard library's XML parser, the mcap library and PyYAML)."""
from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader

REPO = Path(__file__).resolve().parents[1]
BODY = ("rods: {count: 3, length: 1.0, mass_per_length: 1.0, bending_stiffness: 100.0}\n"
        "nodes: {mass: 1.0}\nhinges: {stiffness: 10.0, damping: 0.1}\n")


def scene_file(tmp_path: Path, name: str) -> Path:
    path = tmp_path / "scene.yaml"
    quoted = "".join(c if " " <= c <= "~" and c not in '"\\' else f"\\U{ord(c):08x}"
                     for c in name)                    # a YAML double-quoted scalar
    path.write_text(f'name: "{quoted}"\n' + BODY, encoding="utf-8")
    assert yaml.safe_load(path.read_text(encoding="utf-8"))["name"] == name
    return path


def rod_sim(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", *map(str, args)],
                          cwd=REPO, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("name", ["a\0b", "tab\there", "line\nbreak", "bell\a", "del\x7f",
                                  "esc\x1b[31m", "zero\u200bwidth", "sep\u2028x", "bom\ufeff",
                                  "x" * 201])
def test_a_scene_name_with_control_characters_is_refused(tmp_path, name):
    done = rod_sim("urdf", scene_file(tmp_path, name))
    assert done.returncode == 2, done.stdout
    assert done.stdout == "" and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith("rod-sim urdf: error: name: "), done.stderr


@pytest.mark.slow
@pytest.mark.parametrize("name", ['<robot name="x"/> & \'q\'', "naïve 名前 🚀", "]]>--", "x" * 200])
def test_every_writer_carries_a_printable_name_whole(tmp_path, name):
    scene = scene_file(tmp_path, name)
    done = rod_sim("urdf", scene)
    assert done.returncode == 0, done.stderr
    assert ET.fromstring(done.stdout).get("name") == name
    log = tmp_path / "run.mcap"
    done = rod_sim("simulate", scene, "--t-end", "0.02", "--out", log)
    assert done.returncode == 0, done.stderr
    with open(log, "rb") as f:
        reader = make_reader(f)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        descriptions = [m for _, _, m in reader.iter_messages(topics=["robot_description",
                                                                       "/robot_description"])]
    assert any(yaml.safe_load(v.get("scene", "")) and yaml.safe_load(v["scene"])["name"] == name
               for v in metadata.values() if "scene" in v), metadata.keys()
    for message in descriptions:             # CDR std_msgs/String: 4-byte header, length, text
        text = message.data[8:8 + int.from_bytes(message.data[4:8], "little") - 1]
        assert ET.fromstring(text.decode("utf-8")).get("name") == name
