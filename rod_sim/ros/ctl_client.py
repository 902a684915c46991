"""The ROS side of ``rod-sim ctl`` (no ``ros2`` CLI needed): call the node's services, set or
get one of its parameters, print a topic's messages, measure a topic's rate. One short-lived
client node ``rod_sim_ctl`` in the namespace given, so that relative topic names resolve as the
node's do (``rod_states`` under ``--ns /arm1`` is ``/arm1/rod_states``; ``/diagnostics`` and
``/clock`` stay absolute). Every function returns a process exit status and prints one line
per result; failures raise :class:`CtlError` with a one-line message.
"""
from __future__ import annotations

import sys
import time
from collections import deque

import rclpy
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_srvs.srv import SetBool, Trigger

from rod_sim.io import yaml_text
from rod_sim.ros.conversions import message_class, message_to_dict
from rod_sim.ros.executor import LeanExecutor
from rod_sim.ros.parameters import NODE_NAME

CTL_NODE_NAME = "rod_sim_ctl"


class CtlError(RuntimeError):
    """A control request that could not be carried out; ``str()`` is one line."""


class CtlNameError(ValueError):
    """A namespace, node name or topic name that ROS 2 does not accept (bad input: ``rod-sim
    ctl`` exits 2); ``str()`` is one line naming the option and the rule broken."""


def normal_namespace(namespace: str) -> str:
    """``namespace`` made absolute without a trailing slash ('' and '/' are the root)."""
    return "/" + namespace.strip("/") if namespace.strip("/") else "/"


def _rule(exc: Exception) -> str:
    """The rule rclpy's name check reports, one line (no caret, no C source location)."""
    text = str(exc).splitlines()[0].rstrip(":").split(", at ")[0]
    return text.split(": ", 1)[1] if text.startswith("Invalid ") and ": " in text else text


def check_names(namespace: str, node_name: str, topic: str | None = None) -> None:
    """Raise :class:`CtlNameError` unless ``namespace`` (as --ns), ``node_name`` (--node) and
    ``topic`` (relative to the namespace, as the client resolves it) are valid ROS 2 names,
    by rclpy's own validators, before any ROS context exists."""
    from rclpy.expand_topic_name import expand_topic_name
    from rclpy.validate_full_topic_name import validate_full_topic_name
    from rclpy.validate_namespace import validate_namespace
    from rclpy.validate_node_name import validate_node_name

    ns = normal_namespace(namespace)
    checks = [("--ns", namespace, lambda: validate_namespace(ns)),
              ("--node", node_name, lambda: validate_node_name(node_name))]
    if topic is not None:
        checks.append(("topic", topic, lambda: validate_full_topic_name(
            expand_topic_name(topic, CTL_NODE_NAME, ns))))
    for what, value, check in checks:
        try:
            check()
        except Exception as exc:  # noqa: BLE001 -- rclpy raises NameValidationException or ValueError
            raise CtlNameError(f"{what} {value!r}: {_rule(exc)}") from None


