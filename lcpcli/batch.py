"""Batch solving: many problem files, in parallel worker processes or on a Dask cluster.

The pieces, each usable on its own:

* :func:`expand_inputs` turns command-line inputs (files, folders, globs, multi-problem HDF5
  files) into :class:`Task` records ``(source, problem)``; inputs that cannot even be listed
  become ready-made ``error`` rows.
* :func:`solve_tasks` reads and solves a list of tasks in the current process (HDF5 files are
  opened once per run of consecutive tasks from the same file) and yields result rows.
* :func:`iter_local` runs :func:`solve_tasks` in ``jobs`` worker processes of its own pool:
  chunks are handed out on demand, a worker that exceeds the per-problem ``timeout`` is killed
  and replaced (the problem is recorded as ``unsolved`` with message ``timeout``), a worker that
  dies (segfault, out of memory) costs only its current problem (status ``error``).
* :func:`iter_dask` runs the same chunks on a ``dask.distributed`` cluster.

A **row** is the ``lcpcli solve --json`` object (:meth:`lcpcli.result.Result.to_dict`) plus
``source`` (the file, as given or found) and ``problem`` (the HDF5 group, or the file's stem for
one-problem files); the pair is the row's :func:`key`, which ``--resume`` uses.  Rows of inputs
that could not be read have ``status = "error"``, ``termination = "error"``, ``n = None``, empty
``z``/``w``, ``certificate = None`` and the one-line reason in ``message``.
"""

from __future__ import annotations

import contextlib
import glob
import math
import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from lcpcli.errors import LcpError, ProblemError

#: Status of a row whose input could not be read or solved at all (not a solver verdict).
ERROR = "error"
#: ``message`` and ``termination`` of a problem stopped by ``--timeout``.
TIMEOUT = "timeout"
#: File extensions picked up when a folder is given.
PROBLEM_EXTENSIONS = (".json", ".npz", ".h5", ".hdf5", ".hdf", ".dat")
_GLOB_CHARS = set("*?[")


@dataclass(frozen=True)
class Task:
    """One problem to solve: the file and the problem's name in it."""

    source: str
    problem: str
    hdf5: bool = False


@dataclass(frozen=True)
class SolveOptions:
    """What every problem of a batch is solved with (picklable, sent to the workers)."""

    method: str = "auto"  # = lcpcli.api.DEFAULT_METHOD
    tol: float | None = None
    options: dict[str, Any] = field(default_factory=dict)


@dataclass
class BatchStats:
    """Where the time went, summed over problems (worker seconds, not wall time)."""

    read_seconds: float = 0.0
    solve_seconds: float = 0.0   # lcpcli.solve: method + certificate + result dict
    method_seconds: float = 0.0  # the method alone (the rows' ``seconds``)
    write_seconds: float = 0.0   # the client writing the output (wall)
    problems: int = 0

    def add(self, other: dict[str, float]) -> None:
        self.read_seconds += other.get("read", 0.0)
        self.solve_seconds += other.get("solve", 0.0)
        self.method_seconds += other.get("method", 0.0)
        self.problems += int(other.get("problems", 0))

    def as_dict(self) -> dict[str, float]:
        return {"read_seconds": self.read_seconds, "solve_seconds": self.solve_seconds,
                "method_seconds": self.method_seconds, "write_seconds": self.write_seconds,
                "problems": self.problems}


def key(row: dict[str, Any]) -> tuple[str, str]:
    """The identity of a row: ``(source, problem)``."""
    return (str(row.get("source", "")), str(row.get("problem", "")))


def error_row(source: str, problem: str, message: str, method: str = "",
              *, status: str = ERROR, termination: str = ERROR,
              seconds: float = 0.0) -> dict[str, Any]:
    """A row for a problem that produced no solution at all (bad input, crash, timeout)."""
    return {"file": source, "status": status, "method": method, "n": None, "z": [], "w": [],
            "iterations": 0, "seconds": float(seconds), "residual": None, "error": None,
            "message": " ".join(str(message).split()), "problem": problem,
            "termination": termination, "certificate": None, "source": source}


