"""NPZ problem files: arrays ``M`` and ``q`` (or a sparse M as ``M_format``, ``M_shape``,
``M_data`` with ``M_indices``/``M_indptr`` or ``M_row``/``M_col``), optional ``n_eq``, ``lower``,
``upper``, ``name``, ``description`` and ``meta`` (a JSON string).  Read with
``allow_pickle=False``: object arrays are refused.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.sparse import sparse_from_parts, sparse_parts


def _header_shape(npz: Any, key: str) -> tuple[int, ...]:
    """Shape of member ``key`` from its .npy header, without reading the data."""
    with npz.zip.open(f"{key}.npy") as fh:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, _, _ = np.lib.format.read_array_header_1_0(fh)
        else:
            shape, _, _ = np.lib.format.read_array_header_2_0(fh)
    return tuple(shape)


def read(path: Path) -> Problem:
    try:
        with np.load(path, allow_pickle=False) as npz:
            return _read(npz, path)
    except ProblemError:
        raise
    except (zipfile.BadZipFile, EOFError, OSError) as exc:
        raise ProblemError(f"not a valid NPZ file ({type(exc).__name__}: {exc})") from None
    except ValueError as exc:
        msg = str(exc)
        if "allow_pickle" in msg or "pickle" in msg.lower():
            raise ProblemError("NPZ holds pickled (object) arrays; refused for safety") from None
        raise ProblemError(f"not a valid NPZ file ({msg})") from None


def _read(npz: Any, path: Path) -> Problem:
    keys = set(npz.files)
    if "q" not in keys:
        raise ProblemError(f"missing array 'q' (arrays present: {', '.join(sorted(keys))})")
    if "M" in keys:
        shape = _header_shape(npz, "M")
        if len(shape) == 2:
            check_size(*shape)
        M: Any = npz["M"]
    elif "M_format" in keys:
        parts = {k[2:]: npz[k] for k in keys if k.startswith("M_")}
        M = sparse_from_parts(parts, "M")
    else:
        raise ProblemError(f"missing array 'M' (arrays present: {', '.join(sorted(keys))})")
    meta: dict[str, Any] = {}
    if "meta" in keys:
        try:
            meta = json.loads(str(npz["meta"]))
        except json.JSONDecodeError:
            raise ProblemError("'meta' is not a JSON string") from None
    n_eq = int(npz["n_eq"]) if "n_eq" in keys else 0
    return Problem.create(M, npz["q"], n_eq=n_eq,
                          lower=npz["lower"] if "lower" in keys else None,
                          upper=npz["upper"] if "upper" in keys else None,
                          name=str(npz["name"]) if "name" in keys else path.stem,
                          description=str(npz["description"]) if "description" in keys else "",
                          meta=meta)


def write(problem: Problem, path: Path) -> None:
    arrays: dict[str, Any] = {"q": problem.q}
    if problem.sparse:
        for k, v in sparse_parts(problem.M).items():
            arrays[f"M_{k}"] = np.asarray(v)
    else:
        arrays["M"] = problem.M
    if problem.n_eq:
        arrays["n_eq"] = np.asarray(problem.n_eq)
    if problem.lower is not None:
        arrays["lower"] = problem.lower
        arrays["upper"] = problem.upper
    if problem.name:
        arrays["name"] = np.asarray(problem.name)
    if problem.description:
        arrays["description"] = np.asarray(problem.description)
    if problem.meta:
        arrays["meta"] = np.asarray(json.dumps(problem.meta))
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
