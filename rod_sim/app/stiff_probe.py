"""Which integrator a long full-model reference takes: the stiffness probe shared by
``rod-sim advise`` and ``rod-sim compare``.

A reference is a full-model run at a tight tolerance. On a stiff scene (short stiff rods, strong
hinge damping, a taut tether) dop853-jit's steps are bounded by its stability, not by the
tolerance, and such a run takes minutes to hours where the implicit radau-jit takes seconds;
elsewhere dop853-jit is the faster. The probe runs dop853-jit on the full model for at most
:data:`~rod_sim.app.progress.STIFF_MIN_STEPS` accepted steps and asks the hint's law
(:func:`~rod_sim.app.progress.stiffness_hint`) whether they were stiff.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

PROBED = "dop853-jit"
"""The integrator the probe runs (and the reference's when the probe finds no stiffness)."""
STIFF_REFERENCE = "radau-jit"
"""The reference's integrator when the probe's steps were stiff."""


def probe_label() -> str:
    """What the probe is, for progress lines."""
    from .progress import STIFF_MIN_STEPS

    return f"a probe of the full model's stiffness ({PROBED}, {STIFF_MIN_STEPS} steps at most)"


def reference_integrator(model, rtol: float, t_end: float, atol: float | None = None,
                         running: Callable[[object], None] | None = None,
                         y0=None) -> str:
    """``"radau-jit"`` when dop853-jit's first steps on ``model`` (the full model of the scene,
    from ``y0`` at t = 0 (None: its initial state), scripted loads only) at ``rtol`` and
    ``atol`` (None: the integrator's default) over at most ``t_end`` [s] are stiff, else
    ``"dop853-jit"``. ``running`` is handed the probe's
    :class:`~rod_sim.core.simulator.Simulator` before it runs (for progress lines). A failure of the probe (its step budget, a blow-up) is not reported
    here: the reference itself will report it."""
    from ..core.integrators import IntegrationError, make_integrator
    from ..core.simulator import Simulator
    from .progress import STIFF_MIN_STEPS, stiffness_hint

    probe = Simulator(model, make_integrator(PROBED, rtol=rtol, atol=atol))
    probe.configure(max_steps=STIFF_MIN_STEPS)
    if y0 is not None:
        probe.y = np.array(y0, dtype=float)
        probe.contact = model.contact_state(probe.y, 0.0)
    if running is not None:
        running(probe)
    try:
        probe.advance(t_end)
    except IntegrationError:
        pass
    return STIFF_REFERENCE if stiffness_hint(probe.integrator, probe.stats) else PROBED
