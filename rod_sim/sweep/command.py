"""``rod-sim sweep SPEC.yaml``: batch runs over parameter grids or Monte-Carlo draws.

The spec (``docs/sweep.md``, parsed by :mod:`.spec`) is expanded into runs, every run's
scene is validated before any run starts, then the runs go to a local process pool
(``--workers``, default ``os.cpu_count() - 1``; ``--workers 0`` runs them in this process) or to an
existing Dask cluster (``--scheduler ADDRESS``). Each run is one call of
:func:`.worker.run_one` and one row of the result table (``--out``, CSV or Parquet),
in run order whatever order the runs finish in; failed runs are rows with their reason.
Ctrl-C cancels the outstanding runs, writes the rows finished so far and exits with 130.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from pathlib import Path

from rod_sim.core.quote import quote
from rod_sim.app.common import EXIT_OK, UsageError, new_output_path
from rod_sim.app.signals import done, exit_status, received, signals_deferred

HELP = "batch runs over parameter grids or Monte-Carlo draws (local pool or Dask cluster)"
EXIT_INTERRUPTED = 130
"""Ctrl-C; SIGTERM: 143 (:func:`rod_sim.app.signals.exit_status`)."""


class SweepInterrupted(Exception):
    """Ctrl-C during the runs; ``rows`` holds those finished ({index: row})."""

    def __init__(self, rows: dict):
        super().__init__("interrupted")
        self.rows = rows


def _whole_number(text: str) -> int:
    """argparse type of --workers and --seed: a whole number >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {quote(text)}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0 (got {value})")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", help="sweep spec YAML file (see docs/sweep.md)")
    parser.add_argument("--out", default=None,
                        help="result table, .csv or .parquet (must not exist; default "
                             "<spec name>.csv in the current directory)")
    parser.add_argument("--plot", default=None, metavar="PNG",
                        help="summary plot of outputs against each swept parameter")
    parser.add_argument("--workers", type=_whole_number, default=None,
                        help="local worker processes (default: os.cpu_count() - 1, at least 1; "
                             "0 = run in this process)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on an existing Dask cluster (e.g. tcp://10.0.0.5:8786) "
                             "instead of local processes")
    parser.add_argument("--seed", type=_whole_number, default=None,
                        help="seed of the Monte-Carlo draws (overrides the spec's seed)")


# ----- execution -----

def _progress(total: int, desc: str):
    try:
        from tqdm import tqdm
    except ImportError:                                  # the progress bar is optional
        return None
    # made whole or not at all: a signal inside tqdm's constructor left a half-built bar
    # whose finalizer then printed "AttributeError: 'tqdm' object has no attribute 'disable'"
    with signals_deferred():
        return tqdm(total=total, desc=desc, unit="run", file=sys.stderr, disable=None)


def run_serial(tasks: list[dict], on_row=None) -> dict:
    """Every task in this process, in order. Returns {index: row}."""
    from .worker import run_one

    rows: dict = {}
    try:
        for task in tasks:
            rows[task["index"]] = row = run_one(task)
            if on_row:
                on_row(row)
    except KeyboardInterrupt:
        raise SweepInterrupted(rows) from None
    return rows


def _worker_init() -> None:
    """Initializer of a pool worker: Ctrl-C is the parent's to handle, and the worker dies with
    its parent (the forkserver, which dies with the sweep: :mod:`.forkserver`; or the
    sweep, for spawned workers) even when that is SIGKILLed (issue 27, item 8)."""
    from .parent_death import die_with_parent

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()


def _pool_context():
    """Fresh worker processes: forked from a clean server process that has imported the
    worker module once (forkserver, where the platform has it), else spawned."""
    import multiprocessing

    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        # the first import makes the forkserver die with the sweep (parent-death signal)
        ctx.set_forkserver_preload(["rod_sim.sweep.forkserver",
                                    "rod_sim.sweep.worker"])
        return ctx
    return multiprocessing.get_context("spawn")


def _collect(futures: dict, finished, rows: dict, on_row=None) -> None:
    """Rows of ``futures`` ({future: task}) into ``rows`` ({index: row}) in the order
    ``finished(futures)`` yields them; a future that raised becomes a failed row."""
    from .worker import failed_row

    for future in finished(futures):
        task = futures[future]
        try:
            row = future.result()
        except Exception as err:                     # noqa: BLE001 - e.g. a worker died
            row = failed_row(task, f"worker: {type(err).__name__}: {err}")
        rows[task["index"]] = row
        if on_row:
            on_row(row)


def _started_marker(marker_dir: str, index: int) -> Path:
    return Path(marker_dir) / f"{index}.started"


def tracked(function, marker_dir: str, task: dict) -> dict:
    """``function(task)`` in a worker process, with a marker file present while it runs: when
    the pool breaks (a worker was killed), the parent tells the runs that had started from
    those that had only been queued."""
    marker = _started_marker(marker_dir, task["index"])
    marker.touch()
    try:
        return function(task)
    finally:
        marker.unlink(missing_ok=True)


