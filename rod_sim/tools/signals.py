"""Ctrl-C and SIGTERM for the ``rod-sim`` commands: both raise a KeyboardInterrupt in the main
thread (SIGTERM as :class:`Terminated`), deferred while a log record is being written
(:func:`signals_deferred`), so that every command closes its files as for Ctrl-C."""
from __future__ import annotations

import contextlib
import signal
import threading


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C's KeyboardInterrupt, so that the same
    cleanup runs (a log is closed with its summary, a sweep writes its finished rows)."""


_deferring = 0
_pending: list = []


def _on_signal(signum, frame) -> None:
    """SIGINT raises KeyboardInterrupt, SIGTERM :class:`Terminated`; inside
    :func:`signals_deferred` (a log write) the exception waits until the write is done. The
    first SIGTERM interrupts; a second one during the cleanup is ignored (SIGKILL is the way
    to stop a cleanup that hangs)."""
    if signum == signal.SIGTERM:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    stop = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    if _deferring:
        _pending.append(stop)
        return
    raise stop


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


def handle_sigterm() -> None:
    """SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) in the main thread, as SIGINT
    does: ``simulate``, ``compare``, ``sweep`` and the other commands close their files and
    exit with status 130, as for Ctrl-C (the node and ``replay`` install their own handler).
    Both wait for the end of a log write (:func:`signals_deferred`)."""
    if threading.current_thread() is threading.main_thread():
        # a mask inherited from the launcher (or left by a library's worker threads in this
        # process) would make the command deaf to Ctrl-C and SIGTERM
        if hasattr(signal, "pthread_sigmask"):
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
        signal.signal(signal.SIGTERM, _on_signal)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _on_signal)


def reset() -> None:
    """Forget a signal deferred by an earlier command of this process (``rod-sim`` in tests)."""
    _pending.clear()
