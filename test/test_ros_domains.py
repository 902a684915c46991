"""test/ros_domains.py: the domain ids of the tests that start ROS graphs stay within 1..232
(Fast DDS fails above 232; 0 is everyone's default), follow ROD_SIM_TEST_DOMAIN_BASE, and differ
between processes that do not set it."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import ros_domains

HERE = Path(__file__).resolve().parent


def ids_of_a_process(base: str | None, count: int) -> list[int]:
    """``count`` ids handed out in a fresh process (its own counter) with that base."""
    env = {"PYTHONPATH": str(HERE)}
    if base is not None:
        env["ROD_SIM_TEST_DOMAIN_BASE"] = base
    code = f"import ros_domains; print(*ros_domains.next_domains({count}))"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True)
    return [int(x) for x in done.stdout.split()]


def test_ids_count_up_from_the_base_and_wrap_inside_1_to_232():
    assert ids_of_a_process("7", 3) == [7, 8, 9]
    assert ids_of_a_process("231", 4) == [231, 232, 1, 2]
    every = ids_of_a_process("100", 500)
    assert min(every) == 1 and max(every) == 232 and len(set(every[:232])) == 232


def test_the_default_base_follows_the_process_id():
    assert ros_domains.base({}, pid=0) == 1 and ros_domains.base({}, pid=231) == 232
    assert ros_domains.base({}, pid=232) == 1
    assert ros_domains.base({"ROD_SIM_TEST_DOMAIN_BASE": ""}, pid=41) == 42
    firsts = {ids_of_a_process(None, 1)[0] for _ in range(3)}
    assert len(firsts) > 1, "three processes without a base started at the same id"


@pytest.mark.parametrize("bad", ["0", "233", "-5", "x", "1.5"])
def test_a_bad_base_is_refused_naming_the_variable(bad):
    with pytest.raises(ValueError, match="ROD_SIM_TEST_DOMAIN_BASE.*1..232"):
        ros_domains.base({"ROD_SIM_TEST_DOMAIN_BASE": bad})
