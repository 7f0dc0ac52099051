"""NPZ problem files: arrays ``M`` and ``q`` (or a sparse M as ``M_format``, ``M_shape``,
``M_data`` with ``M_indices``/``M_indptr`` or ``M_row``/``M_col``), optional ``n_eq``, ``lower``,
``upper``, ``name``, ``description`` and ``meta`` (a JSON string).

Nothing is read before it is checked: the zip directory's declared sizes and each member's
``.npy`` header (data type under :mod:`lcpcli.core.numeric`, shape against ``n`` from M's
header) are validated first, so a zip bomb or a mislabelled array costs no memory.  Pickled
(object) arrays are refused; other members are ignored (never decompressed).
"""

from __future__ import annotations

import lzma
import math
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import INDEX_KINDS, REAL_KINDS, check_dtype, json_text
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.files import (
    MAX_JSON_DEPTH,
    MAX_NAME_BYTES,
    MAX_TEXT_BYTES,
    StackedFile,
    check_depth,
    open_input,
    parse_json,
    stored_text,
)
from lcpcli.io.sparse import (
    check_part_sizes,
    parse_format,
    parse_shape,
    sparse_from_parts,
    sparse_parts,
)

#: A problem NPZ holds a handful of arrays; more zip entries than this is not one.
MAX_MEMBERS = 1000
#: What zipfile raises on a damaged or unsupported archive (NotImplementedError: a compression
#: method it does not implement; zlib.error, lzma.LZMAError and OSError (bz2): a compressed
#: member's damaged bytes); readers turn these into one-line ProblemErrors.
ZIP_ERRORS = (zipfile.BadZipFile, EOFError, OSError, NotImplementedError, RuntimeError,
              zlib.error, lzma.LZMAError)
_TEXT_KINDS = "US"


def read_npy_header(fh: IO[bytes]) -> tuple[tuple[int, ...], np.dtype]:
    """Shape and dtype from a ``.npy`` header (the file position ends after the header)."""
    shape, _fortran, dtype = read_npy_header_full(fh)
    return shape, dtype


def read_npy_header_full(fh: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype]:
    """Shape, Fortran order and dtype from a ``.npy`` header (position: after the header)."""
    try:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        else:  # 3.0 (UTF-8 field names): numpy has no public reader of the header alone
            shape, fortran, dtype = np.lib.format._read_array_header(fh, version)
    except (ValueError, TypeError, SyntaxError, EOFError) as exc:
        raise ProblemError(f"damaged .npy header ({str(exc).splitlines()[0][:80]})") from None
    return tuple(int(x) for x in shape), bool(fortran), np.dtype(dtype)


class Member:
    """One ``.npy`` member of the zip: its header read, its data not yet."""

    def __init__(self, zf: zipfile.ZipFile, info: zipfile.ZipInfo, key: str) -> None:
        self.zf, self.info, self.key = zf, info, key
        with zf.open(info) as fh:
            try:
                shape, fortran, dtype = read_npy_header_full(fh)
            except ProblemError as exc:
                raise ProblemError(f"array '{key}': {exc}") from None
            header_len = fh.tell()
        #: Bytes before the data in the member; whether the data are in Fortran order.
        self.header_len, self.fortran = header_len, fortran
        self.shape: tuple[int, ...] = tuple(int(x) for x in shape)
        self.dtype = np.dtype(dtype)
        self.size = math.prod(self.shape)
        if self.dtype.hasobject:
            raise ProblemError(f"array '{key}' holds pickled Python objects; refused for "
                               f"safety (allow_pickle=False)")
        needed = header_len + self.size * self.dtype.itemsize
        if info.file_size != needed:
            raise ProblemError(f"array '{key}' is damaged: its header declares "
                               f"{needed:,} bytes, the zip entry {info.file_size:,}")

    def check(self, label: str, kinds: str = REAL_KINDS) -> None:
        check_dtype(self.dtype, label, kinds=kinds)

    def read(self) -> np.ndarray:
        with self.zf.open(self.info) as fh:
            return _read_array(fh)

    def vector(self, label: str, n: int) -> np.ndarray:
        """A real vector of length ``n`` (shapes (n,), (n, 1), (1, n) accepted)."""
        self.check(label)
        if len(self.shape) > 2 or self.size != n or (len(self.shape) == 2 and 1 not in self.shape
                                                     and n != 1):
            raise ProblemError(f"{label} has shape {self.shape} but M is {n} x {n}")
        return self.read().reshape(-1)

    def scalar_int(self, label: str) -> int:
        if self.size != 1 or self.dtype.kind not in INDEX_KINDS:
            raise ProblemError(f"'{label}' must be one integer (got {self.dtype} "
                               f"of shape {self.shape})")
        return int(self.read().reshape(-1)[0])

    def text(self, label: str, limit: int) -> str:
        if self.size != 1 or self.dtype.kind not in _TEXT_KINDS:
            raise ProblemError(f"'{label}' must be one string (got {self.dtype} of shape "
                               f"{self.shape})")
        if self.dtype.itemsize > limit:
            raise ProblemError(f"'{label}' is longer than {limit:,} bytes")
        value = self.read().reshape(-1)[0]
        return value.decode("utf-8", errors="replace") if isinstance(value, bytes) else str(value)


def _read_array(fh: IO[bytes]) -> np.ndarray:
    try:
        return np.lib.format.read_array(fh, allow_pickle=False)
    except ValueError as exc:
        raise ProblemError(f"damaged array data ({str(exc).splitlines()[0][:80]})") from None


