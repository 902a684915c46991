"""Helpers of the tests that meet the node the way a user does: the node (or any ``rod-sim``
command) as a separate process, and a client graph (context, node, executor) in the test's
process, both in one ROS domain on localhost."""
from __future__ import annotations

import itertools
import os
import signal
import sys
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from procs import Child

STARTUP_S = 40.0
"""[s] allowed for a node process to come up (compiling the kernels on a cold cache)."""
_NAMESPACES = itertools.count()


def unique_namespace() -> str:
    """A namespace no other test run on this machine uses (``/t<pid>_<k>``): other graphs in
    the same ROS domain (another developer's tests) cannot cross-talk with this test's."""
    return f"/t{os.getpid()}_{next(_NAMESPACES)}"


def ros_args(params: dict) -> list[str]:
    """``-p key:=value`` for each parameter (booleans in ROS spelling)."""
    args = []
    for key, value in params.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        args += ["-p", f"{key}:={text}"]
    return args


class NodeProcess(Child):
    """``rod-sim node --ros-args [extra] -p k:=v ...`` (through ``python -m
    rod_sim.tools.cli``; ``command`` replaces ``-m rod_sim.tools.cli node``), stderr in
    ``tmp_path/<name>.err``."""

    def __init__(self, tmp_path: Path, domain: int, name: str = "node",
                 extra: list[str] = (), command=("-m", "rod_sim.tools.cli", "node"), **params):
        args = [sys.executable, *command, "--ros-args", *extra, *ros_args(params)]
        super().__init__(args, domain, tmp_path / f"{name}.err", tmp_path / f"{name}.out")

    def wait_for_output(self, text: str, timeout: float = STARTUP_S) -> None:
        deadline = time.monotonic() + timeout
        while text not in self.stderr:
            if self.proc.poll() is not None:
                raise AssertionError(f"node exited ({self.proc.returncode}): {self.stderr}")
            if time.monotonic() > deadline:
                raise AssertionError(f"node did not print {text!r} in {timeout} s: {self.stderr}")
            time.sleep(0.05)

    def stop(self, sig=signal.SIGINT, timeout: float = 15.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        return self.proc.wait(timeout=timeout)


class Client:
    """A client node ``name`` (in ``namespace``) in its own context in ROS domain ``domain``,
    spun by an ``executor_class`` (rclpy's executor by default); :meth:`close` ends it. The
    environment must already name the domain (monkeypatch ROS_DOMAIN_ID)."""

    def __init__(self, domain: int, name: str = "test_client", namespace: str = "",
                 executor_class=SingleThreadedExecutor):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = Node(name, context=self.context, namespace=namespace)
        self.executor = executor_class(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition, timeout: float, what, process: Child | None = None):
        """Spin until ``condition()``; else AssertionError naming ``what`` (a string, or a
        callable giving one at the time of failure) or the exit of ``process``."""
        deadline = time.monotonic() + timeout
        while not condition():
            if process is not None and process.proc.poll() is not None:
                raise AssertionError(f"process exited: {process.stderr}")
            if time.monotonic() > deadline:
                what = what() if callable(what) else what
                raise AssertionError(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.01)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def wait_for_states(domain: int, count: int, process: Child, namespace: str = "",
                    timeout: float = 60.0) -> None:
    """Until a client in ``domain`` (``namespace``) has received ``count`` rod_states from the
    node of ``process``: a run of a known length, however slowly a loaded machine lets the node
    advance (a fixed 1.5 s sleep gave 87 recorded states where 150 were due, at load 7)."""
    from sensor_msgs.msg import JointState

    client = Client(domain, name="state_counter", namespace=namespace)
    got = []
    try:
        client.node.create_subscription(JointState, "rod_states", got.append, 100)
        client.spin_until(lambda: len(got) >= count, timeout, f"{count} rod_states", process)
    finally:
        client.close()


def stamp_ns(msg) -> int:
    """A message's header stamp [ns]."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
