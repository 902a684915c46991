"""``rod-sim simulate SCENE --t-end T --out LOG``: an offline run of a scene (no ROS graph),
written as the MCAP log of docs/interface.md section 4, sampled at ``--rate`` in simulated time,
the t = 0 state first; ``--integrator`` and its tolerances or step as for the node. A run that
fails keeps every finite sample in the log (exit 1); a write that fails keeps the complete
chunks or removes the file. Limits: docs/interface.md section 6.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from ..version import __version__
from ..core.names import INTEGRATOR_NAMES as INTEGRATORS
from ..core.names import MODEL_NAMES
from rod_sim.app import limits
from rod_sim.app.common import EXIT_CHECK_FAILED, EXIT_OK, UsageError, new_output_path
from rod_sim.app.common import non_negative_float, port_number
from rod_sim.app.common import positive_float as _positive_float
from rod_sim.app.progress import (Pace, Progress, left_text, run_state, steps_text,
                                  stiffness_hint)
from rod_sim.app.signals import done, signals_deferred

HELP = "offline run of a scene, written as an MCAP log"
DESCRIPTION = ("Offline run of a scene (no ROS graph); writes the log of docs/interface.md "
               "section 4 sampled at --rate in simulated time, the t = 0 state first. Limits: "
               "docs/interface.md section 6.")


def configure(parser) -> None:
    parser.add_argument("scene", help="scene YAML file (docs/interface.md section 1)")
    parser.add_argument("--model", choices=sorted(MODEL_NAMES), default="reduced",
                        help="full (3n ODEs), reduced (n ODEs, quasi-static bending) or rigid "
                             "(default reduced)")
    parser.add_argument("--t-end", type=_positive_float, required=True,
                        help=f"end time [s], at most {limits.MAX_T_END:g}")
    parser.add_argument("--out", required=True, help="MCAP log to write (must not exist)")
    parser.add_argument("--rate", type=_positive_float, default=100.0,
                        help="sampling rate of the log [Hz of simulated time], at most "
                             f"{limits.MAX_RATE:g} (default 100)")
    parser.add_argument("--integrator", choices=INTEGRATORS, default="dop853-jit",
                        help="dop853-jit (default; compiled adaptive Dormand-Prince 8(5,3), "
                             "--rtol/--atol), radau-jit (compiled implicit Radau IIA order 5, for "
                             "stiff scenes, --rtol/--atol), rk4, rk2, euler (compiled fixed step, "
                             "--step) or scipy's RK45, DOP853, Radau, BDF, LSODA")
    parser.add_argument("--rtol", type=_positive_float, default=None,
                        help="relative tolerance of adaptive integrators, "
                             f"{limits.RTOL_RANGE[0]:g} .. {limits.RTOL_RANGE[1]:g} (default 1e-8)")
    parser.add_argument("--atol", type=_positive_float, default=None,
                        help="absolute tolerance (default = rtol)")
    parser.add_argument("--step", type=_positive_float, default=None,
                        help="largest step of fixed-step integrators [s], at least 1e-9 "
                             "(default 1e-3)")
    parser.add_argument("--frame-id", default="world",
                        help="frame of the logged headers, poses and markers (default world)")
    parser.add_argument("--markers-rate", type=non_negative_float,
                        default=limits.MARKERS_RATE_HZ,
                        metavar="HZ", help="rate of /markers in the log [Hz of simulated time] "
                        "(display only: with every k-th sample, k = max(1, round(rate / "
                        "markers-rate)), from t = 0, as the node's markers_rate_hz); 0 = every "
                        f"sample; at most {limits.MAX_MARKERS_RATE_HZ:g} (default "
                        f"{limits.MARKERS_RATE_HZ:g})")
    parser.add_argument("--live-view", type=port_number, default=0, metavar="PORT",
                        help="show the run live: a Foxglove WebSocket server on "
                             "127.0.0.1:PORT (foxglove-sdk; connect the Foxglove app or "
                             "Lichtblick), the samples paced at --real-time-factor")
    parser.add_argument("--real-time-factor", type=_positive_float, default=1.0,
                        metavar="F", help="with --live-view: simulated seconds per wall "
                        "second at which the samples are shown (default 1)")


def _sample_grid_ns(rate_hz: float, k: int) -> int:
    """Time [ns] of sample k of the log's grid (as Simulator.run places its samples)."""
    return int(round(k * (1e9 / rate_hz)))