def read(path: Path, check_dense: Callable[[int], None] | None = None) -> Problem:
    """One problem; a stack raises :class:`~lcpcli.io.files.StackedFile` (``lcpcli.io.load``
    reads it with :mod:`lcpcli.io.stack`).  ``check_dense(n)`` is called with the size of a
    dense M from its header, before its data is read (a caller's work budget)."""
    with open_input(path) as fh:
        try:
            zf = zipfile.ZipFile(fh)
        except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
            raise ProblemError(f"not a valid NPZ file ({type(exc).__name__}: {exc})") from None
        try:
            with zf:
                return _read(zf, path, check_dense)
        except ZIP_ERRORS as exc:
            raise zip_error(exc) from None


def zip_error(exc: BaseException) -> ProblemError:
    """The one-line error of a damaged or unsupported NPZ archive."""
    first = str(exc).splitlines()[0][:100] if str(exc) else ""
    return ProblemError(f"not a valid NPZ file ({type(exc).__name__}: {first})")


def read_augmented(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """Dai & Drumwright's augmented form: a dense ``M`` of shape ``(n, n + 1)`` (the artificial
    column last) and ``q`` of length ``n``; None when the file holds anything else.  Same checks as
    :func:`read` (regular file, zip directory and array headers before any data)."""
    with open_input(path) as fh:
        try:
            with zipfile.ZipFile(fh) as zf:
                infos = zf.infolist()
                if len(infos) > MAX_MEMBERS:
                    return None
                entries = {i.filename[:-4]: i for i in infos if i.filename.endswith(".npy")}
                if "M" not in entries or "q" not in entries:
                    return None
                m = Member(zf, entries["M"], "M")
                if len(m.shape) != 2 or m.shape[1] != m.shape[0] + 1:
                    return None
                m.check("M")
                check_size(m.shape[0], m.shape[1])
                return m.read(), Member(zf, entries["q"], "q").vector("q", m.shape[0])
        except (*ZIP_ERRORS, ValueError):
            return None  # the regular reader gives the proper message


def _read(zf: zipfile.ZipFile, path: Path, check_dense: Callable[[int], None] | None = None
          ) -> Problem:
    infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise ProblemError(f"holds {len(infos):,} zip entries; a problem file has a few arrays")
    entries = {i.filename[:-4]: i for i in infos if i.filename.endswith(".npy")}

    def member(key: str) -> Member:
        return Member(zf, entries[key], key)

    if "q" not in entries:
        raise ProblemError(f"missing array 'q' (arrays present: {', '.join(sorted(entries))})")
    if "M" in entries:
        m = member("M")
        m.check("M")
        if len(m.shape) == 3:  # a stack: lcpcli.io.load reads it with lcpcli.io.stack
            raise StackedFile()
        if len(m.shape) != 2:
            raise ProblemError(f"M must be a 2-D matrix, got shape {m.shape}")
        check_size(*m.shape)
        if check_dense is not None:
            check_dense(m.shape[0])
        M: Any = m.read()
        n = m.shape[0]
    elif "M_format" in entries:
        M = sparse_from_parts(_sparse_parts(entries, member), "M")
        n = M.shape[0]
    else:
        raise ProblemError(f"missing array 'M' (arrays present: {', '.join(sorted(entries))})")
    q = member("q").vector("q", n)
    bounds = {k: member(k).vector(k, n) for k in ("lower", "upper") if k in entries}
    meta: dict[str, Any] = {}
    if "meta" in entries:
        text = member("meta").text("meta", MAX_TEXT_BYTES)
        meta = parse_json(text)
        if not isinstance(meta, dict):
            raise ProblemError("'meta' must be a JSON object")
        check_depth(meta, "'meta'", MAX_JSON_DEPTH)
    n_eq = member("n_eq").scalar_int("n_eq") if "n_eq" in entries else 0
    name = member("name").text("name", MAX_NAME_BYTES) if "name" in entries else path.stem
    desc = member("description").text("description", MAX_NAME_BYTES) \
        if "description" in entries else ""
    return Problem.create(M, q, n_eq=n_eq, lower=bounds.get("lower"), upper=bounds.get("upper"),
                          name=name, description=desc, meta=meta)


def _sparse_parts(entries: dict[str, zipfile.ZipInfo], member: Any) -> dict[str, Any]:
    """The ``M_*`` members, checked from their headers before any is read."""
    fmt = parse_format(member("M_format").text("M_format", 16))
    if "M_shape" not in entries:
        raise ProblemError("sparse M: missing 'M_shape'")
    head = member("M_shape")
    if head.size != 2 or head.dtype.kind not in INDEX_KINDS:
        raise ProblemError("sparse M: 'M_shape' must be two integers")
    shape = parse_shape(head.read())
    heads = {k: member(f"M_{k}") for k in ("data", "indices", "indptr", "row", "col")
             if f"M_{k}" in entries}
    for k, h in heads.items():
        h.check(f"sparse M {k}", REAL_KINDS if k == "data" else INDEX_KINDS)
        if len(h.shape) != 1:
            raise ProblemError(f"sparse M: 'M_{k}' must be 1-D, got shape {h.shape}")
    check_part_sizes(fmt, shape, {k: h.size for k, h in heads.items()})
    parts: dict[str, Any] = {"format": fmt, "shape": shape}
    for k, h in heads.items():
        parts[k] = h.read()
    return parts


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
    for label in ("name", "description"):  # UTF-8 bytes: the reader's limit is in bytes
        if getattr(problem, label):
            arrays[label] = np.asarray(stored_text(getattr(problem, label), label, "NPZ"))
    if problem.meta:
        arrays["meta"] = np.asarray(json_text(problem.meta))
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
