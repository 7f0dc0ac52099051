"""A pool of local worker processes for batch solving.

:func:`iter_local` runs :func:`lcpcli.batch.worker.solve_tasks` in ``jobs`` worker processes of its
own pool: chunks are handed out on demand, a worker that exceeds the per-problem ``timeout`` is
killed and replaced (the problem is recorded as ``unsolved`` with message ``timeout``), a worker
that dies (segfault, out of memory) costs only its current problem (status ``error``).
Workers are started by ``forkserver`` (``spawn`` where there is none), never by a bare
``fork``: see :func:`lcpcli.solvers.kernels.process_context`.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from lcpcli.batch import worker
from lcpcli.batch.records import SolveOptions, Task, error_row, timeout_row
from lcpcli.core.text import one_line_warnings
from lcpcli.solvers.kernels import process_context


def make_chunks(tasks: list[Task], jobs: int, *, max_chunk: int = 256) -> list[list[Task]]:
    """Split tasks into chunks: big enough to amortise messages, small enough to balance.

    Consecutive tasks stay together, so a chunk of an HDF5 file opens that file once.
    """
    if not tasks:
        return []
    size = max(1, min(max_chunk, len(tasks) // max(1, 4 * jobs)))
    return [tasks[i:i + size] for i in range(0, len(tasks), size)]


def _worker_main(conn: Any, opts: SolveOptions) -> None:
    """Worker process: receive chunks, send one message per solved problem."""
    one_line_warnings()  # as the CLI prints them: this process is not started through it
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    _die_with_parent()
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    with contextlib.suppress(Exception):  # the problems will report the error one by one
        worker.prepare_method(opts.method)
    try:
        conn.send(("ready",))
        while True:
            msg = conn.recv()
            if msg is None:
                return
            chunk_id, tasks = msg
            for row, timing in worker.solve_tasks(tasks, opts):
                conn.send(("row", chunk_id, row, timing))
            conn.send(("done", chunk_id))
    except (EOFError, OSError):  # the parent is gone (kill -9): leave quietly, no traceback
        return


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


#: Modules the forkserver imports once, so that every worker starts with them loaded.
PRELOAD = ("lcpcli.batch.worker", "lcpcli.api", "lcpcli.io")


def _mp_context() -> Any:
    # not fork: the enumeration kernel's OpenMP threads do not survive fork() (a worker forked
    # after the parent ran a parallel region hangs); forkserver workers fork from a clean server
    return process_context(PRELOAD)


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
        worker.prepare_method(opts.method)
        for row, timing in worker.solve_tasks(tasks, opts):
            if on_timing:
                on_timing(timing)
            yield row
        return
    from multiprocessing.connection import wait

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
                    w.proc.join(timeout=5)  # reap it, so that its exit code is known
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

