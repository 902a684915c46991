"""The spacecraft ledger of a run: the momentum balance and the work a prescribed base injects,
booked sample by sample (pure numpy, O(n) per sample; docs/spacecraft.md section 6).

- Momentum: :class:`~rod_sim.core.momentum.MomentumBalance`, P(t) - P(0) - int (F + D_P) dt
  and H_O(t) - H_O(0) - int (M_O + D_H) dt, with F, M_O the applied loads and gravity
  (:func:`~rod_sim.core.momentum.momentum_rates`) and, on a fixed or prescribed base (an
  external support: the system is the chains), the support's reaction on every chain
  (:func:`~rod_sim.core.momentum.base_reaction`: the force F_c at node 0 and the moment -M_c
  of hinge 0), so the balance closes for every base mode.
- Injected work: int P_inj dt, P_inj = sum_c (F_c . v_0c - psi' M_c)
  (:func:`~rod_sim.core.momentum.injected_power`, 0 unless the base is prescribed).

Both integrals by the trapezoid rule over the samples given to :meth:`SpacecraftLedger.add`
(their error falls with the square of the sample spacing).
"""
from __future__ import annotations

import numpy as np

from . import kernels
from .momentum import MomentumBalance, MomentumRates, _cross, base_reaction, injected_power, \
    momentum_rates

LEDGER_KEYS = ("momentum_balance_residual_x", "momentum_balance_residual_y",
               "angular_momentum_balance_residual", "work_injected")
"""Keys of :meth:`SpacecraftLedger.values`: the linear momentum balance residual (x, y)
[kg m/s], the angular one about O [kg m^2/s] and the injected work [J]."""


def support_rates(model, t: float, y, held=None, mode=None, state=None) -> MomentumRates:
    """:func:`momentum_rates` plus, on a fixed or prescribed base, the support's force and
    moment about O on the chains; at a load breakpoint ``t`` the reaction before it too (from
    the accelerations under the loads before the jump: it jumps with them).
    ``state``: a :class:`~rod_sim.core.state.State` of the arguments to share."""
    s = model.state(t, y, held, mode) if state is None else state
    rates = momentum_rates(model, t, y, held, mode, state=s)
    if model.base_mode == kernels.MODE_FREE:
        return rates
    root = s.nodes[model.table.roots]

    def support(force, moment):
        return force.sum(axis=0), float(np.sum(_cross(root, force)) - np.sum(moment))

    f, m = support(*base_reaction(model, t, y, held, mode, state=s))
    fb, mb = (f, m) if t not in model.breakpoints else support(
        *base_reaction(model, float(np.nextafter(t, -np.inf)), y, held, mode))
    before_f = rates.force if rates.force_before is None else rates.force_before
    before_m = rates.moment if rates.moment_before is None else rates.moment_before
    return MomentumRates(rates.force + f, rates.moment + m, rates.defect_force,
                         rates.defect_moment, before_f + fb, before_m + mb)


class SpacecraftLedger:
    """The momentum balance and injected work of a run of ``model`` (module docstring)."""

    def __init__(self, model):
        self.model = model
        self.start()

    def start(self) -> None:
        """Forget every sample (a reset)."""
        self.balance = MomentumBalance()
        self.work_injected = 0.0
        self._last: tuple[float, float] | None = None

    def add(self, t: float, y, held=None, mode=None, momentum=None, state=None) -> None:
        """Book the state ``y`` at ``t`` [s] (held inputs ``held``, latches ``mode``);
        ``momentum``: :meth:`ChainModel.momentum` at (t, y) if already known; ``state``: a
        :class:`~rod_sim.core.state.State` of these arguments whose quantities (the momentum,
        the node positions, the right-hand side) are shared."""
        model = self.model
        s = model.state(t, y, held, mode) if state is None else state
        mom = s.momentum if momentum is None else momentum
        self.balance.add(t, mom, support_rates(model, t, y, held, mode, state=s))
        power = injected_power(model, t, y, held, mode, state=s)
        if self._last is not None:
            t0, p0 = self._last
            self.work_injected += 0.5 * (t - t0) * (p0 + power)
        self._last = (float(t), power)

    def values(self) -> dict[str, float]:
        """The ledger's values by :data:`LEDGER_KEYS` (zeros before the first sample)."""
        if self.balance.p0 is None:
            return dict.fromkeys(LEDGER_KEYS, 0.0)
        r = self.balance.residual_linear
        return {"momentum_balance_residual_x": float(r[0]),
                "momentum_balance_residual_y": float(r[1]),
                "angular_momentum_balance_residual": float(self.balance.residual_angular),
                "work_injected": float(self.work_injected)}


def diagnostic_values(snapshot, ledger: SpacecraftLedger | None) -> dict[str, float]:
    """The spacecraft values of ``/diagnostics`` and the log (docs/interface.md section 3), keyed
    with their units, from a spacecraft snapshot (:class:`~rod_sim.core.snapshot.Snapshot`
    with ``base``) and the run's ledger: the base's pose and twist, the wheel's rate, momentum,
    centre of mass, the energy terms, the injected work and the momentum balance residuals."""
    b, m, e = snapshot.base, snapshot.momentum, snapshot.energy_terms
    out = {"base_x_m": b[0], "base_y_m": b[1], "base_psi_rad": b[2], "base_x_rate_m_s": b[3],
           "base_y_rate_m_s": b[4], "base_psi_rate_rad_s": b[5],
           "wheel_rate_rad_s": snapshot.wheel_rate,
           "linear_momentum_x_kg_m_s": m[0], "linear_momentum_y_kg_m_s": m[1],
           "angular_momentum_origin_kg_m2_s": m[2], "angular_momentum_com_kg_m2_s": m[3],
           "centre_of_mass_x_m": m[4], "centre_of_mass_y_m": m[5]}
    for name in ("kinetic", "hinge", "bending", "gravity", "base_kinetic", "wheel_kinetic"):
        out[f"energy_{name}_J"] = e[name]
    led = ledger.values() if ledger is not None else dict.fromkeys(LEDGER_KEYS, 0.0)
    out["work_injected_J"] = led["work_injected"]
    out["momentum_balance_residual_x_kg_m_s"] = led["momentum_balance_residual_x"]
    out["momentum_balance_residual_y_kg_m_s"] = led["momentum_balance_residual_y"]
    out["angular_momentum_balance_residual_kg_m2_s"] = led["angular_momentum_balance_residual"]
    return {k: float(v) for k, v in out.items()}


def diagnostic_strings(values: dict[str, float]) -> dict[str, str]:
    """:func:`diagnostic_values` as diagnostic_msgs strings: every digit (``%.17g``: the
    balances are judged at round-off)."""
    return {k: f"{v:.17g}" for k, v in values.items()}
