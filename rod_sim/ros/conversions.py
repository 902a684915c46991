"""Pure conversions between rod_sim's message dicts and rclpy message objects.

:mod:`rod_sim.io.topics` builds every published message as nested dicts and lists (the form
the MCAP log writer encodes); :func:`to_message` fills the matching rclpy message from the same
dict, so the topics and the log carry identical values. :func:`command_forces` turns a received
``std_msgs/Float64MultiArray`` command into a validated (n, 2) force array [N].

No node, context or executor is involved: these functions only need the message packages.
"""
from __future__ import annotations

import importlib
import re
from collections.abc import Mapping, Sequence
from functools import lru_cache
from typing import Any

import numpy as np

_SEQUENCE_RE = re.compile(r"^sequence<\s*([^,>]+?)\s*(?:,\s*\d+\s*)?>$")
_ARRAY_RE = re.compile(r"^(.+?)\[\d*\]$")


class CommandError(ValueError):
    """A command that cannot be applied; ``str(err)`` is one line."""


@lru_cache(maxsize=None)
def message_class(type_name: str) -> type:
    """The rclpy message class of a ROS type name: ``pkg/msg/Name`` or ``pkg/Name``."""
    parts = type_name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"not a ROS message type name: {type_name!r}")
    package, kind, name = parts
    try:
        module = importlib.import_module(f"{package}.{kind}")
        return getattr(module, name)
    except (ImportError, AttributeError):
        raise ValueError(f"message type {type_name!r} is not installed") from None


@lru_cache(maxsize=None)
def _element_type(field_type: str) -> str | None:
    """The message type name of the elements of a sequence/array field type string (e.g.
    ``sequence<geometry_msgs/Point>`` -> ``geometry_msgs/Point``); None for primitives."""
    match = _SEQUENCE_RE.match(field_type) or _ARRAY_RE.match(field_type)
    inner = match.group(1) if match else field_type
    return inner if "/" in inner else None


@lru_cache(maxsize=None)
def _field_types(cls: type) -> dict[str, str]:
    return dict(cls.get_fields_and_field_types())


def fill_message(msg: Any, data: Mapping[str, Any]) -> Any:
    """Set the fields of the rclpy message ``msg`` from the nested dict ``data`` (recursively:
    a dict fills a nested message, a list of dicts a sequence of messages, an int for an
    ``octet``/``byte`` field becomes a one-byte ``bytes``, anything else is assigned as is) and
    return ``msg``. Fields missing from ``data`` keep their defaults.

    Raises ValueError for a key that is not a field of the message, or for a value the field
    rejects when rclpy's field checks are on (``ROS_PYTHON_CHECK_FIELDS=1``).
    """
    fields = _field_types(type(msg))
    for key, value in data.items():
        if key not in fields:
            raise ValueError(f"{type(msg).__name__} has no field {key!r} "
                             f"(fields: {', '.join(fields)})")
        if isinstance(value, Mapping):
            fill_message(getattr(msg, key), value)
            continue
        if fields[key] in ("octet", "byte") and isinstance(value, int):
            value = bytes([value])  # e.g. DiagnosticStatus.level: rclpy wants a 1-byte bytes
        element = _element_type(fields[key])
        if element is not None and isinstance(value, Sequence) and not isinstance(value, str):
            cls = message_class(element)
            value = [fill_message(cls(), item) if isinstance(item, Mapping) else item
                     for item in value]
        try:
            setattr(msg, key, value)
        except (AssertionError, TypeError) as exc:
            raise ValueError(f"{type(msg).__name__}.{key}: cannot set {value!r}: {exc}") from None
    return msg


def to_message(type_name: str, data: Mapping[str, Any]) -> Any:
    """A new rclpy message of ``type_name`` (e.g. ``sensor_msgs/msg/JointState``) filled from
    the message dict ``data`` (see :func:`fill_message`)."""
    return fill_message(message_class(type_name)(), data)


def command_forces(msg: Any, n: int) -> np.ndarray:
    """Validated nodal forces (n, 2) [N] from a ``std_msgs/Float64MultiArray`` command for one
    chain of n rods on the ground.

    ``msg.data[data_offset:]`` must hold exactly 2n finite values [X_1, Y_1, ..., X_n, Y_n];
    the layout's dims are not needed and not checked. Raises CommandError naming the problem.
    Several chains, a wheel: :class:`rod_sim.ros.command_layout.CommandLayout`.
    """
    from rod_sim.ros.command_layout import CommandLayout

    return CommandLayout.single(n).forces(msg)


def command_torques(msg: Any, n: int) -> np.ndarray:
    """Validated hinge torques (n,) [N m] from a ``std_msgs/Float64MultiArray`` command on
    ``hinge_torques`` for one chain of n rods on the ground.

    ``msg.data[data_offset:]`` must hold exactly n finite values [T_0, ..., T_{n-1}] in joint
    order hinge_0..hinge_{n-1} (the ``joint_states`` names; the convention of a joint-group
    effort controller); the layout's dims are not needed and not checked. Raises CommandError
    naming the problem."""
    from rod_sim.ros.command_layout import CommandLayout

    return CommandLayout.single(n).torques(msg)


def message_to_dict(msg: Any) -> Any:
    """The nested dict/list form of an rclpy message (the inverse of :func:`fill_message`),
    e.g. to log a received message; arrays become lists of Python numbers."""
    if hasattr(type(msg), "get_fields_and_field_types"):
        return {key: message_to_dict(getattr(msg, key)) for key in _field_types(type(msg))}
    if isinstance(msg, (bytes, bytearray)):
        return list(msg)
    if isinstance(msg, str):
        return msg
    if isinstance(msg, (list, tuple)) or hasattr(msg, "tolist"):
        items = msg.tolist() if hasattr(msg, "tolist") else list(msg)
        return [message_to_dict(v) for v in items]
    return msg
