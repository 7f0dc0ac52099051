"""Batches of stacked problem files: read a chunk, solve it in one call, write it.

Each input is a stack (:mod:`lcpcli.io.stack`: ``M`` (K, n, n), ``q`` (K, n), ...).  Chunks of
:func:`lcpcli.batch.stack_output.batch_chunk` problems (from n and the thread count; row outputs:
:func:`lcpcli.io.stack.chunk_size`) are read in order, by a reader thread one chunk ahead of
the solver (into reused buffers; from before the output file is made when nothing is
resumed), written in order by a writer thread one chunk behind it, and solved by
:func:`lcpcli.stacks.solve_many` (the batched kernel in threads, the certificate inside the same
call, the full one-problem pipeline for what it could not certify; the method is planned once
per stack by :func:`lcpcli.stacks.plan_stack`).  Results go to the output as stacked datasets
(``.h5``, ``.npz``: :mod:`lcpcli.batch.stack_output`) or as rows (``.jsonl``, ``.csv``, and the
``--json`` stream; row ``problem`` is the stacked problem's name), and ``--resume`` skips the
problems the output already holds, once it has checked that they were computed from the same
data: the chunks holding them are read again and their digests compared with the ones the
output recorded (:func:`lcpcli.batch.stack_output.chunk_digest`, by the algorithm the output
records: :mod:`lcpcli.batch.digest`), and the solve options too.
"""

from __future__ import annotations

import heapq
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.batch.records import SolveOptions, error_row, other_data
from lcpcli.batch.report import BatchReport, BatchStats, Tally
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.problem import problem_kind
from lcpcli.core.result import STATUS_CODES, STATUS_OF_CODE, StackResult, Status, basis_text


def _problem_name(stem: str, k: int, names: list[str] | None, i: int) -> str:
    """Problem k of the stack, entry i of the chunk's ``names`` (io.stack's naming rule)."""
    from lcpcli.io.stack import problem_name

    return problem_name(stem, names, k, start=k - i)


def result_rows(source: str, stem: str, positions: np.ndarray, names: list[str] | None,
                res: Any) -> list[dict[str, Any]]:
    """The batch rows of a solved chunk (the ``solve --json`` fields a stack keeps, plus
    ``source``, ``problem`` and ``index``, the 0-based position in the stack)."""

    per = res.seconds / max(1, len(res))
    n = int(res.z.shape[1])
    rows = []
    for i, k in enumerate(positions.tolist()):
        err, resid = float(res.error[i]), float(res.residual[i])
        status = STATUS_OF_CODE[int(res.status[i])]
        bad = status == "error"  # no solution at all: n null, z and w empty (as per-file rows)
        rows.append({
            "file": source, "status": status, "method": res.method_of(i),
            "n": None if bad else n,
            "z": [] if bad else [x if np.isfinite(x) else None for x in res.z[i].tolist()],
            "w": [] if bad else [x if np.isfinite(x) else None for x in res.w[i].tolist()],
            "iterations": int(res.iterations[i]), "seconds": per,
            "residual": resid if np.isfinite(resid) else None,
            "error": err if np.isfinite(err) else None,
            "message": res.message(i), "problem": _problem_name(stem, k, names, i),
            "index": k, "source": source, "basis": _basis_text(res.basis, i)})
    return rows


def _basis_text(basis: np.ndarray | None, i: int) -> str | None:
    """Row i's basis as ``--json`` writes it (:func:`lcpcli.core.result.basis_text`); None
    without one (an ``error`` problem)."""
    if basis is None or (basis[i] < 0).any():
        return None
    return basis_text(basis[i])


