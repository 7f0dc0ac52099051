"""Warm-start vectors from files (``lcpcli solve --z0 FILE``).

Accepted: a JSON list of numbers; a JSON object with a ``"z"`` list (e.g. the output of
``lcpcli solve --json``; ``null`` entries are refused); an ``.npz`` file with an array ``z`` (or a
single array); an ``.npy`` array.  Errors raise :class:`~lcpcli.core.errors.ProblemError` naming
the file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lcpcli.core.errors import ProblemError


def load_z0(path: str | Path) -> np.ndarray:
    """Read a warm-start vector ``z0`` (see the module docstring); 1-D, finite floats."""
    p = Path(path)
    src = f"--z0 {p}"
    if not p.is_file():
        raise ProblemError("no such file", src)
    suffix = p.suffix.lower()
    try:
        if suffix == ".npz":
            with np.load(p, allow_pickle=False) as data:
                names = list(data.files)
                if "z" in names:
                    arr = data["z"]
                elif len(names) == 1:
                    arr = data[names[0]]
                else:
                    raise ProblemError(f"NPZ file has arrays {names}; expected one named 'z'", src)
        elif suffix == ".npy":
            arr = np.load(p, allow_pickle=False)
        else:
            obj = json.loads(p.read_text())
            if isinstance(obj, dict):
                if "z" not in obj:
                    raise ProblemError("JSON object has no 'z' entry", src)
                obj = obj["z"]
            if not isinstance(obj, list) or any(
                    isinstance(x, bool) or not isinstance(x, (int, float)) for x in obj):
                raise ProblemError("expected a list of numbers", src)
            arr = np.asarray(obj, dtype=np.float64)
    except ProblemError:
        raise
    except (ValueError, OSError, json.JSONDecodeError) as exc:
        first = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
        raise ProblemError(f"cannot read a vector ({first})", src) from None
    arr = np.asarray(arr, dtype=np.float64)
    if arr.ndim != 1:
        arr = arr.ravel() if arr.ndim == 2 and 1 in arr.shape else arr
    if arr.ndim != 1:
        raise ProblemError(f"expected a vector, got shape {arr.shape}", src)
    if not np.all(np.isfinite(arr)):
        raise ProblemError("contains NaN or Inf", src)
    return arr
