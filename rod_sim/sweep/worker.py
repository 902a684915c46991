"""One sweep run as a plain function: scene data and settings in, one result row out.

:func:`run_one` is what ``rod-sim sweep`` sends to local worker processes and to Dask
workers: a top-level function (pickled by reference) taking and returning plain dicts. It
never raises for a failing run: the failure is the row's ``status``. The numba kernels are
compiled (or loaded from numba's disk cache) once per process, outside the timed integration.
"""
from __future__ import annotations

import math
import time

import numpy as np

from rod_sim.api import IntegrationError, Simulator, make_integrator, make_model
from rod_sim.core.scene import Scene
from rod_sim.core.ledger import SpacecraftLedger
from rod_sim.core.validity import balance_run

# Result columns after the run index and the swept parameters, with units.
OUTPUTS = {
    "model": "model name",
    "status": "'ok' or 'failed: <reason>'",
    "wall_s": "wall time of the integration alone [s]",
    "rtf": "real-time factor: t_end / wall_s",
    "nfev": "right-hand side evaluations",
    "max_abs_phi": "max over samples and rods of |phi_k| [rad]",
    "tip_phi_final": "phi_n of the tip rod (the last chain's) at t_end [rad]",
    "max_tip_displacement": "max over samples (and chains) of |r_n(t) - r_n(0)|, r_n the tip "
                            "node (of each chain, in Oxy) [m]",
    "max_abs_alpha": "max over samples and rods of |alpha_k| [rad]",
    "max_abs_beta": "max over samples and rods of |beta_k| [rad]",
    "energy_final": "kinetic + hinge + bending energy at t_end [J]",
    "energy_residual": "E(t_end) - E(0) - W + D [J]: the energy balance of the run as simulate "
                       "books it (rod_sim.core.validity.EnergyBalance: loads, dampers, stop "
                       "contacts, latch impacts, the full model's unpaired term)",
}
SPACECRAFT_OUTPUTS = {
    "base_psi_final": "the base frame's angle psi at t_end [rad]",
    "momentum_residual": "|P(t_end) - P(0) - int (F + D_P) dt| [kg m/s]: the linear momentum "
                         "balance of the run (F: loads, gravity and a fixed or prescribed "
                         "base's support; D_P the full model's defect), as simulate books it "
                         "(rod_sim.core.ledger.SpacecraftLedger)",
    "angular_momentum_residual": "H_O(t_end) - H_O(0) - int (M_O + D_H) dt [kg m^2/s]: the "
                                 "angular momentum balance about the origin of Oxy, likewise",
}
"""Result columns after :data:`OUTPUTS` for a spacecraft scene (``base:``, ``chains:`` or
``gravity:``; a plain chain's table is what it always was)."""
FLOAT_OUTPUTS = [k for k in OUTPUTS if k not in ("model", "status", "nfev")]
METRICS = FLOAT_OUTPUTS[2:] + list(SPACECRAFT_OUTPUTS)  # of a trajectory (NaN: a failed run)

_WARM: set = set()


def _warm_up(model, integrator: str, step) -> None:
    """Compile (or load from cache) the kernels of this model and integrator once per process."""
    key = (model.name, integrator)
    if key in _WARM:
        return
    try:
        Simulator(model, make_integrator(integrator, step=step)).advance(1e-3)
    except IntegrationError:
        pass                                   # compiled all the same; the real run reports it
    _WARM.add(key)