def sample_topics(scene) -> tuple[str, ...]:
    """The state topics of a logged sample of ``scene`` (``base_odometry`` on a moving base)."""
    from ..io import topics

    return topics.DEFAULT_TOPICS + (topics.BASE_TOPICS if scene.moving_base else ())


def log_sample_bytes(scene, frame_id: str) -> tuple[int, int]:
    """(bytes of a logged sample's messages but the markers, bytes of its markers), each with
    its MCAP record, uncompressed: the state topics' exact sizes and, on a spacecraft scene,
    ``/diagnostics`` with every value at its longest (``%.17g`` of a float: 24 characters)."""
    from ..io import encoders

    # the state topics' messages have one size for a scene and frame (their arrays' lengths
    # are the scene's): a snapshot of zeros gives it
    snap = encoders.zero_snapshot(scene)
    sizes = {name: len(data) for name, data in
             encoders.snapshot_bytes(snap, scene, frame_id, sample_topics(scene)).items()}
    markers = sizes.pop("markers") + limits.LOG_RECORD_BYTES
    rest = sum(sizes.values()) + limits.LOG_RECORD_BYTES * len(sizes)
    if scene.is_spacecraft:
        widest = dict.fromkeys(_diagnostic_texts(snap, 0.0, 0.0, None),
                               "-1.2345678901234567e-308")
        rest += len(_diagnostics_bytes(0.0, widest, scene)) + limits.LOG_RECORD_BYTES
    return rest, markers


def _diagnostic_texts(snap, energy: float, residual: float, ledger) -> dict[str, str]:
    """The values of a spacecraft sample's ``/diagnostics`` (docs/interface.md section 3):
    the node's energy keys and the spacecraft keys, the momentum ledger ``ledger`` as booked
    up to the sample (None: zeros)."""
    from ..core.ledger import diagnostic_strings, diagnostic_values

    return {"energy_J": f"{energy:.17g}", "energy_balance_residual_J": f"{residual:.17g}",
            **diagnostic_strings(diagnostic_values(snap, ledger))}


def _diagnostics_bytes(t: float, values: dict[str, str], scene) -> bytes:
    """A spacecraft sample's ``/diagnostics`` message with ``values`` as CDR bytes."""
    from ..io import encoders, topics

    return encoders.diagnostics(t, values, scene.name, name=topics.DIAGNOSTICS_STATUS_NAME)


