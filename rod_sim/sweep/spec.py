"""Sweep specification files for ``rod-sim sweep``: parsing, strict validation, expansion.

A spec (YAML, see ``docs/sweep.md``) names a base scene, the model(s), the integrator settings,
the end time and sample rate, and the swept parameters, each addressed by a path into the scene
data (``hinges.stiffness``, ``loads[1].amplitude``, ``hinges.stiffness[0]``). A parameter is
either a grid (``values`` / ``linspace`` / ``geomspace``) or a Monte-Carlo distribution
(``uniform`` / ``normal`` / ``lognormal``, ``draws`` values from ``seed``).

Runs are the Cartesian product ``grid points x draws x models`` (models vary fastest). Every
run's scene is built and validated here (``Scene.from_dict`` and the model) before any run
starts. Every problem is a :class:`SweepSpecError` whose one-line message starts with the
spec key (``t_end``, ``parameters.hinges.stiffness``, ...).
"""
from __future__ import annotations

import copy
import itertools
import math
import re
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rod_sim.core.integrators import INTEGRATORS, make_integrator
from rod_sim.core.models import MODELS, ModelError, make_model
from rod_sim.core.scene import Scene, SceneError
from rod_sim.core.quote import quote
from rod_sim.io import yaml_text

__all__ = ["SweepSpecError", "Parameter", "SweepSpec", "Run", "load_spec", "parse_spec",
           "expand", "parse_path", "apply_path"]

TOP_KEYS = {"name", "description", "scene", "models", "integrator", "rtol", "atol", "step",
            "t_end", "rate", "parameters", "draws", "seed"}
GRID_KINDS = ("values", "linspace", "geomspace")
MAX_RUNS = 100_000
"""Largest sweep: grid points x draws x models (and points of one grid parameter, draws),
refused up front (exit 2) before anything is allocated."""
RANDOM_KINDS = {"uniform": ("low", "high"), "normal": ("mean", "std"),
                "lognormal": ("median", "sigma")}
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[[0-9]+\])*)$")