def metrics(model, t: np.ndarray, y: np.ndarray, modes=None, events=()) -> dict:
    """Summary outputs of a trajectory: ``t`` (N,) [s], ``y`` (N, state_size), the latches
    ``modes`` (N, n) fired at each sample and the run's hinge ``events``."""
    phi = model.phi(y)                                   # (N, n)
    scene = model.scene
    if scene.has_chains or scene.has_base:
        # every chain's tip node in Oxy (the base may move): (N, chains, 2)
        ends = scene.chain_starts[1:] + np.arange(len(scene.chains))
        tip = np.stack([model.node_positions(ti, yi)[ends] for ti, yi in zip(t, y)])
    else:
        l = model.params.l
        tip = np.stack([np.cos(phi) @ l, np.sin(phi) @ l], axis=1)[:, None]    # (N, 1, 2)
    alpha = np.empty_like(phi)
    beta = np.empty_like(phi)
    ledger = SpacecraftLedger(model) if scene.is_spacecraft else None

    def book(i, held, mode, state):
        ledger.add(float(t[i]), y[i], held, mode, state=state)

    for i, balance, (a, b) in balance_run(model, t, y, None, modes, events,
                                          on_state=None if ledger is None else book):
        alpha[i], beta[i] = a, b
    out = {
        "max_abs_phi": float(np.max(np.abs(phi))),
        "tip_phi_final": float(phi[-1, -1]),
        "max_tip_displacement": float(np.max(np.linalg.norm(tip - tip[0], axis=-1))),
        "max_abs_alpha": float(np.max(np.abs(alpha))),
        "max_abs_beta": float(np.max(np.abs(beta))),
        "energy_final": float(balance.energy),
        "energy_residual": float(balance.residual),
    }
    if ledger is not None:
        led = ledger.values()
        out.update(base_psi_final=float(model.base_state(float(t[-1]), y[-1]).psi),
                   momentum_residual=float(np.hypot(led["momentum_balance_residual_x"],
                                                    led["momentum_balance_residual_y"])),
                   angular_momentum_residual=led["angular_momentum_balance_residual"])
    return out


def _row(task: dict, status: str, wall: float, nfev: int, values: dict | None) -> dict:
    row = {"run": int(task["index"]), **task["params"], "model": task["model"],
           "status": status, "wall_s": float(wall),
           "rtf": float(task["t_end"] / wall) if wall > 0 and status == "ok" else math.nan,
           "nfev": int(nfev)}
    for k in METRICS:
        row[k] = math.nan if values is None else values.get(k, math.nan)
    return row


def failed_row(task: dict, reason: str) -> dict:
    """The row of a run that did not produce a result (e.g. its worker process died)."""
    return _row(task, f"failed: {' '.join(reason.split())}", math.nan, 0, None)


def run_one(task: dict) -> dict:
    """Run one scene and summarise it.

    ``task``: ``index``, ``model``, ``params`` ({path: value}, copied into the row), ``scene``
    (scene data (docs/interface.md section 1)), ``integrator``, ``rtol``, ``atol``, ``step``, ``t_end`` [s],
    ``rate_hz`` [Hz] (samples the outputs are taken over). Returns the row: ``run``, the
    params, then :data:`OUTPUTS`.
    """
    try:
        model = make_model(task["model"], Scene.from_dict(task["scene"]))
        _warm_up(model, task["integrator"], task["step"])
        integrator = make_integrator(task["integrator"], rtol=task["rtol"], atol=task["atol"],
                                     step=task["step"])
    except Exception as err:                 # noqa: BLE001 - a failing run is a row
        return failed_row(task, f"{type(err).__name__}: {err}")
    sim = Simulator(model, integrator)
    started = time.perf_counter()
    try:
        traj = sim.run(task["t_end"], task["rate_hz"])
    except Exception as err:                 # noqa: BLE001
        wall = time.perf_counter() - started
        return _row(task, f"failed: {type(err).__name__}: {' '.join(str(err).split())}", wall,
                    sim.stats.nfev, None)
    wall = time.perf_counter() - started
    try:
        values = metrics(model, traj.t, traj.y, traj.modes, sim.events)
    except Exception as err:                 # noqa: BLE001
        return _row(task, f"failed: outputs: {type(err).__name__}: {err}", wall,
                    sim.stats.nfev, None)
    return _row(task, "ok", wall, sim.stats.nfev, values)