def _start(args):
    """Everything before the run's clock starts: the checks of the options and the scene,
    the model, the compiled drivers (loaded, or compiled if not cached), the log and the live
    view; each step named to the start-up's progress line (:func:`rod_sim.app.startup.phase`).
    Returns (scene, model, integrator, simulator, log, the logged run, the log's path)."""
    from rod_sim.app.startup import phase
    from ..api import IntegrationError, Simulator, load_scene, make_integrator, make_model
    from ..io.log_source import SCENE_TOPIC
    from ..io.log_writer import LogWriter, offered_qos_yaml
    from ..io.topics import divider
    from ..io.scene_yaml import scene_to_yaml

    if not args.frame_id:                   # as the node's frame_id parameter
        raise UsageError("--frame-id: must not be empty")
    if args.markers_rate > limits.MAX_MARKERS_RATE_HZ:     # as the node's markers_rate_hz
        raise UsageError(f"--markers-rate: {args.markers_rate:g} Hz is more than "
                         f"{limits.MAX_MARKERS_RATE_HZ:g}")
    scene = load_scene(args.scene)
    limits.check_rtol(args.rtol)
    out = new_output_path(args.out)
    markers_every = divider(args.rate, args.markers_rate)
    phase("sizing the log")
    sample_bytes, markers_bytes = log_sample_bytes(scene, args.frame_id)
    limits.check_sampling(args.t_end, args.rate, scene.n, sample_bytes=sample_bytes,
                          markers_bytes=markers_bytes, markers_every=markers_every)
    integrator = make_integrator(args.integrator, rtol=args.rtol, atol=args.atol, step=args.step)
    if not integrator.adaptive and args.t_end / integrator.step > limits.MAX_FIXED_STEPS:
        raise UsageError(f"--step: {args.t_end:g} s in steps of {integrator.step:g} s is more "
                         f"than {limits.MAX_FIXED_STEPS:g} steps")
    phase("building the model")
    model = make_model(args.model, scene)          # refuses a chain too large for memory first
    phase("loading the compiled drivers (compiling them if not cached)")
    try:                # compile (or load) the kernels before the clock starts
        Simulator(model, make_integrator(args.integrator)).advance(1e-3)
    except IntegrationError:
        pass            # the run below meets the same failure and reports it
    sim = Simulator(model, integrator)
    metadata = {"scene": scene_to_yaml(scene), "model": model.name,
                "integrator": integrator.describe(), "version": __version__,
                "rate_hz": repr(args.rate), "source": "rod-sim simulate"}
    phase("opening the log")
    try:
        # compression, checksums and file writes in a process of their own (the node's log
        # writer): the samples' thread only encodes
        log = LogWriter(out, metadata=metadata, qos={SCENE_TOPIC: offered_qos_yaml(
            depth=1, durability="transient_local")}, writer_process=True)
        # the scene also as a latched topic: a log converted by rosbag2 tools (which drop MCAP
        # metadata records) stays self-contained
        log.write(SCENE_TOPIC, "std_msgs/msg/String", 0, {"data": metadata["scene"]})
    except OSError as err:
        raise UsageError(f"--out: cannot write {out}: {err.strerror or err}") from None
    logged = _LoggedRun(sim, scene, log, args.frame_id,
                        markers_every=markers_every)
    if args.live_view:
        from ..io.live_view import LiveView, LiveViewError

        phase("opening the live view")
        try:
            logged.live = LiveView(args.live_view, frame_id=args.frame_id,
                                   name="rod-sim simulate")
        except LiveViewError as exc:
            log.close()
            out.unlink(missing_ok=True)
            raise UsageError(str(exc)) from None
        logged.rtf = args.real_time_factor
        print(f"rod-sim simulate: live view on ws://127.0.0.1:{logged.live.port}, "
              f"real time x{args.real_time_factor:g}", file=sys.stderr)
    return scene, model, integrator, sim, log, logged, out


def run(args) -> int:
    from rod_sim.app.startup import Progress

    with Progress("rod-sim simulate", first_phase="reading the scene"):
        scene, model, integrator, sim, log, logged, out = _start(args)
    from ..api import IntegrationError

    started = time.perf_counter()
    try:
        try:
            status = logged.integrate(args.t_end, args.rate, IntegrationError)
        finally:
            with signals_deferred():        # the summary is written whole, even on Ctrl-C
                log.close()
                done(out)
            if logged.live is not None:
                logged.live.close()
    except OSError as err:
        print(f"rod-sim simulate: error: writing {out} failed at t = {logged.t_logged:g} s: "
              f"{err.strerror or err}; {_salvage(out)}", file=sys.stderr)
        return EXIT_CHECK_FAILED
    # the run as the user waited for it (integration, sampling, encoding, the log), and the
    # integration's part of it: a figure of the integration alone hides the sampling's cost
    run_wall = time.perf_counter() - started
    rtf = sim.t / run_wall if run_wall > 0 else math.inf
    print(f"{scene.name}: {model.name} model, {integrator.describe()}, t = 0..{sim.t:g} s, "
          f"{logged.samples} samples -> {out} (run {run_wall:.3f} s wall, {rtf:.3g}x real "
          f"time; integration {logged.wall:.3f} s of it, {sim.stats.nfev} rhs evaluations"
          + (f", {logged.logged_events} hinge events" if logged.logged_events else "") + ")")
    if logged.validity.summary():
        print(f"rod-sim simulate: validity warning: {logged.validity.summary()}", file=sys.stderr)
    hint = stiffness_hint(integrator, sim.stats)
    if hint:
        print(f"rod-sim simulate: hint: {hint}", file=sys.stderr)
    return status


