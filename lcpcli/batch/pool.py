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
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from lcpcli.batch import worker
from lcpcli.batch.records import SolveOptions, Task, error_row, timeout_row
from lcpcli.core.text import one_line_warnings
from lcpcli.solvers.batched import default_threads
from lcpcli.solvers.kernels import process_context


def make_chunks(tasks: list[Task], jobs: int, *, max_chunk: int = 256) -> list[list[Task]]:
    """Split tasks into chunks: big enough to amortise messages, small enough to balance.

    Consecutive tasks stay together, so a chunk of an HDF5 file opens that file once.
    """
    if not tasks:
        return []
    size = max(1, min(max_chunk, len(tasks) // max(1, 4 * jobs)))
    return [tasks[i:i + size] for i in range(0, len(tasks), size)]


#: Most rows a worker sends in one message (without ``--timeout``): one pickle and one pipe
#: write for many rows.
GROUP_ROWS = 64
#: Longest time a worker holds a finished row before sending it (progress stays live, and a
#: worker that dies loses at most this much finished work).
GROUP_SECONDS = 0.05


class _Sender:
    """A worker's finished rows, sent as ``("rows", chunk id, pairs, last)`` messages: at once
    when ``group`` of them are waiting or the chunk is done (``last``), and by a thread at most
    :data:`GROUP_SECONDS` after they were finished (a slow problem holds back no row)."""

    def __init__(self, conn: Any) -> None:
        self.conn = conn
        self.cond = threading.Condition()
        self.pairs: list[Any] = []
        self.chunk_id = -1
        threading.Thread(target=self._run, daemon=True).start()

    def add(self, chunk_id: int, pair: Any, group: int) -> None:
        with self.cond:
            self.chunk_id = chunk_id
            self.pairs.append(pair)
            if len(self.pairs) >= group:
                self._send(last=False)

    def finish(self, chunk_id: int) -> None:
        with self.cond:
            self.chunk_id = chunk_id
            self._send(last=True)

    def _send(self, last: bool) -> None:  # the lock held: messages leave in order
        pairs, self.pairs = self.pairs, []
        self.conn.send(("rows", self.chunk_id, pairs, last))

    def _run(self) -> None:
        while True:
            with self.cond:
                self.cond.wait(GROUP_SECONDS)
                if self.pairs:
                    try:
                        self._send(last=False)
                    except (EOFError, OSError):  # the parent is gone
                        return


#: Row fields holding str enums (Status, Termination): a worker sends them as their text,
#: which they equal and are written as, because unpickling an enum member costs the client
#: 10x a string (a lookup by value per row and field).
_ENUM_FIELDS = ("status", "termination")


def _worker_main(conn: Any, opts: SolveOptions) -> None:
    """Worker process: receive chunks ``(id, tasks, group)``, send their ``(row, timings)``
    pairs in groups of at most ``group`` (:class:`_Sender`)."""
    one_line_warnings()  # as the CLI prints them: this process is not started through it
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    _die_with_parent()
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    with contextlib.suppress(Exception):  # the problems will report the error one by one
        worker.prepare_method(opts.method)
    try:
        conn.send(("ready",))
        sender = _Sender(conn)
        while True:
            msg = conn.recv()
            if msg is None:
                return
            chunk_id, tasks, group = msg
            for row, timing in worker.solve_tasks(tasks, opts):
                for name in _ENUM_FIELDS:  # plain text in the pickle (see _ENUM_FIELDS)
                    if name in row:
                        row[name] = str(row[name])
                sender.add(chunk_id, (row, timing), group)
            sender.finish(chunk_id)
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
        self.group = 1
        self.last = time.monotonic()

    @property
    def busy(self) -> bool:
        return self.chunk is not None

    def assign(self, chunk_id: int, chunk: list[Task], group: int) -> None:
        self.chunk, self.chunk_id, self.received, self.group = chunk, chunk_id, 0, group
        self.last = time.monotonic()
        self.conn.send((chunk_id, chunk, group))

    def unsent(self) -> int:
        """Tasks of the current chunk whose rows have not come back."""
        return 0 if self.chunk is None else len(self.chunk) - self.received

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


#: Most worker processes per core that a batch starts, whatever ``--jobs`` asks: each is an
#: interpreter with numpy and the kernels loaded (about 20 MB), and solving, which is CPU work,
#: gains nothing from more processes than cores (``-j 100000`` started one process per
#: problem until the machine's memory was gone).
MAX_WORKERS_PER_CORE = 4


def worker_limit() -> int:
    """The most worker processes a batch starts: :data:`MAX_WORKERS_PER_CORE` per core this
    process may run on (:func:`lcpcli.solvers.batched.default_threads`)."""
    return MAX_WORKERS_PER_CORE * default_threads()


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
    groups = iter_local_groups(tasks, opts, jobs=jobs, timeout=timeout)
    try:
        for pairs in groups:
            for row, timing in pairs:
                if on_timing:
                    on_timing(timing)
                yield row
    finally:
        groups.close()


@contextlib.contextmanager
def early_workers(opts: SolveOptions, jobs: int, timeout: float | None,
                  ) -> Iterator[list[_Worker]]:
    """``jobs`` worker processes started now, before the batch lists its inputs (their
    start-up, a few tenths of a second, then overlaps the listing); none when the batch runs
    in this process.  :func:`iter_local_groups` (``started=``) takes them from the list; the
    block's end stops those it did not take."""
    started: list[_Worker] = []
    if jobs > 1 or timeout:
        ctx = _mp_context()
        # the chunks are not known yet: at most one process per core now, the rest (up to
        # worker_limit and one per chunk) by iter_local_groups
        started = [_Worker(ctx, opts) for _ in range(min(jobs, default_threads()))]
    try:
        yield started
    finally:
        while started:
            w = started.pop()
            w.stop(kill=not w.ready)


def iter_local_groups(tasks: list[Task], opts: SolveOptions, *, jobs: int = 1,
                      timeout: float | None = None, started: list[_Worker] | None = None,
                      ) -> Iterator[list[tuple[dict[str, Any], dict[str, Any]]]]:
    """:func:`iter_local` as the groups of ``(row, timings)`` pairs that arrive together
    (timings as :func:`lcpcli.batch.worker.solve_tasks` gives them): a caller writes each
    group at once.

    Without a timeout a worker sends up to :data:`GROUP_ROWS` rows per message; when it dies
    with more than one row of its chunk unsent, which problem killed it is not known, so the
    rest of the chunk goes to a fresh worker that sends row by row (the problems solved but
    not sent are solved again): the problem that kills that one is recorded as before.
    ``started``: workers of :func:`early_workers`, used first (the others are stopped).
    """
    if not tasks:
        return
    if jobs <= 1 and not timeout:
        worker.prepare_method(opts.method)
        for pair in worker.solve_tasks(tasks, opts):
            yield [pair]
        return
    from multiprocessing.connection import wait

    ctx = _mp_context()
    group = 1 if timeout else GROUP_ROWS  # a timeout is per problem: every row at once
    pending: deque[tuple[int, list[Task], int]] = deque(
        (cid, chunk, group) for cid, chunk in enumerate(make_chunks(tasks, jobs)))
    next_id = len(pending)
    n_workers = max(1, min(jobs, len(pending), worker_limit()))
    workers: list[_Worker] = []
    try:
        while started and len(workers) < n_workers:
            workers.append(started.pop())
        while started:  # more than this batch has chunks for
            extra = started.pop()
            extra.stop(kill=not extra.ready)
    finally:
        workers += [_Worker(ctx, opts) for _ in range(n_workers - len(workers))]
    failed_starts = 0
    try:
        while pending or any(w.busy for w in workers):
            for w in workers:
                if w.ready and not w.busy and pending:
                    w.assign(*pending.popleft())
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
                            elif msg[0] == "rows" and msg[1] == w.chunk_id:
                                w.received += len(msg[2])
                                w.last = time.monotonic()
                                if msg[3]:
                                    w.chunk, w.chunk_id = None, -1
                                if msg[2]:
                                    yield msg[2]
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
                    if w.group > 1 and w.unsent() > 1:  # which one killed it: not known
                        task = None
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
                rest = w.remaining(skip_current=row is not None)
                w.stop(kill=True)
                if rest:
                    pending.appendleft((next_id, rest, 1))  # row by row from here
                    next_id += 1
                workers[workers.index(w)] = _Worker(ctx, opts)
                if row is not None:
                    yield [(row, {})]
    finally:
        for w in workers:
            w.stop(kill=not w.ready or w.busy)

