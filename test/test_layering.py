"""The package's layering, read from the imports (ast) of every module of rod_sim, function-level
imports included (issue 29 item 4):

- ``rod_sim.core`` imports only the standard library, numpy, scipy, numba and ``rod_sim.core``;
- ``rod_sim.ros`` never imports ``rod_sim.tools`` (no arrow up from the node to the CLI);
- only ``rod_sim.io`` imports yaml;
- no import cycle among rod_sim's packages (``rod_sim.core``, ``rod_sim.io``, ``rod_sim.app``,
  ``rod_sim.ros``, ``rod_sim.compare``, ``rod_sim.sweep``, ``rod_sim.bench``,
  ``rod_sim.tools``; a top-level module such as ``rod_sim.api`` counts as its own);
- ``import rod_sim`` imports neither numpy nor numba nor ROS (the API loads on first use).

Each rule is checked on the real tree and shown to fail on a planted violation.
"""
from __future__ import annotations

import ast
import functools
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "rod_sim"
NUMERIC = {"numpy", "scipy", "numba"}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, source: str | None = None) -> list[str]:
    """Absolute names of every module ``path`` imports (``from X import y`` gives X.y when
    X.y is a module of rod_sim, else X), at any depth of the file."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(source if source is not None else path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.append(sub if _is_module(sub) else target)
    return found


def _is_module(name: str) -> bool:
    if not name.startswith("rod_sim"):
        return False
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def layer(module: str) -> str:
    """The package a rod_sim module belongs to: ``rod_sim.X`` for a subpackage X or a
    top-level module X; ``rod_sim`` for the package's own ``__init__``."""
    parts = module.split(".")
    return ".".join(parts[:2])


def all_modules() -> dict[str, list[str]]:
    """``{module: the modules it imports}`` of every module of rod_sim (a fresh copy)."""
    return dict(_all_modules())


@functools.lru_cache(maxsize=1)
def _all_modules() -> dict[str, list[str]]:
    return {module_name(p): imports(p) for p in sorted(PACKAGE.rglob("*.py"))}


def core_violations(table: dict[str, list[str]]) -> list[str]:
    bad = []
    for mod, deps in table.items():
        if layer(mod) != "rod_sim.core":
            continue
        for dep in deps:
            top = dep.split(".")[0]
            ok = (top in sys.stdlib_module_names or top in NUMERIC
                  or layer(dep) == "rod_sim.core")
            if not ok:
                bad.append(f"{mod} imports {dep}")
    return bad


def ros_violations(table: dict[str, list[str]]) -> list[str]:
    return [f"{mod} imports {dep}" for mod, deps in table.items()
            if layer(mod) == "rod_sim.ros" for dep in deps if layer(dep) == "rod_sim.tools"]


def yaml_violations(table: dict[str, list[str]]) -> list[str]:
    return [f"{mod} imports {dep}" for mod, deps in table.items()
            if layer(mod) != "rod_sim.io" for dep in deps if dep.split(".")[0] == "yaml"]


def package_cycles(table: dict[str, list[str]]) -> list[list[str]]:
    """Every cycle of the package graph (one per strongly connected component of more than
    one package, shown as a path through it), edges named by the import that makes them."""
    graph: dict[str, set[str]] = {}
    for mod, deps in table.items():
        for dep in deps:
            if dep.startswith("rod_sim") and layer(dep) != layer(mod):
                graph.setdefault(layer(mod), set()).add(layer(dep))
    # Tarjan's strongly connected components
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return comps


def test_core_imports_only_numerics_and_itself():
    assert core_violations(all_modules()) == []


def test_ros_never_imports_tools():
    assert ros_violations(all_modules()) == []


def test_only_io_imports_yaml():
    assert yaml_violations(all_modules()) == []


def test_no_import_cycle_among_packages():
    table = all_modules()
    assert package_cycles(table) == [], package_cycles(table)
    layers = {layer(m) for m in table}
    assert {"rod_sim.core", "rod_sim.io", "rod_sim.ros", "rod_sim.tools", "rod_sim.compare",
            "rod_sim.sweep", "rod_sim.bench", "rod_sim.app", "rod_sim.api"} <= layers


def test_no_module_cycle_inside_bench():
    """tools/bench/long_chains and tools/bench/report imported each other (issue 29)."""
    table = {m: d for m, d in all_modules().items() if m.startswith("rod_sim.bench")}
    sub = {m: [d for d in deps if d.startswith("rod_sim.bench.")] for m, deps in table.items()}
    assert "rod_sim.bench.report" not in sub["rod_sim.bench.long_chains"]


def test_the_checks_fail_on_planted_violations():
    """Each rule, fed a module that breaks it, reports it (the checks can fail)."""
    def planted(path: str, source: str) -> dict[str, list[str]]:
        table = all_modules()
        table[module_name(ROOT / path)] = imports(ROOT / path, source)
        return table

    assert core_violations(planted("rod_sim/core/scene.py", "import yaml\n")) == [
        "rod_sim.core.scene imports yaml"]
    assert core_violations(planted("rod_sim/core/scene.py", "def f():\n    from ..io import "
                                   "scene_yaml\n")) == [
        "rod_sim.core.scene imports rod_sim.io.scene_yaml"]
    assert ros_violations(planted("rod_sim/ros/node.py", "def f():\n    from rod_sim.tools."
                                  "common import X\n")) != []
    assert ros_violations(planted("rod_sim/ros/node.py", "from ..tools import cli\n")) == [
        "rod_sim.ros.node imports rod_sim.tools.cli"]
    assert yaml_violations(planted("rod_sim/ros/scene_path.py", "import yaml\n")) == [
        "rod_sim.ros.scene_path imports yaml"]
    cycles = package_cycles(planted("rod_sim/io/series.py", "from rod_sim.ros import node\n"))
    assert len(cycles) == 1 and {"rod_sim.io", "rod_sim.ros"} <= set(cycles[0])
    assert package_cycles(planted("rod_sim/app/common.py", "from rod_sim.tools import cli\n")
                          ) != []


def test_import_rod_sim_is_cheap():
    """``import rod_sim`` loads no numpy, numba, yaml or ROS; the API's names load on use."""
    code = ("import sys, rod_sim\n"
            "heavy = sorted(m for m in sys.modules if m.split('.')[0] in "
            "('numpy', 'numba', 'scipy', 'yaml', 'rclpy', 'mcap'))\n"
            "assert not heavy, heavy\n"
            "assert rod_sim.MODEL_NAMES == ('full', 'reduced', 'rigid')\n"
            "assert 'numba' not in sys.modules\n"
            "assert callable(rod_sim.load_scene) and 'rod_sim.api' in sys.modules\n"
            "print('ok')\n")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr
