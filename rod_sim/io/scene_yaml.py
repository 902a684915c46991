"""Scene files (docs/interface.md section 1): YAML text to a validated :class:`~rod_sim.core.scene.Scene` and back.

Only safe loading is used (libyaml's ``CSafeLoader`` when PyYAML has it, else ``SafeLoader``;
the C parser reads a 4 MiB list 5x faster), with two changes that matter for scene files:

* floats are read as YAML 1.2 writes them, so ``1e5`` and ``1.0e5`` are numbers (plain PyYAML
  reads both as strings, which would then be rejected as "not a number");
* a key repeated in one mapping is an error (plain PyYAML silently keeps the last value).

Every problem is a :class:`SceneError` whose ``key`` names the entry (``scene`` for problems with
the file itself) and whose message is one line.
"""
from __future__ import annotations

import os
import re
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rod_sim.core.scene import Scene, SceneError

__all__ = ["MAX_SCENE_BYTES", "load_scene", "scene_from_yaml_text", "scene_to_yaml"]

# Largest scene file read [bytes]. A chain of 8000 rods (about the most whose reduced model fits
# in 20 GB of memory) with one value per rod for its 8 per-rod keys is ~8 x 8000 x 20 bytes,
# about 1.3 MB. Measured: a 4 MiB list is refused after 13 s with a peak of 0.65 GB RSS
# (CSafeLoader; 71 s and 0.9 GB with the pure-Python SafeLoader), on 2 shared cores.
MAX_SCENE_BYTES = 4 * 1024 * 1024

_MERGE_TAG = "tag:yaml.org,2002:merge"

# YAML 1.1 floats as PyYAML resolves them, plus exponents without a sign or without a dot
# (1e5, 1.0e5, 2E-3), as YAML 1.2 and every other YAML library read them.
_FLOAT_RE = re.compile(
    r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |[-+]?\.[0-9][0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
    re.X,
)


class _SceneLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """A SafeLoader that reads YAML 1.2 floats and rejects duplicate keys in a mapping."""

    def construct_document(self, node: yaml.Node) -> Any:
        self._check_duplicate_keys(node)
        return super().construct_document(node)

    def _check_duplicate_keys(self, root: yaml.Node) -> None:
        seen: set[int] = set()  # aliases may point back up the tree: visit each node once
        stack: list[tuple[yaml.Node, str]] = [(root, "")]
        while stack:
            node, path = stack.pop()
            if id(node) in seen:
                continue
            seen.add(id(node))
            if isinstance(node, yaml.SequenceNode):
                stack.extend((item, f"{path}[{i}]") for i, item in enumerate(node.value))
            elif isinstance(node, yaml.MappingNode):
                first_line: dict[tuple[str, str], int] = {}
                for key_node, value_node in node.value:
                    if key_node.tag == _MERGE_TAG or not isinstance(key_node, yaml.ScalarNode):
                        stack.append((value_node, path))
                        continue
                    child = f"{path}.{key_node.value}" if path else str(key_node.value)
                    ident = (key_node.tag, key_node.value)
                    line = key_node.start_mark.line + 1
                    if ident in first_line:
                        raise SceneError(child, f"duplicate key (first at line {first_line[ident]},"
                                                f" again at line {line})")
                    first_line[ident] = line
                    stack.append((value_node, child))


_SceneLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_RE, list("-+0123456789."))


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _yaml_error(err: yaml.YAMLError, source: str) -> SceneError:
    where = f" (in {source})" if source and source != "<string>" else ""
    if isinstance(err, yaml.MarkedYAMLError):
        mark = err.problem_mark or err.context_mark
        problem = err.problem or err.context or "invalid YAML"
        if err.context and err.problem and err.problem.startswith("but "):
            problem = f"{err.context}, {err.problem}"  # e.g. a second document in the file
        if mark is not None:
            return SceneError("scene", f"YAML error at line {mark.line + 1} column "
                                       f"{mark.column + 1}: {_one_line(problem)}{where}")
        return SceneError("scene", f"YAML error: {_one_line(problem)}{where}")
    return SceneError("scene", f"YAML error: {_one_line(err)}{where}")


