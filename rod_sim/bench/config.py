"""What ``rod-sim bench`` measures: the time spans, references, accuracy target, scenes, the
integrator settings timed per model, and the types of a row, a reference and a run's options.

A new scene is one entry of :data:`SCENES` (and of :data:`SCENE_T_END` if it runs longer than
:data:`T_END`); ``--scene`` offers it and the report gets its table and plot.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rod_sim.core.names import SCIPY_METHODS
from rod_sim.app.common import PAPER_EXAMPLE

T_END = 2.0                 # simulated time of every run [s]
RATE_HZ = 100.0             # output samples [Hz of simulated time]
BENCH_REFERENCE_RTOL = 1e-12    # the bench's converged reference (atol = rtol)
BENCH_CHECK_RTOL = 1e-11    # the reference is checked against this looser run
REFERENCE_GAP = 1e-9        # largest allowed |phi(rtol 1e-11) - phi(rtol 1e-12)| [rad]
TARGET_ERROR = 1e-6         # the accuracy for the speed targets [rad]
HINGE_COST_LIMIT = 1.5
"""Issue 12: a hinge scene's cost per rhs within this factor of the plain chain's."""
FAST_BUDGET_S = 0.3         # runs faster than this in total get up to MAX_REPEATS repeats
MAX_REPEATS = 15
PILOT_FRACTION = 0.05       # compiled runs: a pilot over this fraction of T_END predicts the wall
MODELS = ("reduced", "full", "rigid")
CONFIG = PAPER_EXAMPLE.parent
SCENES = {"paper_example": PAPER_EXAMPLE,
          "chain_n32": CONFIG / "bench" / "chain_n32.yaml",
          "chain_n128": CONFIG / "bench" / "chain_n128.yaml",
          "paper_stiff": CONFIG / "bench" / "paper_stiff.yaml",
          "deployment": CONFIG / "deployment.yaml"}
SCENE_T_END = {"deployment": 10.0}
"""Scenes run over another span than T_END [s] (the deployment latches at 1.0 ... 6.8 s)."""
QUICK_SCENES = ("paper_example",)
RADAU_RTOLS = (1e-4, 1e-5, 6e-6, 3e-6, 1e-6, 3e-7, 1e-7, 1e-8)
RADAU_RTOLS_QUICK = (1e-5, 3e-6, 1e-6)


def cell(x, fmt=".3g") -> str:
    """A table cell: ``x`` formatted with ``fmt``, "-" for None or a non-finite number."""
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


@dataclass
class BenchRow:
    """One timed setting. Errors in rad, times in s; ``simulate_args`` are the ``rod-sim
    simulate`` options (after the scene file ``scene_file``) that reproduce the run."""

    scene: str
    n: int
    model: str
    integrator: str
    setting: str
    simulate_args: list | None
    wall_s: float
    sim_s: float
    rtf: float
    max_phi_error: float
    error_vs_full: float = math.nan
    model_error: float = math.nan
    max_hinge_error: float = math.nan      # max |theta - theta_ref| over hinges and samples
    cpu_s: float = math.nan
    rtf_cpu: float = math.nan
    nfev: int = 0
    steps: int = 0
    rejected: int = 0
    njev: int = 0               # Jacobians (radau-jit; their columns are counted in nfev)
    repeats: int = 0
    scene_file: str = ""
    status: str = "ok"


@dataclass
class Reference:
    """Converged phi (N, n) of one model on one scene and its check."""

    model: str
    phi: np.ndarray | None
    gap: float
    wall_s: float
    ok: bool
    message: str = ""


@dataclass
class BenchConfig:
    quick: bool = False
    repeats: int = 3
    cap_s: float = 45.0          # per-run wall-time cap
    scenes: tuple = ()
    models: tuple = MODELS
    integrators: tuple = ()      # only these integrators ('': all)
    mujoco: bool = True
    log: object = None           # callable(str) for progress lines, or None
    extra: dict = field(default_factory=dict)

def load_bench_scene(key: str):
    from rod_sim.io.scene_yaml import load_scene

    return load_scene(str(SCENES[key]))


def settings_grid(model_name: str, quick: bool) -> list[tuple[str, dict]]:
    """(integrator, settings) pairs timed for one model (``quick``: fewer of them)."""
    rtols = (1e-4, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 1e-8, 1e-9, 1e-10)
    grid = [("dop853-jit", {"rtol": r}) for r in rtols]
    grid += [("radau-jit", {"rtol": r}) for r in (RADAU_RTOLS_QUICK if quick else RADAU_RTOLS)]
    if quick:
        grid += [("rk4", {"step": h}) for h in (2e-3, 1e-3, 5e-4)]
        grid += [("rk2", {"step": h}) for h in (2.5e-4, 1e-4)]
        grid += [("euler", {"step": 1e-4})]
        grid += [(m, {"rtol": 1e-7}) for m in SCIPY_METHODS]
        return grid
    grid += [("rk4", {"step": h}) for h in (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)]
    grid += [("rk2", {"step": h}) for h in (1e-3, 2.5e-4, 1e-4)]
    grid += [("euler", {"step": h}) for h in (1e-4, 1e-5)]
    grid += [(m, {"rtol": r}) for m in SCIPY_METHODS for r in (1e-5, 1e-7, 1e-9)]
    return grid


def simulate_args(model_name: str, integrator: str, settings: dict, t_end=T_END) -> list[str]:
    """``rod-sim simulate`` options reproducing one run (the scene file goes first)."""
    args = ["--model", model_name, "--integrator", integrator]
    for key in ("rtol", "atol", "step"):
        if key in settings:
            args += [f"--{key}", repr(float(settings[key]))]
    return args + ["--t-end", repr(float(t_end)), "--rate", repr(RATE_HZ)]


def describe_setting(settings: dict) -> str:
    return " ".join(f"{k}={v:g}" for k, v in settings.items())
