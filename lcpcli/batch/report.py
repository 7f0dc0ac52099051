"""What a batch did: counts and extremes (:class:`Tally`), timings, the final report."""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field
from typing import Any

from lcpcli.batch.records import ERROR, key
from lcpcli.core.errors import EXIT_BAD_INPUT, EXIT_NOT_SOLVED, EXIT_SOLVED
from lcpcli.core.result import Status


@dataclass
class BatchStats:
    """Where the time went, summed over problems (worker seconds, not wall time)."""

    read_seconds: float = 0.0
    solve_seconds: float = 0.0   # lcpcli.solve: method + certificate + result dict
    method_seconds: float = 0.0  # the method alone (the rows' ``seconds``)
    write_seconds: float = 0.0   # the client writing the output (wall)
    problems: int = 0
    in_place_chunks: int = 0     # stacked chunks solved from the mapped file, not copies

    def add(self, other: dict[str, float]) -> None:
        self.read_seconds += other.get("read", 0.0)
        self.solve_seconds += other.get("solve", 0.0)
        self.method_seconds += other.get("method", 0.0)
        self.problems += int(other.get("problems", 0))

    def as_dict(self) -> dict[str, float]:
        return {"read_seconds": self.read_seconds, "solve_seconds": self.solve_seconds,
                "method_seconds": self.method_seconds, "write_seconds": self.write_seconds,
                "problems": self.problems, "in_place_chunks": self.in_place_chunks}


@dataclass
class Tally:
    """Counts and extremes of a batch, kept small whatever the number of problems."""

    top: int = 5
    counts: dict[str, int] = field(default_factory=dict)
    slowest: list[tuple[float, str, str]] = field(default_factory=list)
    worst: list[tuple[float, str, str]] = field(default_factory=list)
    errors: list[tuple[str, str, str]] = field(default_factory=list)

    def add(self, row: dict[str, Any]) -> None:
        status = str(row.get("status", ERROR))
        self.counts[status] = self.counts.get(status, 0) + 1
        src, prob = key(row)
        if status == ERROR:
            if len(self.errors) < self.top:
                self.errors.append((src, prob, str(row.get("message", ""))))
            return
        seconds = row.get("seconds")
        if isinstance(seconds, (int, float)):
            _keep(self.slowest, (float(seconds), src, prob), self.top)
        if row.get("n") is not None:
            err = row.get("error")
            _keep(self.worst, (float("inf") if err is None else float(err), src, prob),
                  self.top)

    def add_counts(self, counts: dict[str, int]) -> None:
        """Add status counts of rows not passed one by one (a stacked chunk)."""
        for status, k in counts.items():
            self.counts[status] = self.counts.get(status, 0) + k

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def exit_code(self) -> int:
        """2 if some input was bad, else 1 if some problem was not solved, else 0."""
        if self.counts.get(ERROR):
            return EXIT_BAD_INPUT
        if any(s != Status.SOLVED and c for s, c in self.counts.items()):
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


def _keep(heap: list[Any], item: Any, top: int) -> None:
    """Keep the ``top`` largest items in the min-heap ``heap``: an item no larger than the
    smallest kept is dropped without touching the heap (most rows of a batch)."""
    if len(heap) < top:
        heapq.heappush(heap, item)
    elif heap and item > heap[0]:
        heapq.heapreplace(heap, item)


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