def _parse(text: str, source: str, default_name: str | None) -> Scene:
    loader = _SceneLoader(text)
    try:
        data = loader.get_single_data()
    except yaml.YAMLError as err:
        raise _yaml_error(err, source) from None
    finally:
        loader.dispose()
    if data is None:
        raise SceneError("scene", "the scene is empty: expected a mapping with rods, nodes, hinges")
    if not isinstance(data, Mapping):
        raise SceneError("scene", "the top level must be a mapping with rods, nodes, hinges, ..."
                                  f" (got a {type(data).__name__})")
    if default_name and "name" not in data:
        data = {"name": default_name, **data}
    return Scene.from_dict(data)


def scene_from_yaml_text(text: str, source: str = "<string>") -> Scene:
    """Parse and validate a scene from YAML ``text``; ``source`` names it in YAML error messages."""
    return _parse(text, source, default_name=None)


def load_scene(path: str | os.PathLike) -> Scene:
    """Load and validate the scene file at ``path``.

    A scene without a ``name`` is named after the file (its stem).
    """
    p = Path(path)
    try:
        info = os.stat(p)             # before opening: opening a FIFO would block
        if not stat.S_ISREG(info.st_mode) and not stat.S_ISDIR(info.st_mode):
            raise SceneError("scene", f"cannot read {os.fspath(path)}: not a regular file")
        if info.st_size > MAX_SCENE_BYTES:
            raise SceneError("scene", f"{os.fspath(path)} is {info.st_size} bytes; a scene file "
                                      f"may have at most {MAX_SCENE_BYTES} bytes")
        with open(p, "rb") as fh:
            data = fh.read(MAX_SCENE_BYTES + 1)
        if len(data) > MAX_SCENE_BYTES:
            raise SceneError("scene", f"{os.fspath(path)} grew beyond {MAX_SCENE_BYTES} bytes "
                                      "while being read")
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise SceneError("scene", f"file not found: {os.fspath(path)}") from None
    except IsADirectoryError:
        raise SceneError("scene", f"cannot read {os.fspath(path)}: is a directory") from None
    except UnicodeDecodeError as err:
        raise SceneError("scene", f"cannot read {os.fspath(path)}: not UTF-8 text "
                                  f"(byte {err.start})") from None
    except OSError as err:
        raise SceneError("scene", f"cannot read {os.fspath(path)}: "
                                  f"{_one_line(err.strerror or err)}") from None
    return _parse(text, os.fspath(path), default_name=p.stem or None)


_BUILTIN_SCALARS = {bool, int, float, str, type(None)}


def _plain(value: Any) -> Any:
    """Python built-ins only (numpy scalars and arrays converted), so SafeDumper can write it."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        return value.tolist()           # built-in bool / int / float, at C speed (O(n))
    if isinstance(value, list) and set(map(type, value)) <= _BUILTIN_SCALARS:
        return value                    # already plain (Scene.to_dict's per-rod lists)
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    return value


# entries that are one pair [x, y], never a per-rod list (a scalar there is not a pair)
_PAIR_KEYS = frozenset({"attach", "centre_of_mass", "gravity"})


def _compact(value: Any) -> Any:
    """A list of equal numbers or booleans as that one value (the scene format broadcasts a
    scalar to every rod, node or hinge): a uniform 100 000-rod chain's YAML stays small.
    Pairs (``attach``, ``centre_of_mass``, ``gravity``) stay pairs."""
    if isinstance(value, dict):
        return {k: v if k in _PAIR_KEYS else _compact(v) for k, v in value.items()}
    if isinstance(value, list) and len(value) > 1 and isinstance(value[0], (int, float)):
        first = value[0]
        kind = type(first)
        if (value.count(first) == len(value) and all(type(v) is kind for v in value)
                and not (isinstance(first, float) and first != first)):
            return first
    if isinstance(value, list):
        return [_compact(v) if isinstance(v, dict) else v for v in value]
    return value


def scene_to_yaml(scene: Scene) -> str:
    """The resolved scene as YAML (a per-rod, node or hinge value that is the same for every
    one written once, as a scalar); ``load`` gives it back exactly."""
    data = _compact(_plain(scene.to_dict()))
    # libyaml's emitter when PyYAML has it: the same text, 3x faster (800k values: 1.6 s)
    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    body = yaml.dump(data, Dumper=dumper, sort_keys=False, default_flow_style=None,
                     allow_unicode=True, width=100)
    return ("# rod_sim scene (resolved; a scalar applies to every rod, node or hinge; SI units)"
            f"\n{body}")
