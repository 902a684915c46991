"""rod_sim: a ROS 2 Jazzy simulator of chains of elastic rods, and its Python API.

``import rod_sim`` is cheap (no numpy, numba or ROS yet): the names below load
:mod:`rod_sim.api` on first use. docs/python_api.md has the guide and two examples.

- :func:`load_scene` (path, dict or Scene -> Scene), :func:`make_model` (``MODEL_NAMES``),
  :func:`make_integrator` (``INTEGRATOR_NAMES``);
- :class:`Simulator` (``Simulator.from_scene(path, model, integrator)``; advance, sample, run,
  state, snapshot, energies, momentum, base_state), :class:`Trajectory`,
  :func:`energy_balance`;
- :func:`open_log`, :func:`read_rod_states`, :func:`read_joint_states`,
  :func:`read_base_odometry`, :func:`read_applied_forces` (a log's topics as numpy arrays);
- the errors :class:`SceneError`, :class:`ModelError`, :class:`IntegrationError`,
  :class:`LogFormatError` (one line each).
"""
from .version import __version__

__all__ = ["__version__", "MODEL_NAMES", "INTEGRATOR_NAMES", "load_scene", "make_model",
           "make_integrator", "Simulator", "Trajectory", "Snapshot", "Energies", "Momentum",
           "BaseState", "energy_balance", "open_log", "read_rod_states", "read_joint_states",
           "read_base_odometry", "read_applied_forces", "Scene", "SceneError", "ModelError",
           "IntegrationError", "LogFormatError"]


def __getattr__(name: str):
    """The API's names, imported from :mod:`rod_sim.api` on first use (PEP 562)."""
    if name in ("MODEL_NAMES", "INTEGRATOR_NAMES"):       # without numba (command lines)
        from .core import names

        return getattr(names, name)
    if name in __all__:
        from . import api

        value = getattr(api, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rod_sim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
