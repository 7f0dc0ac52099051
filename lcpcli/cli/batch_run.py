"""The batch side of ``lcpcli solve``: many files, folders, globs, HDF5 files of many problems.

``solve_cmd`` calls :func:`wants_batch` and, when it says yes, hands everything to
:func:`run_batch_command`; the engine is :mod:`lcpcli.batch.run`, the files
:mod:`lcpcli.batch.output`, the tables :mod:`lcpcli.cli.render.batch`. Not a subcommand module (no
``register``).
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

from lcpcli.cli.common import (
    duration,
    install_stop_handlers,
    pending_exit,
    plural,
    progress_allowed,
    restore_handlers,
    say_stopped,
    stderr_console,
    stdout_console,
    stopped_code,
    stopped_word,
    write_json_line,
)
from lcpcli.core.errors import OptionError, ProblemError

#: Up to this many problems, the batch summary lists every problem with its status.
FEW_PROBLEMS = 20
#: A batch expected to run longer than this (seconds) prints an estimate on stderr.
ESTIMATE_AFTER_SECONDS = 10.0
#: The rate behind the estimate is measured after the first result, over at least this many
#: seconds and this many problems.
ESTIMATE_MIN_SECONDS = 1.0
ESTIMATE_MIN_PROBLEMS = 8


def wants_batch(files: list[str], output: Any, *, problem: str | None = None,
                recursive: bool = False, jobs: int | None = None, resume: bool = False,
                timeout: float | None = None, quiet: bool = False,
                scheduler: str | None = None) -> bool:
    """True unless this is the classic one-file solve (one FILE, no batch option).

    Batch mode: several FILEs, a folder, a glob, a batch option (--recursive, --jobs,
    --resume, --timeout, --quiet, --scheduler), ``--output`` ending in .jsonl/.csv/.h5/.npz,
    a stacked file (:mod:`lcpcli.io.stack`), or an HDF5 file holding several problems without
    ``--problem`` (every problem is solved).
    """
    if len(files) != 1:
        return True
    if recursive or resume or quiet or jobs is not None or timeout is not None \
            or scheduler is not None:
        return True
    f = files[0]
    if f == "-":
        return False
    from lcpcli.io import FORMATS

    binary = FORMATS.get(Path(f).suffix.lower()) in ("hdf5", "npz")
    if binary:  # only these can be stacks (the import is skipped for a JSON one-liner)
        from lcpcli.io.stack import is_stack

        if is_stack(f):
            return problem is None  # --problem picks one stacked problem: a single solve
    if Path(f).is_dir():
        # a folder is a batch; a directory named like a problem file (adir.json) is a bad
        # input of a single solve: one line on stderr, as the README promises
        return not f.rstrip("/").lower().endswith(tuple(FORMATS))
    if not Path(f).exists():
        from lcpcli.batch.inputs import GLOB_CHARS

        if GLOB_CHARS & set(f):
            return True
    if output is not None:
        from lcpcli.batch.output import is_batch_output

        if is_batch_output(output):
            return True
    return problem is None and binary and _holds_several_problems(f)


def _holds_several_problems(path: str) -> bool:
    """An HDF5 file with more than one problem group (errors: False, the solve reports them)."""
    from lcpcli.io import detect_format, list_problems

    try:
        return detect_format(path) == "hdf5" and Path(path).is_file() \
            and len(list_problems(path)) > 1
    except ProblemError:
        return False


def run_batch_command(files: list[str], *, method: str, tol: float | None,
                      opts: dict[str, Any], problem: str | None, as_json: bool,
                      output: Any, recursive: bool, jobs: int | None, resume: bool,
                      timeout: float | None, quiet: bool, scheduler: str | None,
                      warm: str | None = None) -> int:
    """Run the batch, show progress and the summary; return the exit code (0/1/2; 129, 130
    or 143 when stopped)."""
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.core.result import Status  # imports numpy: not at --help time

    if problem is not None:
        raise OptionError("--problem picks one problem of one HDF5 file; a batch solves every "
                          "problem of each file")
    if "-" in files:
        raise OptionError("'-' (stdin) cannot be part of a batch")
    if resume and output is None:
        raise OptionError("--resume needs --output (the file whose finished problems are "
                          "skipped)")
    stream_rows = as_json and output is None
    show_bar = not quiet and progress_allowed()
    progress = None
    state: dict[str, Any] = {"task": None, "counts": {}, "total": 0, "done": 0, "start": 0.0,
                             "estimated": False, "rows": []}

    def on_start(total: int, skipped: int) -> None:
        state["total"], state["done"] = total, skipped
        state["start"] = time.perf_counter()
        if progress is not None:
            state["task"] = progress.add_task("solving", total=total, completed=skipped,
                                              counts="")

    def on_row(row: dict[str, Any]) -> None:
        if stream_rows:
            write_json_line(row)
        state["done"] += 1
        if len(state["rows"]) <= FEW_PROBLEMS:
            state["rows"].append({k: row.get(k) for k in
                                  ("source", "problem", "status", "method", "n", "iterations",
                                   "error", "message")})
        _maybe_estimate(state, quiet)
        if progress is not None and state["task"] is not None:
            c = state["counts"]
            status = row.get("status", Status.ERROR)
            bucket = "failed" if status == Status.ERROR else (
                "solved" if status == Status.SOLVED else "unsolved")
            c[bucket] = c.get(bucket, 0) + 1
            progress.update(state["task"], advance=1,
                            counts=f"solved {c.get('solved', 0)}  unsolved "
                                   f"{c.get('unsolved', 0)}  failed {c.get('failed', 0)}")

    def on_progress(count: int, counts: dict[str, int]) -> None:
        state["done"] += count
        _maybe_estimate(state, quiet)
        if progress is not None and state["task"] is not None:
            failed = counts.get(Status.ERROR, 0)
            solved = counts.get(Status.SOLVED, 0)
            unsolved = sum(counts.values()) - failed - solved
            progress.update(state["task"], advance=count,
                            counts=f"solved {solved}  unsolved {unsolved}  failed {failed}")

    from lcpcli.io.stack import is_stack

    # stacks: rows only for the --json stream (building them costs more than solving)
    stacked = any(is_stack(f) for f in files)
    row_sink = (write_json_line if stream_rows else None) if stacked else on_row
    kept = False  # a new batch over a previous result file replaces it only once complete
    if output is not None and not stacked:
        from lcpcli.batch.output import replaced_when_complete

        kept = replaced_when_complete(output, resume)
    if show_bar:
        from lcpcli.cli.render.batch import make_progress

        progress = make_progress(stderr_console())
    installed = install_stop_handlers() if _main_thread() else []  # (main: already there)
    report = None
    try:
        if progress is not None:
            progress.start()
        report = run_batch(files, SolveOptions(method=method, tol=tol, options=dict(opts),
                                               warm=warm),
                           recursive=recursive, jobs=jobs, timeout=timeout, output=output,
                           resume=resume, scheduler=scheduler, on_start=on_start,
                           on_row=row_sink, on_progress=on_progress)
    except KeyboardInterrupt as exc:
        if progress is not None:
            progress.stop()
        what = stopped_word(exc)
        done = f" after {plural(state['done'], 'problem')} of {state['total']:,}" \
            if state["total"] else ""
        where = f"; finished results are in {output}: run again with --resume to go on" \
            if output is not None and os.path.lexists(output) else ""
        if output is not None and not where:  # stopped before the file was made
            where = f"; nothing was written to {output}"
        if kept:
            where = f"; {output} is kept as it was (a new batch replaces it only when complete)"
        say_stopped(f"lcpcli: {what}{done}{where}")
        return stopped_code(exc)
    finally:
        if progress is not None:
            progress.stop()
        restore_handlers(installed)
    code = pending_exit(report.exit_code)
    if as_json:
        if not stream_rows:
            write_json_line(report.as_dict())
    else:
        from lcpcli.cli.render.batch import render_summary

        rows = state["rows"] if report.total <= FEW_PROBLEMS and not report.skipped else None
        stdout_console().print(render_summary(report, rows=rows))
    return code


def _maybe_estimate(state: dict[str, Any], quiet: bool) -> None:
    """Say how long a long batch will take (stderr), from the rate measured after start-up.

    The clock starts at the first finished problem (worker start-up and imports come before
    it, and a rate that includes them overstates the time left many times over); the rate is
    then measured over at least :data:`ESTIMATE_MIN_SECONDS` and :data:`ESTIMATE_MIN_PROBLEMS`
    further problems, and the notice is shown once, only when the rest takes longer than
    :data:`ESTIMATE_AFTER_SECONDS` at that rate.  A small batch gets no estimate.
    """
    if state["estimated"] or quiet:
        return
    now = time.perf_counter()
    done, total = state["done"], state["total"]
    if done == 0 or done >= total:
        return
    if state.get("first_at") is None:  # the first result: start-up is over
        state["first_at"], state["first_done"] = now, done
        return
    measured = done - state["first_done"]
    elapsed = now - state["first_at"]
    if elapsed < ESTIMATE_MIN_SECONDS or measured < ESTIMATE_MIN_PROBLEMS:
        return
    state["estimated"] = True
    rate = measured / elapsed
    left = (total - done) / rate
    if left > ESTIMATE_AFTER_SECONDS:
        sys.stderr.write(f"lcpcli: {plural(total, 'problem')}; about {duration(left)} to go "
                         f"at {rate:,.1f} problems per second (Ctrl-C stops and keeps what is "
                         f"finished)\n")


def _main_thread() -> bool:

    return threading.current_thread() is threading.main_thread() and os.name == "posix"