class SweepSpecError(ValueError):
    """A sweep spec entry is missing, unknown or invalid; ``key`` names it, the message is one
    line starting with it."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(f"{key}: {' '.join(str(message).split())}")


@dataclass(frozen=True)
class Parameter:
    """One swept scene entry. ``path`` as written in the spec; ``segments`` its parsed keys
    (str) and list indices (int). Grid parameters carry ``values``; random ones ``kind`` and
    ``args`` (the distribution's named numbers) and get their values from :func:`draw`."""

    path: str
    segments: tuple
    kind: str                  # 'grid' or one of RANDOM_KINDS
    values: tuple = ()
    args: tuple = ()
    log: bool = False          # geometric grid or lognormal: plotted on a log axis

    @property
    def random(self) -> bool:
        return self.kind != "grid"

    def draw(self, draws: int, seed: int) -> tuple:
        """``draws`` values from the distribution: reproducible from (seed, path) alone, so
        adding or reordering other parameters does not change this parameter's draws."""
        rng = np.random.default_rng([int(seed), zlib.crc32(self.path.encode())])
        a = dict(self.args)
        if self.kind == "uniform":
            x = rng.uniform(a["low"], a["high"], draws)
        elif self.kind == "normal":
            x = rng.normal(a["mean"], a["std"], draws)
        else:
            with np.errstate(over="ignore"):     # an overflow is refused below, in one line
                x = a["median"] * np.exp(a["sigma"] * rng.standard_normal(draws))
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise SweepSpecError(f"parameters.{self.path}.{self.kind}",
                                 f"draw {int(bad[0])} of {draws} is not finite (the "
                                 f"distribution's numbers are too large: "
                                 f"{', '.join(f'{k} {v:g}' for k, v in self.args)})")
        return tuple(float(v) for v in x)


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep spec. ``base_scene`` is plain scene data (docs/interface.md section 1)."""

    name: str
    base_scene: dict
    models: tuple
    integrator: str
    rtol: float | None
    atol: float | None
    step: float | None
    t_end: float
    rate_hz: float
    parameters: tuple
    draws: int
    seed: int

    def settings(self) -> dict:
        """The run settings every worker receives (plain data)."""
        return {"integrator": self.integrator, "rtol": self.rtol, "atol": self.atol,
                "step": self.step, "t_end": self.t_end, "rate_hz": self.rate_hz}


@dataclass(frozen=True)
class Run:
    """One run: its index (row order), model, swept values ``{path: value}`` and scene data."""

    index: int
    model: str
    params: dict
    scene: dict

    def task(self, spec: SweepSpec) -> dict:
        """Plain-dict input of :func:`rod_sim.sweep.worker.run_one`."""
        return {"index": self.index, "model": self.model, "params": dict(self.params),
                "scene": self.scene, **spec.settings()}


# ----- YAML -----

def _read_yaml(path: Path, key: str) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SweepSpecError(key, f"file not found: {path}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SweepSpecError(key, f"cannot read {path}: {err}") from None
    try:
        return yaml_text.load_strict(text)      # as scene files: YAML 1.2 floats, duplicate keys
    except SceneError as err:                      # a duplicate key, named by its path
        if key == "spec":
            raise SweepSpecError(err.key, str(err)[len(err.key) + 2:]) from None
        raise SweepSpecError(key, f"{err} (in {path})") from None
    except yaml_text.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1} column {mark.column + 1}" if mark else ""
        problem = getattr(err, "problem", None) or str(err)
        raise SweepSpecError(key, f"YAML error{where}: {problem} (in {path})") from None


def load_spec(path: str | Path, seed: int | None = None) -> SweepSpec:
    """Read and validate the spec file at ``path``; ``seed`` overrides the spec's seed."""
    p = Path(path)
    data = _read_yaml(p, "spec")
    return parse_spec(data, base_dir=p.parent, default_name=p.stem, seed=seed)


# ----- validation helpers -----

def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _number(key: str, v: Any, *, positive=False, minimum=None) -> float:
    if not _is_number(v) or not math.isfinite(float(v)):
        raise SweepSpecError(key, f"must be a finite number (got {quote(v)})")
    if positive and not float(v) > 0:
        raise SweepSpecError(key, f"must be > 0 (got {quote(v)})")
    if minimum is not None and float(v) < minimum:
        raise SweepSpecError(key, f"must be >= {minimum:g} (got {quote(v)})")
    return float(v)


def _whole(key: str, v: Any, minimum: int) -> int:
    if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < minimum:
        raise SweepSpecError(key, f"must be a whole number >= {minimum} (got {quote(v)})")
    return int(v)


def parse_path(path: Any) -> tuple:
    """``'loads[1].amplitude'`` -> ``('loads', 1, 'amplitude')`` (SweepSpecError if malformed)."""
    key = f"parameters.{path}"
    if not isinstance(path, str) or not path:
        raise SweepSpecError(f"parameters.{quote(path)}", "a parameter path must be a non-empty string")
    segments: list = []
    for part in path.split("."):
        m = _SEGMENT.match(part)
        if not m:
            raise SweepSpecError(key, f"malformed path segment {quote(part)} (write e.g. "
                                      f"hinges.stiffness, loads[1].amplitude, initial.phi[0])")
        segments.append(m.group(1))
        segments.extend(int(i) for i in re.findall(r"\[([0-9]+)\]", m.group(2)))
    return tuple(segments)


def apply_path(scene: dict, segments: tuple, value: Any, path: str = "") -> None:
    """Set the entry at ``segments`` of scene data ``scene`` (in place) to ``value``.

    A per-rod entry given as a scalar (``hinges.stiffness: 100``) is spelled out to one value
    per rod (``rods.count`` of the scene, or of the chain for a path into ``chains[c]``, e.g.
    ``chains[1].rods.length[2]``) before one of its elements is set. Missing mappings are created
    (e.g. ``initial`` for ``initial.phi``); unknown keys are left to the scene validation.
    """
    key = f"parameters.{path or '.'.join(map(str, segments))}"
    node: Any = scene
    owner: Any = scene          # the innermost mapping passed that holds rods: (scene or chain)
    for i, seg in enumerate(segments):
        if isinstance(node, dict) and isinstance(node.get("rods"), dict):
            owner = node
        last = i == len(segments) - 1
        nxt = None if last else segments[i + 1]
        if isinstance(seg, str):
            if not isinstance(node, dict):
                raise SweepSpecError(key, f"{quote(seg)} addresses into a {type(node).__name__}, "
                                          f"not a mapping")
            if last:
                node[seg] = value
                return
            if node.get(seg) is None:
                if isinstance(nxt, int):
                    raise SweepSpecError(key, f"{quote(seg)} is not set in the base scene, so it "
                                              f"cannot be indexed")
                node[seg] = {}
            if isinstance(nxt, int) and _is_number(node[seg]):
                count = owner.get("rods", {}).get("count") if isinstance(owner, dict) and \
                    isinstance(owner.get("rods"), dict) else None
                if not isinstance(count, int) or count < 1:
                    where = "" if owner is scene else " of the chain"
                    raise SweepSpecError(key, f"rods.count{where} is needed to spell out a "
                                              f"per-rod value")
                node[seg] = [node[seg]] * count
            node = node[seg]
        else:
            if not isinstance(node, list):
                raise SweepSpecError(key, f"index [{seg}] into a {type(node).__name__}, not a list")
            if seg >= len(node):
                raise SweepSpecError(key, f"index [{seg}] out of range (the base scene has "
                                          f"{len(node)} entries there)")
            if last:
                node[seg] = value
                return
            node = node[seg]


def _parameter(path: Any, body: Any) -> Parameter:
    segments = parse_path(path)
    key = f"parameters.{path}"
    if isinstance(body, list):
        body = {"values": body}
    if not isinstance(body, Mapping) or len(body) != 1:
        kinds = ", ".join(GRID_KINDS + tuple(RANDOM_KINDS))
        raise SweepSpecError(key, f"must be a list of values or a mapping with exactly one of "
                                  f"{kinds}")
    (kind, arg), = body.items()
    sub = f"{key}.{kind}"
    if kind == "values":
        if not isinstance(arg, list) or not arg:
            raise SweepSpecError(sub, "must be a non-empty list")
        for v in arg:
            if _is_number(v) and not math.isfinite(float(v)):
                raise SweepSpecError(sub, f"must be finite (got {quote(v)})")
        if len({repr(v) for v in arg}) != len(arg):
            raise SweepSpecError(sub, "has a repeated value")
        return Parameter(str(path), segments, "grid", values=tuple(arg))
    if kind in ("linspace", "geomspace"):
        if not isinstance(arg, list) or len(arg) != 3:
            raise SweepSpecError(sub, "must be [start, stop, count]")
        start = _number(f"{sub}[0]", arg[0])
        stop = _number(f"{sub}[1]", arg[1])
        num = _whole(f"{sub}[2]", arg[2], 1)
        if num > MAX_RUNS:
            raise SweepSpecError(f"{sub}[2]", f"at most {MAX_RUNS} points (got {num})")
        if kind == "geomspace":
            if start <= 0 or stop <= 0:
                raise SweepSpecError(sub, "start and stop must be > 0")
            grid = np.geomspace(start, stop, num)
        else:
            grid = np.linspace(start, stop, num)
        return Parameter(str(path), segments, "grid", values=tuple(float(v) for v in grid),
                         log=kind == "geomspace")
    if kind in RANDOM_KINDS:
        names = RANDOM_KINDS[kind]
        if not isinstance(arg, Mapping):
            raise SweepSpecError(sub, f"must be a mapping with {', '.join(names)}")
        for k in arg:
            if k not in names:
                raise SweepSpecError(f"{sub}.{k}", f"unknown key (allowed: {', '.join(names)})")
        values = {}
        for k in names:
            if k not in arg:
                raise SweepSpecError(f"{sub}.{k}", "missing")
            values[k] = _number(f"{sub}.{k}", arg[k])
        if kind == "uniform" and not values["low"] < values["high"]:
            raise SweepSpecError(sub, f"low must be < high (got {values['low']:g}, {values['high']:g})")
        if kind == "normal" and not values["std"] > 0:
            raise SweepSpecError(f"{sub}.std", f"must be > 0 (got {values['std']:g})")
        if kind == "lognormal":
            if not values["median"] > 0:
                raise SweepSpecError(f"{sub}.median", f"must be > 0 (got {values['median']:g})")
            if not values["sigma"] > 0:
                raise SweepSpecError(f"{sub}.sigma", f"must be > 0 (got {values['sigma']:g})")
        return Parameter(str(path), segments, kind, args=tuple(values.items()),
                         log=kind == "lognormal")
    kinds = ", ".join(GRID_KINDS + tuple(RANDOM_KINDS))
    raise SweepSpecError(sub, f"unknown kind (allowed: {kinds})")


def _base_scene(value: Any, base_dir: Path) -> dict:
    if value is None:
        raise SweepSpecError("scene", "missing (a scene file path or an inline scene mapping)")
    if isinstance(value, str):
        path = (base_dir / value) if not Path(value).is_absolute() else Path(value)
        data = _read_yaml(path, "scene")
        if not isinstance(data, Mapping):
            raise SweepSpecError("scene", f"{path} does not hold a scene mapping")
        data = dict(data)
        data.setdefault("name", path.stem)
    elif isinstance(value, Mapping):
        data = copy.deepcopy(dict(value))
        data.setdefault("name", "scene")
    else:
        raise SweepSpecError("scene", f"must be a file path or a mapping (got {quote(value)})")
    try:
        Scene.from_dict(data)
    except SceneError as err:
        raise SweepSpecError("scene", f"the base scene is invalid: {err}") from None
    return data


def parse_spec(data: Any, base_dir: str | Path = ".", default_name: str = "sweep",
               seed: int | None = None) -> SweepSpec:
    """Validate spec data (the parsed YAML); a scene path is relative to ``base_dir``."""
    if not isinstance(data, Mapping):
        raise SweepSpecError("spec", "the top level must be a mapping with scene, models, "
                                     "t_end, parameters, ...")
    for k in data:
        if k not in TOP_KEYS:
            raise SweepSpecError(str(k), f"unknown key (allowed: {', '.join(sorted(TOP_KEYS))})")
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise SweepSpecError("name", f"must be a non-empty string (got {quote(name)})")
    base = _base_scene(data.get("scene"), Path(base_dir))

    models = data.get("models", "reduced")
    models = [models] if isinstance(models, str) else models
    if not isinstance(models, list) or not models:
        raise SweepSpecError("models", "must be a model name or a non-empty list of them")
    for m in models:
        if m not in MODELS:
            raise SweepSpecError("models", f"unknown model {quote(m)} (choose from {', '.join(MODELS)})")
    if len(set(models)) != len(models):
        raise SweepSpecError("models", "a model is listed twice")

    integrator = data.get("integrator", "dop853-jit")
    if integrator not in INTEGRATORS:
        raise SweepSpecError("integrator", f"unknown integrator {quote(integrator)} "
                                           f"(choose from {', '.join(INTEGRATORS)})")
    tol = {k: (None if data.get(k) is None else _number(k, data[k], positive=True))
           for k in ("rtol", "atol", "step")}
    try:
        make_integrator(integrator, **tol)
    except ValueError as err:
        raise SweepSpecError("integrator", str(err)) from None

    if "t_end" not in data:
        raise SweepSpecError("t_end", "missing (end time of every run [s])")
    t_end = _number("t_end", data["t_end"], positive=True)
    rate = _number("rate", data.get("rate", 100.0), positive=True)

    params = data.get("parameters", {}) or {}
    if not isinstance(params, Mapping):
        raise SweepSpecError("parameters", "must be a mapping from scene paths to grids or "
                                           "distributions")
    parameters = tuple(_parameter(p, body) for p, body in params.items())
    random = [p for p in parameters if p.random]
    if random and "draws" not in data:
        raise SweepSpecError("draws", f"missing: parameters.{random[0].path} is a Monte-Carlo "
                                      f"distribution and needs the number of draws")
    if "draws" in data and not random:
        raise SweepSpecError("draws", "given, but no parameter is a Monte-Carlo distribution")
    draws = _whole("draws", data["draws"], 1) if random else 1
    if draws > MAX_RUNS:
        raise SweepSpecError("draws", f"at most {MAX_RUNS} (got {draws})")
    grid_sizes = {p.path: len(p.values) for p in parameters if not p.random}
    total = math.prod(grid_sizes.values()) * draws * len(models)
    if total > MAX_RUNS:
        largest = max(grid_sizes, key=grid_sizes.get) if grid_sizes else None
        raise SweepSpecError("parameters", f"the sweep would be {total} runs ("
                             + " x ".join([*(str(v) for v in grid_sizes.values()),
                                           *([f"{draws} draws"] if random else []),
                                           f"{len(models)} model(s)"])
                             + f"); at most {MAX_RUNS}"
                             + (f" (largest: parameters.{largest}, {grid_sizes[largest]} "
                                "values)" if largest else ""))
    spec_seed = _whole("seed", data.get("seed", 0), 0)
    if seed is not None:
        spec_seed = _whole("--seed", seed, 0)
    spec = SweepSpec(name=name, base_scene=base, models=tuple(models), integrator=integrator,
                     rtol=tol["rtol"], atol=tol["atol"], step=tol["step"], t_end=t_end,
                     rate_hz=rate, parameters=parameters, draws=draws, seed=spec_seed)
    for p in parameters:                           # the paths must address the base scene
        apply_path(copy.deepcopy(base), p.segments, p.values[0] if p.values else 1.0, p.path)
    return spec


# ----- expansion -----

def _strip_indices(key: str) -> str:
    return re.sub(r"\[[0-9]+\]", "", key)


def _blame(spec: SweepSpec, err_key: str) -> str:
    """The swept parameter a scene error is about (its path), or '' when none matches."""
    for p in spec.parameters:
        if _strip_indices(p.path) == _strip_indices(err_key) or \
                _strip_indices(err_key).startswith(_strip_indices(p.path) + "."):
            return p.path
    return ""


def expand(spec: SweepSpec, validate: bool = True) -> list[Run]:
    """Every run of the sweep, in row order (grid points, then draws, then models).

    With ``validate`` each run's scene goes through ``Scene.from_dict`` and the model is built;
    the first bad one raises SweepSpecError naming the parameter and the run.
    """
    grid = [p for p in spec.parameters if not p.random]
    random = [p for p in spec.parameters if p.random]
    drawn = [p.draw(spec.draws, spec.seed) for p in random]
    runs = []
    index = 0
    for point in itertools.product(*(p.values for p in grid)):
        for d in range(spec.draws):
            values = dict(zip((p.path for p in grid), point))
            values.update({p.path: v[d] for p, v in zip(random, drawn)})
            scene = copy.deepcopy(spec.base_scene)
            for p in spec.parameters:
                apply_path(scene, p.segments, values[p.path], p.path)
            ordered = {p.path: values[p.path] for p in spec.parameters}
            for model in spec.models:
                runs.append(Run(index, model, ordered, scene))
                index += 1
    if validate:
        for run in runs:
            check_run(spec, run)
    return runs


def check_run(spec: SweepSpec, run: Run) -> None:
    """Build the run's scene and model; SweepSpecError naming the parameter if either fails."""
    where = ", ".join(f"{k}={quote(v)}" for k, v in run.params.items()) or "the base scene"
    try:
        make_model(run.model, Scene.from_dict(run.scene))
    except SceneError as err:
        culprit = _blame(spec, err.key)
        key = f"parameters.{culprit}" if culprit else "parameters"
        raise SweepSpecError(key, f"run {run.index} ({where}) gives an invalid scene: {err}") from None
    except ModelError as err:
        raise SweepSpecError("models", f"run {run.index} ({where}): {err}") from None