def timeout_row(task: Task, seconds: float, method: str) -> dict[str, Any]:
    """The row of a problem stopped by the per-problem time limit."""
    return error_row(task.source, task.problem, TIMEOUT, method, status="unsolved",
                     termination=TIMEOUT, seconds=seconds)


# ----------------------------------------------------------------------------- inputs
def expand_inputs(inputs: Iterable[str], *, recursive: bool = False,
                  ) -> tuple[list[Task], list[dict[str, Any]]]:
    """Files, folders and globs -> tasks (in a stable order) and error rows for bad inputs.

    A folder contributes its problem files (by extension; sub-folders with ``recursive``); a
    glob is expanded (``**`` crosses folders with ``recursive``); an HDF5 file contributes one
    task per problem group.  Duplicates (the same file reached twice) are dropped.
    """
    from lcpcli.io import detect_format, list_problems

    tasks: list[Task] = []
    errors: list[dict[str, Any]] = []
    seen: set[str] = set()

    def add_file(path: str) -> None:
        path = os.path.normpath(path)
        if path in seen:
            return
        seen.add(path)
        try:
            fmt = detect_format(path)
        except ProblemError as exc:
            errors.append(error_row(path, Path(path).stem, str(exc.with_source(path))))
            return
        if fmt != "hdf5":
            tasks.append(Task(path, Path(path).stem))
            return
        if not Path(path).is_file():
            errors.append(error_row(path, Path(path).stem, f"{path}: no such file"))
            return
        try:
            names = _hdf5_problem_names(path)
            if names is None:
                names = list_problems(path)
        except (ProblemError, OSError) as exc:
            msg = str(exc) if isinstance(exc, ProblemError) else f"{path}: {exc}"
            errors.append(error_row(path, Path(path).stem, msg))
            return
        if not names:
            errors.append(error_row(path, Path(path).stem,
                                    f"{path}: no problem found (expected datasets M and q "
                                    f"at the root or in groups)"))
        tasks.extend(Task(path, name, hdf5=True) for name in names)

    for item in inputs:
        item = str(item)
        p = Path(item)
        if p.is_dir():
            walker = p.rglob("*") if recursive else p.glob("*")
            found = sorted(str(f) for f in walker
                           if f.is_file() and f.suffix.lower() in PROBLEM_EXTENSIONS)
            for f in found:
                add_file(f)
        elif not p.exists() and _GLOB_CHARS & set(item):
            matches = sorted(m for m in glob.glob(item, recursive=recursive)
                             if Path(m).is_file())
            if not matches:
                errors.append(error_row(item, "", f"{item}: no file matches this pattern"))
            for m in matches:
                add_file(m)
        else:
            add_file(item)
    return tasks, errors


def _hdf5_problem_names(path: str) -> list[str] | None:
    """The problem groups of an HDF5 file in one pass over its links (fast for 10^4+ groups).

    Same answer as :func:`lcpcli.io.list_problems` (groups holding ``M`` and ``q``, in the
    file's order); None when the file has a root problem or anything goes wrong, and the
    caller then asks ``list_problems``.
    """
    try:
        import h5py

        children: list[bytes] = []
        parts: dict[bytes, set[bytes]] = {}

        def visit(name: bytes) -> None:
            head, sep, tail = name.partition(b"/")
            if not sep:
                children.append(head)
            elif tail in (b"M", b"q"):
                parts.setdefault(head, set()).add(tail)

        with h5py.File(path, "r") as f:
            f.id.links.visit(visit)
        if b"M" in children and b"q" in children:
            return None  # a root problem: let list_problems name it
        return [c.decode() for c in children if len(parts.get(c, ())) == 2]
    except Exception:  # noqa: BLE001 - the general lister reports the error properly
        return None


