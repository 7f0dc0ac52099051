"""Warm-start vectors from files (``lcpcli solve --z0 FILE``).

Accepted: a JSON list of numbers; a JSON object with a ``"z"`` list (e.g. the output of
``lcpcli solve --json``; ``null`` entries are refused); an ``.npz`` file with an array ``z`` (or a
single array); an ``.npy`` array.  The same rules as for problem files apply (regular files only,
sizes and data types checked from headers before reading, numbers under
:mod:`lcpcli.core.numeric`).  Errors raise :class:`~lcpcli.core.errors.ProblemError` naming the
file.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import REAL_KINDS, check_dtype, real_array
from lcpcli.core.problem import MAX_N
from lcpcli.io.files import (
    MAX_TEXT_BYTES,
    check_input_file,
    decode_text,
    open_input,
    parse_json,
    read_input_bytes,
)


def load_z0(path: str | Path) -> np.ndarray:
    """Read a warm-start vector ``z0`` (see the module docstring); 1-D, finite floats."""
    p = Path(path)
    src = f"--z0 {p}"
    try:
        check_input_file(p, "a vector file")
        suffix = p.suffix.lower()
        if suffix == ".npz":
            arr = _from_npz(p)
        elif suffix == ".npy":
            arr = _from_npy(p)
        else:
            arr = _from_json(p)
    except ProblemError as exc:
        raise exc.with_source(src) from None
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        first = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
        raise ProblemError(f"cannot read a vector ({first})", src) from None
    if not np.all(np.isfinite(arr)):
        raise ProblemError("contains NaN or Inf", src)
    return arr


def _vector_shape(shape: tuple[int, ...]) -> None:
    """A vector (or an n x 1 / 1 x n matrix) of at most MAX_N entries, from a header."""
    if len(shape) > 2 or (len(shape) == 2 and 1 not in shape):
        raise ProblemError(f"expected a vector, got shape {shape}")
    if math.prod(shape) > MAX_N:
        raise ProblemError(f"vector of {math.prod(shape):,} entries is too long "
                           f"(limit n = {MAX_N:,})")


def _from_json(p: Path) -> np.ndarray:
    obj = parse_json(decode_text(read_input_bytes(p, MAX_TEXT_BYTES, "a JSON vector file"),
                                 "a UTF-8 text file"))
    if isinstance(obj, dict):
        if "z" not in obj:
            raise ProblemError("JSON object has no 'z' entry")
        obj = obj["z"]
    if not isinstance(obj, list) or any(isinstance(x, list) for x in obj):
        raise ProblemError("expected a list of numbers")
    if any(x is None for x in obj):
        raise ProblemError("the list holds null entries (a result with NaN/Inf is no warm start)")
    return real_array(obj, "z0")


def _from_npy(p: Path) -> np.ndarray:
    from lcpcli.io.npz_format import read_npy_header

    with open_input(p, "a vector file") as fh:
        shape, dtype = read_npy_header(fh)
        if dtype.hasobject:
            raise ProblemError("holds pickled Python objects; refused for safety")
        check_dtype(dtype, "z0", kinds=REAL_KINDS)
        _vector_shape(tuple(shape))
        fh.seek(0)
        arr = np.lib.format.read_array(fh, allow_pickle=False)
    return np.asarray(arr, dtype=np.float64).reshape(-1)


def _from_npz(p: Path) -> np.ndarray:
    from lcpcli.io.npz_format import Member

    with open_input(p, "a vector file") as fh, zipfile.ZipFile(fh) as zf:
        entries = {i.filename[:-4]: i for i in zf.infolist() if i.filename.endswith(".npy")}
        if "z" in entries:
            key = "z"
        elif len(entries) == 1:
            key = next(iter(entries))
        else:
            raise ProblemError(f"NPZ file has arrays {sorted(entries)[:10]}; expected one "
                               f"named 'z'")
        member: Any = Member(zf, entries[key], key)
        member.check("z0")
        _vector_shape(member.shape)
        return np.asarray(member.read(), dtype=np.float64).reshape(-1)
