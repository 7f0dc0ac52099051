"""JSON problem files: ``{"M": [[...]], "q": [...]}`` (see :mod:`lcpcli.io` for the schema)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.sparse import sparse_from_parts, sparse_parts

KNOWN_KEYS = {"M", "q", "name", "description", "n_eq", "lower", "upper", "meta"}


def read(path: Path) -> Problem:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ProblemError("not a UTF-8 text file (is it really JSON?)") from None
    return read_text(text, default_name=path.stem)


def read_text(text: str, default_name: str = "") -> Problem:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ProblemError(f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    return from_dict(data, default_name)


def from_dict(data: Any, default_name: str = "") -> Problem:
    """Build a problem from the decoded JSON object."""
    if not isinstance(data, dict):
        raise ProblemError("expected a JSON object with keys 'M' and 'q'")
    missing = [k for k in ("M", "q") if k not in data]
    if missing:
        raise ProblemError(f"missing key {', '.join(repr(k) for k in missing)}")
    unknown = sorted(set(data) - KNOWN_KEYS)
    if unknown:
        raise ProblemError(f"unknown key {', '.join(repr(k) for k in unknown)} "
                           f"(known: {', '.join(sorted(KNOWN_KEYS))})")
    M = data["M"]
    if isinstance(M, dict):
        M = sparse_from_parts(M, "M")
    elif isinstance(M, list):
        rows = len(M)
        cols = len(M[0]) if rows and isinstance(M[0], list) else 0
        check_size(rows, cols)
        if any(not isinstance(r, list) or len(r) != cols for r in M):
            raise ProblemError("M must be a list of rows of equal length")
    else:
        raise ProblemError("M must be a list of rows or a sparse {'format': ...} object")
    meta = data.get("meta") or {}
    if not isinstance(meta, dict):
        raise ProblemError("'meta' must be an object")
    return Problem.create(M, data["q"], n_eq=data.get("n_eq", 0) or 0,
                          lower=data.get("lower"), upper=data.get("upper"),
                          name=data.get("name") or default_name,
                          description=data.get("description") or "", meta=meta)


def to_dict(problem: Problem) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if problem.name:
        out["name"] = problem.name
    if problem.description:
        out["description"] = problem.description
    if problem.sparse:
        parts = sparse_parts(problem.M)
        out["M"] = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in parts.items()}
    else:
        out["M"] = problem.M.tolist()
    out["q"] = problem.q.tolist()
    if problem.n_eq:
        out["n_eq"] = problem.n_eq
    if problem.lower is not None:
        out["lower"] = [None if math.isinf(x) else x for x in problem.lower.tolist()]
        out["upper"] = [None if math.isinf(x) else x for x in problem.upper.tolist()]
    if problem.meta:
        out["meta"] = problem.meta
    return out


def dumps(problem: Problem) -> str:
    return json.dumps(to_dict(problem))


def write(problem: Problem, path: Path) -> None:
    path.write_text(dumps(problem) + "\n", encoding="utf-8")
