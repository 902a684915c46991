"""Where the node's ``scene_file`` is (docs/interface.md section 3): an absolute path, a
``package://PKG/relative/path`` URL, or a path relative to the params file that set it (else to
the working directory). Pure file-system logic and YAML, no ROS graph.

A params file's entry applies to the node when its key matches the node's full name as ROS 2
matches them: ``/**`` (any), ``/ns/name``, ``name``, ``/**/name``, ``*`` for one name part;
nested namespace keys are joined. The last params file (in command-line order) whose entry for
the node sets ``scene_file`` to the value the node got is the one it is relative to.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from rod_sim.io import yaml_text


PACKAGE_SCHEME = "package://"
PACKAGE_NAME = "rod_sim"


class ScenePathError(ValueError):
    """The scene file cannot be found: the message names the places searched."""


def _key_pattern(key: str) -> re.Pattern:
    """The regular expression of a params-file node key (``/**``, ``/ns/*``, ``name``)."""
    key = key if key.startswith("/") else "/" + key
    parts = []
    for token in re.split(r"(\*\*|\*)", key):
        parts.append(".*" if token == "**" else "[^/]*" if token == "*" else re.escape(token))
    return re.compile("".join(parts) + "$")


def _entries(tree, prefix: str = ""):
    """(node key, ros__parameters mapping) of a params file's YAML tree, nested keys joined."""
    if not isinstance(tree, dict):
        return
    for key, value in tree.items():
        if not isinstance(value, dict):
            continue
        name = f"{prefix}/{str(key).strip('/')}" if prefix else str(key)
        if isinstance(value.get("ros__parameters"), dict):
            yield name, value["ros__parameters"]
        yield from _entries({k: v for k, v in value.items() if k != "ros__parameters"}, name)


def params_file_value(path: str | os.PathLike, full_name: str, key: str):
    """The value of parameter ``key`` that params file ``path`` gives the node ``full_name``
    (e.g. '/arm1/rod_sim'); None when it gives none or cannot be read. Later entries win."""
    try:
        tree = yaml_text.load(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml_text.YAMLError):
        return None
    found = None
    for node_key, params in _entries(tree):
        if _key_pattern(node_key).match(full_name) and key in params:
            found = params[key]
    return found


def package_share_dirs(package: str) -> list[Path]:
    """Where ``package://package/...`` may point, in search order: the ament index (a colcon
    workspace or a ROS install), ``<sys.prefix>/share/<package>`` (a pip install's data files)
    and, for rod_sim, the source tree it runs from (a clone)."""
    dirs = []
    try:
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory(package)))
    except Exception:  # noqa: BLE001 -- no index (pip install) or package not in it
        pass
    dirs.append(Path(sys.prefix) / "share" / package)
    if package == PACKAGE_NAME:
        dirs.append(Path(__file__).resolve().parents[2])
    return list(dict.fromkeys(dirs))


def _inside(base: Path, rest: str, roots) -> Path | None:
    """``base / rest`` with every symbolic link and '..' resolved, or None when that leads
    outside the package: ``rest`` must stay inside ``base`` as written (no '..' above it, not
    absolute), and its resolved target inside one of the package's directories ``roots``
    (resolved; a colcon ``--symlink-install`` share folder links into the source tree, which
    is one of them for rod_sim), so ``package://`` never reads outside the package."""
    parts = Path(rest).parts
    depth = 0
    for part in parts:
        depth += -1 if part == ".." else 0 if part in ("", ".") else 1
        if depth < 0 or Path(rest).is_absolute():
            return None
    target = (base / rest).resolve()
    for root in (Path(r).resolve() for r in roots):
        if target != root and target.is_relative_to(root):
            return target
    return None


def resolve_scene_file(value: str, full_name: str, params_files=(), cwd=None) -> tuple[Path, str]:
    """The scene file the node's ``scene_file`` parameter ``value`` names, and a note ('' or a
    warning to log). ``full_name``: the node's full name; ``params_files``: the params files of
    its command line, in order; ``cwd``: the working directory (default: the current one).
    Raises ScenePathError naming every place searched."""
    cwd = Path.cwd() if cwd is None else Path(cwd)
    if value.startswith(PACKAGE_SCHEME):
        package, _, rest = value[len(PACKAGE_SCHEME):].partition("/")
        if not package or not rest:
            raise ScenePathError(f"{value}: expected package://PACKAGE/PATH")
        dirs = package_share_dirs(package)
        for base in dirs:
            found = _inside(base, rest, dirs)
            if found is not None and found.is_file():
                return found, ""
            if found is None and (base / rest).exists():
                raise ScenePathError(f"{value}: refused: {rest} leads outside the share "
                                     f"directory of {package} ({base}) by '..', an absolute "
                                     "path or a symbolic link")
        raise ScenePathError(f"{value}: file not found: no {rest} in the share directory of "
                             f"{package} (searched {', '.join(str(d) for d in dirs)})")
    path = Path(value).expanduser()
    if path.is_absolute():
        if not path.exists():
            raise ScenePathError(f"{value}: file not found (absolute path; searched "
                                 f"{path.parent})")
        return path, ""
    source = None
    for params in params_files:
        if params_file_value(params, full_name, "scene_file") == value:
            source = Path(params)
    if source is None:
        if not (cwd / path).exists():
            raise ScenePathError(f"{value}: file not found (relative to the working directory: "
                                 f"searched {cwd})")
        return cwd / path, ""
    base = (cwd / source).parent
    if (base / path).exists():
        return base / path, ""
    if (cwd / path).exists():
        return cwd / path, (f"scene_file {value}: not next to the params file {source} "
                            f"(searched {base}); using {cwd / path} relative to the working "
                            "directory; write it relative to the params file")
    raise ScenePathError(f"{value}: file not found (relative to the params file {source}: "
                         f"searched {base}; also searched the working directory {cwd})")
