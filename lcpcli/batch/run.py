"""One batch from start to end: expand inputs, resume, solve (locally or on Dask), write rows."""

from __future__ import annotations

import contextlib
import math
import os
import signal
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from lcpcli.batch import output as batch_output
from lcpcli.batch.cluster import iter_dask
from lcpcli.batch.inputs import expand_inputs
from lcpcli.batch.pool import MAX_WORKERS_PER_CORE, early_workers, iter_local_groups, worker_limit
from lcpcli.batch.records import (
    SolveOptions,
    key,
    no_fingerprints,
    other_data,
    other_settings,
)
from lcpcli.batch.report import BatchReport, BatchStats, Tally
from lcpcli.batch.worker import prepare_method
from lcpcli.core.errors import STOP_SIGNALS, OptionError, ProblemError
from lcpcli.io import check_output, output_lock


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold the stop signals (SIGINT, SIGTERM, SIGHUP: :data:`STOP_SIGNALS`) while a result is
    being written (delivered right after; an ignored one stays ignored).

    A write is then never cut in the middle by Ctrl-C, ``kill`` or a closed terminal: the
    journal line and the HDF5 group of a row are written together or not at all.  The
    holding is done at the Python level (the handlers are swapped for one that only records
    the signal): blocking the signals in the main thread is not enough, because the kernel
    then delivers them to another thread (BLAS, OpenMP) and Python still runs the handler in
    the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []

    def hold(signum: int, frame: Any) -> None:
        pending.append(signum)

    held = [sig for sig in STOP_SIGNALS if signal.getsignal(sig) != signal.SIG_IGN]
    old = {sig: signal.signal(sig, hold) for sig in held}
    try:
        yield
    finally:
        for sig in held:
            signal.signal(sig, old[sig] if old[sig] is not None else signal.SIG_DFL)
        if pending:
            sig = pending[0]
            handler = old[sig]
            if callable(handler):
                handler(sig, None)  # e.g. KeyboardInterrupt, or the CLI's SIGTERM handler
            elif handler in (signal.SIG_DFL, None):
                os.kill(os.getpid(), sig)  # the default action, now that the write is done


def run_batch(inputs: Iterable[str], opts: SolveOptions, *, recursive: bool = False,
              jobs: int | None = None, timeout: float | None = None,
              output: str | os.PathLike[str] | None = None, resume: bool = False,
              scheduler: Any = None,
              on_start: Callable[[int, int], None] | None = None,
              on_row: Callable[[dict[str, Any]], None] | None = None,
              on_progress: Callable[[int, dict[str, int]], None] | None = None) -> BatchReport:
    """Expand ``inputs``, skip what ``output`` already holds (``resume``), solve the rest.

    Rows are written to ``output`` as they complete (see :mod:`lcpcli.batch.output`) and passed
    to ``on_row``; ``on_start(total, skipped)`` is called once the work is known.  Local worker
    processes (``jobs``, default the number of cores) unless ``scheduler`` (a Dask address or
    Client) is given.  On KeyboardInterrupt the output is closed cleanly, then it propagates.

    Stacked inputs (:mod:`lcpcli.io.stack`) are solved chunk by chunk in this process, the
    batched kernels running ``jobs`` threads (:mod:`lcpcli.batch.stacked`), or as Dask tasks
    with ``scheduler``; ``on_row`` then
    gets rows only when given, and ``on_progress(count, counts)`` follows each chunk.  A batch
    is either all stacks or no stack.
    """

    if timeout is not None and not (timeout > 0 and math.isfinite(timeout)):
        raise OptionError(f"--timeout must be a positive number of seconds, got {timeout}")
    if jobs is not None and jobs < 1:
        raise OptionError(f"--jobs must be at least 1, got {jobs}")
    if scheduler is not None and timeout:
        raise OptionError("--timeout is not available with --scheduler (a Dask worker cannot "
                          "stop a running problem); bound the work with --max-iter instead")
    jobs = jobs or os.cpu_count() or 1
    start = time.perf_counter()
    inputs = [str(i) for i in inputs]
    from lcpcli.batch.stacked import early_reads, memory_pool

    # a large stack's chunk buffers are faulted in by a thread while the rest starts up, and
    # (resuming nothing) the stack's first chunks read into them; the early reader starts the
    # buffers only for a stack that it cannot read in place
    memory = memory_pool(inputs, start=False) if scheduler is None else None
    early = early_reads(inputs, output, jobs, memory) \
        if scheduler is None and not resume and opts.warm is None else None
    if memory is not None and early is None:
        memory.start()
    try:
        return _run_batch(inputs, opts, recursive=recursive, jobs=jobs, timeout=timeout,
                          output=output, resume=resume, scheduler=scheduler,
                          on_start=on_start, on_row=on_row, on_progress=on_progress,
                          start=start, memory=memory, early=early)
    finally:
        if early is not None:
            early.close()  # unused (another input, an error before), or done with


