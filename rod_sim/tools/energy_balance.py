"""The energy balance residual of scenes, per model, sample rate and tolerance.

The figures docs/energy.md and docs/hinges.md state.

``python -m rod_sim.tools.energy_balance [SCENE ...] [--models rigid,reduced,full]
[--rates 100,1000] [--rtols 1e-8] [--t-end 3]`` prints a Markdown table of the largest
|residual| over each run (:func:`rod_sim.core.validity.assess_trajectory`, the balance
``simulate`` and the node keep: E - E0 - integral of the net power + latch impact losses),
the energy scale and the latch losses booked. Default: every shipped scene (config/*.yaml).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..api import Simulator, make_integrator, make_model
from ..core.validity import assess_trajectory, latch_losses
from ..io.scene_yaml import load_scene

CONFIG = Path(__file__).resolve().parents[2] / "config"
SHIPPED = ("deployment.yaml", "paper_example.yaml", "small_chain.yaml")


def residual(scene, model: str, rate_hz: float, rtol: float, t_end: float) -> dict:
    """One run of dop853-jit: {'residual': largest |residual| [J], 'scale' [J], 'latch' [J],
    'events': number of hinge events}."""
    sim = Simulator(make_model(model, scene), make_integrator("dop853-jit", rtol=rtol))
    traj = sim.run(t_end, rate_hz)
    mon = assess_trajectory(sim.model, traj.t, traj.y, modes=traj.modes, events=sim.events)
    return {"residual": abs(mon.energy_residual), "scale": mon.energy_scale,
            "latch": latch_losses(sim.events), "events": len(sim.events)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", help="scene files (default: the shipped ones)")
    ap.add_argument("--models", default="rigid,reduced,full")
    ap.add_argument("--rates", default="100,1000", help="sample rates [Hz]")
    ap.add_argument("--rtols", default="1e-8")
    ap.add_argument("--t-end", type=float, default=3.0)
    args = ap.parse_args(argv)
    scenes = args.scenes or [str(CONFIG / name) for name in SHIPPED]
    print("| scene | model | rate [Hz] | rtol | max abs residual [J] | / scale | scale [J] "
          "| latch losses [J] | hinge events |")
    print("|---|---|---|---|---|---|---|---|---|")
    for path in scenes:
        scene = load_scene(path)
        for model in args.models.split(","):
            for rate in (float(r) for r in args.rates.split(",")):
                for rtol in (float(r) for r in args.rtols.split(",")):
                    r = residual(scene, model, rate, rtol, args.t_end)
                    print(f"| {Path(path).name} | {model} | {rate:g} | {rtol:g} | "
                          f"{r['residual']:.2g} | {r['residual'] / r['scale']:.1e} | "
                          f"{r['scale']:.4g} | {r['latch']:.4g} | {r['events']} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
