"""The long-chain bench (rod_sim.bench.long_chains) on small n: it verifies before it times
(Pinocchio's accelerations against the rigid model), its rows are complete and its targets
and report lines follow from the numbers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rod_sim.core.models import make_model
from rod_sim.bench import long_chains as bench_long
from rod_sim.bench import pinocchio_peer


def test_scenes_are_what_the_docs_say():
    chain = bench_long.uniform_chain(16)
    assert chain.n == 16 and chain.loads[0].node == 16
    np.testing.assert_array_equal(chain.length, 2.0)
    tether = bench_long.tether(64)
    assert tether.n == 64 and float(tether.length[0]) == 0.05
    # the tether's rods are stiff: first chord-fixed bending mode 1.56 kHz (9800 rad/s)
    from rod_sim.core.validity import bending_frequencies

    assert 1500 < bending_frequencies(tether)[0] < 1600


@pytest.mark.skipif(not pinocchio_peer.available(), reason="pin not installed")
def test_pinocchio_is_the_same_chain_and_a_wrong_chain_is_caught():
    scene = bench_long.uniform_chain(12)
    assert pinocchio_peer.check(scene, make_model("rigid", scene)) < 1e-10
    other = make_model("rigid", scene.with_changes(node_mass=np.full(12, 3.5)))
    with pytest.raises(pinocchio_peer.PeerError, match="disagree"):
        pinocchio_peer.check(scene, other)


def test_scaling_rows_and_targets():
    data = bench_long.scaling((8, 16), models=("rigid", "reduced"))
    assert data["n"] == [8, 16]
    for m in ("rigid", "reduced"):
        assert len(data["per_rhs_s"][m]) == 2 and all(c > 0 for c in data["per_rhs_s"][m])
    if pinocchio_peer.available():
        assert all(c > 0 for c in data["pinocchio_aba_s"]) and data["pinocchio_check"] < 1e-10
    # targets from synthetic numbers: met and not met follow the stated bounds
    fake = {"scaling": {"ratio_4096_over_512": {"rigid": 8.0, "full": 11.0},
                        "over_pinocchio_at_256": {"rigid": 0.4, "reduced": 1.2}}}
    t = bench_long.targets(fake)
    assert t["rigid: cost(4096) / cost(512) <= 10"] == (8.0, True)
    assert t["full: cost(4096) / cost(512) <= 10"][1] is False
    assert t["rigid rhs / Pinocchio aba at n = 256 <= 0.5"][1] is True
    assert t["reduced rhs / Pinocchio aba at n = 256 <= 1"][1] is False


def test_work_precision_rows_measure_against_a_checked_reference():
    block = bench_long.work_precision(bench_long.tether(8), "full", 0.02,
                                      [("dop853-jit", 1e-6), ("radau-jit", 1e-6)])
    assert block["reference_gap"] < 1e-8
    rows = {r["integrator"]: r for r in block["rows"]}
    for r in rows.values():
        assert r["cpu_s"] > 0 and math.isfinite(r["max_phi_error"]) and r["nfev"] > 0
        assert r["max_phi_error"] < 1e-4
    assert rows["radau-jit"]["newton_iters"] > 0 and rows["dop853-jit"]["newton_iters"] == 0
    # the stiff tether: the explicit method pays for the bending modes, the implicit does not
    assert rows["radau-jit"]["nfev"] < rows["dop853-jit"]["nfev"]
    lines = bench_long.markdown_lines({"tether": [block]})
    assert any("Stiff tether" in line for line in lines)
    assert sum(line.startswith("| radau-jit") for line in lines) == 1


def test_radau_cost_per_step_is_reported_per_n():
    r = bench_long.radau_cost_per_step((8, 16), t_end=0.002)
    assert r["n"] == [8, 16] and all(c > 0 for c in r["cpu_per_step_s"])
    assert r["ratio_last_over_first"] == r["cpu_per_step_s"][1] / r["cpu_per_step_s"][0]