def run_stacks(inputs: list[str], opts: SolveOptions, report: BatchReport, *,
               output: Any, resume: bool, threads: int,
               on_start: Callable[[int, int], None] | None,
               on_progress: Callable[[int, dict[str, int]], None] | None,
               on_row: Callable[[dict[str, Any]], None] | None,
               write: Callable[[Callable[[], None]], None], scheduler: Any = None,
               memory: MemoryPool | None = None, early_reads: EarlyReads | None = None
               ) -> None:
    """Solve every problem of the stacked ``inputs`` into ``report`` (see the module docstring).

    ``write(fn)`` runs an output write (the caller holds signals around it and times it);
    ``on_progress(count, counts)`` after each chunk with the number of problems it finished
    and the status counts so far; ``on_row`` gets each row when given (the ``--json`` stream).
    ``scheduler`` (a Dask address or Client): chunks are solved as tasks on its workers
    (:func:`lcpcli.batch.cluster.iter_stack_dask`), written here as locally.  ``memory``:
    the :func:`memory_pool` started for the chunk buffers, if any; ``early_reads``: the
    :func:`early_reads` started with the batch, used for the first stack when they read it
    as this batch does (closed otherwise; the caller closes them too).
    """
    from lcpcli.batch import stack_output
    from lcpcli.io.stack import stack_info

    tally, stats = report.tally, report.stats
    infos: list[Any] = []
    for path in inputs:
        try:
            infos.append(stack_info(path))
        except ProblemError as exc:
            if len(inputs) == 1:  # one input: its one-line error, as for a single problem
                raise exc.with_source(path) from None
            infos.append(None)
            row = error_row(path, Path(path).stem, str(exc), opts.method)
            tally.add(row)
            report.new += 1
            if on_row:
                on_row(row)
    if scheduler is not None:  # Dask workers copy their chunks: the chunks for copies
        infos = [None if i is None else replace(i, in_place=False) for i in infos]
    report.total = sum(i.K for i in infos if i is not None) + infos.count(None)
    per_problem = any(one_at_a_time(opts.method, stack_kind(i)) for i in infos if i is not None)
    warm, warm_digest = _open_warm(opts, infos, scheduler)
    writer = None
    early: tuple[Any, int, _LocalParts] | None = None  # the first stack, read from now on
    try:
        first = next((i for i in infos if i is not None), None)
        if first is not None and scheduler is None and not resume:
            # nothing is resumed: the first chunks are read while the output file is made
            chunk = stack_output.new_chunk(output, first.n, threads, first.in_place,
                                           per_problem)
            digest = None if output is None else stack_output.new_algorithm(output)
            started = None
            if early_reads is not None:
                started = early_reads.take(first, chunk, digest) if warm is None else None
                if started is None:
                    early_reads.close()
            early = (first, chunk, _local_parts(first.path, first, opts,
                                                np.zeros(first.K, bool), threads=threads,
                                                chunk=chunk, digest=digest, warm=warm,
                                                memory=memory, started=started))
        if output is not None:
            def make() -> Any:
                return stack_output.open_stack_writer(
                    output, [i for i in infos if i is not None], resume=resume,
                    options=stack_output.options_fingerprint(opts, warm_digest),
                    threads=threads, per_problem=per_problem)

            # resuming nothing, the file is made in a thread while the first chunks are read
            # and solved (making it is mostly waiting for the disk: fsync, rename)
            writer = make() if early is None else _OpeningWriter(
                make, stack_output.wants_rows(output), early[0], early[1],
                stack_output.new_algorithm(output))
            if early is not None:  # made once the first chunk is read: a batch whose first
                early[2].on_read = writer.start  # read fails leaves no file (nor replaces one)
        if writer is not None and resume:
            for info in infos:
                if info is not None:
                    _check_identity(info, writer, output)
    except BaseException:
        if early is not None:
            early[2].close()
        if writer is not None:
            writer.close()
        if warm is not None:
            warm.close()
        raise
    done_masks = {}
    for path, info in zip(inputs, infos, strict=True):
        if info is not None:
            done = writer.done(info) if (writer is not None and resume) else \
                np.zeros(info.K, bool)
            done_masks[path] = done
            if resume and done.any():
                report.skipped += int(done.sum())
                writer.tally_done(info, tally)
    try:
        if on_start:
            on_start(report.total, report.skipped + infos.count(None))
        for path, info in zip(inputs, infos, strict=True):
            if info is None:
                continue
            parts, chunk = None, None
            if early is not None and info is early[0]:
                parts, chunk, early = early[2], early[1], None
            elif writer is not None:
                chunk = writer.chunk(info)
            _run_one(path, info, opts, report, tally, stats, writer, done_masks[path],
                     threads=threads,
                     chunk=chunk if chunk is not None else
                     stack_output.batch_chunk(info.n, threads, info.in_place, per_problem),
                     on_progress=on_progress, on_row=on_row, write=write,
                     scheduler=scheduler, warm=warm, parts=parts, memory=memory)
    finally:
        if early is not None:
            early[2].close()
        if warm is not None:
            warm.close()
        if writer is not None:
            write(writer.close)


def stack_kind(info: Any) -> str:
    """The kind of the problems of a stack (:attr:`lcpcli.core.problem.Problem.kind`'s names):
    ``"mlcp"`` with ``n_eq > 0``, ``"box"`` with stored bounds, else ``"lcp"``."""
    return problem_kind(info.n_eq, info.bounds is not None)


def one_at_a_time(method: str, kind: str = "lcp") -> bool:
    """Whether the named method solves a stack of ``kind`` one problem at a time (it has no
    batched kernel for that kind, :attr:`lcpcli.solvers.registry.Method.batch`): its chunks
    are then at most :data:`lcpcli.batch.stack_output.PER_PROBLEM_CHUNK` problems.  ``auto``
    plans on the first chunk, after the chunk is chosen: one at a time when no method has a
    batched kernel for ``kind`` (MLCP stacks), else not known yet: False."""
    from lcpcli.solvers.registry import methods
    from lcpcli.solvers.request import method_of

    spec = method_of(method)
    if spec.name == "auto":
        return not any(m.batch is not None and kind in m.batch.kinds
                       for m in methods().values())
    return spec.batch is None or kind not in spec.batch.kinds


