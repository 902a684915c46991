"""The reference runs of ``rod-sim compare``: the full model of the logged scene re-run with the
logged held inputs, window by window (:class:`Run`), and the pair of re-runs at two tolerances
whose difference estimates the reference's own error (:class:`References`).

Units: states y (6n + 2 nb,) = [phi, alpha, beta, base, phi_rate, alpha_rate, beta_rate,
base_rate] [rad, m, rad/s, m/s] (the full model's layout; ``nb`` base coordinates x_B, y_B, psi
[, theta_w] of a free base, none otherwise: take phi and its rates with the model's ``phi`` and
``phi_rate``), times [ns] where named ``*_ns`` or ``t_out``/``bounds``.
"""
from __future__ import annotations

import numpy as np

from rod_sim.api import Simulator, make_integrator, make_model
from rod_sim.core.models import FullModel
from rod_sim.core.scene import Scene

COMPARE_REFERENCE_RTOL = 1e-10
"""Relative tolerance of compare's full-model re-run; atol = rtol * 1e-2."""
COMPARE_CHECK_RTOL = 1e-12
"""compare's tighter second re-run: the two differ by about the first one's own error."""


def reference_model(scene: Scene) -> FullModel:
    """The model every reference run of compare integrates (one place to build it): the full
    model of the logged scene, hinge features included."""
    return make_model("full", scene)


class Run:
    """A full-model run from the scene's initial state, continued window by window through the
    one driver (a :class:`Simulator`: hinge features, latches and stop contacts included) with
    ``integrator`` (dop853-jit, or radau-jit on a stiff scene: :mod:`rod_sim.app.stiff_probe`)
    at ``rtol`` (atol = rtol * 1e-2). ``y`` (the full model's state, see
    above) is the state at ``t_ns``; setting ``y`` (the twin's renormalisation) keeps the mode
    and re-derives the contacts."""

    def __init__(self, model: FullModel, rtol: float, y0: np.ndarray,
                 integrator: str = "dop853-jit"):
        self.model = model
        self.integ = make_integrator(integrator, rtol=rtol, atol=rtol * 1e-2)
        self.sim = Simulator(model, self.integ)
        self.y = y0

    @property
    def y(self) -> np.ndarray:
        return self.sim.y

    @y.setter
    def y(self, value) -> None:
        self.sim.y = np.array(value, dtype=float)
        self.sim.contact = self.model.contact_state(self.sim.y, self.sim.t)

    @property
    def t_ns(self) -> int:
        return self.sim.t_ns

    def advance(self, t_out: np.ndarray, bounds: list[int], helds: list[np.ndarray]) -> np.ndarray:
        """States (len(t_out), state size) at the sorted times ``t_out`` [ns] (all >= ``t_ns``,
        the last <= ``bounds[-1]``); the held input ``helds[i]`` (n, 3) = forces X, Y [N] and hinge
        torques T [N m] (or (n, 2): forces, zero torques; or (n + 2, 3) with the free base's
        rows of ``Simulator.set_held``) applies up to
        ``bounds[i]`` [ns] (the integrator restarts there). Raises IntegrationError."""
        out = np.empty((t_out.size, self.y.size))
        k = 0
        while k < t_out.size and t_out[k] <= self.t_ns:
            out[k] = self.y
            k += 1
        for b, held in zip(bounds, helds):
            if b <= self.t_ns:
                continue
            j = k
            while j < t_out.size and t_out[j] <= b:
                j += 1
            held = np.asarray(held, dtype=float)
            if held.shape == (self.model.n + 2, 3):      # with a free base's rows
                self.sim.set_held(held)
                held = held[:self.model.n]
            held = held.reshape(self.model.n, -1)
            self.sim.set_forces(held[:, :2])
            self.sim.set_hinge_torques(held[:, 2] if held.shape[1] == 3
                                       else np.zeros(self.model.n))
            Y = self.sim.sample(np.concatenate([t_out[k:j], [int(b)]]))
            out[k:j] = Y[:-1]
            k = j
        return out


class References:
    """The re-run at ``rtol`` (``ref``) and, unless ``check_rtol`` is None, the check re-run at
    ``check_rtol`` (``check``), both from ``y0`` with ``integrator``; :meth:`advance` runs both
    and books the
    largest phi [rad] and phi_rate [rad/s] separations between them (``phi_change``,
    ``rate_change``)."""

    def __init__(self, model: FullModel, rtol: float, check_rtol: float | None,
                 y0: np.ndarray, integrator: str = "dop853-jit"):
        self.ref = Run(model, rtol, y0, integrator)
        self.check = Run(model, check_rtol, y0, integrator) if check_rtol else None
        self.phi_change = 0.0
        self.rate_change = 0.0

    def advance(self, t_out, bounds, helds) -> tuple[np.ndarray, np.ndarray | None]:
        """States (len(t_out), state size) of the reference and of the check run (None without
        one) at ``t_out`` [ns] (see :meth:`Run.advance`). Raises IntegrationError."""
        y = self.ref.advance(t_out, bounds, helds)
        yc = self.check.advance(t_out, bounds, helds) if self.check else None
        return y, yc

    def separation(self, y: np.ndarray, yc: np.ndarray | None, rows: np.ndarray,
                   n: int) -> np.ndarray:
        """Per sample ``rows`` the largest |phi_check - phi_ref| [rad] over rods (zeros without a
        check run); books the running maxima of phi and phi_rate separations."""
        if yc is None:
            return np.zeros(rows.size)
        ref_sep = np.max(np.abs(yc[rows, :n] - y[rows, :n]), axis=1)
        self.phi_change = max(self.phi_change, float(np.max(ref_sep)))
        rates = self.ref.model.phi_rate
        self.rate_change = max(self.rate_change, float(np.max(
            np.abs(rates(yc[rows]) - rates(y[rows])))))
        return ref_sep
