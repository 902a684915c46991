"""Hinge events (latch, stop contact begin/end) as messages and log records.

Topic ``hinge_events`` (absolute ``/hinge_events`` in a log), type std_msgs/msg/String, one
message per event, stamped (log_time) at the event's simulated time; ``data`` is a JSON object
``{"t": s, "event": "latch"|"stop_contact_begin"|"stop_contact_end", "hinge": h, "angle": rad,
"rate": rad/s, ...}`` (a latch adds ``kinetic_energy_loss`` [J], its share of the impact's
loss ``impact_kinetic_energy_loss`` [J] that latched ``impact_hinges`` at once; a contact
``stop``: 'lower'|'upper'). See docs/hinges.md.
"""
from __future__ import annotations

import json
import math
from typing import Any, Mapping

HINGE_EVENTS_TOPIC = "hinge_events"
HINGE_EVENTS_TYPE = "std_msgs/msg/String"


def event_message(event: Mapping[str, Any]) -> dict[str, str]:
    """The std_msgs/String message dict of one event (a dict with at least ``t``)."""
    return {"data": json.dumps(dict(event), sort_keys=True)}


def event_time_ns(event: Mapping[str, Any]) -> int:
    """The event's simulated time [ns]."""
    return int(round(float(event["t"]) * 1e9))


def write_events(log, events) -> int:
    """Write HingeEvent objects (or dicts) to an open LogWriter; returns how many."""
    count = 0
    for ev in events:
        d = ev.to_dict() if hasattr(ev, "to_dict") else dict(ev)
        if not math.isfinite(float(d["t"])):
            continue
        log.write("/" + HINGE_EVENTS_TOPIC, HINGE_EVENTS_TYPE, event_time_ns(d), event_message(d))
        count += 1
    return count


def read_hinge_events(path) -> list[dict[str, Any]]:
    """The events recorded in the log at ``path`` (any that
    :func:`rod_sim.io.log_open.open_log` opens; ``hinge_events`` under any one namespace), in
    log order (dicts as written)."""
    from .log_open import open_log

    with open_log(path) as log:
        topic = log.resolve([HINGE_EVENTS_TOPIC]).get(HINGE_EVENTS_TOPIC,
                                                      "/" + HINGE_EVENTS_TOPIC)
        return [json.loads(msg.data) for _, _, msg in log.messages([topic])]