class _LoggedRun:
    """A simulator run logged sample by sample: the t = 0 state first, then chunks of at most
    CHUNK_SAMPLES samples on the grid of --rate (plus the end time), with the hinge events."""

    CHUNK_SAMPLES = 10_000
    CHUNK_SECONDS = 0.5          # simulated seconds integrated per call at most
    PROGRESS_EVERY_S = 10.0      # [s] of wall time between progress lines of a slow run

    def __init__(self, sim, scene, log, frame_id: str, markers_every: int = 1):
        from ..core.validity import EnergyBalance, ValidityMonitor

        self.sim, self.scene, self.log, self.frame_id = sim, scene, log, frame_id
        self.markers_every = markers_every
        """``markers`` with every k-th logged sample, from t = 0
        (:func:`~rod_sim.io.topics.divider`)."""
        self.validity = ValidityMonitor(sim.model)
        self.balance = None             # the energy balance (the node judges the same one)
        self._last = None               # BalanceSample of the previous sample
        self.balanced_events = 0
        self.samples = 0
        self.logged_events = 0
        self.wall = 0.0
        self.t_logged = 0.0
        self.live = None
        """A :class:`~rod_sim.io.live_view.LiveView` shown each sample (or None)."""
        self.rtf = 1.0
        self._live_start: float | None = None
        from ..core.ledger import SpacecraftLedger

        self.spacecraft = SpacecraftLedger(sim.model) if sim.model.is_spacecraft else None
        """The momentum ledger of a spacecraft scene (its values go to ``/diagnostics``)."""
        self.topics = sample_topics(scene)
        """The state topics of a sample (``base_odometry`` on a moving base)."""
        self.topics_between = tuple(name for name in self.topics if name != "markers")
        """Those of a sample off the markers' divider."""

    def _write(self, t: float, y, mode=None, logged: bool = True) -> None:
        """The sample (t, y, mode) into the ledgers and, if ``logged``, the log (a sample at
        a load or base-motion breakpoint off the log's grid is booked only: no ledger span
        then holds a jump of the loads inside it)."""
        from ..core.validity import balance_sample

        model = self.sim.model
        # one State: each quantity of the sample (the right-hand side with the slopes, node
        # velocities, momentum, powers, ...) computed once for the snapshot, the energy
        # balance, the momentum ledger and the diagnostics
        state = model.state(t, y, None, mode, data=self.sim.data)   # its scratch: between steps
        if logged:
            snap = model.snapshot(t, y, None, mode, state=state)
            self.validity.update(snap.t, y, None, snap.alpha, snap.beta)
        self._book(t, balance_sample(model, t, y, None, mode, state=state))
        if self.spacecraft is not None:
            self.spacecraft.add(t, y, None, mode, state=state)
        if not logged:
            return
        from ..io import encoders, topics

        t_ns = topics.time_ns(snap.t)
        names = self.topics if self.samples % self.markers_every == 0 else self.topics_between
        encoded = encoders.snapshot_bytes(snap, self.scene, self.frame_id, names)
        diagnostics = self._diagnostics(t, snap)
        with signals_deferred():            # every record of a sample whole, or none
            for name, data in encoded.items():
                self.log.write_cdr("/" + name, topics.TOPIC_TYPES[name], t_ns, data)
            if diagnostics is not None:
                self.log.write_cdr("/diagnostics", topics.TOPIC_TYPES["diagnostics"], t_ns,
                                   diagnostics)
            self.samples += 1
            self.t_logged = t
        if self.live is not None:
            self._show(t, t_ns, snap, encoded)

    def _book(self, t: float, sample) -> None:
        """The energy balance from the previous sample to ``sample`` (a BalanceSample)."""
        from ..core.validity import EnergyBalance

        model = self.sim.model
        if self.balance is None:
            self.balance = EnergyBalance.for_model(model, sample.energy)
        else:
            events = self.sim.events
            k = self.balanced_events
            while k < len(events) and events[k].t < t:    # a sample at a latch's time: before it
                k += 1
            self.balance.add(self._last, sample, events[self.balanced_events:k])
            self.balanced_events = k
            self.validity.update_energy(t, self.balance.residual, self.balance.scale,
                                        self.balance.unresolved)
        self._last = sample

    def _diagnostics(self, t: float, snap):
        """A spacecraft scene's ``/diagnostics`` message of the sample as CDR bytes (None
        otherwise): the node's energy keys and the spacecraft keys (docs/interface.md section
        3), the momentum ledger as booked up to this sample."""
        if self.spacecraft is None:
            return None
        b = self.balance
        values = _diagnostic_texts(snap, self._last.energy,
                                   b.residual if b is not None else 0.0, self.spacecraft)
        return _diagnostics_bytes(t, values, self.scene)

    def _show(self, t: float, t_ns: int, snap, encoded) -> None:
        """Pace the samples at ``rtf`` and show them in the live view."""
        import numpy as np

        now = time.perf_counter()
        if self._live_start is None:
            self._live_start = now - t / self.rtf
        wait = self._live_start + t / self.rtf - now
        if wait > 0:
            time.sleep(wait)
        if self.live.wanted():
            if "markers" not in encoded:        # off the markers' divider: for the view only
                from ..io import encoders
                encoded = {**encoded, **encoders.snapshot_bytes(snap, self.scene, self.frame_id,
                                                                ("markers",))}
            b = self.balance
            self.live.send(t_ns, encoded, snap.nodes, snap.phi, {
                "energy": self._last.energy,
                "energy_residual": b.residual if b is not None else 0.0, "rtf": self.rtf,
                "max_abs_alpha": float(np.max(np.abs(snap.alpha), initial=0.0)),
                "max_abs_beta": float(np.max(np.abs(snap.beta), initial=0.0))})

    def _write_traj(self, traj, kink: float | None = None) -> None:
        """The samples of ``traj`` after its first (the previous call's last), then the hinge
        events since the last call. ``kink``: a breakpoint [s] of the loads or the base's
        motion that ``traj`` ends at (its last sample, the nearest whole ns): that sample is
        booked at the breakpoint's own time, where the ledgers take the loads on either side
        of it, and not logged."""
        from ..io.hinge_events import write_events

        last = traj.t.size - 1
        for i in range(1, traj.t.size):
            at_kink = kink is not None and i == last
            self._write(kink if at_kink else float(traj.t[i]), traj.y[i],
                        None if traj.modes is None else traj.modes[i], not at_kink)
        with signals_deferred():
            self.logged_events += write_events(self.log, self.sim.events[self.logged_events:])

    def integrate(self, t_end: float, rate_hz: float, failure) -> int:
        """Run to t_end [s]; on ``failure`` (IntegrationError) keep every finite sample, print
        one line and return EXIT_CHECK_FAILED."""
        sim = self.sim
        self._write(sim.t, sim.y, sim.mode)
        end_ns = round(t_end * 1e9)
        per_chunk = max(1, min(self.CHUNK_SAMPLES, math.floor(self.CHUNK_SECONDS * rate_hz)))
        every = self.PROGRESS_EVERY_S
        with Progress(_RunLine(sim, t_end), every, every, "rod-sim-simulate-progress"):
            return self._chunks(sim, end_ns, rate_hz, per_chunk, failure)

    def _chunks(self, sim, end_ns: int, rate_hz: float, per_chunk: int, failure) -> int:
        k = 0
        while sim.t_ns < end_ns:
            k += per_chunk
            t_next = min(end_ns, _sample_grid_ns(rate_hz, k)) / 1e9
            started = time.perf_counter()
            try:
                # up to each load or base-motion breakpoint off the grid (booked, not logged),
                # then to the chunk's end
                for kink in self._kinks_before(sim.t_ns, round(t_next * 1e9), rate_hz):
                    traj = sim.run(round(kink * 1e9) / 1e9, rate_hz)
                    self.wall += time.perf_counter() - started
                    self._write_traj(traj, kink)
                    started = time.perf_counter()
                traj = sim.run(t_next, rate_hz)
            except failure as err:
                # redo the chunk one sample at a time so the log keeps every finite sample
                try:
                    while sim.t_ns < round(t_next * 1e9):
                        j = math.floor(sim.t_ns * rate_hz / 1e9 + 1e-6) + 1
                        self._write_traj(sim.run(min(t_next, _sample_grid_ns(rate_hz, j) / 1e9),
                                                 rate_hz))
                except failure as again:
                    err = again
                print(f"rod-sim: {err}; the log holds {self.samples} samples, t = 0.."
                      f"{self.t_logged:g} s", file=sys.stderr)
                return EXIT_CHECK_FAILED
            self.wall += time.perf_counter() - started
            self._write_traj(traj)
        return EXIT_OK

    def _kinks_before(self, start_ns: int, end_ns: int, rate_hz: float) -> list[float]:
        """The breakpoints [s] of the scripted loads and a prescribed base motion (where
        their power may jump) strictly between ``start_ns`` and ``end_ns`` [ns] and not on a
        sample of the log's grid."""
        out = []
        for b in self.scene.breakpoints():
            b_ns = round(b * 1e9)
            k = round(b_ns * rate_hz / 1e9)
            if start_ns < b_ns < end_ns and _sample_grid_ns(rate_hz, k) != b_ns:
                out.append(b)
        return out


