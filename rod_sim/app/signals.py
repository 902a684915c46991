"""Ctrl-C and SIGTERM for the ``rod-sim`` commands: both raise a KeyboardInterrupt in the main
thread (SIGTERM as :class:`Terminated`), deferred while a log record is being written
(:func:`signals_deferred`), so that every command closes its files as for Ctrl-C.

Whenever the signal arrives (while the command table imports, while a library swallows the
exception, during the cleanup), the command ends within :data:`GRACE_S` with exit status 130
(SIGINT) or 143 (SIGTERM) and one line (:func:`exit_status`, ``rod_sim.tools.cli.main``): the
first signal starts a watchdog thread that ends the process then if it is still running,
removing the outputs it had not finished (:func:`unfinished`), so an output is closed or absent.
Later signals are only counted: the cleanup of the first is not interrupted."""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Callable


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C's KeyboardInterrupt, so that the same
    cleanup runs (a log is closed with its summary, a sweep writes its finished rows)."""


GRACE_S = 0.75
"""[s] from the first signal to the forced end of a command that has not ended by itself."""
NUDGE_S = 0.02
"""[s] between two nudges of the main thread whose handler has not run yet (:func:`_nudge_main`)."""
EXIT_SIGINT, EXIT_SIGTERM = 128 + signal.SIGINT, 128 + signal.SIGTERM      # 130, 143

_deferring = 0
_pending: list = []
_received: list[int] = []
_unfinished: dict[Path, int] = {}
command = "rod-sim"
"""The name the forced end's line gives the command (``rod-sim simulate``)."""


def received() -> int | None:
    """The first signal (SIGINT or SIGTERM) this command received, or None."""
    return _received[0] if _received else None


def exit_status(signum: int | None = None) -> int:
    """130 for SIGINT, 143 for SIGTERM (the shell's 128 + signal number): of ``signum``,
    else of the first signal received (130 when none was, e.g. a KeyboardInterrupt raised by
    a library)."""
    signum = received() if signum is None else signum
    return EXIT_SIGTERM if signum == signal.SIGTERM else EXIT_SIGINT


def interrupted_line(signum: int | None = None) -> str:
    """The one line of an interrupted command."""
    signum = received() if signum is None else signum
    return f"{command}: interrupted" + (" (SIGTERM)" if signum == signal.SIGTERM else "")


class ArrivalWatch:
    """Calls ``on_arrival(signum)`` in a daemon thread as soon as one of ``signals`` arrives,
    whatever the main thread is doing. Python runs a signal's handler in the main thread
    only between two bytecodes: while the main thread is in one long call that does not
    return to the interpreter (LLVM compiling a driver, a compiled integrator's call, a C
    library) the handler waits, and so did the watchdog it starts (CI: 1.28 s of CPU from a
    SIGINT to the end of a 100 000-rod node's start-up). The C-level handler writes the
    signal's number to :func:`signal.set_wakeup_fd`'s pipe at once; this thread reads it.
    It runs Python as soon as the main thread releases the GIL, which C libraries and
    rod_sim's compiled code (``nogil``, :mod:`rod_sim.core.jit`) do.

    A context manager for the main thread (elsewhere, or where the wakeup descriptor cannot
    be set, it does nothing); on exit the previous wakeup descriptor is restored. Only
    signals with a Python handler are written to the pipe. A child made by ``fork`` without
    ``exec`` would write its own signals into the same pipe: rod_sim starts its processes by
    exec, ``spawn`` or ``forkserver`` (the pipe's descriptors are not inherited across exec)."""

    def __init__(self, on_arrival, signals=(signal.SIGINT, signal.SIGTERM)):
        self.on_arrival = on_arrival
        self.signals = frozenset(int(s) for s in signals)
        self._write_fd: int | None = None
        self._previous = -1

    def __enter__(self) -> "ArrivalWatch":
        if threading.current_thread() is not threading.main_thread():
            return self
        read_fd, write_fd = os.pipe()
        os.set_blocking(write_fd, False)
        try:
            self._previous = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
        except (ValueError, OSError):
            os.close(read_fd)
            os.close(write_fd)
            return self
        self._write_fd = write_fd
        threading.Thread(target=self._read, args=(read_fd,), daemon=True,
                         name="rod-sim-signal-arrival").start()
        return self

    def __exit__(self, *exc) -> None:
        if self._write_fd is None:
            return
        with contextlib.suppress(ValueError, OSError):
            signal.set_wakeup_fd(self._previous)
        os.close(self._write_fd)        # the reader sees the end of the pipe and stops
        self._write_fd = None

    def _read(self, read_fd: int) -> None:
        try:
            while data := os.read(read_fd, 64):
                for signum in data:
                    if signum in self.signals:
                        self.on_arrival(signum)
        except OSError:
            pass
        finally:
            os.close(read_fd)


