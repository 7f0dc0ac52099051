"""Warm-start vectors from files (``lcpcli solve --z0 FILE``, ``contact-matrix --z0 FILE``).

Accepted: a JSON list of numbers; a JSON object with a ``"z"`` list (e.g. the output of
``lcpcli solve --json``; ``null`` entries are refused), or with ``"unknowns"`` (names) and
``"z"`` or ``"impulses"`` (what ``contact-matrix --impulses`` and ``--json`` write); an ``.npz``
file with an array ``z`` (or a single array; with ``unknowns`` beside ``z``: the names); an
``.npy`` array.  A file that names its unknowns may also give the basis its solve ended on:
``"basic"`` (JSON: booleans, one per value) or an array ``basic`` (NPZ: bool, beside ``z``),
True where ``z_i`` is basic (read by :func:`read_warm_basis`).  The reading rules of every
input apply (docs/files.md, "Reading"): regular
files only, JSON bounded by :func:`lcpcli.io.files.parse_json` (size, duplicate keys, integer
length, nesting), the zip directory and ``.npy`` headers checked (types, shapes, declared
sizes) before any data is decompressed, and the data rule of :mod:`lcpcli.core.numeric` (real
numbers only: numeric text, booleans and complex numbers are refused).  Given the problem's
``n``, the declared length is checked against it from the ``.npy`` header, before anything is
decompressed: n values, or for a file that names its unknowns and is matched by name at most
:func:`lcpcli.core.limits.warm_start_entries` (without ``n``: the vector limit ``MAX_N``).
Errors raise :class:`~lcpcli.core.errors.ProblemError` naming the file.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.limits import warm_start_entries
from lcpcli.core.numeric import REAL_KINDS, check_dtype, real_array
from lcpcli.core.problem import MAX_N
from lcpcli.core.text import plural
from lcpcli.io.files import MAX_TEXT_BYTES, check_input_file, open_input, read_json_file, too_big
from lcpcli.io.npz_format import MAX_MEMBERS, ZIP_ERRORS, Member, read_npy_header

#: The type of a warm start read with the names of its unknowns (None: matched by position).
Named = tuple[np.ndarray, list[str] | None]
#: ... and its basis (booleans, True: z_i basic; None: the file gives none).
Based = tuple[np.ndarray, list[str] | None, np.ndarray | None]


def load_z0(path: str | Path, n: int | None = None) -> np.ndarray:
    """Read a warm-start vector ``z0`` (see the module docstring); 1-D, finite floats; with
    ``n`` (the problem's), one declaring more than n values is refused before anything is
    decompressed, and one of another length once read (``--z0 FILE: ...``)."""
    z0 = read_warm_start(path, n=n)[0]
    if n is not None and z0.shape[0] != n:
        raise ProblemError(f"has {plural(z0.shape[0], 'value')}, the problem has n = {n:,}",
                           f"--z0 {path}")
    return z0


def read_warm_start(path: str | Path, source: str | None = None, *, n: int | None = None,
                    by_name: bool = False) -> Named:
    """A warm start's values and, when the file gives them, the names of its unknowns.

    ``source`` prefixes errors (default ``--z0 PATH``).  ``n``: the problem's size, which
    bounds the declared length before any data is read (:class:`Bound`); ``by_name``: the
    caller matches a file that names its unknowns by name, so it may hold more values.
    """
    values, names, _ = read_warm_basis(path, source, n=n, by_name=by_name)
    return values, names


def read_warm_basis(path: str | Path, source: str | None = None, *, n: int | None = None,
                    by_name: bool = False) -> Based:
    """:func:`read_warm_start`'s values and names, and the basis the file gives (booleans
    aligned with the values; None when it gives none)."""
    p = Path(path)
    src = source or f"--z0 {p}"
    bound = Bound(n, by_name)
    try:
        check_input_file(p, "a vector file")
        suffix = p.suffix.lower()
        if suffix == ".npz":
            values, names, basic = _from_npz(p, bound)
        elif suffix == ".npy":
            values, names, basic = _from_npy(p, bound), None, None
        else:
            # read already: its length is the caller's to check
            values, names, basic = _from_json(p)
    except ProblemError as exc:
        raise exc.with_source(src) from None
    except (*ZIP_ERRORS, ValueError) as exc:  # the archive errors of the problem readers
        first = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
        raise ProblemError(f"cannot read a vector ({first})", src) from None
    if not np.all(np.isfinite(values)):
        raise ProblemError("contains NaN or Inf", src)
    return values, names, basic


class Bound:
    """How many values a warm start may hold: at most MAX_N; for a problem of ``n`` unknowns,
    n (or, named and matched ``by_name``, :func:`~lcpcli.core.limits.warm_start_entries`)."""

    def __init__(self, n: int | None, by_name: bool) -> None:
        self.n, self.by_name = n, by_name

    def check(self, size: int, named: bool) -> None:
        """ProblemError when ``size`` values declared by a header are more than allowed."""
        if size > MAX_N:
            raise ProblemError(f"vector of {size:,} entries is too long (limit n = {MAX_N:,})")
        if self.n is None:
            return
        most = warm_start_entries(self.n, named and self.by_name)
        if size > most:
            what = f"at most {most:,} (by name)" if most != self.n else f"{self.n:,}"
            raise ProblemError(f"declares {size:,} values but the problem has n = {self.n:,} "
                               f"({what} expected): refused before reading them")


def _vector_shape(shape: tuple[int, ...], bound: Bound, named: bool = False) -> None:
    """A vector (or an n x 1 / 1 x n matrix) within ``bound``, from a header."""
    if len(shape) > 2 or (len(shape) == 2 and 1 not in shape):
        raise ProblemError(f"expected a vector, got shape {shape}")
    bound.check(math.prod(shape), named)


def _names(names: Any, n: int) -> list[str]:
    if not isinstance(names, list) or len(names) != n or \
            not all(isinstance(x, str) for x in names):
        raise ProblemError(f"'unknowns' must be a list of {n} names")
    return names


def _from_json(p: Path) -> Based:
    obj = read_json_file(p, "a JSON vector file")
    names = basic = None
    if isinstance(obj, dict):
        if "unknowns" in obj and ("impulses" in obj or "z" in obj):
            key = "impulses" if "impulses" in obj else "z"
        elif "z" in obj:
            key = "z"
        else:
            raise ProblemError("JSON object has no 'z' entry")
        values = obj[key]
        label = "z0" if key == "z" else "'impulses'"
        if "unknowns" in obj:
            if not isinstance(values, list):
                raise ProblemError(f"{label} must be a list of numbers")
            names = _names(obj["unknowns"], len(values))
            if "basic" in obj:
                basic = _basic(obj["basic"], len(values))
        obj = values
    if not isinstance(obj, list) or any(isinstance(x, list) for x in obj):
        raise ProblemError("expected a list of numbers")
    if any(x is None for x in obj):
        raise ProblemError("the list holds null entries (a result with NaN/Inf is no warm start)")
    return real_array(obj, "z0"), names, basic


def _basic(flags: Any, n: int) -> np.ndarray:
    """A JSON basis: exactly ``n`` booleans (True: z_i basic)."""
    if not isinstance(flags, list) or len(flags) != n or \
            not all(isinstance(x, bool) for x in flags):
        raise ProblemError(f"'basic' must be a list of {n} booleans")
    return np.array(flags, dtype=bool)


def _from_npy(p: Path, bound: Bound) -> np.ndarray:

    with open_input(p, "a vector file") as fh:
        shape, dtype = read_npy_header(fh)
        if dtype.hasobject:
            raise ProblemError("holds pickled Python objects; refused for safety")
        check_dtype(dtype, "z0", kinds=REAL_KINDS)
        _vector_shape(tuple(shape), bound)
        fh.seek(0)
        arr = np.lib.format.read_array(fh, allow_pickle=False)
    return np.asarray(arr, dtype=np.float64).reshape(-1)


def _from_npz(p: Path, bound: Bound) -> Based:
    """``z`` (or the one array), ``unknowns`` and ``basic``, every member checked from the zip
    directory and its ``.npy`` header (declared sizes included) before anything is
    decompressed."""

    with open_input(p, "a vector file") as fh, zipfile.ZipFile(fh) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_MEMBERS:
            raise ProblemError(f"holds {len(infos):,} zip entries; a vector file has one or two "
                               f"arrays")
        entries = {i.filename[:-4]: i for i in infos if i.filename.endswith(".npy")}
        if "z" in entries:
            key = "z"
        elif len(entries) == 1:
            key = next(iter(entries))
        else:
            raise ProblemError(f"NPZ file has arrays {sorted(entries)[:10]}; expected one "
                               f"named 'z'")
        member = Member(zf, entries[key], key)
        member.check("z0")
        _vector_shape(member.shape, bound, named=key == "z" and "unknowns" in entries)
        names_member = None
        if key == "z" and "unknowns" in entries:
            names_member = Member(zf, entries["unknowns"], "unknowns")
            if names_member.dtype.kind not in "SU" or names_member.shape != (member.size,):
                raise ProblemError(f"'unknowns' must be {member.size:,} names (strings), got "
                                   f"{names_member.dtype} of shape {names_member.shape}")
            declared = names_member.size * names_member.dtype.itemsize
            if declared > MAX_TEXT_BYTES:
                raise too_big(declared, MAX_TEXT_BYTES, "array 'unknowns'")
        basic_member = None
        if names_member is not None and "basic" in entries:
            basic_member = Member(zf, entries["basic"], "basic")
            if basic_member.dtype.kind != "b" or basic_member.shape != (member.size,):
                raise ProblemError(f"'basic' must be {member.size:,} booleans, got "
                                   f"{basic_member.dtype} of shape {basic_member.shape}")
        values = np.asarray(member.read(), dtype=np.float64).reshape(-1)
        names = None if names_member is None else [
            x.decode("utf-8", errors="replace") if isinstance(x, bytes) else str(x)
            for x in names_member.read()]
        basic = None if basic_member is None else np.asarray(basic_member.read(), dtype=bool)
    return values, names, basic
