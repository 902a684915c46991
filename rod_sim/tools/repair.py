"""``rod-sim repair LOG [--out OUT]``: rewrite a truncated log (its writer was killed before
closing it, e.g. by SIGKILL or a power cut) or a damaged one (a chunk, the summary or the
data-section CRC does not match) with a new summary, data-end and indexes, keeping every
message of its intact chunks, so that rosbags, ``ros2 bag`` and other MCAP readers that need
the summary open it (like ``mcap recover``). A damaged chunk is left out (a warning names it
and the gap in log time); one flipped bit outside the chunks' data is located by the
data-section CRC and written corrected.

Exit 0 when the repaired copy was written (or LOG was already complete and intact: nothing
written); 2 with one line for a missing or non-MCAP LOG (opened as every command opens a log,
:mod:`rod_sim.io.log_open`), a directory, a LOG whose record framing is damaged, or an existing
OUT. LOG itself is never changed.
"""
from __future__ import annotations

import sys
from pathlib import Path

from rod_sim.app.common import EXIT_OK, UsageError, new_output_path
from rod_sim.app.signals import done

HELP = "rewrite a truncated (writer killed) or damaged log with a new summary and indexes"


def configure(parser) -> None:
    parser.description = __doc__.split("\n\n")[0].replace("``", "").split(": ", 1)[1]
    parser.add_argument("log", metavar="LOG", help="the truncated MCAP log")
    parser.add_argument("--out", default=None, metavar="OUT",
                        help="file to write (must not exist; default: LOG with .repaired.mcap "
                             "in place of .mcap)")


def default_out(log: Path) -> Path:
    stem = log.name[:-len(".mcap")] if log.name.endswith(".mcap") else log.name
    return log.with_name(stem + ".repaired.mcap")


def run(args) -> int:
    from ..io.log_open import open_log
    from ..io.repair import repair_log

    log = Path(args.log)
    if log.is_dir():
        raise UsageError(f"{log}: a directory; repair rewrites one MCAP file (repair each "
                         ".mcap file of a bag)")
    with open_log(log) as opened:           # refuses a non-MCAP or corrupt log before writing
        reader = opened.readers[0]
        if reader.complete:
            print(f"{log} is complete (it has its summary and indexes): nothing to repair")
            return EXIT_OK
        damaged = reader.damaged
    out = new_output_path(args.out if args.out is not None else str(default_out(log)))
    try:
        result = repair_log(log, out)
    except OSError as exc:
        raise UsageError(f"cannot write {out}: {exc.strerror or exc} (nothing written)") from None
    if damaged and result.messages == 0:        # nothing intact to keep: not a repair
        out.unlink(missing_ok=True)
        raise UsageError(f"{log}: corrupt log: no intact message to keep (the warnings above "
                         "name the damaged chunks); nothing written")
    done(out)
    span = ("no messages" if result.first_ns is None else
            f"log time {result.first_ns / 1e9:.9g}..{result.last_ns / 1e9:.9g} s")
    print(f"{out}: {result.messages} messages on {result.channels} channels ({span}), "
          f"{result.metadata} metadata record(s); "
          + ("rebuilt from the intact records, as the warnings above say" if damaged else
             f"dropped the incomplete last {result.dropped_bytes} bytes of {log}"))
    sys.stdout.flush()
    return EXIT_OK