class _RunLine:
    """The progress line of a slow run (issue 27, item 10: radau-jit at rtol 1e-12 on a stiff
    scene ran past 60 s silently; :class:`~rod_sim.app.progress.Progress` prints it every
    :attr:`_LoggedRun.PROGRESS_EVERY_S`): the simulated time reached, the integrator, its steps
    (and current step size) and rhs evaluations, and the wall time left
    (:class:`~rod_sim.app.progress.Pace`)."""

    def __init__(self, sim, t_end: float):
        self.sim, self.t_end = sim, t_end
        self.pace = Pace(t_end, *run_state(sim)[:2])

    def __call__(self, elapsed: float) -> str:
        sim = self.sim
        t, steps, h = run_state(sim)
        left = self.pace.left(t, steps, h)
        stiff = "; stiff: try --integrator radau-jit" if stiffness_hint(
            sim.integrator, sim.stats) else ""
        return (f"rod-sim simulate: t = {t:.6g} of {self.t_end:g} s after {elapsed:.0f} s "
                f"({sim.integrator.describe()}: {steps_text(steps, h)}, {sim.stats.nfev} rhs "
                f"evaluations; {left_text(left)}){stiff}")


def _salvage(path: Path) -> str:
    """After a failed write: keep ``path`` if it holds complete samples (say which), else
    remove it. Returns what was done, for the error line."""
    from ..io.series import read_rod_states

    try:
        t, _, _ = read_rod_states(path)
    except Exception:                         # nothing readable: no complete chunk
        t = ()
    if len(t):
        return (f"{path} keeps the {len(t)} samples of t = 0..{t[-1]:g} s written in complete "
                "chunks (no summary: readers scan it)")
    try:
        path.unlink()
    except OSError as err:
        return f"{path} holds no complete sample and could not be removed: {err.strerror or err}"
    return f"removed {path}, which held no complete sample"