class _OpeningWriter:
    """The output writer of a batch that resumes nothing, made by ``make()`` in a thread of
    its own once :meth:`start` is called (when the first chunk is read: it is then made while
    that chunk is solved) or the writer is first used; each use waits for it (also when
    Ctrl-C arrives meanwhile) and raises what making it raised (an unwritable output, a full
    disk).  A batch that ends before either (the first chunk cannot be read: a damaged
    input) never makes it: no output file is created, none is replaced (an empty
    ``out.jsonl`` was left by a corrupted NPZ, exit 2).  ``wants_rows``: the writer's, known
    from the output's kind; ``first``, ``chunk``, ``algorithm``: the first stack, the chunk it
    is read in and the digest its chunks are fingerprinted with, which a new file must record
    (checked)."""

    def __init__(self, make: Callable[[], Any], wants_rows: bool, first: Any,
                 chunk: int, algorithm: str) -> None:
        self.wants_rows, self.first, self.want_chunk = wants_rows, first, chunk
        self.want_algorithm = algorithm
        self.writer: Any = None
        self.error: BaseException | None = None
        self.go = threading.Event()  # set: make the writer; with ``cancelled``: do not
        self.cancelled = False
        self.thread = threading.Thread(target=self._run, args=(make,),
                                       name="lcpcli-stack-opener", daemon=True)
        self.thread.start()

    def start(self) -> None:
        """Have the writer made now (idempotent)."""
        self.go.set()

    def _run(self, make: Callable[[], Any]) -> None:
        self.go.wait()
        if self.cancelled:
            return
        try:
            self.writer = make()
        except BaseException as exc:  # noqa: BLE001 - raised where the writer is used
            self.error = exc

    def _wait(self) -> BaseException | None:
        """Join the thread (on through Ctrl-C: the file is renamed into place); the
        interrupt that arrived meanwhile, if any."""
        interrupted: BaseException | None = None
        while self.thread.is_alive():
            try:
                self.thread.join()
            except KeyboardInterrupt as exc:
                interrupted = exc
        if self.error is None and (self.writer.chunk(self.first), self.writer.algorithm(
                self.first)) != (self.want_chunk, self.want_algorithm):
            self.writer.close()
            self.error = RuntimeError(
                f"a new result file records chunks of {self.writer.chunk(self.first)} "
                f"problems by {self.writer.algorithm(self.first)}, not {self.want_chunk} by "
                f"{self.want_algorithm}")
        return interrupted

    def get(self) -> Any:
        """The writer, once made."""
        self.start()
        interrupted = self._wait()
        if self.error is not None:
            raise self.error
        if interrupted is not None:
            raise interrupted
        return self.writer

    def chunk(self, info: Any) -> int:
        return self.get().chunk(info)

    def algorithm(self, info: Any) -> str:
        return self.get().algorithm(info)

    def write(self, *args: Any) -> None:
        self.get().write(*args)

    def close(self) -> None:
        """Close the writer once made (nothing when making it failed: that error was
        raised where the writer was used; nothing when it was never started: no file)."""
        if not self.go.is_set():
            self.cancelled = True
            self.go.set()
            self.thread.join()
            return
        interrupted = self._wait()
        if self.error is None:
            self.writer.close()
        if interrupted is not None:
            raise interrupted


def _open_warm(opts: SolveOptions, infos: list[Any], scheduler: Any) -> tuple[Any, str | None]:
    """The previous stacked result file of ``--z0`` (``opts.warm``), opened and checked
    against the one input stack (:class:`lcpcli.io.stack.results.StackResultFile`), and the
    digest of its bytes, which the run's solve options record (``--resume`` then refuses
    another warm file); ``(None, None)`` without one."""
    if opts.warm is None:
        return None, None
    from lcpcli.io.stack.results import StackResultFile, file_digest

    stacks = [i for i in infos if i is not None]
    if len(infos) != 1 or not stacks:
        raise OptionError(f"--z0 {opts.warm}: a stacked result file warm-starts one stacked "
                          f"input (got {len(infos)})")
    if scheduler is not None:
        raise OptionError("--z0 with stacked inputs is solved in this process; it does not "
                          "apply to --scheduler")
    info = stacks[0]
    warm = StackResultFile(opts.warm, info.K, info.n)
    try:
        return warm, file_digest(opts.warm)
    except BaseException:
        warm.close()
        raise


def warm_result(prev: Any, todo: np.ndarray) -> StackResult:
    """Problems ``todo`` of a chunk of a previous stacked result file
    (:class:`lcpcli.io.stack.results.ResultChunk`) as the :class:`StackResult` that
    ``solve_many(..., warm=)`` starts from: each problem from its basis (from its ``z`` where
    the file has none), cold where it was not solved."""
    z = np.ascontiguousarray(prev.z[todo])
    k = int(todo.size)
    return StackResult(z=z, w=np.full_like(z, np.nan), status=prev.status[todo],
                       iterations=np.zeros(k, np.int64), error=np.full(k, np.nan),
                       residual=np.full(k, np.nan), method="", tol=float("nan"),
                       basis=None if prev.basis is None else prev.basis[todo])


def _check_identity(info: Any, writer: Any, output: Any) -> None:
    """Refuse to resume when a chunk holding finished results now holds other data."""
    from lcpcli.batch.stack_output import chunk_digest
    from lcpcli.io.stack import open_stack

    recorded = writer.recorded(info)
    if not recorded:
        return
    chunk, algorithm = writer.chunk(info), writer.algorithm(info)
    with open_stack(info.path, direct=True) as reader:
        for c, want in sorted(recorded.items()):
            start, stop = c * chunk, min(info.K, (c + 1) * chunk)
            if chunk_digest(reader.read(start, stop), algorithm) != want:
                raise other_data(output, info.path,
                                 f"problems {start:,} to {stop - 1:,} differ")


def solve_part(reader: Any, info: Any, start: int, stop: int, todo: np.ndarray,
               opts: SolveOptions, plan: Any, *, threads: int, digest: str | None,
               ) -> tuple[list[str] | None, bytes, Any, Any, float, float]:
    """Read problems ``start + todo`` of the open stack ``reader`` and solve them with
    :func:`lcpcli.stacks.solve_many` (``plan``: made here on this chunk when None).  Returns the
    chunk's names (of ``todo``), the digest of the whole chunk by the algorithm ``digest``
    (:mod:`lcpcli.batch.digest`; None: ``b""``), the
    result, the plan, and the read and solve seconds.  The one chunk step of the local and the
    Dask paths (:func:`lcpcli.batch.cluster.stack_chunk_task`)."""
    part, fingerprint, read_s = read_part(reader, start, stop, digest=digest)
    names, res, plan, solve_s = solve_read(part, info, todo, opts, plan, threads=threads)
    return names, fingerprint, res, plan, read_s, solve_s