def _run_batch(inputs: list[str], opts: SolveOptions, *, recursive: bool, jobs: int,
               timeout: float | None, output: Any, resume: bool, scheduler: Any,
               on_start: Any, on_row: Any, on_progress: Any, start: float,
               memory: Any, early: Any = None) -> BatchReport:
    """:func:`run_batch` once its clock, memory pool and early reads
    (:func:`lcpcli.batch.stacked.early_reads`) are started."""
    from lcpcli.solvers.request import method_of, resolve_tol

    spec = method_of(opts.method)  # unknown method or bad tol: OptionError before any work
    canonical = spec.name
    resolve_tol(spec, opts.tol)
    opts = SolveOptions(canonical, opts.tol, dict(opts.options), opts.warm)
    stacked = _stacked_inputs(inputs, timeout=timeout)
    if opts.warm is not None and not stacked:
        raise OptionError(f"--z0 {opts.warm}: a stacked result file warm-starts a stacked "
                          f"input; give a vector (or a --json result) for other problems")
    if output is not None:
        batch_output.output_kind(output)
        # a link, a device, a directory or an input (the --z0 file included): refused
        check_output(output, inputs=inputs if opts.warm is None else [*inputs, opts.warm])
    if stacked:
        return _run_stacked(inputs, opts, output=output, resume=resume, threads=jobs,
                            start=start, on_start=on_start, on_row=on_row,
                            on_progress=on_progress, scheduler=scheduler, memory=memory,
                            early=early)
    if output is not None and batch_output.output_kind(output) == "npz":
        raise OptionError(f"--output {output}: an .npz result file is written for stacked "
                          f"inputs only (see docs/batch.md); use {batch_output.suffixes()}")
    prepare_method(canonical)
    if scheduler is None and jobs > worker_limit():
        warnings.warn(f"--jobs {jobs}: at most {worker_limit()} worker processes are started "
                      f"({MAX_WORKERS_PER_CORE} per core: more only cost memory)", stacklevel=2)
    with contextlib.ExitStack() as held:
        # local workers start while the inputs are listed (a few tenths of a second)
        started = [] if scheduler is not None else \
            held.enter_context(early_workers(opts, jobs, timeout))
        identities: dict[str, tuple[int, int]] = {}
        tasks, bad_inputs = expand_inputs(inputs, recursive=recursive, identities=identities)
        if output is not None:  # never read our own result file back as an input
            own = _identity(output)
            if own is not None and any(identities.get(t.source) == own for t in tasks):

                raise ProblemError("holds problems of this batch (it was found among the "
                                   "inputs): choose another output file", str(output))
            bad_inputs = [r for r in bad_inputs if _identity(r["source"]) != own or own is None]
        tally, stats = Tally(), BatchStats()
        report = BatchReport(tally=tally, stats=stats, total=len(tasks) + len(bad_inputs),
                             output=None if output is None else str(output))
        if output is not None:

            held.enter_context(output_lock(output))  # a second writer is refused here
        return _run(tasks, bad_inputs, opts, report, output=output, resume=resume,
                    scheduler=scheduler, jobs=jobs, timeout=timeout, start=start,
                    on_start=on_start, on_row=on_row, started=started)


def _stacked_inputs(inputs: list[str], *, timeout: float | None) -> bool:
    """Whether this is a batch of stacked files (all of them; a mix is refused)."""
    from lcpcli.io.stack import is_stack

    flags = [is_stack(i) for i in inputs]
    if not any(flags):
        return False
    if not all(flags):
        first = inputs[flags.index(True)]
        raise OptionError(f"{first} is a stacked file: a batch of stacks takes stacked files "
                          f"only (convert the others with 'lcpcli convert DIR OUT.h5 --stack')")
    if timeout is not None:
        raise OptionError("--timeout does not apply to stacked inputs (their chunks are solved "
                          "by compiled threads); bound the work with --max-iter")
    return True


def _run_stacked(inputs: list[str], opts: SolveOptions, *, output: Any, resume: bool,
                 threads: int, start: float, on_start: Any, on_row: Any,
                 on_progress: Any, scheduler: Any = None, memory: Any = None,
                 early: Any = None) -> BatchReport:
    """A batch of stacked files (see :mod:`lcpcli.batch.stacked`), output locked."""
    from lcpcli.batch.stacked import run_stacks

    report = BatchReport(tally=Tally(), stats=BatchStats(), total=0,
                         output=None if output is None else str(output))

    def write(fn: Callable[[], None]) -> None:
        t0 = time.perf_counter()
        with signals_deferred():
            fn()
        report.stats.write_seconds += time.perf_counter() - t0

    with contextlib.ExitStack() as held:
        if output is not None:

            held.enter_context(output_lock(output))
        report.setup_seconds = time.perf_counter() - start
        try:
            run_stacks(inputs, opts, report, output=output, resume=resume, threads=threads,
                       on_start=on_start, on_progress=on_progress, on_row=on_row, write=write,
                       scheduler=scheduler, memory=memory, early_reads=early)
        except KeyboardInterrupt:
            report.interrupted = True
            raise
        finally:
            report.wall_seconds = time.perf_counter() - start
    return report


