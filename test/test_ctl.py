"""Issue 20 item 7: `rod-sim ctl` against a running node in a namespace, each call a separate
process as a user types it: pause, step, resume, step refused while running, param get/set
(a read-only one refused with the node's reason), echo, hz, reset; and a node that is not there
is one line, exit 1. ROS domain id from ros_domains (LOCALHOST)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("rclpy")

from ros_domains import next_domain  # noqa: E402
from procs import ros_env  # noqa: E402
from ros_graph import NodeProcess, unique_namespace  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.timeout(240)]

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "config" / "small_chain.yaml"
DOMAIN = next_domain()


def ctl(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rod_sim.tools.cli", "ctl", *args], cwd=REPO,
                          env=ros_env(DOMAIN), capture_output=True, text=True, timeout=timeout)


def stepped_to(done: subprocess.CompletedProcess) -> float:
    assert done.returncode == 0, done.stdout + done.stderr
    return float(re.search(r"stepped to t = ([0-9.e+-]+) s", done.stdout).group(1))


@pytest.mark.slow
def test_ctl_drives_a_namespaced_node(tmp_path):
    ns = unique_namespace()                  # e.g. /t1234_0: no other graph in this domain
    node = NodeProcess(tmp_path, DOMAIN, extra=["-r", f"__ns:={ns}"], scene_file=SCENE)
    try:
        node.wait_for_output("commands on")
        paused = ctl("--ns", ns, "pause")
        assert paused.returncode == 0 and paused.stdout.startswith("pause: ok: paused at t ="), \
            paused.stdout + paused.stderr
        t1 = stepped_to(ctl("--ns", ns.strip("/"), "step"))
        t2 = stepped_to(ctl("--ns", ns + "/", "step"))
        assert t2 == pytest.approx(t1 + 0.01, abs=1e-9), "one step is one 10 ms period"

        count = ctl("--ns", ns, "param", "step_count", "3")
        assert count.returncode == 0 and count.stdout.strip() == "step_count: set to 3"
        assert stepped_to(ctl("--ns", ns, "step")) == pytest.approx(t2 + 0.03, abs=1e-9)
        rtf = ctl("--ns", ns, "param", "real_time_factor", "1")      # int -> double
        assert rtf.returncode == 0 and "set to 1.0" in rtf.stdout, rtf.stdout + rtf.stderr
        got = ctl("--ns", ns, "param", "rate_hz")
        assert got.returncode == 0 and got.stdout.strip() == "rate_hz: 100.0"
        refused = ctl("--ns", ns, "param", "rate_hz", "50.0")
        assert refused.returncode == 1 and "refused" in refused.stdout and "read-only" in \
            refused.stdout.lower().replace("read only", "read-only"), refused.stdout
        unknown = ctl("--ns", ns, "param", "no_such", "1")
        assert unknown.returncode == 1 and "no parameter 'no_such'" in unknown.stderr

        resumed = ctl("--ns", ns, "resume")
        assert resumed.returncode == 0 and "resumed at t =" in resumed.stdout
        running = ctl("--ns", ns, "step")
        assert running.returncode == 1 and "refused" in running.stdout

        echo = ctl("--ns", ns, "echo", "rod_states", "--count", "2")
        assert echo.returncode == 0, echo.stderr
        docs = [d for d in yaml.safe_load_all(echo.stdout) if d is not None]
        assert len(docs) == 2
        assert docs[0]["name"] == ["rod_1", "rod_2", "rod_3"] and len(docs[0]["position"]) == 3
        stamps = [d["header"]["stamp"]["sec"] * 10**9 + d["header"]["stamp"]["nanosec"]
                  for d in docs]
        assert stamps[1] > stamps[0]

        hz = ctl("--ns", ns, "hz", "rod_states", "--duration", "3.5")
        assert hz.returncode == 0, hz.stderr
        rates = [float(r) for r in re.findall(r"average rate: ([0-9.]+) Hz", hz.stdout)]
        assert rates and 70.0 < rates[-1] < 130.0, hz.stdout     # 100 Hz at real time

        reset = ctl("--ns", ns, "reset")
        assert reset.returncode == 0 and "reset to the initial state at t = 0 s" in reset.stdout
    finally:
        node.kill()


@pytest.mark.slow
def test_ctl_without_the_node_is_one_line_exit_1():
    done = ctl("--ns", "/nowhere", "--timeout", "1", "pause")
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert done.stderr.strip() == (
        f"rod-sim ctl: no service /nowhere/rod_sim/pause within 1 s: is the node running as "
        f"/nowhere/rod_sim in ROS_DOMAIN_ID {DOMAIN}? (--ns, --node)")
    bad = ctl("param")
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("args, rule", [
    (["--ns", "bad//ns", "pause"], "--ns 'bad//ns': namespace must not contain repeated '/'"),
    (["--ns", "/1abc", "pause"], "--ns '/1abc': namespace must not have a token that starts"),
    (["--node", "x y", "pause"], "--node 'x y': node name must not contain characters"),
    (["echo", "bad topic!"], "topic 'bad topic!': topic name 'bad topic!' is invalid"),
    (["hz", "~/a{b"], "topic '~/a{b': "),
])
def test_ctl_bad_names_are_one_line_exit_2(args, rule):
    """Issue 27, item 3: a namespace, node or topic name ROS 2 refuses printed a 36-line rclpy
    traceback (exit 1), or rcl's C source location (exit 1): now one line naming the option and
    the rule, exit 2, before any ROS context is created."""
    done = ctl("--timeout", "1", *args)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.startswith(f"rod-sim ctl: error: {rule}"), done.stderr
    assert ".c:" not in done.stderr and done.stdout == ""


class _LostFirst:
    """A service client whose first answer is lost (the server had not matched the client's
    response reader), later ones arrive: counts the requests sent."""

    def __init__(self):
        self.sent = []

    def service_is_ready(self):
        return True

    def call_async(self, request):
        from rclpy.task import Future

        future = Future()
        if self.sent:
            future.set_result(f"answer to request {len(self.sent) + 1}")
        self.sent.append(request)
        return future


@pytest.mark.parametrize("idempotent, sent, outcome", [(True, 2, "answer to request 2"),
                                                       (False, 1, "did not answer")])
def test_ctl_sends_an_idempotent_request_again_when_its_answer_is_lost(idempotent, sent,
                                                                        outcome):
    """pause/resume and parameters are sent again every RESEND_S until an answer comes; step
    and reset once (a late repetition would act twice): without ROS, a client whose first
    answer is lost."""
    import types

    from rod_sim.ros.ctl_client import CtlClient, CtlError

    lost = _LostFirst()
    ctl = object.__new__(CtlClient)
    ctl.timeout = 0.3
    ctl.RESEND_S = 0.05
    ctl.node = types.SimpleNamespace(create_client=lambda srv, name: lost)
    ctl.executor = types.SimpleNamespace(spin_once=lambda timeout_sec: None)
    try:
        result = ctl._call(object, "/rod_sim/pause", "request", idempotent=idempotent)
    except CtlError as err:
        result = str(err)
    assert outcome in result
    assert len(lost.sent) == sent