class Watchdog:
    """Ends the process ``grace_s`` [s] after :meth:`start` unless :meth:`claim` is called
    before: writes ``line()`` to stderr and exits with ``status()`` through ``os._exit`` (no
    cleanup: a cleanup that hangs is what it ends). The first signal of a command starts
    one (:func:`_arrived`), and so does a signal during a node's start-up
    (:class:`rod_sim.ros.process.StopRequest`); the code that ends by itself in time claims
    it. Both methods may be called from a signal handler, from any thread, more than once."""

    def __init__(self, line: Callable[[], str], status: Callable[[], int],
                 grace_s: float = GRACE_S, name: str = "rod-sim-signal-watchdog"):
        self.line = line
        self.status = status
        self.grace_s = grace_s
        self.name = name
        self._claimed = threading.Event()
        self._lock = threading.RLock()      # a handler may run inside a method of the main thread
        self._started = False

    def start(self) -> None:
        """Start the countdown (the first call only)."""
        with self._lock:
            if self._started:
                return
            self._started = True
        threading.Thread(target=self._run, name=self.name, daemon=True).start()

    def claim(self) -> bool:
        """The caller has ended (or reports the end) itself: True the first time, and the
        watchdog stands down; False once the watchdog (or an earlier call) has claimed it."""
        with self._lock:
            if self._claimed.is_set():
                return False
            self._claimed.set()
            return True

    def _run(self) -> None:
        if self._claimed.wait(self.grace_s) or not self.claim():
            return
        line = self.line()
        with contextlib.suppress(Exception):
            sys.stderr.flush()
            os.write(2, (line + "\n").encode("utf-8", "replace"))
        releaser = threading.Thread(target=release_semaphores, daemon=True,
                                    name="rod-sim-semaphore-release")
        releaser.start()
        releaser.join(SEMAPHORE_RELEASE_S)      # bounded: the end must not wait on a lock
        os._exit(self.status())


SEMAPHORE_RELEASE_S = 0.1
"""[s] the most a forced end waits for :func:`release_semaphores`."""


def release_semaphores() -> None:
    """Unlink the named semaphores that multiprocessing objects of this process still hold (a
    process pool's queues hold 5) and unregister them from multiprocessing's resource tracker,
    as the interpreter's exit would (``os._exit`` skips it). Else the tracker, a process that
    outlives this one, prints a warning of "leaked semaphore objects" after the forced end's
    line (CI: a sweep ended by its watchdog while starting its pool)."""
    util = sys.modules.get("multiprocessing.util")
    synchronize = sys.modules.get("multiprocessing.synchronize")
    if util is None or synchronize is None:
        return
    cleanup = getattr(synchronize.SemLock, "_cleanup", None)
    for finalizer in list(getattr(util, "_finalizer_registry", {}).values()):
        if cleanup is not None and getattr(finalizer, "_callback", None) is cleanup:
            with contextlib.suppress(Exception):
                finalizer()


_first_lock = threading.RLock()
_interrupting: list[int] = []
"""The signal the main thread's handler has raised (or deferred) its interruption for."""
_generation = [0]
"""Counts the commands of this process (:func:`reset`): a nudge stops when it changes."""


def _arrived(signum: int) -> bool:
    """The first SIGINT / SIGTERM of the command, seen by whichever comes first, the
    :class:`ArrivalWatch` thread or the main thread's handler: recorded, and the watchdog
    starts. Whether this call was the first."""
    with _first_lock:
        if _received:
            return False
        _received.append(signum)
        _watchdog.start()
        return True