def _check_fingerprint(row: dict[str, Any], now: str | None, options: str, output: Any
                       ) -> None:
    """Refuse to resume from a row computed from other content than its source has now or
    with other solve options (``options``: this run's fingerprint of them), or from a row
    without these fingerprints (written by an older lcpcli)."""
    INPUT_HASH, SOLVE_OPTIONS = batch_output.INPUT_HASH, batch_output.SOLVE_OPTIONS
    source = str(row.get("source"))
    if INPUT_HASH not in row or SOLVE_OPTIONS not in row:
        raise no_fingerprints(output, source)
    if row[INPUT_HASH] != now:
        raise other_data(output, source)
    if row[SOLVE_OPTIONS] != options:
        raise other_settings(output, source, str(row[SOLVE_OPTIONS]), options)


def _identity(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """(device, inode) of an existing file, else None."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _one_by_one(rows: Iterator[dict[str, Any]]
                ) -> Iterator[list[tuple[dict[str, Any], dict[str, Any]]]]:
    """Rows as groups of one ``(row, timings)`` pair (timings already counted), the source
    closed with this generator."""
    try:
        for row in rows:
            yield [(row, {})]
    finally:
        rows.close()  # type: ignore[attr-defined]


def _run(tasks: list[Any], bad_inputs: list[dict[str, Any]], opts: SolveOptions,
         report: BatchReport, *, output: Any, resume: bool, scheduler: Any, jobs: int,
         timeout: float | None, start: float,
         on_start: Callable[[int, int], None] | None,
         on_row: Callable[[dict[str, Any]], None] | None,
         started: list[Any] | None = None) -> BatchReport:
    """The batch once the output (if any) is locked: resume, solve, write rows (``started``:
    local workers already started, :func:`lcpcli.batch.pool.early_workers`)."""
    tally, stats = report.tally, report.stats
    writer = None
    fingerprints: dict[str, str | None] = {}

    def fingerprint(source: str) -> str | None:
        """The input_hash of a source file (computed once per file)."""
        if source not in fingerprints:
            fingerprints[source] = batch_output.input_fingerprint(source)
        return fingerprints[source]

    from lcpcli.batch.stack_output import options_fingerprint

    options = options_fingerprint(opts)
    if output is not None:
        if resume:
            wanted = {(t.source, t.problem) for t in tasks} | {key(r) for r in bad_inputs}
            for row in batch_output.read_rows(output):  # links refused, never followed
                k = key(row)
                if k in wanted:
                    _check_fingerprint(row, fingerprint(k[0]), options, output)
                    wanted.discard(k)  # a duplicate line counts once
                    tally.add(row)
                    report.skipped += 1
            done = {(t.source, t.problem) for t in tasks} | {key(r) for r in bad_inputs}
            done -= wanted
            tasks = [t for t in tasks if (t.source, t.problem) not in done]
            bad_inputs = [r for r in bad_inputs if key(r) not in done]
        # a new batch replaces a previous result file only once complete
        writer = batch_output.open_writer(output, resume=resume, keep_previous=True)
    report.setup_seconds = time.perf_counter() - start
    if on_start:
        on_start(report.total, report.skipped)

    def emit(pairs: list[tuple[dict[str, Any], dict[str, Any]]]) -> None:
        """Write rows that arrived together in one write; ``input_hash`` as the worker hashed
        the bytes it parsed, else from the file."""
        for _row, timing in pairs:
            stats.add(timing)
        if writer is not None:
            t0 = time.perf_counter()
            stamped = [{**row, batch_output.INPUT_HASH: timing.get("digest")
                        or fingerprint(str(row.get("source", ""))),
                        batch_output.SOLVE_OPTIONS: options} for row, timing in pairs]
            with signals_deferred():
                writer.write(stamped)
            stats.write_seconds += time.perf_counter() - t0
        for row, _timing in pairs:
            tally.add(row)
            report.new += 1
            if on_row:
                on_row(row)

    complete = False
    try:
        if bad_inputs:
            emit([(row, {}) for row in bad_inputs])
        if scheduler is not None:
            groups: Any = _one_by_one(iter_dask(tasks, opts, scheduler, on_timing=stats.add))
        else:
            groups = iter_local_groups(tasks, opts, jobs=jobs, timeout=timeout,
                                       started=started)
        try:
            for pairs in groups:
                emit(pairs)
        finally:
            groups.close()
        complete = True
    except KeyboardInterrupt:
        report.interrupted = True
        raise
    finally:
        if writer is not None:
            t0 = time.perf_counter()
            with signals_deferred():
                writer.close(complete=complete)
            stats.write_seconds += time.perf_counter() - t0
        report.wall_seconds = time.perf_counter() - start
    return report
