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


def test_processes_running_at_once_get_disjoint_blocks_of_ids(tmp_path):
    """Test processes alive at the same time (CI's two suites side by side) never share an id:
    each claims its own block, held until it exits; a fifth gets ids from its process id."""
    env = {"PYTHONPATH": str(HERE), "ROD_SIM_TEST_DOMAIN_LOCKS": str(tmp_path)}
    code = ("import sys, ros_domains; print(*ros_domains.next_domains(70), flush=True); "
            "sys.stdin.read()")
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True) for _ in range(5)]
    try:
        got = [set(map(int, p.stdout.readline().split())) for p in procs]
    finally:
        for p in procs:
            p.communicate("", timeout=30)
    ids = [g for g in got if len(g) == ros_domains.BLOCK_SIZE]   # 70 ids wrapped in a block
    assert len(ids) == 4 and sum(len(g) == 70 for g in got) == 1, [sorted(g) for g in got]
    for i in range(4):
        assert all(1 <= x <= 232 for x in ids[i])
        for j in range(i):
            assert not ids[i] & ids[j], (i, j)
    # a block is free again once its process has exited
    again = ros_domains.claim_block(pid=0, lock_dir=str(tmp_path))
    assert again is not None and again[0] == 1


@pytest.mark.parametrize("bad", ["0", "233", "-5", "x", "1.5"])
def test_a_bad_base_is_refused_naming_the_variable(bad):
    with pytest.raises(ValueError, match="ROD_SIM_TEST_DOMAIN_BASE.*1..232"):
        ros_domains.base({"ROD_SIM_TEST_DOMAIN_BASE": bad})
