"""Sweep worker functions for test_sweep.py that kill their own process (as SIGKILL or the
out-of-memory killer would), importable by the pool's worker processes (by reference)."""
import contextlib
import os
import signal
import tempfile
import time
from pathlib import Path


@contextlib.contextmanager
def flag_dir():
    with tempfile.TemporaryDirectory(prefix="sweep-crash-") as d:
        yield Path(d)


def _row(task: dict) -> dict:
    return {"run": task["index"], "status": "ok"}


def _note(task: dict, what: str) -> Path:
    path = Path(task["flags"]) / f"{task['index']}.{what}.{time.monotonic_ns()}"
    path.touch()
    return path


def runs(flags: Path, index: int) -> int:
    return len(list(flags.glob(f"{index}.run.*")))


def died(flags: Path) -> list[int]:
    return sorted(int(p.name.split(".")[0]) for p in flags.glob("*.died.*"))


def die_once_at_index_2(task: dict) -> dict:
    _note(task, "run")
    time.sleep(0.3)                 # the other worker is in the middle of a run meanwhile
    if task["index"] == 2 and not list(Path(task["flags"]).glob("2.died.*")):
        _note(task, "died")
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.3)
    return _row(task)


def always_die_at_index_1(task: dict) -> dict:
    _note(task, "run")
    time.sleep(0.2)
    if task["index"] == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return _row(task)
