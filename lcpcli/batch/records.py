"""The records a batch passes around: tasks, solve options and result rows.

A **row** is the ``lcpcli solve --json`` object (:meth:`lcpcli.core.result.Result.to_dict`) plus
``source`` (the file, as given or found) and ``problem`` (the HDF5 group, or the file's stem for
one-problem files); the pair is the row's :func:`key`, which ``--resume`` uses.  Rows of inputs
that could not be read have ``status = "error"``, ``termination = "error"``, ``n = None``, empty
``z``/``w``, ``certificate = None`` and the one-line reason in ``message``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from lcpcli.core.result import Status, Termination
from lcpcli.solvers import DEFAULT_METHOD

#: Status (and termination) of a row whose input could not be read or solved at all.
ERROR = Status.ERROR
#: ``message`` and ``termination`` of a problem stopped by ``--timeout``.
TIMEOUT = Termination.TIMEOUT


@dataclass(frozen=True)
class Task:
    """One problem to solve: the file and the problem's name in it."""

    source: str
    problem: str
    hdf5: bool = False


@dataclass(frozen=True)
class SolveOptions:
    """What every problem of a batch is solved with (picklable, sent to the workers)."""

    method: str = DEFAULT_METHOD
    tol: float | None = None
    options: dict[str, Any] = field(default_factory=dict)
    #: A previous stacked result file that warm-starts a batch of one stack (``--z0``).
    warm: str | None = None


def key(row: dict[str, Any]) -> tuple[str, str]:
    """The identity of a row: ``(source, problem)``."""
    return (str(row.get("source", "")), str(row.get("problem", "")))


def error_row(source: str, problem: str, message: str, method: str = "",
              *, status: Status = Status.ERROR,
              termination: Termination = Termination.ERROR,
              seconds: float = 0.0) -> dict[str, Any]:
    """A row for a problem that produced no solution at all (bad input, crash, timeout)."""
    return {"file": source, "status": status, "method": method, "n": None, "z": [], "w": [],
            "iterations": 0, "seconds": float(seconds), "residual": None, "error": None,
            "message": " ".join(str(message).split()), "problem": problem,
            "termination": termination, "certificate": None, "source": source}


def timeout_row(task: Task, seconds: float, method: str) -> dict[str, Any]:
    """The row of a problem stopped by the per-problem time limit."""
    return error_row(task.source, task.problem, TIMEOUT, method, status=Status.UNSOLVED,
                     termination=TIMEOUT, seconds=seconds)



def options_difference(recorded: str, now: str) -> str:
    """Which settings differ between two solve-options fingerprints (JSON: method, tol,
    options), in words: ``"method was 'lemke', now 'pgs'"``, ``"tol was 1e-06, now the
    default"``, ``"option max_iter was 10, now 20"``; the raw texts when one is not such a
    fingerprint."""
    try:
        old, new = json.loads(recorded), json.loads(now)
        parts = []
        for name in ("method", "tol"):
            if old.get(name) != new.get(name):
                parts.append(f"{name} was {_setting(old.get(name))}, now "
                             f"{_setting(new.get(name))}")
        old_opts, new_opts = old.get("options") or {}, new.get("options") or {}
        for name in sorted(set(old_opts) | set(new_opts)):
            if old_opts.get(name) != new_opts.get(name):
                parts.append(f"option {name} was {_setting(old_opts.get(name))}, now "
                             f"{_setting(new_opts.get(name))}")
    except (ValueError, TypeError, AttributeError):
        return f"{recorded}, now {now}"
    return "; ".join(parts) or f"{recorded}, now {now}"


def _setting(value: Any) -> str:
    return "the default" if value is None else repr(value)
