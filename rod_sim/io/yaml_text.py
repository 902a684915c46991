"""YAML for the rest of the package: every parse and dump of YAML text goes through ``rod_sim.io``
(scene files: :mod:`.scene_yaml`; logs' metadata: :mod:`.log_open`; this module for the
others: ``rod-sim ctl``'s values and echo, the node's params files, sweep specs).

Only safe loading is used. :data:`YAMLError` is PyYAML's error type (a failed parse).
"""
from __future__ import annotations

from typing import Any

import yaml

YAMLError = yaml.YAMLError
"""PyYAML's parse error (with ``problem_mark`` / ``problem`` when it knows where)."""


def load(text: str) -> Any:
    """The plain Python value of YAML ``text`` (safe loader: mappings, lists, scalars).
    Raises :data:`YAMLError`."""
    return yaml.safe_load(text)


def dump(value: Any, **options) -> str:
    """``value`` (built-in types only) as YAML text; ``options`` as for ``yaml.safe_dump``."""
    return yaml.safe_dump(value, **options)


def load_strict(text: str) -> Any:
    """YAML ``text`` read as scene files are (:mod:`.scene_yaml`): YAML 1.2 floats (``1e5`` is
    a number) and duplicate keys refused (a :class:`~rod_sim.core.scene.SceneError` keyed by
    the entry's path). Raises :data:`YAMLError` on a syntax error."""
    from .scene_yaml import _SceneLoader

    loader = _SceneLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()
