"""The node's live view (``live_view_port``): :class:`rod_sim.io.live_view.LiveView` fed
from the node's outputs, with ``pause``, ``step`` and ``reset`` callable from the viewer.

The view is a tap of :class:`~rod_sim.ros.outputs.Outputs`: it gets each state's snapshot and
the bytes already encoded for DDS and the log, and does nothing unless a client subscribes and
a frame is due (:data:`~rod_sim.io.live_view.MAX_FRAME_HZ`). Service calls arrive on the
SDK's thread; each is handed to the node's executor through a guard condition and answered
when the executor has run it (or "busy" after :data:`CALL_TIMEOUT_S`).
"""
from __future__ import annotations

import queue
import threading
import time

from rod_sim.io.live_view import LiveView, LiveViewError
from rod_sim.ros.errors import NodeConfigError

CALL_TIMEOUT_S = 5.0
"""[s] a viewer's service call waits for the executor at most."""


class NodeLiveView:
    """The live view of ``node`` (a :class:`~rod_sim.ros.node.RodSimNode`) on ``port``."""

    def __init__(self, node, port: int):
        self.node = node
        self._calls: queue.SimpleQueue = queue.SimpleQueue()
        self._wake = node.create_guard_condition(self._run_calls)
        try:
            self.view = LiveView(port, frame_id=node._outputs.frame_id,
                                 name=node.get_fully_qualified_name(),
                                 services={"pause": self._pause, "step": self._step,
                                           "reset": self._reset},
                                 run_on_owner=self._on_owner)
        except LiveViewError as exc:
            raise NodeConfigError(f"live_view_port: {exc}") from None
        node._outputs.taps.append(self.frame)
        node.get_logger().info(f"live view on ws://127.0.0.1:{self.view.port} (Foxglove "
                               "WebSocket, subprotocol foxglove.sdk.v1)")

    def frame(self, snap, t_ns: int, encoded: dict) -> None:
        """A tap of the outputs: one frame if a client wants it."""
        view = self.view
        if not view.wanted():
            return
        node = self.node
        if "markers" not in encoded:       # off the markers' divider: drawn for the view only
            encoded = {**encoded, "markers": node._outputs.encode("markers", snap)}
        p = node.period
        view.frame_id = node._outputs.frame_id
        view.send(t_ns, encoded, snap.nodes, snap.phi, {
            "energy": p.ledger.energy, "energy_residual": p.ledger.residual,
            "rtf": p.meter.real_time_factor(time.monotonic_ns()),
            "max_abs_alpha": p.max_alpha, "max_abs_beta": p.max_beta})

    # ----- services, run on the executor -----

    def _on_owner(self, fn):
        done, box = threading.Event(), {}
        self._calls.put((fn, box, done))
        self._wake.trigger()
        if not done.wait(CALL_TIMEOUT_S):
            return False, f"busy: the node did not run the call within {CALL_TIMEOUT_S:g} s"
        return box["result"]

    def _run_calls(self) -> None:
        while True:
            try:
                fn, box, done = self._calls.get_nowait()
            except queue.Empty:
                return
            try:
                box["result"] = fn()
            except Exception as exc:  # noqa: BLE001 -- a viewer's call never stops the node
                box["result"] = (False, f"failed: {type(exc).__name__}: {exc}")
            done.set()

    def _pause(self, request: dict):
        return True, self.node.pause(bool(request.get("data", True)))

    def _reset(self, request: dict):
        return True, self.node.reset()

    def _step(self, request: dict):
        """``step_count`` periods while paused (as ``~/step``, in one go)."""
        node = self.node

        async def no_yield():
            return None

        coro = node.control.step(node.settings.step_count,
                                 lambda: node._step_period(node._held(wall_age=False)),
                                 lambda: node.sim.t, no_yield, float("inf"))
        try:
            coro.send(None)
        except StopIteration as stop:
            return stop.value
        coro.close()
        return False, "step did not finish"

    def close(self) -> None:
        self.view.close()
