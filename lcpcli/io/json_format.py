"""JSON problem files: ``{"M": [[...]], "q": [...]}`` (see :mod:`lcpcli.io` for the schema).

Values follow :mod:`lcpcli.core.numeric`: ``M``, ``q``, ``lower`` and ``upper`` hold JSON numbers
only (``true``/``false`` and strings are refused, numeric text included); ``lower``/``upper``
also take ``null`` (and ``"inf"``/``"-inf"``) for an infinite bound.  ``name`` and
``description`` are strings, ``n_eq`` an integer, ``meta`` an object nested at most
:data:`~lcpcli.io.files.MAX_JSON_DEPTH` deep.  The file is at most
:data:`~lcpcli.io.files.MAX_TEXT_BYTES` long.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import json_text, real_array, scan_nested
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.files import (
    MAX_TEXT_BYTES,
    check_depth,
    decode_text,
    fast_parse,
    parse_json,
    read_input_bytes,
)
from lcpcli.io.sparse import sparse_from_parts, sparse_parts

KNOWN_KEYS = {"M", "q", "name", "description", "n_eq", "lower", "upper", "meta"}
#: Strings accepted for an infinite bound (as :mod:`lcpcli.core.problem` reads them).
INF_WORDS = {"inf": math.inf, "+inf": math.inf, "infinity": math.inf, "+infinity": math.inf,
             "-inf": -math.inf, "-infinity": -math.inf}


def read(path: str | os.PathLike[str], content: list[bytes] | None = None,
         default_name: str | None = None) -> Problem:
    """The problem of a JSON file (``content``: a list that receives the bytes read;
    ``default_name``: the name of a problem without one, by default the file's stem).

    The bytes go to orjson as read (:func:`lcpcli.io.files.fast_parse`: no decoding); what it
    does not decode exactly as the standard library would (a BOM, text that is not UTF-8,
    duplicate keys, long integers, ...) is decoded and parsed by :func:`read_text`, which words
    the refusals: the problem, or the error, is the same either way."""
    data = read_input_bytes(path, MAX_TEXT_BYTES, "a JSON problem file")
    if content is not None:
        content.append(data)
    if default_name is None:
        default_name = Path(path).stem
    ok, value = fast_parse(data)
    if ok:
        return from_dict(value, default_name, scan=may_hold_booleans(data))
    return read_text(decode_text(data, "a UTF-8 text file (is it really JSON?)"),
                     default_name=default_name)


def may_hold_booleans(text: str | bytes) -> bool:
    """Whether JSON ``text`` holds ``true`` or ``false`` (anywhere, strings included): only
    then can booleans hide in float arrays, which :func:`from_dict` then scans element by
    element.  A ``t`` / ``f`` is looked for first (one ``memchr``; most problem files have
    neither outside their numbers' exponents)."""
    if isinstance(text, str):
        return ("t" in text and "true" in text) or ("f" in text and "false" in text)
    return (b"t" in text and b"true" in text) or (b"f" in text and b"false" in text)


def read_text(text: str, default_name: str = "") -> Problem:
    # booleans hide in float arrays: scan element by element only when the text has any
    return from_dict(parse_json(text), default_name, scan=may_hold_booleans(text))


def from_dict(data: Any, default_name: str = "", *, scan: bool = True) -> Problem:
    """Build a problem from the decoded JSON object (``scan``: look for booleans in arrays)."""
    if not isinstance(data, dict):
        raise ProblemError("expected a JSON object with keys 'M' and 'q'")
    missing = [k for k in ("M", "q") if k not in data]
    if missing:
        raise ProblemError(f"missing key {', '.join(repr(k) for k in missing)}")
    unknown = sorted(set(data) - KNOWN_KEYS)
    if unknown:
        shown = ", ".join(repr(k[:40]) for k in unknown[:5])
        raise ProblemError(f"unknown key {shown} (known: {', '.join(sorted(KNOWN_KEYS))})")
    M = _matrix(data["M"], scan)
    q = _vector(data["q"], "q", scan)
    n_eq = data.get("n_eq")
    if n_eq is None:
        n_eq = 0
    if isinstance(n_eq, bool) or not isinstance(n_eq, int):
        raise ProblemError(f"'n_eq' must be an integer, got {json.dumps(n_eq)[:40]}")
    meta = data.get("meta")
    if meta is None:
        meta = {}
    if not isinstance(meta, dict):
        raise ProblemError("'meta' must be an object")
    check_depth(meta, "'meta'")
    return Problem.create(M, q, n_eq=n_eq, lower=_bound(data.get("lower"), "lower", -math.inf),
                          upper=_bound(data.get("upper"), "upper", math.inf),
                          name=_text(data.get("name"), "name") or default_name,
                          description=_text(data.get("description"), "description"),
                          meta=meta)


def _text(value: Any, label: str) -> str:
    if value is None:
        return ""
    if not isinstance(value, str):
        raise ProblemError(f"'{label}' must be a string")
    return value


def _matrix(M: Any, scan: bool) -> Any:
    if not scan and type(M) is list and M:
        # the usual case in one step: rows of numbers (no boolean in the text: ``scan``
        # False) make a 2-D float or integer array; anything else takes the checks below,
        # which word the refusal
        try:
            arr = np.asarray(M)
        except (ValueError, TypeError, OverflowError):  # ragged: the checks below say so
            arr = None
        if arr is not None and arr.ndim == 2 and arr.dtype.kind in "fiu" \
                and arr.shape[0] == len(M):
            check_size(*arr.shape)
            return real_array(arr, "M", scan=False)
    if isinstance(M, dict):
        return sparse_from_parts(M, "M")
    if not isinstance(M, list):
        raise ProblemError("M must be a list of rows or a sparse {'format': ...} object")
    rows = len(M)
    if rows == 0:
        return np.zeros((0, 0))
    if not all(isinstance(r, list) for r in M):
        raise ProblemError("M must be a list of rows (lists of numbers)")
    cols = len(M[0])
    check_size(rows, cols)
    if any(len(r) != cols for r in M):
        raise ProblemError("M must be a list of rows of equal length")
    arr = real_array(M, "M", scan=scan)
    if arr.ndim != 2:
        raise ProblemError(f"M must be a list of rows of numbers, got {arr.ndim}-D data")
    return arr


def _vector(v: Any, label: str, scan: bool) -> np.ndarray:
    if isinstance(v, (dict, str)):
        raise ProblemError(f"{label} must be a list of numbers")
    arr = real_array(v, label, scan=scan)
    if arr.ndim > 1 and arr.size != max(arr.shape):
        raise ProblemError(f"{label} must be a vector, got shape {arr.shape}")
    return arr.reshape(-1)


def _bound(v: Any, label: str, inf: float) -> Any:
    """A bound vector: numbers, ``null`` (= ``inf`` of this side) or the words of INF_WORDS."""
    if v is None:
        return None
    if not isinstance(v, list):
        raise ProblemError(f"'{label}' must be a list of numbers (null = infinite)")
    out = []
    for x in v:
        if x is None:
            out.append(inf)
        elif isinstance(x, str) and x.strip().lower() in INF_WORDS:
            out.append(INF_WORDS[x.strip().lower()])
        else:
            out.append(x)
    scan_nested(out, label)
    return real_array(out, label, scan=False)


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
    return json_text(to_dict(problem))


def write(problem: Problem, path: Path) -> None:
    path.write_text(dumps(problem) + "\n", encoding="utf-8")
