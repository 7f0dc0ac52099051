"""Batch solving on a ``dask.distributed`` cluster (optional dependency, imported on use)."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import Any

from lcpcli.batch.pool import make_chunks
from lcpcli.batch.records import SolveOptions, Task, error_row
from lcpcli.batch.worker import prepare_method, solve_tasks


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
        from lcpcli.core.errors import OptionError

        raise OptionError("--scheduler needs dask.distributed: pip install 'lcpcli[dask]'") \
            from None
    own = not hasattr(address, "submit")
    if own:
        try:
            client = Client(address, timeout="20s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            from lcpcli.core.errors import OptionError

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