def _pool_round(tasks: list[dict], workers: int, function, marker_dir: str, rows: dict,
                on_row) -> tuple[list[dict], list[dict], str]:
    """The tasks on one pool of ``workers`` fresh processes; rows into ``rows``. When a worker
    process dies the pool breaks: returns (started, queued, reason), the tasks lost with it
    that had started and those that had not."""
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool
    from functools import partial

    from .worker import failed_row

    executor = None
    futures = {}
    lost: list[dict] = []
    reason = ""
    try:
        # a signal inside the constructor (it makes the pool's 5 semaphores) lost the
        # half-made pool: the command exited without releasing them, and multiprocessing's
        # resource tracker warned of "5 leaked semaphore objects"; here it is raised once the
        # pool exists, and the handler below stops it
        with signals_deferred():
            executor = ProcessPoolExecutor(max_workers=workers, initializer=_worker_init,
                                           mp_context=_pool_context())
        job = partial(tracked, function, marker_dir)
        futures = {executor.submit(job, task): task for task in tasks}
        for future in as_completed(futures):
            task = futures[future]
            try:
                row = future.result()
            except BrokenProcessPool as err:
                lost.append(task)
                reason = reason or " ".join(str(err).split())
                continue
            except Exception as err:                 # noqa: BLE001 - e.g. unpicklable
                row = failed_row(task, f"worker: {type(err).__name__}: {err}")
            rows[task["index"]] = row
            if on_row:
                on_row(row)
    except KeyboardInterrupt:
        if executor is None:
            raise SweepInterrupted(rows) from None
        for future in futures:
            future.cancel()
        # Runs in progress would finish first; stop their processes (no public API before
        # Python 3.14's terminate_workers()).
        for process in list(getattr(executor, "_processes", {}).values()):
            process.terminate()
        executor.shutdown(wait=True, cancel_futures=True)
        raise SweepInterrupted(rows) from None
    executor.shutdown(wait=True)
    started = [t for t in lost if _started_marker(marker_dir, t["index"]).exists()]
    for task in started:
        _started_marker(marker_dir, task["index"]).unlink(missing_ok=True)
    queued = [t for t in lost if t not in started]
    return started, queued, reason


def run_local(tasks: list[dict], workers: int, on_row=None, function=None) -> dict:
    """The tasks on a pool of ``workers`` fresh processes. Returns {index: row}.

    A worker process that dies (killed, out of memory, a crash in compiled code) breaks the
    pool and every run on it: the runs that had not started go to a fresh pool again; those
    that had started are retried one at a time in a pool of one process, where a death can
    only be the run's own: that run alone becomes a failed row ("its worker process died").
    """
    import tempfile

    from .worker import failed_row, run_one

    function = function or run_one
    rows: dict = {}
    fresh, suspects = list(tasks), []
    with tempfile.TemporaryDirectory(prefix="rod-sim-sweep-") as marker_dir:
        while fresh or suspects:
            alone = not fresh
            batch = fresh if fresh else suspects[:1]
            started, queued, reason = _pool_round(batch, 1 if alone else workers, function,
                                                  marker_dir, rows, on_row)
            if alone:
                suspects = suspects[1:]
                for task in started + queued:
                    row = failed_row(task, "worker: its process died while running it, also "
                                           f"when run alone (killed or out of memory?): {reason}")
                    rows[task["index"]] = row
                    if on_row:
                        on_row(row)
                continue
            if queued and not started:               # the pool broke before running anything
                for task in queued:
                    rows[task["index"]] = row = failed_row(task, f"worker: {reason}")
                    if on_row:
                        on_row(row)
                queued = []
            fresh, suspects = queued, suspects + started
    return rows


