"""Topic names of a log under any namespace: a node started with ``-r __ns:=/arm1`` records
``/arm1/rod_states`` where the root node records ``/rod_states``."""
from __future__ import annotations

from collections.abc import Iterable

from rod_sim.io.log_format import LogFormatError


def base_name(topic: str) -> str:
    """The last component of a topic name: ``/arm1/rod_states`` -> ``rod_states``."""
    return topic.rstrip("/").rsplit("/", 1)[-1]


def namespace_of(topic: str) -> str:
    """The namespace of an absolute topic: ``/arm1/rod_states`` -> ``/arm1``, ``/x`` -> ``/``."""
    ns = topic.rstrip("/").rsplit("/", 1)[0]
    return ns or "/"


def resolve_topics(available: Iterable[str], names: Iterable[str], namespace: str | None = None,
                   where: str = "the log") -> dict[str, str]:
    """Map base topic names (``rod_states``, ``/rod_states``) to the absolute topics of
    ``available`` that end in them under any namespace (a node started with ``-r __ns:=/arm1``
    records ``/arm1/rod_states``). ``namespace`` (e.g. ``/arm1``) picks one namespace. Names
    not found are left out. Raises LogFormatError when the names are found under more than one
    namespace and none was chosen (two nodes recorded in one log)."""
    available = list(available)
    bases = [base_name(n) for n in names]
    if namespace is not None:
        ns = "/" + namespace.strip("/")
        prefix = ns if ns != "/" else ""
        return {b: prefix + "/" + b for b in bases if prefix + "/" + b in available}
    found: dict[str, list[str]] = {b: sorted(t for t in available if base_name(t) == b)
                                   for b in bases}
    spaces = sorted({namespace_of(t) for ts in found.values() for t in ts})
    if len(spaces) > 1:
        raise LogFormatError(f"{where} holds our topics under {len(spaces)} namespaces "
                             f"({', '.join(spaces[:6])}); choose one with --namespace NS")
    return {b: ts[0] for b, ts in found.items() if ts}
