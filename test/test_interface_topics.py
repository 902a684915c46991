"""docs/interface.md section 3's topic table is the node's: every output topic it lists is an
entry of the node's output table (or /clock) with the documented type, and the other way round;
every input topic it lists is one of the node's command intakes. The document is the oracle:
a topic added to the code and not to the document (or the reverse) fails here."""
from __future__ import annotations

import re
from pathlib import Path

from rod_sim.io import topics
from rod_sim.ros.inputs import Inputs
from rod_sim.ros.outputs import OUTPUTS

DOC = Path(__file__).resolve().parents[1] / "docs" / "interface.md"
ROW = re.compile(r"^\| `(/?[a-z_]+)` \| (\w+/\w+) \| (in|out) \|", re.M)


def documented() -> list[tuple[str, str, str]]:
    """(relative name, pkg/Type, direction) of each row of section 3's topic table."""
    section = DOC.read_text().split("## 3. ROS 2 node")[1].split("\n## 4.")[0]
    rows = [(name.lstrip("/"), kind, way) for name, kind, way in ROW.findall(section)]
    assert len(rows) >= 10, rows
    return rows


def test_every_documented_output_is_a_table_entry_of_that_type_and_back():
    outs = {name: kind for name, kind, way in documented() if way == "out"}
    table = {o.name: o.type_name for o in OUTPUTS}
    table["clock"] = topics.TOPIC_TYPES["clock"]          # sent by the node's SimClock
    assert set(outs) == set(table), set(outs) ^ set(table)
    for name, kind in outs.items():
        assert table[name].replace("/msg/", "/") == kind, (name, table[name], kind)


def test_every_documented_input_is_a_command_intake():
    ins = {name for name, _, way in documented() if way == "in"}
    assert ins == set(Inputs(3, 0.5).intakes), ins
