"""Solving in this process: read a list of tasks (HDF5 files opened once per run) and solve each.

This is what every worker of a pool (:mod:`lcpcli.batch.pool`) or of a Dask cluster
(:mod:`lcpcli.batch.cluster`) runs.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from lcpcli.batch.output import content_fingerprint
from lcpcli.batch.records import SolveOptions, Task, error_row
from lcpcli.core.errors import LcpError, ProblemError
from lcpcli.core.numeric import load_fast_json
from lcpcli.io import load


def _load_runs(tasks: list[Task]) -> Iterator[tuple[Task, Any, float, str | None]]:
    """Yield ``(task, Problem or ProblemError, read seconds, input_hash)``; HDF5 files opened
    once per run; the input_hash (:func:`lcpcli.batch.output.content_fingerprint`) of the bytes
    a JSON file was parsed from, None for other files (the client hashes those)."""
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
                yield t, item, now - start, None
                start = time.perf_counter()
            gen.close()
            i = j
        else:
            start = time.perf_counter()
            content: list[bytes] = []  # a JSON file's bytes as parsed: its input_hash
            try:
                item: Any = load(task.source, content=content)
            except ProblemError as exc:
                item = exc
            except Exception as exc:  # noqa: BLE001
                item = ProblemError(f"unreadable ({type(exc).__name__}: {exc})", task.source)
            yield task, item, time.perf_counter() - start, \
                content_fingerprint(content[0]) if content else None
            i += 1


def solve_tasks(tasks: list[Task], opts: SolveOptions,
                ) -> Iterator[tuple[dict[str, Any], dict[str, float]]]:
    """Read and solve ``tasks`` here; yield ``(row, timings)`` per task, never raising for data.

    ``timings`` has ``read``, ``solve`` (lcpcli.solve plus the row) and ``method`` seconds,
    and ``digest``: the row's ``input_hash`` where this process read the file whole (JSON).
    """
    from lcpcli.api import solve

    for task, item, t_read, digest in _load_runs(tasks):
        timing: dict[str, Any] = {"read": t_read, "solve": 0.0, "method": 0.0, "problems": 1}
        if digest is not None:
            timing["digest"] = digest
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
    """Load the method's compiled kernel and the optional fast JSON codec (outside any timing,
    once per worker: a batch reads and writes JSON for every problem); unknown methods raise."""
    from lcpcli.solvers.request import method_of

    load_fast_json()
    method_of(method).prepare_once()

