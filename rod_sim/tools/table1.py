"""Table 1 of the paper and its recomputation with our full and reduced models (``rod-sim
table1 [--json]``).

The published values (section 3 of the paper: n = 8, tip pulse, integration to 2 s) are
transcribed below as printed; "П" (full) is ``full`` and "Р" (reduced) is ``reduced``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rod_sim.app.common import PAPER_EXAMPLE

HELP = "recompute Table 1 of the paper"
DESCRIPTION = ("Recompute Table 1 of the paper with the full and reduced models and print it "
               "beside the published values.")

TIMES = (0.5, 1.0, 1.5, 2.0)

# (var, rod, model): values at TIMES, as printed in Table 1.
PAPER: dict[tuple[str, int, str], tuple[float, float, float, float]] = {
    ("phi_rate", 2, "full"): (-0.00950, 3.50311, 3.12768, 0.92900),
    ("phi_rate", 2, "reduced"): (-0.00945, 3.50803, 3.16662, 0.98172),
    ("phi_rate", 4, "full"): (-0.39923, 2.54956, 1.69934, 6.27426),
    ("phi_rate", 4, "reduced"): (-0.40050, 2.54610, 1.64601, 6.27792),
    ("phi_rate", 6, "full"): (5.73717, 1.69062, -0.21457, -4.93915),
    ("phi_rate", 6, "reduced"): (5.73867, 1.69230, -0.22518, -4.95233),
    ("phi_rate", 8, "full"): (-2.53956, -0.31132, -0.05238, 1.34521),
    ("phi_rate", 8, "reduced"): (-2.53880, -0.31110, -0.03762, 1.35888),
    ("phi", 2, "full"): (-0.00089, 0.01607, 1.55280, 3.25023),
    ("phi", 2, "reduced"): (-0.00089, 0.01627, 1.55337, 3.24869),
    ("phi", 4, "full"): (-0.00047, 1.70235, 1.92237, 2.65990),
    ("phi", 4, "reduced"): (-0.00050, 1.70252, 1.92242, 2.65925),
    ("phi", 6, "full"): (0.20474, 1.47268, 1.78593, 1.24211),
    ("phi", 6, "reduced"): (0.20479, 1.47266, 1.78564, 1.23788),
    ("phi", 8, "full"): (1.68550, 1.48557, 1.67493, 2.57061),
    ("phi", 8, "reduced"): (1.68552, 1.48558, 1.67492, 2.56772),
    ("alpha", 2, "full"): (-1.998e-7, -0.00057, 0.00341, 0.00059),
    ("alpha", 2, "reduced"): (-5.591e-8, -0.00057, 0.00344, -0.00025),
    ("alpha", 4, "full"): (5.872e-5, -0.00097, -0.00285, -0.00519),
    ("alpha", 4, "reduced"): (5.897e-5, -0.00097, -0.00266, 0.00083),
    ("alpha", 6, "full"): (-0.00107, -2.033e-6, -0.00019, 0.00589),
    ("alpha", 6, "reduced"): (-0.00107, -6.780e-6, -0.00030, -0.00071),
    ("alpha", 8, "full"): (-0.00076, 0.00025, 7.172e-5, 0.00257),
    ("alpha", 8, "reduced"): (-0.00076, 0.00024, 0.00016, -0.00019),
    ("beta", 2, "full"): (2.120e-6, 0.00082, -0.00312, -0.00082),
    ("beta", 2, "reduced"): (2.268e-6, 0.00082, -0.00316, -1.743e-5),
    ("beta", 4, "full"): (-9.298e-5, 0.00062, 0.00250, 0.00484),
    ("beta", 4, "reduced"): (-9.321e-5, 0.00062, 0.00231, -0.00129),
    ("beta", 6, "full"): (0.00136, 0.00012, 0.00014, -0.00569),
    ("beta", 6, "reduced"): (0.00136, 0.00013, 0.00025, 0.00098),
    ("beta", 8, "full"): (0.00057, -0.00016, -4.238e-5, -0.00274),
    ("beta", 8, "reduced"): (0.00057, -0.00016, -0.00013, 8.178e-5),
}
VARIABLES = ("phi_rate", "phi", "alpha", "beta")


@dataclass(frozen=True)
class Row:
    """One cell of Table 1: variable ``var`` of rod ``rod`` (1-based) by ``model`` at ``t``."""

    var: str
    rod: int
    model: str
    t: float
    paper: float
    ours: float

    @property
    def diff(self) -> float:
        return self.ours - self.paper

    def as_dict(self) -> dict:
        return {"var": self.var, "rod": self.rod, "model": self.model, "t": self.t,
                "paper": self.paper, "ours": self.ours}


def model_values(scene, model_name: str, rtol: float = 1e-11) -> dict[tuple[str, int, float], float]:
    """Our phi, phi_rate, alpha, beta for every rod at TIMES from a converged run."""
    from ..api import Simulator, make_integrator, make_model

    model = make_model(model_name, scene)
    sim = Simulator(model, make_integrator("dop853-jit", rtol=rtol))
    traj = sim.run(max(TIMES), rate_hz=1.0 / 0.5)
    out = {}
    for t in TIMES:
        y = traj.at(t)
        alpha, beta = model.bending(t, y)
        series = {"phi": model.phi(y), "phi_rate": model.phi_rate(y), "alpha": alpha, "beta": beta}
        for var, values in series.items():
            for k in range(model.n):
                out[(var, k + 1, t)] = float(values[k])
    return out


def compute(scene, rtol: float = 1e-11) -> list[Row]:
    """Every Table 1 cell, the paper's value beside ours, in the table's order."""
    ours = {name: model_values(scene, name, rtol) for name in ("full", "reduced")}
    rows = []
    for (var, rod, model_name), values in PAPER.items():
        for t, paper in zip(TIMES, values):
            rows.append(Row(var, rod, model_name, t, paper, ours[model_name][(var, rod, t)]))
    return rows


def format_table(rows: list[Row], times_per_block: int = 2) -> str:
    """Plain-text table: for each variable, rod and model, paper / ours / difference; the
    times are split into blocks of ``times_per_block`` (two keep lines within 100 columns)."""
    by_key: dict[tuple, dict[float, Row]] = {}
    for r in rows:
        by_key.setdefault((r.var, r.rod, r.model), {})[r.t] = r
    blocks = []
    for i in range(0, len(TIMES), times_per_block):
        times = TIMES[i:i + times_per_block]
        lines = [f"{'var':9s}{'rod':>4s} {'model':8s}"
                 + "".join(f"{'t = %.1f s' % t:>34s}" for t in times),
                 " " * 22 + "".join(f"{'paper':>12s}{'ours':>12s}{'diff':>10s}" for _ in times)]
        for (var, rod, model_name), cells in by_key.items():
            line = f"{var:9s}{rod:>4d} {model_name:8s}"
            for t in times:
                c = cells[t]
                line += f" {c.paper:>11.5g} {c.ours:>11.5g} {c.diff:>9.2g}"
            lines.append(line)
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)


def summary(rows: list[Row]) -> dict[str, float]:
    """Largest |ours - paper| per variable (over rods, models and times)."""
    out = {}
    for var in VARIABLES:
        diffs = [abs(r.diff) for r in rows if r.var == var]
        out[var] = float(np.max(diffs))
    return out


def configure(parser) -> None:
    import argparse

    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.add_argument("--scene", default=str(PAPER_EXAMPLE), help=argparse.SUPPRESS)


def run(args) -> int:
    import json

    from rod_sim.app.common import EXIT_OK, load_scene

    scene = load_scene(args.scene)
    rows = compute(scene)
    if args.json:
        print(json.dumps({"rows": [r.as_dict() for r in rows]}, indent=1))
    else:
        print("Table 1 of the paper (n = 8, tip pulse): published values beside ours")
        print(format_table(rows))
        worst = summary(rows)
        print("largest |ours - paper|: " + ", ".join(f"{k} {v:.2g}" for k, v in worst.items()))
    return EXIT_OK
