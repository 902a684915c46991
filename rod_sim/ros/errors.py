"""Errors of the rod_sim ROS 2 entry points and the one-line form of their messages."""
from __future__ import annotations

import time
from typing import Any


class NodeConfigError(ValueError):
    """A parameter or the scene it names is unusable; ``str(err)`` is one line."""


def one_line(text: Any) -> str:
    """``str(text)`` with every run of white space (newlines included) folded to one space."""
    return " ".join(str(text).split())


THROTTLE_S = 2.0
"""[s] minimum interval between repeated log lines of one kind."""


class ThrottledLog:
    """Log lines at most once per :data:`THROTTLE_S` per key, through an rclpy ``logger``.
    rclpy's own ``throttle_duration_sec`` inspects the caller's frame and module on every call,
    milliseconds each: too slow on a 1 kHz path. rclpy refuses a call site that changes
    severity (ValueError), so each level has its own call below; and a log line never stops
    the node."""

    def __init__(self, logger):
        self.logger = logger
        self.until: dict[str, int] = {}
        """key -> monotonic time [ns] before which that key stays silent."""

    def log(self, key: str, level: str, text: str) -> None:
        """Log ``text`` at ``level`` ('info', 'warning' or 'error') unless ``key`` is silent."""
        now = time.monotonic_ns()
        if now < self.until.get(key, 0):
            return
        self.until[key] = now + int(THROTTLE_S * 1e9)
        try:
            if level == "error":
                self.logger.error(text)
            elif level == "warning":
                self.logger.warning(text)
            else:
                self.logger.info(text)
        except Exception:  # noqa: BLE001 -- logging must never take the simulation down
            pass
