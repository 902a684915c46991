"""Errors of the rod_sim ROS 2 entry points and the one-line form of their messages."""
from __future__ import annotations

from typing import Any


class NodeConfigError(ValueError):
    """A parameter or the scene it names is unusable; ``str(err)`` is one line."""


def one_line(text: Any) -> str:
    """``str(text)`` with every run of white space (newlines included) folded to one space."""
    return " ".join(str(text).split())