def read_part(reader: Any, start: int, stop: int, *, digest: str | None,
              out: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[Any, bytes, float]:
    """Problems ``start .. stop-1`` of the open stack ``reader``, the digest of that chunk
    by the algorithm ``digest`` (None: ``b""``) and the seconds both took: the reading half of
    :func:`solve_part`.  ``out``: the buffers ``(M, q)`` to read into
    (:meth:`lcpcli.io.stack.StackReader.read`)."""
    from lcpcli.batch.stack_output import chunk_digest

    t0 = time.perf_counter()
    part = reader.read(start, stop, out)
    fingerprint = b"" if digest is None else chunk_digest(part, digest)
    return part, fingerprint, time.perf_counter() - t0


def solve_read(part: Any, info: Any, todo: np.ndarray, opts: SolveOptions, plan: Any, *,
               threads: int, prev: Any = None) -> tuple[list[str] | None, Any, Any, float]:
    """Solve problems ``todo`` (0-based in the chunk) of the chunk ``part`` read by
    :func:`read_part`: the chunk's names (of ``todo``), the result, the plan (made here when
    None) and the seconds: the solving half of :func:`solve_part`.  ``prev``: the same chunk
    of a previous stacked result file (``--z0``), which warm-starts every problem."""
    from lcpcli.stacks import plan_stack, solve_many

    t1 = time.perf_counter()
    start, stop = part.start, part.start + part.q.shape[0]
    M, q = part.M, part.q
    lo, up = part.lower, part.upper
    if todo.size != stop - start:
        M, q = M[todo], q[todo]
        lo = None if lo is None else lo[todo]
        up = None if up is None else up[todo]
    names = part.names if todo.size == stop - start or part.names is None else \
        [part.names[i] for i in todo.tolist()]
    options = dict(opts.options)
    if plan is None:
        plan = plan_stack(M, q, opts.method, lower=lo, upper=up, n_eq=info.n_eq, **options)
    warm = None if prev is None else warm_result(prev, todo)
    res = solve_many(M, q, opts.method, tol=opts.tol, lower=lo, upper=up, n_eq=info.n_eq,
                     threads=threads, on_error="mark", plan=plan, warm=warm,
                     record_basis=True, **options)  # the output's basis
    return names, res, plan, time.perf_counter() - t1


def _reads(path: str, info: Any, done: np.ndarray, chunk: int, digest: str | None,
           stop_event: threading.Event | None = None, warm: Any = None,
           buffers: _Buffers | None = None, reader: Any = None) -> Iterator[tuple[Any, ...]]:
    """``(todo, part, digest, read_s, prev, held)`` of each chunk with work, in order (the
    reader's side); ``part``: its rows read in place where the file allows
    (:mod:`lcpcli.io.stack.mapped`: ``part.check`` then runs after the chunk's solve and
    digest, :func:`checked`), else copied; ``digest``: the chunk's :class:`_Digest` by the
    algorithm ``digest`` (None: ``b""``),
    computed here once the chunk is handed over, so that the solver starts on it meanwhile;
    ``prev``: the chunk of the ``--z0`` result file ``warm`` (None without one); ``held``:
    the buffers of ``buffers`` that ``part`` was read into (None without them), which the
    consumer gives back once it is done with the chunk's data.  ``reader``: the stack
    already opened so (:func:`_open_mapped`; closed here), else opened here."""
    if reader is None:
        reader = _open_mapped(path)
    with reader:
        if buffers is not None and not reader.copies(0, info.K):
            buffers.unneeded()
        for start in range(0, info.K, chunk):
            if stop_event is not None and stop_event.is_set():
                return
            stop = min(info.K, start + chunk)
            todo = np.flatnonzero(~done[start:stop])
            if todo.size:
                # rows read in place (views of the mapped file) need no buffer
                copies = buffers is not None and reader.copies(start, stop)
                held = buffers.take(stop_event) if copies else None  # type: ignore[union-attr]
                if copies and held is None:  # told to stop while waiting
                    return
                part, _, read_s = read_part(reader, start, stop, digest=None, out=held)
                prev = None
                if warm is not None:  # its read counts as reading
                    t0 = time.perf_counter()
                    prev = warm.read(start, stop)
                    read_s += time.perf_counter() - t0
                fingerprint = None if digest is None else _Digest(digest, path)
                yield todo, part, fingerprint or b"", read_s, prev, held
                if fingerprint is not None:  # beside the solver, before the next read
                    fingerprint.compute(part)


def checked(part: Any, path: str) -> None:
    """Refuse (ProblemError naming ``path``) a chunk read in place from a stack file that was
    truncated under it (``part.check``, :mod:`lcpcli.io.stack.mapped`); called on the chunk
    once its results and its digest are computed, before they are written or counted."""
    if part.check is not None:
        try:
            part.check()
        except ProblemError as exc:
            raise exc.with_source(path) from None


def _open_mapped(path: str) -> Any:
    """The stack at ``path`` opened as a stacked batch reads it: large chunks in order,
    rows in place where the file allows (:func:`lcpcli.io.stack.open_stack`)."""
    from lcpcli.io.stack import open_stack

    return open_stack(path, direct=True, mapped=True)


class _Digest:
    """The digest of a chunk (:func:`lcpcli.batch.stack_output.chunk_digest`) that the reader
    thread computes after it handed the chunk over; :meth:`result` (the chunk's write) waits
    for it, and raises what computing it raised, or :func:`checked`'s error when the chunk was
    read in place from ``path`` and the file was truncated under it.  ``algorithm``: the
    digest's (:mod:`lcpcli.batch.digest`); ``seconds``: what computing it took (counted as
    reading)."""

    def __init__(self, algorithm: str, path: str) -> None:
        self.algorithm, self.path = algorithm, path
        self.done = threading.Event()
        self.value, self.seconds = b"", 0.0
        self.error: BaseException | None = None

    def compute(self, part: Any) -> None:
        from lcpcli.batch.stack_output import chunk_digest

        t0 = time.perf_counter()
        try:
            self.value = chunk_digest(part, self.algorithm)
            checked(part, self.path)  # the digest is of the file's bytes
        except BaseException as exc:  # noqa: BLE001 - raised by result(), in the writer
            self.error = exc
            raise
        finally:
            self.seconds = time.perf_counter() - t0
            self.done.set()

    def result(self) -> bytes:
        self.done.wait()
        if self.error is not None:
            raise self.error
        return self.value


def _digest_bytes(digest: bytes | _Digest, stats: BatchStats) -> bytes:
    """A chunk's digest as bytes (waiting for a :class:`_Digest`, whose seconds count as
    reading)."""
    if isinstance(digest, _Digest):
        value = digest.result()
        stats.read_seconds += digest.seconds
        return value
    return digest


class MemoryPool:
    """``count`` blocks of ``nbytes`` bytes that a thread of its own allocates and writes
    once (so that the kernel maps and zeroes their pages) as soon as the pool is made:
    started before the rest of a stacked batch (loading h5py and the solver's modules, checking
    the inputs: one thread), it makes the chunk buffers on a core that is idle meanwhile.  New
    memory is costly on the reference machine (2-2.5 ms per MiB written the first time, a
    virtual machine whose host backs each new page: a chunk of 16 MiB read into new memory
    took 37 ms instead of 4).  :meth:`take` is called from one thread (the reader).  Made
    with ``start=False``, the thread starts at :meth:`start` (a batch's early reader starts it
    once it knows that the stack is copied, not read in place); :meth:`cancel` stops the
    writing (a stack read in place needs no buffer: 12-54 ms of CPU at the start of a batch,
    beside the first solves, measured at n = 50, and the GIL in 1 MiB steps while the main
    thread imports the solver).  A pool never started or cancelled gives no block."""

    #: Bytes written between two looks at :meth:`cancel`.
    STEP = 2**20

    def __init__(self, count: int, nbytes: int, start: bool = True) -> None:

        self.nbytes, self.left, self.count = nbytes, count, count
        self.blocks: queue.Queue[np.ndarray | None] = queue.Queue()
        self.cancelled = threading.Event()
        self.thread: threading.Thread | None = None
        if start:
            self.start()

    def start(self) -> None:
        """Start writing the blocks (once; not after :meth:`cancel`)."""
        if self.thread is None and not self.cancelled.is_set():
            self.thread = threading.Thread(target=self._run, args=(self.count,),
                                           name="lcpcli-stack-memory", daemon=True)
            self.thread.start()

    def _run(self, count: int) -> None:
        made = 0
        try:
            for _ in range(count):
                if self.cancelled.is_set():
                    break
                block = np.empty(self.nbytes, np.uint8)
                for a in range(0, self.nbytes, self.STEP):
                    if self.cancelled.is_set():
                        break
                    block[a:a + self.STEP].fill(0)
                self.blocks.put(block)
                made += 1
        except BaseException:  # noqa: BLE001 - out of memory: the reader allocates instead
            pass
        for _ in range(count - made):  # none made: the caller allocates
            self.blocks.put(None)

    def cancel(self) -> None:
        """Stop writing blocks (those not made yet are None for :meth:`take`)."""
        self.cancelled.set()

    def take(self, nbytes: int) -> np.ndarray | None:
        """A block of at least ``nbytes`` (waits while it is being written); None when the
        pool has none that large or none left, or was never started (the caller
        allocates)."""
        if nbytes > self.nbytes or self.left <= 0 or self.thread is None:
            return None
        self.left -= 1
        return self.blocks.get()


def memory_pool(inputs: list[str], count: int = 2, start: bool = True) -> MemoryPool | None:
    """The :class:`MemoryPool` of a batch whose first input looks like a large stack (a
    stack's extension, :data:`lcpcli.io.stack.layout.STACK_FORMATS`, and at least ``count``
    chunks of :data:`lcpcli.batch.stack_output.BATCH_CHUNK_BYTES`): ``count`` blocks of one
    chunk's M (the chunk buffers of :class:`_LocalParts`); None otherwise.  Looks at the
    file's name and size only (a batch that turns out not to be stacked frees the blocks)."""

    from lcpcli.batch.stack_output import BATCH_CHUNK_BYTES
    from lcpcli.io.stack.layout import STACK_FORMATS

    if not inputs or Path(inputs[0]).suffix.lower() not in STACK_FORMATS:
        return None
    try:
        size = os.stat(inputs[0]).st_size
    except (OSError, ValueError):
        return None
    return MemoryPool(count, BATCH_CHUNK_BYTES, start) \
        if size >= count * BATCH_CHUNK_BYTES else None


class _Buffers:
    """At most ``count`` pairs of chunk buffers ``(M (chunk, n, n), q (chunk, n))``, made
    when first needed and then reused, chunk after chunk: reading into memory already
    faulted in costs a copy, a new allocation of 32 MiB also the kernel's page faults (the
    arrays ``solve_many`` is measured on were faulted in before it runs).  ``count`` is
    :data:`READ_AHEAD` + 1: those queued and the one being solved; the reader reads the next
    chunk into the solved one's pair once it is given back (a read takes a tenth of a solve
    or less), so no third pair of fresh pages is zeroed by the kernel (a third of the
    memory a short batch touches)."""

    def __init__(self, count: int, chunk: int, n: int, memory: MemoryPool | None = None
                 ) -> None:

        self.free: queue.Queue[tuple[np.ndarray, np.ndarray]] = queue.Queue()
        self.count, self.made, self.shape = count, 0, (chunk, n)
        self.memory = memory  # M's memory, faulted in ahead when it has a block

    def _new_m(self) -> np.ndarray:
        c, n = self.shape
        block = None if self.memory is None else self.memory.take(8 * c * n * n)
        if block is None:
            return np.empty((c, n, n))
        return block[:8 * c * n * n].view(np.float64).reshape(c, n, n)

    def take(self, stop: threading.Event | None) -> tuple[np.ndarray, np.ndarray] | None:
        """A free pair (waits for one given back); None once ``stop`` is set."""

        while True:
            try:
                return self.free.get_nowait()
            except queue.Empty:
                pass
            if self.made < self.count:
                self.made += 1
                c, n = self.shape
                return self._new_m(), np.empty((c, n))
            try:
                return self.free.get(timeout=0.1)
            except queue.Empty:
                if stop is not None and stop.is_set():
                    return None

    def give(self, pair: tuple[np.ndarray, np.ndarray] | None) -> None:
        if pair is not None:
            self.free.put(pair)

    def unneeded(self) -> None:
        """No chunk will be copied (the stack is read in place): the memory pool stops."""
        if self.memory is not None:
            self.memory.cancel()


class _Prefetch:
    """The items of ``items(stop_event)`` made in a reader thread, started at once, at most
    ``depth`` ahead of the consumer (memory: ``depth + 2`` chunks); its exceptions are raised
    by :meth:`__next__`, in order.  :meth:`close` (also when the consumer stops early: an
    error, Ctrl-C) tells the thread to stop and joins it, so no read outlives the batch."""

    def __init__(self, items: Callable[[threading.Event], Iterator[Any]], depth: int) -> None:

        self.q: queue.Queue[tuple[str, Any]] = queue.Queue(maxsize=depth)
        self.stop = threading.Event()
        self.ended = False
        self.thread = threading.Thread(target=self._run, args=(items,),
                                       name="lcpcli-stack-reader", daemon=True)
        self.thread.start()

    def _put(self, item: tuple[str, Any]) -> bool:

        while not self.stop.is_set():
            try:
                self.q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _run(self, items: Callable[[threading.Event], Iterator[Any]]) -> None:
        made = items(self.stop)
        try:
            for item in made:
                if not self._put(("item", item)):
                    return
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer
            self._put(("error", exc))
            return
        finally:
            made.close()  # the input file is closed in this thread, before it ends
        self._put(("end", None))

    def __iter__(self) -> _Prefetch:
        return self

    def __next__(self) -> Any:
        if self.ended:
            raise StopIteration
        kind, value = self.q.get()
        if kind == "item":
            return value
        self.close()
        if kind == "error":
            raise value
        raise StopIteration

    def close(self) -> None:
        self.ended = True
        self.stop.set()
        self.thread.join()


def _prefetched(items: Callable[[threading.Event], Iterator[Any]], depth: int) -> _Prefetch:
    """:class:`_Prefetch` of ``items`` (the reader thread starts now)."""
    return _Prefetch(items, depth)


#: Chunks the reader thread of :class:`_LocalParts` reads ahead of the solver.
READ_AHEAD = 1


class _LocalParts:
    """``(start, todo, names, digest, res, read_s, solve_s)`` of each chunk with work, in
    order, solved in this process (the plan is made on the first chunk solved).  Reading (and
    the chunk's digest) overlaps solving: a reader thread, started when this is made (it may
    read while the output file is created), reads the next chunk into reused buffers
    (:class:`_Buffers`) while the compiled kernel's threads solve this one
    (:class:`_Prefetch`, :data:`READ_AHEAD`); the caller writes each result in order.
    ``before_solve``, when the caller sets it, is called right before each chunk is solved
    (:func:`_consume` hands the previous chunk's write to the writer thread there).
    :meth:`close` stops and joins the reader."""

    def __init__(self, path: str, info: Any, opts: SolveOptions, done: np.ndarray, *,
                 threads: int, chunk: int, digest: str | None, warm: Any = None,
                 memory: MemoryPool | None = None,
                 started: tuple[_Prefetch, _Buffers] | None = None) -> None:
        self.info, self.opts, self.threads = info, opts, threads
        self.before_solve: Callable[[], None] | None = None
        self.on_read: Callable[[], None] | None = None  # each chunk, once it is read
        self.in_place = 0  # chunks solved from views of the mapped file
        if started is not None:  # the same reads, begun earlier (:class:`EarlyReads`)
            self.reads, self.buffers = started
            return
        self.buffers = _Buffers(READ_AHEAD + 1, min(chunk, info.K), info.n, memory)
        self.reads = _prefetched(lambda stop: _reads(path, info, done, chunk, digest, stop,
                                                     warm, self.buffers), READ_AHEAD)

    def __iter__(self) -> Iterator[tuple[Any, ...]]:
        plan = None
        for todo, part, fingerprint, read_s, prev, held in self.reads:
            if self.on_read is not None:
                self.on_read()
            if self.before_solve is not None:
                self.before_solve()
            names, res, plan, solve_s = solve_read(part, self.info, todo, self.opts, plan,
                                                   threads=self.threads, prev=prev)
            checked(part, self.info.path)  # solved from the file's bytes
            if part.check is not None:
                self.in_place += 1
            yield part.start, todo, names, fingerprint, res, read_s, solve_s
            # the consumer is done with this chunk (its results hold no view of M or q)
            self.buffers.give(held)

    def close(self) -> None:
        self.reads.close()


def _local_parts(path: str, info: Any, opts: SolveOptions, done: np.ndarray, *, threads: int,
                 chunk: int, digest: str | None, warm: Any = None,
                 memory: MemoryPool | None = None,
                 started: tuple[_Prefetch, _Buffers] | None = None) -> _LocalParts:
    """:class:`_LocalParts` (its reader thread starts now, unless ``started`` gives the
    reads begun by :class:`EarlyReads`; ``memory``: where its chunk buffers come from, when
    it has blocks)."""
    return _LocalParts(path, info, opts, done, threads=threads, chunk=chunk, digest=digest,
                       warm=warm, memory=memory, started=started)


class EarlyReads:
    """The reads of a batch's first input, started with the batch (:func:`early_reads`),
    before the method is looked up (its modules take ~9 ms to load on the reference
    machine), the inputs checked and the output made: a reader thread opens the stack as
    the batch reads it (:func:`_open_mapped`, once: its layout, then its chunks), starts or
    stops the memory pool by the layout, and reads its first chunks as a batch that resumes
    nothing reads them (:func:`_reads`: the chunk of
    :func:`lcpcli.batch.stack_output.new_chunk` for ``output``, every problem, no ``--z0``).
    :meth:`take` hands them to the batch when it reads that stack so; :meth:`close` stops
    and joins the thread (idempotent).  An input that is no stack only ends the thread: the
    batch reports it as it would have."""

    def __init__(self, path: str, output: Any, threads: int,
                 memory: MemoryPool | None) -> None:
        self.path, self.output, self.threads, self.memory = path, output, threads, memory
        self.known = threading.Event()  # set once the layout is known, or could not be
        self.info: Any = None
        self.chunk, self.digest = 0, None
        self.buffers: _Buffers | None = None
        self.taken = False
        self.reads = _prefetched(self._items, READ_AHEAD)

    def _items(self, stop: threading.Event) -> Iterator[tuple[Any, ...]]:
        from lcpcli.batch.stack_output import new_algorithm, new_chunk

        reader = None
        try:
            reader = _open_mapped(self.path)  # opened once: its layout, then its chunks
            info = reader.info
            if self.memory is not None and reader.copies(0, info.K):
                self.memory.start()  # buffers only for a stack that is copied (a stack
                # read in place stops the pool in _reads, by the same test)
            self.chunk = new_chunk(self.output, info.n, self.threads, info.in_place)
            self.digest = None if self.output is None else new_algorithm(self.output)
            self.buffers = _Buffers(READ_AHEAD + 1, min(self.chunk, info.K), info.n,
                                    self.memory)
            self.info = info
        except BaseException:
            if reader is not None:
                reader.close()
            raise
        finally:
            self.known.set()
        yield from _reads(self.path, info, np.zeros(info.K, bool), self.chunk, self.digest,
                          stop, None, self.buffers, reader)

    def take(self, info: Any, chunk: int, digest: str | None
             ) -> tuple[_Prefetch, _Buffers] | None:
        """The started reads and their buffers, for :class:`_LocalParts`, when they read
        ``info`` (the same layout of the same path) in ``chunk`` with ``digest``; None
        otherwise (the caller then closes these)."""
        self.known.wait()
        if self.taken or self.info != info or (self.chunk, self.digest) != (chunk, digest):
            return None
        self.taken = True
        assert self.buffers is not None
        return self.reads, self.buffers

    def close(self) -> None:
        self.reads.close()


def early_reads(inputs: list[str], output: Any, threads: int,
                memory: MemoryPool | None) -> EarlyReads | None:
    """:class:`EarlyReads` of the first input when its name is a stack's
    (:data:`lcpcli.io.stack.layout.STACK_FORMATS`), started now; None otherwise.  For a batch
    that resumes nothing, runs no ``--z0`` and no ``--scheduler`` (the caller's test)."""
    from lcpcli.io.stack.layout import STACK_FORMATS

    if not inputs or Path(inputs[0]).suffix.lower() not in STACK_FORMATS:
        return None
    return EarlyReads(inputs[0], output, threads, memory)


def _run_one(path: str, info: Any, opts: SolveOptions, report: BatchReport, tally: Tally,
             stats: BatchStats, writer: Any, done: np.ndarray, *, threads: int, chunk: int,
             on_progress: Any, on_row: Any, write: Any, scheduler: Any = None,
             warm: Any = None, parts: Any = None, memory: MemoryPool | None = None) -> None:
    """One stacked input, chunk by chunk: solved here, or as Dask tasks when ``scheduler``;
    ``warm``: the ``--z0`` result file (local runs only); ``parts``: its
    :class:`_LocalParts` when already started (closed here)."""
    stem = Path(path).stem
    if parts is None and scheduler is None:
        parts = _local_parts(path, info, opts, done, threads=threads, chunk=chunk,
                             digest=None if writer is None else writer.algorithm(info),
                             warm=warm, memory=memory)
    elif parts is None:
        from lcpcli.batch.cluster import iter_stack_dask

        parts = iter_stack_dask(path, info, opts, done, scheduler, chunk=chunk,
                                digest=None if writer is None else writer.algorithm(info))
    try:
        _consume(path, stem, info, parts, report, tally, stats, writer, chunk=chunk,
                 on_progress=on_progress, on_row=on_row, write=write)
    finally:
        stats.in_place_chunks += getattr(parts, "in_place", 0)
        # closed here, not when the garbage collector finds it: closing joins the reader
        # thread, which must not happen inside h5py (its lock held) on some later line
        close = getattr(parts, "close", None)
        if close is not None:
            close()


class _WriteBehind:
    """The output writes of a stacked batch in one thread of their own, in order, at most
    :data:`WRITE_BEHIND` chunks behind the solver: chunk k is written while chunk k + 1 is
    solved (HDF5 releases the GIL while it writes; the compiled solver never needs it).

    ``write(fn)`` runs one write (the caller times it; it holds no signal here: Python runs
    signal handlers in the main thread only, so a write in this thread is never cut by
    Ctrl-C).  The first error of a write (a full disk) is raised in the main thread by the
    next :meth:`submit` or by :meth:`close`, and no later write runs.  :meth:`close` lets
    the writes already handed over finish, then joins the thread, also when Ctrl-C arrives
    while it waits, so the output is never closed under a running write."""

    def __init__(self, write: Callable[[Callable[[], None]], None]) -> None:

        self.write = write
        self.pending: queue.Queue[Callable[[], None] | None] = queue.Queue(maxsize=WRITE_BEHIND)
        self.error: BaseException | None = None  # the first failed write's; none runs after
        self.reported = False
        self.thread = threading.Thread(target=self._run, name="lcpcli-stack-writer",
                                       daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while True:
            fn = self.pending.get()
            if fn is None:
                return
            if self.error is None:
                try:
                    self.write(fn)
                except BaseException as exc:  # noqa: BLE001 - raised in the main thread
                    self.error = exc

    def _raise(self) -> None:
        if self.error is not None and not self.reported:
            self.reported = True
            raise self.error

    def submit(self, fn: Callable[[], None]) -> None:
        """Hand one write over (waits while :data:`WRITE_BEHIND` are pending)."""
        self._raise()
        self.pending.put(fn)

    def close(self) -> None:
        """Finish the writes handed over and stop the thread; raise the first write error
        (unless :meth:`submit` raised it already)."""
        interrupted: BaseException | None = None
        stopped = False
        while self.thread.is_alive():
            try:
                if not stopped:
                    self.pending.put(None)
                    stopped = True
                self.thread.join()
            except KeyboardInterrupt as exc:  # wait on: the output closes after the write
                interrupted = exc
        self._raise()
        if interrupted is not None:
            raise interrupted


#: Chunk writes handed to the writer thread of :class:`_WriteBehind` and not yet finished.
WRITE_BEHIND = 1


def _consume(path: str, stem: str, info: Any, parts: Any, report: BatchReport, tally: Tally,
             stats: BatchStats, writer: Any, *, chunk: int, on_progress: Any, on_row: Any,
             write: Any) -> None:
    """Write, tally and report each solved chunk of ``parts`` in order (the writes in the
    thread of :class:`_WriteBehind`, one chunk behind).  Parts solved here
    (:class:`_LocalParts`) get each chunk's write handed over right before the next chunk is
    solved (the stack's last chunk at once), not as soon as the chunk is solved: the writer
    thread's work, most of it under the GIL (h5py's Python code, and the Python file object
    that HDF5 writes through), then runs beside the compiled solver instead of delaying the
    main thread's own work between two solves (the tally, starting the next solve), while
    the kernel's threads wait (n = 50, 24 chunks: the tallies took 9-29 ms of wall time for
    4.5 ms of CPU; handed over later, their CPU time)."""
    writes = _WriteBehind(write) if writer is not None else None
    pending: list[Callable[[], None]] = []  # at most one: the last chunk solved

    def hand_over() -> None:
        while pending:
            writes.submit(pending.pop(0))  # type: ignore[union-attr]

    defer = writes is not None and hasattr(parts, "before_solve")
    if defer:
        parts.before_solve = hand_over
    try:
        for start, todo, names, digest, res, read_s, solve_s in parts:
            stats.read_seconds += read_s
            stats.solve_seconds += solve_s
            stats.method_seconds += res.seconds
            stats.problems += len(res)
            positions = todo + start
            rows = result_rows(path, stem, positions, names, res) \
                if (on_row is not None or (writer is not None and writer.wants_rows)) else None
            if writes is not None:
                pending.append(lambda positions=positions, names=names, res=res, rows=rows,
                               chunk_no=start // chunk, digest=digest:
                               writer.write(info, positions, names, res, rows, chunk_no,
                                            _digest_bytes(digest, stats)))
                if not defer or start + chunk >= info.K:  # the stack's last chunk: now
                    hand_over()
            add_to_tally(tally, path, stem, positions, names, res)
            report.new += len(res)
            if rows is not None and on_row is not None:
                for row in rows:
                    on_row(row)
            if on_progress:
                on_progress(len(res), dict(tally.counts))
    finally:
        if writes is not None:
            try:  # the last chunk's write; also a finished chunk's when a later one failed
                hand_over()
            finally:
                writes.close()


def _largest_first(values: np.ndarray, k: int) -> np.ndarray:
    """Positions of the ``k`` largest of ``values`` (no NaN), largest first, ties in position
    order: ``np.argsort(-values, kind="stable")[:k]``, without sorting all of them (the
    candidates are those at least the k-th largest, found by a partition)."""
    if k <= 0:
        return np.zeros(0, np.intp)
    neg = -values
    if neg.size > 4 * k:
        kth = np.partition(neg, k - 1)[k - 1]
        cand = np.flatnonzero(neg <= kth)
        return cand[np.argsort(neg[cand], kind="stable")[:k]]
    return np.argsort(neg, kind="stable")[:k]


def add_to_tally(tally: Tally, source: str, stem: str, positions: np.ndarray,
                 names: list[str] | None, res: Any) -> None:
    """Counts, the worst errors and the first error messages of a chunk, without rows."""
    tally.add_counts(res.counts())
    ok = res.status != STATUS_CODES[Status.ERROR]
    err = np.where(np.isfinite(res.error), res.error, np.inf)
    idx = np.flatnonzero(ok)
    if idx.size:
        worst = idx[_largest_first(err[idx], tally.top)]
        for i in worst.tolist():
            k = int(positions[i])
            heapq.heappush(tally.worst, (float(err[i]), source,
                                         _problem_name(stem, k, names, i)))
            if len(tally.worst) > tally.top:
                heapq.heappop(tally.worst)
    for i in np.flatnonzero(~ok).tolist()[:max(0, tally.top - len(tally.errors))]:
        k = int(positions[i])
        tally.errors.append((source, _problem_name(stem, k, names, i), res.message(i)))