class CtlClient:
    """A client node in namespace ``namespace`` talking to the simulator node ``node_name``
    there; ``timeout`` [s] bounds each wait for discovery or an answer. Use as a context
    manager (it owns its rclpy context)."""

    def __init__(self, namespace: str = "/", node_name: str = NODE_NAME, timeout: float = 10.0):
        check_names(namespace, node_name)
        self.namespace = normal_namespace(namespace)
        self.target = f"{self.namespace.rstrip('/')}/{node_name}"
        self.timeout = timeout
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context)
        self.node = rclpy.create_node(CTL_NODE_NAME, namespace=self.namespace,
                                      context=self.context)
        self.executor = LeanExecutor(context=self.context)
        self.executor.add_node(self.node)

    def __enter__(self) -> "CtlClient":
        return self

    def __exit__(self, *exc) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()

    def _where(self) -> str:
        return (f"is the node running as {self.target} in ROS_DOMAIN_ID "
                f"{self.context.get_domain_id()}? (--ns, --node)")

    RESEND_S = 2.0
    """[s] without an answer after which a request whose repetition changes nothing is sent
    again (:meth:`_call`)."""

    def _call(self, srv_type, service: str, request, idempotent: bool = False):
        """The answer of ``service`` to ``request``. A service is "ready" once its server is
        discovered, which can be before the server has matched this client's response reader:
        Fast DDS then drops the response (it waits 100 ms for the match: rmw_fastrtps #390,
        #467), which a loaded machine makes likely. An ``idempotent`` request (pause, resume, the
        parameters) is therefore sent again every :data:`RESEND_S` until an answer comes;
        ``step`` and ``reset`` are sent once (a late second one would step again, or reset a
        running node again)."""
        client = self.node.create_client(srv_type, service)
        deadline = time.monotonic() + self.timeout
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                raise CtlError(f"no service {service} within {self.timeout:g} s: {self._where()}")
            self.executor.spin_once(timeout_sec=0.05)
        futures = [client.call_async(request)]
        resend = time.monotonic() + self.RESEND_S
        while not any(f.done() for f in futures):
            now = time.monotonic()
            if now > deadline + self.timeout:
                raise CtlError(f"{service} did not answer within {self.timeout:g} s")
            if idempotent and now > resend:
                futures.append(client.call_async(request))
                resend = now + self.RESEND_S
            self.executor.spin_once(timeout_sec=0.05)
        return next(f for f in futures if f.done()).result()

    # ----- services -----

    def service(self, action: str) -> int:
        """``pause``, ``resume``, ``step`` or ``reset``: print the node's answer; 0 when it
        succeeded, 1 when the node refused (e.g. ``step`` while running)."""
        if action in ("pause", "resume"):
            answer = self._call(SetBool, f"{self.target}/pause",
                                SetBool.Request(data=action == "pause"), idempotent=True)
        else:
            answer = self._call(Trigger, f"{self.target}/{action}", Trigger.Request())
        print(f"{action}: {'ok' if answer.success else 'refused'}: {answer.message}")
        return 0 if answer.success else 1

    # ----- parameters -----

    def get_parameter(self, name: str):
        """The value of parameter ``name`` of the node (None when it has none)."""
        answer = self._call(GetParameters, f"{self.target}/get_parameters",
                            GetParameters.Request(names=[name]), idempotent=True)
        return from_parameter_value(answer.values[0]) if answer.values else None

    def set_parameter(self, name: str, text: str) -> int:
        """Set ``name`` from ``text`` (a YAML scalar: 1.0 double, 1 integer, true bool, else a
        string; an integer given for a double parameter is sent as a double). 0 when the node
        accepted it, 1 when it refused (its reason printed)."""
        current = self.get_parameter(name)
        if current is None:
            raise CtlError(f"{self.target} has no parameter {name!r}")
        value = parse_value(text)
        if isinstance(current, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        msg = ParameterMsg(name=name, value=to_parameter_value(value))
        answer = self._call(SetParameters, f"{self.target}/set_parameters",
                            SetParameters.Request(parameters=[msg]), idempotent=True)
        result = answer.results[0]
        if result.successful:
            print(f"{name}: set to {value!r}")
            return 0
        print(f"{name}: refused: {result.reason or 'no reason given'}")
        return 1

    # ----- topics -----

    def _topic(self, topic: str) -> tuple[str, type, QoSProfile]:
        """(resolved name, message class, QoS matching every publisher) of ``topic``, once a
        publisher is seen (as ``ros2 topic echo`` adapts its QoS to the publishers)."""
        name = self.node.resolve_topic_name(topic)
        deadline = time.monotonic() + self.timeout
        while True:
            infos = self.node.get_publishers_info_by_topic(name)
            if infos:
                break
            if time.monotonic() > deadline:
                raise CtlError(f"no publisher of {name} within {self.timeout:g} s: "
                               f"{self._where()}")
            self.executor.spin_once(timeout_sec=0.05)
        cls = message_class(infos[0].topic_type)
        reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE if reliable
                         else ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                         else DurabilityPolicy.VOLATILE)
        return name, cls, qos

    def echo(self, topic: str, count: int = 0, out=sys.stdout) -> int:
        """Print each message of ``topic`` as a YAML document (``---`` between them), ``count``
        of them (0: until interrupted)."""
        name, cls, qos = self._topic(topic)
        seen = [0]

        def on_message(msg) -> None:
            if count and seen[0] >= count:
                return
            seen[0] += 1
            out.write("---\n" + yaml_text.dump(message_to_dict(msg), sort_keys=False,
                                              default_flow_style=None, width=100))
            out.flush()

        self.node.create_subscription(cls, name, on_message, qos)
        while self.context.ok() and not (count and seen[0] >= count):
            self.executor.spin_once(timeout_sec=0.1)
        return 0

    def hz(self, topic: str, window: int = 1000, duration: float = 0.0, out=sys.stdout) -> int:
        """Print the message rate of ``topic`` every second of wall time (average, min and max
        interval, standard deviation over the last ``window`` messages), as ``ros2 topic hz``
        does; for ``duration`` [s] (0: until interrupted)."""
        name, cls, qos = self._topic(topic)
        arrivals: deque[int] = deque(maxlen=window + 1)
        self.node.create_subscription(cls, name, lambda _msg: arrivals.append(
            time.monotonic_ns()), qos)
        start = next_print = time.monotonic()
        while self.context.ok() and not (duration and time.monotonic() - start >= duration):
            self.executor.spin_once(timeout_sec=0.05)
            if time.monotonic() >= next_print + 1.0:
                next_print = time.monotonic()
                out.write(rate_line(list(arrivals)) + "\n")
                out.flush()
        return 0


def rate_line(arrivals_ns: list[int]) -> str:
    """``average rate: R Hz (min I s, max I s, std dev S s, window N)`` of the arrival times
    [ns]; ``no new messages`` with fewer than two."""
    if len(arrivals_ns) < 2:
        return "no new messages"
    gaps = [(b - a) / 1e9 for a, b in zip(arrivals_ns, arrivals_ns[1:])]
    mean = sum(gaps) / len(gaps)
    std = (sum((g - mean) ** 2 for g in gaps) / len(gaps)) ** 0.5
    return (f"average rate: {1.0 / mean:.3f} Hz (min {min(gaps):.4f} s, max {max(gaps):.4f} s, "
            f"std dev {std:.5f} s, window {len(gaps) + 1})")


def parse_value(text: str):
    """A parameter value from the command line as ``ros2 param set`` reads it: a YAML scalar
    (``1.0`` double, ``1`` integer, ``true`` bool, anything else a string)."""
    try:
        value = yaml_text.load(text)
    except yaml_text.YAMLError:
        return text
    return value if isinstance(value, (bool, int, float, str)) else text


def to_parameter_value(value) -> ParameterValue:
    if isinstance(value, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    if isinstance(value, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    if isinstance(value, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=str(value))


def from_parameter_value(value: ParameterValue):
    """The Python value of a scalar ParameterValue (None when not set)."""
    return {ParameterType.PARAMETER_BOOL: lambda v: v.bool_value,
            ParameterType.PARAMETER_INTEGER: lambda v: v.integer_value,
            ParameterType.PARAMETER_DOUBLE: lambda v: v.double_value,
            ParameterType.PARAMETER_STRING: lambda v: v.string_value}.get(
                value.type, lambda v: None)(value)
