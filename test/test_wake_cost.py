"""python -m rod_sim.bench.wake_cost: runs, prints one line per way of waiting, refuses bad
counts (the figures themselves are the machine's and are not asserted)."""
import re

import pytest

from rod_sim.bench import wake_cost


def test_prints_a_median_for_each_way_of_waiting(capsys):
    assert wake_cost.main(["--rods", "8", "--wait-ms", "0.2", "--blocks", "3",
                           "--calls", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["back to back", "after spinning",
                                                       "after sleeping"]
    for line in lines:
        m = re.search(r"of 8 rods: median ([0-9.]+) us, .* \((\d+) calls, ([0-9.]+) x", line)
        assert m and float(m.group(1)) > 0 and m.group(2) == "2" and float(m.group(3)) > 0
    assert "1.00 x back to back" in lines[0]


def test_blocks_take_turns_so_every_way_gets_its_calls():
    out = wake_cost.measure(rods=4, wait_ms=0.0, blocks=4, calls=3)
    assert [len(out[w]) for w in wake_cost.WAYS] == [6, 3, 3]


@pytest.mark.parametrize("bad", [["--calls", "0"], ["--rods", "0"], ["--wait-ms", "-1"]])
def test_bad_counts_exit_2(bad, capsys):
    with pytest.raises(SystemExit) as e:
        wake_cost.main(bad)
    assert e.value.code == 2
    assert "must be" in capsys.readouterr().err


@pytest.mark.parametrize("work, label", [("arithmetic", "20000 compiled multiply-adds"),
                                         ("sum", "a compiled sum of 2 KiB, 5 passes")])
def test_the_other_works_are_timed_and_named(work, label, capsys):
    assert wake_cost.main(["--work", work, "--kib", "2", "--wait-ms", "0.2", "--blocks", "3",
                           "--calls", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3
    for line in lines:
        m = re.search(re.escape(label) + r": median ([0-9.]+) us, .* \((\d+) calls", line)
        assert m and float(m.group(1)) > 0 and m.group(2) == "2"


def test_a_bad_array_size_exits_2(capsys):
    with pytest.raises(SystemExit) as e:
        wake_cost.main(["--work", "sum", "--kib", "0"])
    assert e.value.code == 2
    assert "--kib must be > 0" in capsys.readouterr().err
