"""Batch solving on a ``dask.distributed`` cluster (optional dependency, imported on use)."""

from __future__ import annotations

import collections
import contextlib
import itertools
import os
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from lcpcli.batch.pool import make_chunks
from lcpcli.batch.records import SolveOptions, Task, error_row
from lcpcli.batch.worker import prepare_method, solve_tasks
from lcpcli.core.errors import OptionError


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
    with _connected(address) as client:
        yield from _dask_rows(client, tasks, opts, on_timing, chunk_size)


@contextlib.contextmanager
def _connected(address: Any) -> Iterator[Any]:
    """A Client of the scheduler at ``address`` (closed after), or ``address`` itself when it
    is a Client; current while the block runs."""
    try:
        from distributed import Client
    except ImportError:

        raise OptionError("--scheduler needs dask.distributed: pip install 'lcpcli[dask]'") \
            from None
    own = not hasattr(address, "submit")
    if own:
        try:
            client = Client(address, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:

            raise OptionError(f"cannot reach the Dask scheduler at {address}: "
                              f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") \
                from None
    else:
        client = address
    try:
        with client.as_current():
            yield client
    finally:
        if own:
            client.close()


def stack_chunk_task(path: str, info: Any, start: int, stop: int, todo: np.ndarray,
                     opts: SolveOptions, plan: Any, digest: str | None) -> tuple[Any, ...]:
    """Run on a Dask worker: read problems ``start + todo`` of the stack at ``path`` (a path
    every worker sees) through the reading layer and solve them on one thread (the cluster's
    workers give the parallelism); :func:`lcpcli.batch.stacked.solve_part`'s tuple."""
    from lcpcli.batch.stacked import solve_part
    from lcpcli.io.stack import open_stack

    with open_stack(path, direct=True) as reader:
        return solve_part(reader, info, start, stop, todo, opts, plan, threads=1, digest=digest)


def iter_stack_dask(path: str, info: Any, opts: SolveOptions, done: np.ndarray, address: Any,
                    *, chunk: int, digest: str | None) -> Iterator[tuple[Any, ...]]:
    """The chunks of one stacked input solved as Dask tasks, yielded in stack order as
    ``(start, todo, names, digest, res, read_s, solve_s)`` (what the local path yields, so the
    client writes the same output).  The first chunk with work is solved alone and its plan
    (:func:`lcpcli.stacks.plan_stack`) sent with the others, as the local path plans once per
    stack; at most two tasks per worker thread are in flight.  A chunk whose task failed (its
    worker lost beyond Dask's retries, or an exception) is solved in this process instead."""
    from lcpcli.batch.stacked import solve_part
    from lcpcli.io.stack import open_stack

    absolute = os.path.abspath(path)
    work = []
    for start in range(0, info.K, chunk):
        stop = min(info.K, start + chunk)
        todo = np.flatnonzero(~done[start:stop])
        if todo.size:
            work.append((start, stop, todo))
    if not work:
        return
    with _connected(address) as client:
        workers = client.scheduler_info().get("workers", {})
        window = max(2, 2 * sum(int(w.get("nthreads", 1)) for w in workers.values()))
        plan = None

        def submit(item: tuple[int, int, np.ndarray]) -> Any:
            return client.submit(stack_chunk_task, absolute, info, item[0], item[1], item[2],
                                 opts, plan, digest, pure=False)

        def result(fut: Any, item: tuple[int, int, np.ndarray]) -> tuple[Any, ...]:
            try:
                return fut.result()
            except Exception:  # noqa: BLE001 - a lost chunk is solved here, not dropped
                with open_stack(path, direct=True) as reader:
                    return solve_part(reader, info, item[0], item[1], item[2], opts, plan,
                                      threads=1, digest=digest)
            finally:
                fut.release()

        first = result(submit(work[0]), work[0])
        plan = first[3]
        yield (work[0][0], work[0][2], first[0], first[1], first[2], first[4], first[5])
        pending: collections.deque[tuple[Any, tuple[int, int, np.ndarray]]] = \
            collections.deque()
        rest = iter(work[1:])
        try:
            for item in itertools.islice(rest, window):
                pending.append((submit(item), item))
            while pending:
                fut, item = pending.popleft()
                names, fingerprint, res, _plan, read_s, solve_s = result(fut, item)
                nxt = next(rest, None)
                if nxt is not None:
                    pending.append((submit(nxt), nxt))
                yield item[0], item[2], names, fingerprint, res, read_s, solve_s
        finally:
            for fut, _item in pending:
                fut.cancel()


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

