"""Bounded quoting of untrusted values (log metadata, scene entries) in one-line messages.

``repr()`` of a value from a file can be arbitrarily large: a YAML "billion laughs" scene
shares one list a billion times and its repr takes minutes and gigabytes (issue 11 item 8).
:func:`rod_sim.core.quote.quote` never builds more than about ``limit`` characters;
:func:`yaml_node_count`
measures what a YAML text expands to before anything walks it.
"""
from __future__ import annotations

import yaml

from rod_sim.core.quote import quote  # noqa: F401  (re-exported for the readers)


def yaml_node_count(text: str, cap: int = 10**6) -> int:
    """How many YAML nodes ``text`` (one document) expands to when every alias is replaced by
    its anchor's content, counted without expanding (capped at ``cap``; a recursive alias
    counts as ``cap``). Raises yaml.YAMLError for text that is not YAML."""
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    if root is None:
        return 0
    size: dict[int, int] = {}
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    active: set[int] = set()
    while stack:
        node, done = stack.pop()
        key = id(node)
        if key in size and not done:
            continue
        children = (node.value if isinstance(node, yaml.SequenceNode) else
                    [x for pair in node.value for x in pair]
                    if isinstance(node, yaml.MappingNode) else [])
        if not done:
            if key in active:
                return cap                      # recursive alias
            active.add(key)
            stack.append((node, True))
            stack.extend((c, False) for c in children if id(c) not in size)
            continue
        active.discard(key)
        size[key] = min(cap, 1 + sum(size.get(id(c), cap) for c in children))
    return size[id(root)]