def run_dask(tasks: list[dict], address: str, on_row=None) -> dict:
    """The tasks on the Dask cluster whose scheduler is at ``address``. Returns {index: row}."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise UsageError("--scheduler needs dask.distributed: pip install 'rod_sim[sweep]'") from None
    from .worker import run_one

    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as err:
        raise UsageError(f"--scheduler: cannot connect to {address}: "
                         f"{' '.join(str(err).split()) or type(err).__name__}") from None
    rows: dict = {}
    futures = {}
    try:
        stamp = f"{os.getpid()}-{time.time_ns()}"
        futures = {client.submit(run_one, task, key=f"rod-sim-sweep-{stamp}-{task['index']}",
                                 pure=False): task for task in tasks}
        _collect(futures, lambda fs: as_completed(list(fs)), rows, on_row)
    except KeyboardInterrupt:
        client.cancel(list(futures))
        raise SweepInterrupted(rows) from None
    finally:
        client.close()
    return rows


def _plural(count: int, word: str, plural: str = "") -> str:
    return f"{count} {word if count == 1 else plural or word + 's'}"


def _design(spec) -> str:
    """What the runs are, e.g. "3 x 4 grid, 64 Monte-Carlo draws each, 2 models"."""
    parts = []
    sizes = [len(p.values) for p in spec.parameters if not p.random]
    if sizes:
        parts.append(" x ".join(map(str, sizes)) + " grid")
    if any(p.random for p in spec.parameters):
        draws = _plural(spec.draws, "Monte-Carlo draw")
        parts.append(draws + (" per grid point" if sizes else ""))
    if not parts:
        parts.append("the base scene")
    parts.append(_plural(len(spec.models), "model"))
    return ", ".join(parts)


def local_workers(requested: int | None, runs: int) -> int:
    """Worker processes to start: ``requested`` (default os.cpu_count() - 1, leaving a core to
    the machine), at most one per run."""
    return max(1, min(requested or (os.cpu_count() or 2) - 1, runs))


def execute(tasks: list[dict], workers: int | None = None, scheduler: str | None = None,
            on_row=None) -> list[dict]:
    """Run the tasks locally or on Dask; the rows in task-index order."""
    if scheduler:
        rows = run_dask(tasks, scheduler, on_row)
    elif workers == 0:
        rows = run_serial(tasks, on_row)
    else:
        rows = run_local(tasks, local_workers(workers, len(tasks)), on_row)
    return [rows[i] for i in sorted(rows)]


# ----- the command -----

def result_columns(spec) -> list[str]:
    """The table's columns: the run, the swept parameters, the outputs (and, for a spacecraft
    scene, the base's angle and the momentum balance)."""
    from rod_sim.core.scene import Scene
    from .worker import OUTPUTS, SPACECRAFT_OUTPUTS

    extra = SPACECRAFT_OUTPUTS if Scene.from_dict(spec.base_scene).is_spacecraft else {}
    return ["run", *(p.path for p in spec.parameters), *OUTPUTS, *extra]


def metadata(spec) -> dict:
    from rod_sim.version import __version__

    return {"name": spec.name, "models": list(spec.models), "seed": spec.seed,
            "draws": spec.draws, "version": __version__, **spec.settings(),
            "parameters": {p.path: (list(p.values) if not p.random else
                                    {p.kind: dict(p.args)}) for p in spec.parameters}}


def _summary(rows: list[dict], total: int) -> str:
    ok = sum(r["status"] == "ok" for r in rows)
    failed = [r for r in rows if r["status"] != "ok"]
    text = f"{len(rows)} of {total} runs: {ok} ok, {len(failed)} failed"
    if failed:
        text += f" (first: run {failed[0]['run']}: {failed[0]['status']})"
    return text


def run(args) -> int:
    from .spec import expand, load_spec
    from .table import table_format, write_table

    spec = load_spec(args.spec, seed=args.seed)
    out = new_output_path(args.out or f"{spec.name}.csv")
    if table_format(out) == ".parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise UsageError("--out: Parquet needs pyarrow: pip install 'rod_sim[sweep]'") from None
    plot = None
    if args.plot:
        plot = new_output_path(args.plot, "--plot")
        if plot.suffix.lower() not in (".png", ".svg", ".pdf"):
            raise UsageError(f"--plot: {plot} must end in .png, .svg or .pdf")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise UsageError("--plot needs matplotlib: pip install 'rod_sim[plot]'") from None
    runs = expand(spec)                       # validates every scene before any run starts
    tasks = [r.task(spec) for r in runs]
    where = (f"Dask scheduler {args.scheduler}" if args.scheduler else
             "this process" if args.workers == 0 else
             _plural(local_workers(args.workers, len(tasks)), "local worker process",
                     "local worker processes"))
    print(f"rod-sim sweep: {spec.name}: {len(tasks)} runs ({_design(spec)}) on {where}",
          file=sys.stderr, flush=True)

    bar = _progress(len(tasks), spec.name)
    started = time.perf_counter()
    try:
        rows = execute(tasks, args.workers, args.scheduler,
                       on_row=(lambda row: bar.update(1)) if bar is not None else None)
    except SweepInterrupted as stop:
        if bar is not None:
            bar.close()
        rows = [stop.rows[i] for i in sorted(stop.rows)]
        write_table(rows, out, result_columns(spec), metadata(spec))
        done(out)
        print(f"rod-sim sweep: interrupted{' (SIGTERM)' if received() == signal.SIGTERM else ''}"
              f": {_summary(rows, len(tasks))}; finished rows written to {out}",
              file=sys.stderr)
        return exit_status()
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - started
    write_table(rows, out, result_columns(spec), metadata(spec))
    done(out)
    if plot is not None:
        from .plot import plot_sweep

        plot_sweep(rows, [p.path for p in spec.parameters],
                   {p.path for p in spec.parameters if p.random}, plot,
                   title=f"{spec.name}: {', '.join(spec.models)}, t_end = {spec.t_end:g} s",
                   logx={p.path for p in spec.parameters if p.log})
        done(plot)
    print(f"{spec.name}: {_summary(rows, len(tasks))}; {wall:.1f} s wall -> {out}"
          + (f", {plot}" if plot else ""))
    return EXIT_OK
