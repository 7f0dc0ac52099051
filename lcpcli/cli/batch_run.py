"""The batch side of ``lcpcli solve``: many files, folders, globs, HDF5 files of many problems.

``solve_cmd`` calls :func:`wants_batch` and, when it says yes, hands everything to
:func:`run_batch_command`; the engine is :mod:`lcpcli.batch.run`, the files
:mod:`lcpcli.batch.output`, the tables :mod:`lcpcli.cli.render.batch`. Not a subcommand module (no
``register``).
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path
from typing import Any

from lcpcli.core.errors import EXIT_INTERRUPTED, EXIT_TERMINATED

_GLOB_CHARS = set("*?[")
_BATCH_SUFFIXES = (".jsonl", ".ndjson", ".csv", ".h5", ".hdf5")


def wants_batch(files: list[str], output: Any, *, recursive: bool = False,
                jobs: int | None = None, resume: bool = False, timeout: float | None = None,
                quiet: bool = False, scheduler: str | None = None) -> bool:
    """True unless this is the classic one-file solve (one FILE, no batch option).

    Batch mode: several FILEs, a folder, a glob, a batch option (--recursive, --jobs,
    --resume, --timeout, --quiet, --scheduler), or ``--output`` ending in .jsonl/.csv/.h5.
    """
    if len(files) != 1:
        return True
    if recursive or resume or quiet or jobs is not None or timeout is not None \
            or scheduler is not None:
        return True
    f = files[0]
    if f != "-" and (Path(f).is_dir() or (not Path(f).exists() and _GLOB_CHARS & set(f))):
        return True
    return output is not None and str(output).lower().endswith(_BATCH_SUFFIXES)


class _Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an interrupt so that the output file is closed cleanly."""


def _on_sigterm(signum: int, frame: Any) -> None:
    raise _Terminated()


def run_batch_command(files: list[str], *, method: str, tol: float | None,
                      opts: dict[str, Any], problem: str | None, as_json: bool,
                      output: Any, recursive: bool, jobs: int | None, resume: bool,
                      timeout: float | None, quiet: bool, scheduler: str | None) -> int:
    """Run the batch, show progress and the summary; return the exit code (0/1/2, 130)."""
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.cli.common import stderr_console, stdout_console, write_json_line
    from lcpcli.core.errors import OptionError
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
    err = stderr_console()
    show_bar = not quiet and err.is_terminal
    progress = None
    state: dict[str, Any] = {"task": None, "counts": {}}

    def on_start(total: int, skipped: int) -> None:
        if progress is not None:
            state["task"] = progress.add_task("solving", total=total, completed=skipped,
                                              counts="")

    def on_row(row: dict[str, Any]) -> None:
        if stream_rows:
            write_json_line(row)
        if progress is not None and state["task"] is not None:
            c = state["counts"]
            status = row.get("status", Status.ERROR)
            bucket = "failed" if status == Status.ERROR else (
                "solved" if status == Status.SOLVED else "unsolved")
            c[bucket] = c.get(bucket, 0) + 1
            progress.update(state["task"], advance=1,
                            counts=f"solved {c.get('solved', 0)}  unsolved "
                                   f"{c.get('unsolved', 0)}  failed {c.get('failed', 0)}")

    if show_bar:
        from lcpcli.cli.render.batch import make_progress

        progress = make_progress(err)
    old_term = signal.signal(signal.SIGTERM, _on_sigterm) \
        if _main_thread() else None
    report = None
    try:
        if progress is not None:
            progress.start()
        report = run_batch(files, SolveOptions(method=method, tol=tol, options=dict(opts)),
                           recursive=recursive, jobs=jobs, timeout=timeout, output=output,
                           resume=resume, scheduler=scheduler, on_start=on_start,
                           on_row=on_row)
    except KeyboardInterrupt as exc:
        if progress is not None:
            progress.stop()
        what = "terminated" if isinstance(exc, _Terminated) else "interrupted"
        where = f"; finished results are in {output}: run again with --resume to go on" \
            if output is not None else ""
        sys.stderr.write(f"lcpcli: {what}{where}\n")
        return EXIT_TERMINATED if isinstance(exc, _Terminated) else EXIT_INTERRUPTED
    finally:
        if progress is not None:
            progress.stop()
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    if as_json:
        if not stream_rows:
            write_json_line(report.as_dict())
    else:
        from lcpcli.cli.render.batch import render_summary

        stdout_console().print(render_summary(report))
    return report.exit_code


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread() and os.name == "posix"