def _on_signal(signum, frame) -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM :class:`Terminated`; inside
    :func:`signals_deferred` (a log write) the exception waits until the write is done. The
    first signal interrupts and starts the watchdog (unless the :class:`ArrivalWatch` thread
    saw it first); later ones are ignored (the cleanup is bounded by the watchdog)."""
    _arrived(signum)
    with _first_lock:
        if _interrupting:
            return
        _interrupting.append(signum)
    signum = _received[0]
    stop = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    if _deferring:
        _pending.append(stop)
        return
    raise stop


def ended_line(signum: int | None = None) -> str:
    """The one line of an interrupted command (``signum``, else the first signal received),
    its unfinished outputs removed first and named (an output is whole or absent): what the
    command says when it unwinds (``rod_sim.tools.cli``) and what its watchdog says."""
    return interrupted_line(signum) + removed_note(remove_unfinished())


def _command_watchdog() -> Watchdog:
    """The watchdog of a command: :data:`GRACE_S` after its first signal, unless it has
    returned (:func:`finished`), the unfinished outputs are removed, one line, 130 / 143."""
    return Watchdog(ended_line, exit_status)


_watchdog = _command_watchdog()


def unfinished(path) -> None:
    """``path`` is an output this command creates (:func:`rod_sim.app.common.new_output_path`
    registers each): if the watchdog has to end the process before :func:`done` is called
    for it, the file is removed (an output is whole or absent)."""
    _unfinished[Path(path)] = 1


def done(path) -> None:
    """The output ``path`` is closed (complete): the watchdog leaves it."""
    _unfinished.pop(Path(path), None)


def remove_unfinished() -> list[str]:
    """Remove the outputs registered by :func:`unfinished` and not :func:`done` (an
    interrupted command's: e.g. a log whose file was created but whose writer had not
    started); the paths removed."""
    removed = []
    for path in list(_unfinished):
        _unfinished.pop(path, None)
        with contextlib.suppress(OSError):
            path.unlink()
            removed.append(str(path))
    return removed


def removed_note(removed: list[str]) -> str:
    """The tail of the interrupted line that names the outputs removed ('' for none)."""
    return f"; removed the unfinished {', '.join(removed)}" if removed else ""


@contextlib.contextmanager
def signals_deferred():
    """A Ctrl-C or SIGTERM arriving inside the block is raised when the block ends, so that
    a log record is never left half written (the log could not be closed cleanly then)."""
    global _deferring
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
    if not _deferring and _pending:
        stop = _pending[0]
        _pending.clear()
        raise stop


def quiet_unraisable(unraisable) -> None:
    """``sys.unraisablehook`` of a command: once a signal has been received, an exception that
    Python cannot propagate (a finaliser's, a weakref callback's) is not reported as
    "Exception ignored in ..." with a traceback: the command reports its end once, as its one
    line (``rod_sim.tools.cli.main`` sees the received signal). Such exceptions are the
    interruption itself, raised in a weakref callback of the import system's module locks, or
    its fallout: an object whose construction or close the signal's exception cut in half
    fails in its finaliser (CI: llvmlite's ``ObjectRef.__del__`` raised "AttributeError:
    'GlobalContextRef' object has no attribute '_as_parameter_'" after a SIGTERM during
    simulate's compile-cache load). Before any signal, everything goes to the hook it
    replaced."""
    if received() is not None:
        return
    _replaced_unraisablehook[0](unraisable)


_replaced_unraisablehook = [sys.__unraisablehook__]


def quiet_excepthook(kind, value, traceback) -> None:
    """``sys.excepthook`` of a command: the interruption of a received signal printed by C
    code that catches it and prints it itself (``PyErr_Print``: numpy's ``import_array()``
    in a C extension's initialization, when the signal lands in its import of numpy, then
    raises "ImportError: numpy.core.multiarray failed to import") is not shown as a traceback:
    the command reports it once, as its one line. Anything else goes to the hook it
    replaced."""
    if received() is not None and isinstance(value, KeyboardInterrupt):
        return
    _replaced_excepthook[0](kind, value, traceback)


_replaced_excepthook = [sys.__excepthook__]


def handle_sigterm() -> None:
    """SIGINT and SIGTERM raise KeyboardInterrupt / :class:`Terminated` in the main thread:
    ``simulate``, ``compare``, ``sweep`` and the other commands close their files and exit
    with status 130 / 143 (the node and ``replay`` install their own handler once they run).
    Both wait for the end of a log write (:func:`signals_deferred`)."""
    if sys.unraisablehook is not quiet_unraisable:
        _replaced_unraisablehook[0] = sys.unraisablehook
        sys.unraisablehook = quiet_unraisable
    if sys.excepthook is not quiet_excepthook:
        _replaced_excepthook[0] = sys.excepthook
        sys.excepthook = quiet_excepthook
    if threading.current_thread() is threading.main_thread():
        # a mask inherited from the launcher (or left by a library's worker threads in this
        # process) would make the command deaf to Ctrl-C and SIGTERM
        if hasattr(signal, "pthread_sigmask"):
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
        signal.signal(signal.SIGTERM, _on_signal)
        current = signal.getsignal(signal.SIGINT)
        if current in (signal.default_int_handler, _on_signal) or getattr(
                current, "rod_sim_early", False):     # rod_sim.tools.launch's first handler
            signal.signal(signal.SIGINT, _on_signal)
        if _arrival_watch is None:
            _start_arrival_watch()


_arrival_watch: ArrivalWatch | None = None
"""The commands' :class:`ArrivalWatch` (one per process, from the first
:func:`handle_sigterm` on; the node's and replay's handlers set their own while they run)."""


def _start_arrival_watch() -> None:
    global _arrival_watch
    _arrival_watch = ArrivalWatch(_arrived_here).__enter__()


def _arrived_here(signum: int) -> None:
    """:func:`_arrived` for a signal that this module's handler handles (not one that the
    node's, or a handler set after the command returned, does); for the first, the main
    thread is nudged until its handler has run (:func:`_nudge_main`)."""
    if signal.getsignal(signum) is not _on_signal:
        return
    with _first_lock:
        first = _arrived(signum)
        generation = _generation[0]
    if first:
        _nudge_main(signum, generation)


def _nudge_main(signum: int, generation: int) -> None:
    """Send ``signum`` to the main thread itself every :data:`NUDGE_S` until its handler has
    run, for at most :data:`GRACE_S` (the watchdog's time), unless the command changed (a new
    :func:`reset`, another handler). CI's sweep sat in the forkserver's read of a new worker's
    pid (its preloading takes ~2 s) until the watchdog ended it: the signal had not
    interrupted that read (the kernel may deliver a process's signal to another thread, and
    one that lands just before the call does not interrupt it; which of these happened is not
    known), and Python runs the handler only when the call returns. Sent to the main thread,
    the signal makes such a call fail with EINTR, and Python runs the handler. Called by the
    :class:`ArrivalWatch` thread."""
    main = threading.main_thread().ident
    for _ in range(int(GRACE_S / NUDGE_S)):
        time.sleep(NUDGE_S)
        with _first_lock:
            if (_interrupting or _generation[0] != generation
                    or signal.getsignal(signum) is not _on_signal):
                return
        try:
            signal.pthread_kill(main, signum)
        except (OSError, ValueError):            # the main thread has ended
            return


def finished() -> None:
    """The current command has returned: its watchdog (if a signal started one) stands down."""
    _watchdog.claim()


def write_line(text: str, stream) -> None:
    """``text`` and its newline in one write, flushed: a line another thread writes (the
    main thread's interrupted line; a node's start-up progress, a command's compile notice)
    can come before or after it, never inside it (``print`` writes the text and the newline
    in two calls: CI once got a node's interrupted line glued to a progress line)."""
    stream.write(text + "\n")
    stream.flush()


def exit_now(status: int) -> None:
    """End the process with ``status`` at once, stdout and stderr flushed (no interpreter
    teardown: the outputs are already closed)."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


def exit_quietly_on_signal() -> None:
    """After the command has returned (its outputs closed, its exit status known), while the
    interpreter shuts down: SIGINT / SIGTERM end the process at once, streams flushed, with
    status 130 / 143 and no further line (no traceback from the shutdown's own code)."""
    def end(signum, frame):
        exit_now(exit_status(signum))

    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) is not signal.SIG_IGN:
                signal.signal(sig, end)


def reset(name: str = "rod-sim") -> None:
    """Start a command: forget a signal of an earlier command of this process (``rod-sim`` in
    tests); ``name`` is the command's name in the forced end's line."""
    global command, _watchdog
    _watchdog.claim()
    _watchdog = _command_watchdog()
    _pending.clear()
    _received.clear()
    _interrupting.clear()
    _unfinished.clear()
    _generation[0] += 1
    command = name
