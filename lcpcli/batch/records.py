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

from lcpcli.core.errors import ProblemError
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


#: The advice of a refused ``--resume`` (the result file is left as it was).
RERUN = "run again without --resume"


def resume_refused(output: Any, source: str, why: str, advice: str = RERUN) -> ProblemError:
    """The one form of a ``--resume`` refused because the result file ``output`` holds
    results of ``source`` that this run cannot keep, for per-file and stacked batches alike:
    ``OUTPUT: holds results of SOURCE WHY; ADVICE`` (the reasons: :func:`other_settings`,
    :func:`other_data`, :func:`no_fingerprints`)."""
    return ProblemError(f"holds results of {source} {why}; {advice}", str(output))


def other_settings(output: Any, source: str, recorded: str, now: str) -> ProblemError:
    """``--resume`` with other solve settings than ``output``'s results of ``source`` were
    computed with (fingerprints ``recorded`` and ``now``), naming what differs."""
    return resume_refused(output, source, f"computed with other settings: "
                          f"{options_difference(recorded, now)}", f"give the same settings, "
                          f"or {RERUN}")


def other_data(output: Any, source: str, which: str = "") -> ProblemError:
    """``--resume`` where ``source`` no longer holds the data ``output``'s results were
    computed from (``which``: the problems that differ, when known)."""
    return resume_refused(output, source, f"computed from other data: {source} has changed "
                          f"since{f' ({which})' if which else ''}",
                          f"{RERUN}, or give another --output")


def no_fingerprints(output: Any, source: str) -> ProblemError:
    """``--resume`` of results without the fingerprints of their input and solve settings
    (written by an older lcpcli)."""
    return resume_refused(output, source, "without the fingerprints of their input and solve "
                          "settings (written by an older lcpcli), so they cannot be checked "
                          "against them")