def make_chunks(tasks: list[Task], jobs: int, *, max_chunk: int = 256) -> list[list[Task]]:
    """Split tasks into chunks: big enough to amortise messages, small enough to balance.

    Consecutive tasks stay together, so a chunk of an HDF5 file opens that file once.
    """
    if not tasks:
        return []
    size = max(1, min(max_chunk, len(tasks) // max(1, 4 * jobs)))
    return [tasks[i:i + size] for i in range(0, len(tasks), size)]


# ----------------------------------------------------------------------------- solving
def _load_runs(tasks: list[Task]) -> Iterator[tuple[Task, Any, float]]:
    """Yield ``(task, Problem or ProblemError, read seconds)``; HDF5 files opened once per run."""
    from lcpcli.io import load

    i = 0
    while i < len(tasks):
        task = tasks[i]
        if task.hdf5:
            j = i
            while j < len(tasks) and tasks[j].source == task.source and tasks[j].hdf5:
                j += 1
            from lcpcli.io.hdf5_format import read_many

            run = tasks[i:j]
            start = time.perf_counter()
            gen = read_many(Path(task.source), [t.problem for t in run])
            for t in run:
                try:
                    _name, item = next(gen)
                except StopIteration:  # pragma: no cover - read_many yields one per name
                    item = ProblemError("not read")
                except Exception as exc:  # noqa: BLE001 - a broken file must not stop the batch
                    item = ProblemError(f"unreadable HDF5 file ({type(exc).__name__}: {exc})")
                if isinstance(item, ProblemError):
                    item = item.with_source(t.source)
                now = time.perf_counter()
                yield t, item, now - start
                start = time.perf_counter()
            gen.close()
            i = j
        else:
            start = time.perf_counter()
            try:
                item: Any = load(task.source)
            except ProblemError as exc:
                item = exc
            except Exception as exc:  # noqa: BLE001
                item = ProblemError(f"unreadable ({type(exc).__name__}: {exc})", task.source)
            yield task, item, time.perf_counter() - start
            i += 1


def solve_tasks(tasks: list[Task], opts: SolveOptions,
                ) -> Iterator[tuple[dict[str, Any], dict[str, float]]]:
    """Read and solve ``tasks`` here; yield ``(row, timings)`` per task, never raising for data.

    ``timings`` has ``read``, ``solve`` (lcpcli.solve plus the row) and ``method`` seconds.
    """
    from lcpcli.api import solve

    for task, item, t_read in _load_runs(tasks):
        timing = {"read": t_read, "solve": 0.0, "method": 0.0, "problems": 1}
        if isinstance(item, ProblemError):
            yield error_row(task.source, task.problem, str(item), opts.method), timing
            continue
        start = time.perf_counter()
        try:
            result = solve(item, opts.method, tol=opts.tol, **opts.options)
            row = result.to_dict(file=task.source)
            timing["method"] = result.seconds
        except LcpError as exc:
            row = error_row(task.source, task.problem, f"{task.source}: {exc}", opts.method)
        except Exception as exc:  # noqa: BLE001 - a solver bug must not stop the batch
            row = error_row(task.source, task.problem,
                            f"{task.source}: internal error: {type(exc).__name__}: {exc}",
                            opts.method)
        row["problem"] = task.problem
        row["source"] = task.source
        timing["solve"] = time.perf_counter() - start
        yield row, timing


def prepare_method(method: str) -> None:
    """Load the method's compiled kernel (outside any timing); unknown methods raise."""
    from lcpcli.solvers import get_method

    spec = get_method(method)
    if spec.prepare is not None:
        spec.prepare()


# ----------------------------------------------------------------------------- local pool
def _worker_main(conn: Any, opts: SolveOptions) -> None:
    """Worker process: receive chunks, send one message per solved problem."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    _die_with_parent()
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    with contextlib.suppress(Exception):  # the problems will report the error one by one
        prepare_method(opts.method)
    conn.send(("ready",))
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        chunk_id, tasks = msg
        for row, timing in solve_tasks(tasks, opts):
            conn.send(("row", chunk_id, row, timing))
        conn.send(("done", chunk_id))


def _die_with_parent() -> None:
    """Linux: have the kernel kill this worker when the parent dies (even by ``kill -9``)."""
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(Exception):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG


class _Worker:
    def __init__(self, ctx: Any, opts: SolveOptions) -> None:
        parent, child = ctx.Pipe(duplex=True)
        self.conn = parent
        self.proc = ctx.Process(target=_worker_main, args=(child, opts), daemon=True)
        self.proc.start()
        child.close()
        self.ready = False
        self.chunk: list[Task] | None = None
        self.chunk_id = -1
        self.received = 0
        self.last = time.monotonic()

    @property
    def busy(self) -> bool:
        return self.chunk is not None

    def assign(self, chunk_id: int, chunk: list[Task]) -> None:
        self.chunk, self.chunk_id, self.received = chunk, chunk_id, 0
        self.last = time.monotonic()
        self.conn.send((chunk_id, chunk))

    def remaining(self, skip_current: bool) -> list[Task]:
        if self.chunk is None:
            return []
        return self.chunk[self.received + (1 if skip_current else 0):]

    def current(self) -> Task | None:
        if self.chunk is None or self.received >= len(self.chunk):
            return None
        return self.chunk[self.received]

    def stop(self, kill: bool = False) -> None:
        if self.proc.is_alive():
            if kill:
                self.proc.kill()
            else:
                with contextlib.suppress(OSError):
                    self.conn.send(None)
        self.proc.join(timeout=0 if kill else 2)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(timeout=5)
        self.conn.close()


def _mp_context() -> Any:
    import multiprocessing as mp

    # fork is fast (the parent has numpy and the kernel loaded) and safe here: workers only
    # compute and talk over their pipe.  Elsewhere use spawn.
    if sys.platform.startswith("linux"):
        return mp.get_context("fork")
    return mp.get_context("spawn")


def iter_local(tasks: list[Task], opts: SolveOptions, *, jobs: int = 1,
               timeout: float | None = None,
               on_timing: Callable[[dict[str, float]], None] | None = None,
               ) -> Iterator[dict[str, Any]]:
    """Solve ``tasks`` in ``jobs`` worker processes; yield rows as they complete.

    Without a timeout and with one job, everything runs in this process.  With a ``timeout``
    (seconds per problem, reading included) a worker that runs over is killed, its problem
    recorded as ``unsolved``/``timeout`` and a fresh worker takes the rest of its chunk.
    Closing the generator (or an exception in the caller) stops every worker.
    """
    if not tasks:
        return
    if jobs <= 1 and not timeout:
        prepare_method(opts.method)
        for row, timing in solve_tasks(tasks, opts):
            if on_timing:
                on_timing(timing)
            yield row
        return
    from multiprocessing.connection import wait

    with contextlib.suppress(Exception):  # load once in the parent: forked workers inherit
        prepare_method(opts.method)
    ctx = _mp_context()
    pending: deque[tuple[int, list[Task]]] = deque(enumerate(make_chunks(tasks, jobs)))
    next_id = len(pending)
    n_workers = max(1, min(jobs, len(pending)))
    workers = [_Worker(ctx, opts) for _ in range(n_workers)]
    failed_starts = 0
    try:
        while pending or any(w.busy for w in workers):
            for w in workers:
                if w.ready and not w.busy and pending:
                    cid, chunk = pending.popleft()
                    w.assign(cid, chunk)
            now = time.monotonic()
            wait_for = 0.5
            if timeout:
                deadlines = [w.last + timeout - now for w in workers if w.busy]
                if deadlines:
                    wait_for = max(0.0, min(wait_for, min(deadlines)))
            ready = wait([w.conn for w in workers] + [w.proc.sentinel for w in workers],
                         timeout=wait_for)
            ready_set = set(ready)
            replace: list[tuple[_Worker, dict[str, Any] | None]] = []
            for w in workers:
                dead = False
                if w.conn in ready_set or w.proc.sentinel in ready_set:
                    alive_before = w.proc.is_alive()
                    try:
                        while w.conn.poll():
                            msg = w.conn.recv()
                            if msg[0] == "ready":
                                w.ready = True
                            elif msg[0] == "row" and msg[1] == w.chunk_id:
                                w.received += 1
                                w.last = time.monotonic()
                                if on_timing:
                                    on_timing(msg[3])
                                yield msg[2]
                            elif msg[0] == "done" and msg[1] == w.chunk_id:
                                w.chunk, w.chunk_id = None, -1
                    except (EOFError, OSError):
                        dead = True
                    if not alive_before:
                        dead = True
                if dead:
                    if not w.ready:
                        failed_starts += 1
                        if failed_starts > 2 * jobs + 2:
                            raise RuntimeError("worker processes die at start-up "
                                               f"(exit code {w.proc.exitcode})")
                    task = w.current()
                    row = None
                    if task is not None:
                        row = error_row(task.source, task.problem,
                                        f"{task.source}: worker process died while solving "
                                        f"this problem (exit code {w.proc.exitcode})",
                                        opts.method)
                    replace.append((w, row))
                elif timeout and w.busy and time.monotonic() - w.last > timeout \
                        and not w.conn.poll():  # unread rows: it is not stuck, we were busy
                    task = w.current()
                    row = timeout_row(task, timeout, opts.method) if task else None
                    replace.append((w, row))
            for w, row in replace:
                rest = w.remaining(skip_current=True)
                w.stop(kill=True)
                if rest:
                    pending.appendleft((next_id, rest))
                    next_id += 1
                workers[workers.index(w)] = _Worker(ctx, opts)
                if row is not None:
                    yield row
    finally:
        for w in workers:
            w.stop(kill=not w.ready or w.busy)


# ----------------------------------------------------------------------------- dask
def _dask_chunk(tasks: list[Task], opts: SolveOptions,
                ) -> tuple[list[dict[str, Any]], dict[str, float]]:
    """Run on a Dask worker: solve a chunk, return its rows and summed timings."""
    prepare_method(opts.method)
    rows: list[dict[str, Any]] = []
    total = {"read": 0.0, "solve": 0.0, "method": 0.0, "problems": 0}
    for row, timing in solve_tasks(tasks, opts):
        rows.append(row)
        for k in total:
            total[k] += timing.get(k, 0.0)
    return rows, total


def iter_dask(tasks: list[Task], opts: SolveOptions, address: Any, *,
              on_timing: Callable[[dict[str, float]], None] | None = None,
              chunk_size: int | None = None) -> Iterator[dict[str, Any]]:
    """Solve ``tasks`` on the ``dask.distributed`` cluster at ``address`` (or a Client).

    Chunks are submitted as Dask tasks; rows come back as chunks complete and are yielded here
    (the client writes the output, so output semantics are the same as locally).  The workers
    need ``lcpcli`` importable and the input files at the same paths.
    """
    if not tasks:
        return
    try:
        from distributed import Client
    except ImportError:
        from lcpcli.errors import OptionError

        raise OptionError("--scheduler needs dask.distributed: pip install 'lcpcli[dask]'") \
            from None
    own = not hasattr(address, "submit")
    if own:
        try:
            client = Client(address, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            from lcpcli.errors import OptionError

            raise OptionError(f"cannot reach the Dask scheduler at {address}: "
                              f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") \
                from None
    else:
        client = address
    try:
        with client.as_current():
            yield from _dask_rows(client, tasks, opts, on_timing, chunk_size)
    finally:
        if own:
            client.close()


def _dask_rows(client: Any, tasks: list[Task], opts: SolveOptions,
               on_timing: Callable[[dict[str, float]], None] | None,
               chunk_size: int | None) -> Iterator[dict[str, Any]]:
    from distributed import as_completed

    n_workers = max(1, len(client.scheduler_info().get("workers", {})) or 1)
    # Workers resolve paths in their own working directory: send absolute paths, and give
    # the rows back the paths as the user wrote them.
    given = {os.path.abspath(t.source): t.source for t in tasks}
    tasks = [Task(os.path.abspath(t.source), t.problem, t.hdf5) for t in tasks]
    if chunk_size:
        chunks = [tasks[i:i + chunk_size] for i in range(0, len(tasks), chunk_size)]
    else:
        chunks = make_chunks(tasks, n_workers, max_chunk=1024)
    futures = [client.submit(_dask_chunk, chunk, opts, pure=False) for chunk in chunks]
    index = {f.key: chunk for f, chunk in zip(futures, chunks, strict=True)}
    try:
        for fut in as_completed(futures):
            try:
                rows, timing = fut.result()
            except Exception as exc:  # noqa: BLE001 - a lost chunk is recorded, not fatal
                msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                rows = [error_row(t.source, t.problem,
                                  f"{t.source}: Dask task failed: {msg}", opts.method)
                        for t in index[fut.key]]
                timing = {}
            if on_timing and timing:
                on_timing(timing)
            for row in rows:
                absolute = row["source"]
                row["source"] = row["file"] = given.get(absolute, absolute)
                if row["source"] != absolute and row["message"].startswith(absolute):
                    row["message"] = row["source"] + row["message"][len(absolute):]
                yield row
            fut.release()
    finally:
        for f in futures:
            if not f.done():
                f.cancel()


# ----------------------------------------------------------------------------- orchestration
@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM while a result is being written (delivered right after).

    A write is then never cut in the middle by Ctrl-C or ``kill``: the journal line and the
    HDF5 group of a row are written together or not at all.
    """
    import threading

    if not hasattr(signal, "pthread_sigmask") or \
            threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@dataclass
class Tally:
    """Counts and extremes of a batch, kept small whatever the number of problems."""

    top: int = 5
    counts: dict[str, int] = field(default_factory=dict)
    slowest: list[tuple[float, str, str]] = field(default_factory=list)
    worst: list[tuple[float, str, str]] = field(default_factory=list)
    errors: list[tuple[str, str, str]] = field(default_factory=list)

    def add(self, row: dict[str, Any]) -> None:
        import heapq

        status = str(row.get("status", ERROR))
        self.counts[status] = self.counts.get(status, 0) + 1
        src, prob = key(row)
        seconds = row.get("seconds")
        if status != ERROR and isinstance(seconds, (int, float)):
            heapq.heappush(self.slowest, (float(seconds), src, prob))
            if len(self.slowest) > self.top:
                heapq.heappop(self.slowest)
        err = row.get("error")
        if status != ERROR and row.get("n") is not None:
            value = float("inf") if err is None else float(err)
            heapq.heappush(self.worst, (value, src, prob))
            if len(self.worst) > self.top:
                heapq.heappop(self.worst)
        if status == ERROR and len(self.errors) < self.top:
            self.errors.append((src, prob, str(row.get("message", ""))))

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def exit_code(self) -> int:
        """2 if some input was bad, else 1 if some problem was not solved, else 0."""
        from lcpcli.errors import EXIT_BAD_INPUT, EXIT_NOT_SOLVED, EXIT_SOLVED

        if self.counts.get(ERROR):
            return EXIT_BAD_INPUT
        if any(s != "solved" and c for s, c in self.counts.items()):
            return EXIT_NOT_SOLVED
        return EXIT_SOLVED

    def as_dict(self) -> dict[str, Any]:
        return {"total": self.total, "counts": dict(sorted(self.counts.items())),
                "slowest": [{"source": s, "problem": p, "seconds": t}
                            for t, s, p in sorted(self.slowest, reverse=True)],
                "worst": [{"source": s, "problem": p,
                           "error": e if e != float("inf") else None}
                          for e, s, p in sorted(self.worst, reverse=True)],
                "errors": [{"source": s, "problem": p, "message": m}
                           for s, p, m in self.errors]}


@dataclass
class BatchReport:
    """What :func:`run_batch` did: the tally (resumed rows included), timings and counts."""

    tally: Tally
    stats: BatchStats
    total: int = 0        # problems (and bad inputs) in this batch
    skipped: int = 0      # already in the output (--resume)
    new: int = 0          # rows produced by this run
    wall_seconds: float = 0.0
    setup_seconds: float = 0.0  # part of wall_seconds: listing inputs, loading the kernel
    output: str | None = None
    interrupted: bool = False

    @property
    def exit_code(self) -> int:
        return self.tally.exit_code()

    def as_dict(self) -> dict[str, Any]:
        return {"total": self.total, "skipped": self.skipped, "new": self.new,
                "wall_seconds": self.wall_seconds, "setup_seconds": self.setup_seconds,
                "output": self.output,
                "interrupted": self.interrupted, "exit_code": self.exit_code,
                "summary": self.tally.as_dict(), "timings": self.stats.as_dict()}


def run_batch(inputs: Iterable[str], opts: SolveOptions, *, recursive: bool = False,
              jobs: int | None = None, timeout: float | None = None,
              output: str | os.PathLike[str] | None = None, resume: bool = False,
              scheduler: Any = None,
              on_start: Callable[[int, int], None] | None = None,
              on_row: Callable[[dict[str, Any]], None] | None = None) -> BatchReport:
    """Expand ``inputs``, skip what ``output`` already holds (``resume``), solve the rest.

    Rows are written to ``output`` as they complete (see :mod:`lcpcli.batch_output`) and passed
    to ``on_row``; ``on_start(total, skipped)`` is called once the work is known.  Local worker
    processes (``jobs``, default the number of cores) unless ``scheduler`` (a Dask address or
    Client) is given.  On KeyboardInterrupt the output is closed cleanly, then it propagates.
    """
    from lcpcli.errors import OptionError

    if timeout is not None and not (timeout > 0 and math.isfinite(timeout)):
        raise OptionError(f"--timeout must be a positive number of seconds, got {timeout}")
    if jobs is not None and jobs < 1:
        raise OptionError(f"--jobs must be at least 1, got {jobs}")
    if scheduler is not None and timeout:
        raise OptionError("--timeout is not available with --scheduler (a Dask worker cannot "
                          "stop a running problem); bound the work with --max-iter instead")
    jobs = jobs or os.cpu_count() or 1
    start = time.perf_counter()
    from lcpcli.solvers import get_method

    canonical = get_method(opts.method).name  # unknown method: OptionError before any work
    opts = SolveOptions(canonical, opts.tol, dict(opts.options))
    prepare_method(canonical)
    tasks, bad_inputs = expand_inputs(inputs, recursive=recursive)
    if output is not None:  # never read our own result file back as an input
        own = os.path.realpath(output)
        tasks = [t for t in tasks if os.path.realpath(t.source) != own]
        bad_inputs = [r for r in bad_inputs if os.path.realpath(r["source"]) != own]
    tally, stats = Tally(), BatchStats()
    report = BatchReport(tally=tally, stats=stats, total=len(tasks) + len(bad_inputs),
                         output=None if output is None else str(output))
    writer = None
    if output is not None:
        from lcpcli import batch_output

        batch_output.output_kind(output)
        if resume and Path(output).exists() or resume and \
                batch_output.journal_path(Path(output)).exists():
            wanted = {(t.source, t.problem) for t in tasks} | {key(r) for r in bad_inputs}
            for row in batch_output.read_rows(output):
                k = key(row)
                if k in wanted:
                    wanted.discard(k)  # a duplicate line counts once
                    tally.add(row)
                    report.skipped += 1
            done = {(t.source, t.problem) for t in tasks} | {key(r) for r in bad_inputs}
            done -= wanted
            tasks = [t for t in tasks if (t.source, t.problem) not in done]
            bad_inputs = [r for r in bad_inputs if key(r) not in done]
        writer = batch_output.open_writer(output, resume=resume)
    report.setup_seconds = time.perf_counter() - start
    if on_start:
        on_start(report.total, report.skipped)

    def emit(row: dict[str, Any]) -> None:
        if writer is not None:
            t0 = time.perf_counter()
            with signals_deferred():
                writer.write([row])
            stats.write_seconds += time.perf_counter() - t0
        tally.add(row)
        report.new += 1
        if on_row:
            on_row(row)

    try:
        for row in bad_inputs:
            emit(row)
        if scheduler is not None:
            rows = iter_dask(tasks, opts, scheduler, on_timing=stats.add)
        else:
            rows = iter_local(tasks, opts, jobs=jobs, timeout=timeout, on_timing=stats.add)
        try:
            for row in rows:
                emit(row)
        finally:
            rows.close()
    except KeyboardInterrupt:
        report.interrupted = True
        raise
    finally:
        if writer is not None:
            t0 = time.perf_counter()
            with signals_deferred():
                writer.close()
            stats.write_seconds += time.perf_counter() - t0
        report.wall_seconds = time.perf_counter() - start
    return report
