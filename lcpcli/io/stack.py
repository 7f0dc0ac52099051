"""Stacked problem files: K problems of one size n in one NPZ or HDF5 file.

Problem ``k`` (0-based, ``k = 0 .. K-1``) is ``w = M[k] z + q[k]``.  Layout, the same names in
both formats (HDF5: datasets at the root; NPZ: members ``NAME.npy``):

* ``M`` of shape (K, n, n) and ``q`` of shape (K, n): real numbers (integers or floats, read as
  float64; the rule of :mod:`lcpcli.core.numeric`), K >= 1, n x n within
  :func:`~lcpcli.core.problem.check_size`, K at most :data:`MAX_STACK_PROBLEMS`;
* ``names`` (K,), optional: strings (HDF5 variable-length UTF-8 or fixed-length; NPZ a numpy
  string array), each at most :data:`~lcpcli.io.files.MAX_NAME_BYTES`;
* ``lower`` and ``upper``, optional, both or neither, of one shape: (n,) shared by every
  problem or (K, n) (box LCPs);
* ``n_eq``, optional, one integer ``0 <= n_eq <= n`` shared by every problem (MLCP: the first
  ``n_eq`` variables free), not together with bounds: in HDF5 a root *attribute* ``n_eq`` (as
  in the one-problem layout), in NPZ a member ``n_eq``.

Naming rule (:func:`problem_name`, used everywhere): problem ``k`` is called ``names[k]`` when
the file has names and that name is not empty, else ``STEM[k]`` (the file's stem, then the
index in brackets: ``scenes[0]``, ``scenes[1]``, ...).

Everything is checked from headers and metadata before any data is read (:func:`stack_info`);
data are read one chunk of problems at a time (:class:`StackReader`): HDF5 by slicing into
preallocated float64 arrays, NPZ by reading at the member's offset in the zip (a member
stored uncompressed, as ``np.savez`` writes it) or by decompressing sequentially (a compressed
one).  NaN/Inf values are not refused by the reader (a batch records such a problem as an
error on its own); :func:`iter_problems` validates each problem (:meth:`Problem.create`).
Errors are :class:`ProblemError` with a one-line message; readers leave the file name out
(``io.load`` adds it), the functions that take a whole file from start to end
(:func:`iter_problems`, the conversions) add it.
"""

from __future__ import annotations

import contextlib
import math
import shutil
import stat
import struct
import tempfile
import zipfile
from collections.abc import Iterable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import kind_name, real_array
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.files import MAX_NAME_BYTES, check_input_file, open_input
from lcpcli.io.npz_format import ZIP_ERRORS, zip_error
from lcpcli.io.writing import Hdf5Handle, StagedFiles, atomic_path, open_hdf5, writing

#: Extensions of stack files and their formats.
STACK_FORMATS = {".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5", ".npz": "npz"}
#: Most problems one stack may declare (a batch keeps one record per problem).
MAX_STACK_PROBLEMS = 100_000_000
#: About the bytes of one HDF5 storage chunk of M written by :func:`write_stack`.
H5_CHUNK_BYTES = 2**20
#: The HDF5 chunk cache of a reader (a storage chunk cut by two read chunks is read once).
H5_CACHE_BYTES = 16 * 2**20
H5_CACHE_SLOTS = 10_007
#: Most bytes of fixed-width names decoded at once.
_NAME_BLOCK_BYTES = 8 * 2**20
#: Largest size of a stack's ``names`` as declared by the HDF5 header: rows x fixed length, or
#: x the fill value that the rows never written repeat (1 GiB: 16.7 million 64-byte names).
MAX_NAMES_DECLARED = 2**30
#: Default bytes of M in one chunk read by :meth:`StackReader.chunks` / :func:`chunk_size`.
_CHUNK_BUDGET = 32 * 2**20


def stacked_message(K: int) -> str:
    """What ``io.load`` says about a stack of ``K > 1`` problems."""
    return (f"holds {K:,} stacked problems; solve them as a batch (lcpcli solve FILE), pick one "
            f"with --problem NAME (or its index), or convert them (lcpcli convert)")


@dataclass(frozen=True)
class StackInfo:
    """What a stack file holds, from its headers (nothing read yet)."""

    path: str
    fmt: str             # "hdf5" | "npz"
    K: int               # problems
    n: int               # size of each
    n_eq: int            # 0 for LCP
    has_names: bool
    bounds: str | None   # None, "shared" ((n,)) or "per_problem" ((K, n))


@dataclass
class StackChunk:
    """Problems ``start .. start + len(M) - 1`` of a stack (C-contiguous float64 arrays)."""

    start: int
    M: np.ndarray                 # (c, n, n)
    q: np.ndarray                 # (c, n)
    names: list[str] | None       # the stored names (empty strings kept), None without names
    lower: np.ndarray | None      # (c, n); a shared bound is copied to every row
    upper: np.ndarray | None


def problem_name(stem: str, names: list[str] | None, k: int, start: int = 0) -> str:
    """The naming rule: ``names[k - start]`` if present and not empty, else ``STEM[k]``."""
    if names is not None and names[k - start]:
        return names[k - start]
    return f"{stem}[{k}]"


def chunk_size(n: int, *, budget_bytes: int = _CHUNK_BUDGET) -> int:
    """Problems per chunk so that one chunk's M (float64) fits ``budget_bytes`` (at least 1)."""
    return max(1, budget_bytes // max(8, 8 * n * n))


def _stack_format(path: str | Path) -> str:
    ext = Path(path).suffix.lower()
    if ext not in STACK_FORMATS:
        raise ProblemError(f"a stacked file is .h5/.hdf5/.hdf or .npz, not {ext or '(none)'}")
    return STACK_FORMATS[ext]


# ------------------------------------------------------------------------- detection
def is_stack(path: str | Path) -> bool:
    """True when ``path`` is an HDF5 file with a root dataset ``M`` of 3 dimensions, or an
    NPZ whose member ``M.npy`` declares 3 dimensions.  Reads headers only; never raises."""
    try:
        fmt = _stack_format(path)
        check_input_file(path)
        if fmt == "hdf5":
            from lcpcli.io.hdf5_format import is_stacked_root, open_file

            with open_file(Path(path)) as f:
                return is_stacked_root(f)
        from lcpcli.io.npz_format import read_npy_header

        with open_input(path) as fh, zipfile.ZipFile(fh) as zf, zf.open("M.npy") as m:
            shape, _dtype = read_npy_header(m)
            return len(shape) == 3
    except Exception:  # noqa: BLE001 - a cheap test: the normal reader reports the problem
        return False


def _layout(path: str, fmt: str, m_shape: tuple[int, ...], q_shape: tuple[int, ...] | None, *,
            names_shape: tuple[int, ...] | None, lower: tuple[int, ...] | None,
            upper: tuple[int, ...] | None, n_eq: int | None) -> StackInfo:
    """Every rule on shapes, from the headers (one definition for both formats)."""
    if len(m_shape) != 3:
        raise ProblemError(f"a stack needs M of shape (K, n, n), got shape {m_shape}")
    K, n, m = m_shape
    if n != m:
        raise ProblemError(f"M must hold square matrices, got shape {m_shape}")
    check_size(n, n)
    if K < 1:
        raise ProblemError(f"holds no problem (M has shape {m_shape})")
    if K > MAX_STACK_PROBLEMS:
        raise ProblemError(f"M declares {K:,} problems (limit {MAX_STACK_PROBLEMS:,})")
    if q_shape is None:
        raise ProblemError("missing 'q' (a stack holds M of shape (K, n, n) and q of (K, n))")
    if q_shape != (K, n):
        raise ProblemError(f"q has shape {q_shape}; expected ({K}, {n}) for M of shape "
                           f"{m_shape}")
    if names_shape is not None and names_shape != (K,):
        raise ProblemError(f"names has shape {names_shape}; expected ({K},)")
    bounds = None
    if (lower is None) != (upper is None):
        given, missing = ("lower", "upper") if lower is not None else ("upper", "lower")
        raise ProblemError(f"'{given}' without '{missing}': give both bounds or neither")
    if lower is not None:
        for label, shape in (("lower", lower), ("upper", upper)):
            if shape not in ((n,), (K, n)):
                raise ProblemError(f"{label} has shape {shape}; expected ({n},) or ({K}, {n})")
        if lower != upper:
            raise ProblemError(f"lower has shape {lower} but upper {upper}; give both of one "
                               f"shape")
        bounds = "shared" if lower == (n,) else "per_problem"
    n_eq = n_eq or 0
    if not 0 <= n_eq <= n:
        raise ProblemError(f"n_eq = {n_eq} is outside 0..{n}")
    if n_eq and bounds:
        raise ProblemError("give either n_eq (MLCP) or bounds (box LCP), not both")
    return StackInfo(path=path, fmt=fmt, K=K, n=n, n_eq=n_eq,
                     has_names=names_shape is not None, bounds=bounds)


def _check_names(text: list[str]) -> list[str]:
    for name in text:
        if len(name.encode("utf-8", errors="replace")) > MAX_NAME_BYTES:
            raise ProblemError(f"a name is longer than {MAX_NAME_BYTES:,} bytes")
    return text


# ------------------------------------------------------------------------------ HDF5
class _H5Source:
    """The HDF5 side of a reader: checked datasets, read by slices."""

    def __init__(self, path: Path) -> None:
        from lcpcli.io import hdf5_format as h5

        self.f = h5.open_file(path, rdcc_nbytes=H5_CACHE_BYTES, rdcc_nslots=H5_CACHE_SLOTS,
                          rdcc_w0=1.0)
        try:
            self._scan(path)
        except BaseException:
            self.f.close()
            raise

    def _scan(self, path: Path) -> None:
        import h5py

        from lcpcli.io import hdf5_format as h5

        f = self.f
        try:
            self.d: dict[str, Any] = {}
            for key in ("M", "q", "lower", "upper"):
                self.d[key] = h5.dataset(f, key, key)
            if self.d["M"] is None:
                raise ProblemError("no dataset 'M' at the root (a stack holds M of shape "
                                   "(K, n, n) and q of (K, n))")
            names = h5.dataset(f, "names", "names", kinds=None)
            if names is not None:
                sd = h5py.check_string_dtype(names.dtype)
                if sd is None:
                    raise ProblemError(f"'names' holds {kind_name(names.dtype.kind)}; "
                                       f"expected strings")
                # variable length: rows never written hold the fill value, of any length
                fill = names.fillvalue if sd.length is None else None
                longest = sd.length or (len(fill) if isinstance(fill, (bytes, str)) else 0)
                if longest > MAX_NAME_BYTES:
                    raise ProblemError(f"'names' are longer than {MAX_NAME_BYTES:,} bytes")
                self.name_bytes = sd.length or max(longest, 64)
            self.d["names"] = names

            def shape(key: str) -> tuple[int, ...] | None:
                d = self.d[key]
                return None if d is None else tuple(int(x) for x in d.shape)

            self.info = _layout(str(path), "hdf5", shape("M"), shape("q"),
                                names_shape=shape("names"), lower=shape("lower"),
                                upper=shape("upper"), n_eq=h5.attr_int(f, "n_eq"))
            if names is not None and self.info.K * longest > MAX_NAMES_DECLARED:
                from lcpcli.io.files import too_big

                raise too_big(self.info.K * longest, MAX_NAMES_DECLARED,
                              "the declared 'names' (rows x longest name or fill value)")
        except ProblemError:
            raise
        except h5.H5_ERRORS as exc:
            raise h5.damaged(exc) from None

    def rows(self, key: str, start: int, stop: int, out: np.ndarray) -> None:
        from lcpcli.io import hdf5_format as h5

        if out.size:
            try:
                self.d[key].read_direct(out, source_sel=np.s_[start:stop])
            except h5.H5_ERRORS as exc:
                raise h5.damaged(exc) from None

    def whole(self, key: str, out: np.ndarray) -> None:
        from lcpcli.io import hdf5_format as h5

        if out.size:
            try:
                self.d[key].read_direct(out)
            except h5.H5_ERRORS as exc:
                raise h5.damaged(exc) from None

    def names(self, start: int, stop: int) -> list[str]:
        from lcpcli.io import hdf5_format as h5

        out: list[str] = []
        step = max(1, _NAME_BLOCK_BYTES // self.name_bytes)
        try:
            view = self.d["names"].asstr(errors="replace")
            for a in range(start, stop, step):
                out.extend(_check_names([str(x) for x in view[a:min(stop, a + step)]]))
        except h5.H5_ERRORS as exc:
            raise h5.damaged(exc) from None
        return out

    def close(self) -> None:
        self.f.close()


# ------------------------------------------------------------------------------- NPZ
#: npz_format's zip errors, plus what seeking and reading inside a member can raise.
_ZIP_ERRORS = (*ZIP_ERRORS, ValueError, struct.error)


class _NpzSource:
    """The NPZ side of a reader: members checked from the zip directory and ``.npy`` headers;
    a stored member is read at its file offset, a compressed one sequentially."""

    def __init__(self, path: Path, stack: ExitStack) -> None:
        self.fh = stack.enter_context(open_input(path))
        try:
            self.zf = zipfile.ZipFile(self.fh)
        except _ZIP_ERRORS as exc:
            raise zip_error(exc) from None
        stack.callback(self.zf.close)
        self.ext: dict[str, Any] = {}
        stack.callback(self._close_members)
        try:
            self._scan(path)
        except ProblemError:
            raise
        except _ZIP_ERRORS as exc:
            raise zip_error(exc) from None

    def _scan(self, path: Path) -> None:
        from lcpcli.io.npz_format import MAX_MEMBERS, Member

        infos = self.zf.infolist()
        if len(infos) > MAX_MEMBERS:
            raise ProblemError(f"holds {len(infos):,} zip entries; a stack has a few arrays")
        entries = {i.filename[:-4]: i for i in infos if i.filename.endswith(".npy")}
        if "M" not in entries:
            raise ProblemError(f"missing array 'M' (arrays present: "
                               f"{', '.join(sorted(entries))})")
        self.m: dict[str, Any] = {}
        for key in ("M", "q", "lower", "upper", "names"):
            if key in entries:
                member = Member(self.zf, entries[key], key)
                if key == "names":
                    if member.dtype.kind not in "US":
                        raise ProblemError(f"'names' holds {kind_name(member.dtype.kind)}; "
                                           f"expected strings")
                    width = member.dtype.itemsize // (4 if member.dtype.kind == "U" else 1)
                    if width > MAX_NAME_BYTES:
                        raise ProblemError(f"'names' are longer than {MAX_NAME_BYTES:,} bytes")
                    declared = member.size * member.dtype.itemsize
                    if declared > MAX_NAMES_DECLARED:
                        from lcpcli.io.files import too_big

                        raise too_big(declared, MAX_NAMES_DECLARED, "the declared 'names'")
                else:
                    member.check(f"'{key}'")
                if member.fortran and len(member.shape) > 1:
                    raise ProblemError(f"array '{key}' is stored in Fortran order; save it "
                                       f"C-contiguous (numpy.ascontiguousarray)")
                self.m[key] = member
        n_eq = Member(self.zf, entries["n_eq"], "n_eq").scalar_int("n_eq") \
            if "n_eq" in entries else 0

        def shape(key: str) -> tuple[int, ...] | None:
            return self.m[key].shape if key in self.m else None

        self.info = _layout(str(path), "npz", shape("M"), shape("q"),
                            names_shape=shape("names"), lower=shape("lower"),
                            upper=shape("upper"), n_eq=n_eq)
        self.offsets = {key: self._data_offset(m.info) for key, m in self.m.items()}

    def _data_offset(self, info: zipfile.ZipInfo) -> int | None:
        """Where a stored (uncompressed, unencrypted) member's bytes start in the file;
        None for other members (read through zipfile)."""
        if info.compress_type != zipfile.ZIP_STORED or info.flag_bits & 0x1:
            return None
        self.fh.seek(info.header_offset)
        head = self.fh.read(30)
        if len(head) != 30 or head[:4] != b"PK\x03\x04":
            raise ProblemError(f"damaged zip entry {info.filename}")
        name_len, extra_len = struct.unpack("<HH", head[26:30])
        start = info.header_offset + 30 + name_len + extra_len
        import os

        if start + info.file_size > os.fstat(self.fh.fileno()).st_size:
            raise ProblemError(f"zip entry {info.filename} runs past the end of the file")
        return start

    def _read_at(self, key: str, offset: int, buf: memoryview) -> None:
        """Fill ``buf`` from byte ``offset`` of member ``key`` (counted from its start)."""
        member, base = self.m[key], self.offsets[key]
        if base is not None:
            self.fh.seek(base + offset)
            fill = self.fh
        else:
            fill = self.ext.get(key)
            if fill is None:
                fill = self.ext[key] = self.zf.open(member.info)
            if fill.tell() != offset:
                fill.seek(offset)  # forward: decompresses what it skips; backward: restarts
        got = 0
        while got < len(buf):
            count = fill.readinto(buf[got:])
            if not count:
                raise ProblemError(f"array '{key}' is truncated")
            got += count

    def _fill(self, key: str, offset: int, out: np.ndarray) -> None:
        """Fill ``out`` from byte ``offset`` of member ``key``'s data (converted to out's
        dtype; read in place when the stored dtype is out's)."""
        member = self.m[key]
        raw = out if out.dtype == member.dtype else np.empty(out.shape, dtype=member.dtype)
        if raw.size:
            try:
                self._read_at(key, member.header_len + offset,
                              memoryview(raw.reshape(-1).view(np.uint8)))
            except ProblemError:
                raise
            except _ZIP_ERRORS as exc:
                raise zip_error(exc) from None
        if raw is not out:
            out[...] = raw

    def rows(self, key: str, start: int, stop: int, out: np.ndarray) -> None:
        member = self.m[key]
        self._fill(key, start * math.prod(member.shape[1:]) * member.dtype.itemsize, out)

    def whole(self, key: str, out: np.ndarray) -> None:
        self._fill(key, 0, out)

    def names(self, start: int, stop: int) -> list[str]:
        member = self.m["names"]
        step = max(1, _NAME_BLOCK_BYTES // max(1, member.dtype.itemsize))
        out: list[str] = []
        for a in range(start, stop, step):
            b = min(stop, a + step)
            raw = np.empty(b - a, dtype=member.dtype)
            self.rows("names", a, b, raw)
            if member.dtype.kind == "S":
                out.extend(x.decode("utf-8", errors="replace") for x in raw.tolist())
            else:
                out.extend(str(x) for x in raw.tolist())
        return _check_names(out)

    def _close_members(self) -> None:
        for fh in self.ext.values():
            fh.close()

    def close(self) -> None:  # the ExitStack closes everything
        pass


# ---------------------------------------------------------------------------- reader
class StackReader:
    """An open stack file (from :func:`open_stack`); use it as a context manager.

    ``read(start, stop)`` returns problems ``start .. stop-1`` (0-based) as one
    :class:`StackChunk`; only that chunk is allocated.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._stack = ExitStack()
        try:
            fmt = _stack_format(path)
            check_input_file(path)
            if fmt == "hdf5":
                src: Any = _H5Source(self.path)
                self._stack.callback(src.close)
            else:
                src = _NpzSource(self.path, self._stack)
            self._src = src
            self.info: StackInfo = src.info
            n = self.info.n
            self._shared: tuple[np.ndarray, np.ndarray] | None = None
            if self.info.bounds == "shared":
                lower, upper = np.empty(n), np.empty(n)
                src.whole("lower", lower)
                src.whole("upper", upper)
                self._shared = (lower, upper)
        except BaseException:
            self._stack.close()
            raise

    def __enter__(self) -> StackReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._stack.close()

    def _check_range(self, start: int, stop: int) -> None:
        if not 0 <= start <= stop <= self.info.K:
            raise IndexError(f"problems {start}..{stop - 1} are outside 0..{self.info.K - 1}")

    def read_names(self, start: int, stop: int) -> list[str] | None:
        """The stored names of problems ``start .. stop-1`` (None when the file has none)."""
        self._check_range(start, stop)
        return self._src.names(start, stop) if self.info.has_names else None

    def read(self, start: int, stop: int) -> StackChunk:
        """Problems ``start .. stop-1``: float64 C-contiguous arrays (values not checked)."""
        self._check_range(start, stop)
        c, n = stop - start, self.info.n
        M = np.empty((c, n, n))
        self._src.rows("M", start, stop, M)
        q = np.empty((c, n))
        self._src.rows("q", start, stop, q)
        lower = upper = None
        if self._shared is not None:
            lower = np.repeat(self._shared[0][None, :], c, axis=0)
            upper = np.repeat(self._shared[1][None, :], c, axis=0)
        elif self.info.bounds == "per_problem":
            lower, upper = np.empty((c, n)), np.empty((c, n))
            self._src.rows("lower", start, stop, lower)
            self._src.rows("upper", start, stop, upper)
        return StackChunk(start, M, q, self.read_names(start, stop), lower, upper)

    def problem(self, chunk: StackChunk, i: int) -> Problem:
        """Row ``i`` of ``chunk`` as a validated Problem named by :func:`problem_name`
        (ProblemError ``problem k (NAME): reason`` when its values are refused)."""
        k = chunk.start + i
        name = problem_name(self.path.stem, chunk.names, k, chunk.start)
        try:
            return Problem.create(
                chunk.M[i].copy(), chunk.q[i].copy(), n_eq=self.info.n_eq,
                lower=None if chunk.lower is None else chunk.lower[i].copy(),
                upper=None if chunk.upper is None else chunk.upper[i].copy(), name=name)
        except ProblemError as exc:
            raise ProblemError(f"problem {k} ({name}): {exc}") from None

    def chunks(self, budget_bytes: int = _CHUNK_BUDGET) -> Iterator[StackChunk]:
        """Every problem, chunk by chunk (:func:`chunk_size` problems each)."""
        step = chunk_size(self.info.n, budget_bytes=budget_bytes)
        for start in range(0, self.info.K, step):
            yield self.read(start, min(self.info.K, start + step))


def open_stack(path: str | Path) -> StackReader:
    """Open and check a stack file (every rule of :func:`stack_info`)."""
    return StackReader(path)


def stack_info(path: str | Path) -> StackInfo:
    """The layout of a stack file, every check done from headers and metadata (no data read,
    except the one integer ``n_eq``).  ProblemError (one line, no file name) on failure."""
    fmt = _stack_format(path)
    check_input_file(path)
    if fmt == "hdf5":
        src = _H5Source(Path(path))
        src.close()
        return src.info
    with ExitStack() as stack:
        return _NpzSource(Path(path), stack).info


def iter_problems(path: str | Path) -> Iterator[Problem]:
    """Every problem of the stack as a validated Problem (names: :func:`problem_name`),
    read chunk by chunk.  ProblemError names the file (and the problem, for bad values)."""
    try:
        with open_stack(path) as reader:
            for chunk in reader.chunks():
                for i in range(len(chunk.M)):
                    yield reader.problem(chunk, i)
    except ProblemError as exc:
        raise exc.with_source(str(path)) from None


def read_single(path: str | Path, problem: str | None = None) -> Problem:
    """``io.load`` of a stack: its problem when it holds one, or the one ``problem`` names (a
    name by the naming rule, ``STEM[k]``, or the 0-based index ``k``), else ProblemError."""
    with open_stack(path) as reader:
        K = reader.info.K
        if problem is None:
            if K > 1:
                raise ProblemError(stacked_message(K))
            return reader.problem(reader.read(0, 1), 0)
        k = _find(reader, str(problem))
        return reader.problem(reader.read(k, k + 1), 0)


def _find(reader: StackReader, problem: str) -> int:
    """The index of the problem called ``problem`` (first match), or of index ``problem``."""
    K, stem = reader.info.K, reader.path.stem
    step = 100_000
    for a in range(0, K, step):
        b = min(K, a + step)
        names = reader.read_names(a, b)
        for k in range(a, b):
            if problem_name(stem, names, k, a) == problem:
                return k
    if problem.isdigit() and int(problem) < K:
        return int(problem)
    raise ProblemError(f"no problem named '{problem}' among its {K:,} stacked problems (a name, "
                       f"{stem}[k] or an index 0..{K - 1})")


def list_names(path: str | Path) -> list[str]:
    """The names of the stacked problems (the naming rule), read in blocks."""
    with open_stack(path) as reader:
        K, stem = reader.info.K, reader.path.stem
        out: list[str] = []
        step = 100_000
        for a in range(0, K, step):
            b = min(K, a + step)
            names = reader.read_names(a, b)
            out.extend(problem_name(stem, names, k, a) for k in range(a, b))
        return out


# ---------------------------------------------------------------------------- writer
class StackWriter:
    """Write a stack chunk by chunk to ``path`` (a new file; callers go through
    :func:`~lcpcli.io.writing.atomic_path`).  ``fmt`` is "hdf5" or "npz"; ``bounds`` is None,
    "shared" (give ``lower``/``upper`` of shape (n,) here) or "per_problem" (give them with
    every :meth:`append`).  :meth:`close` completes the file and returns K.
    """

    def __init__(self, path: Path, fmt: str, n: int, *, n_eq: int = 0, names: bool = False,
                 bounds: str | None = None, lower: np.ndarray | None = None,
                 upper: np.ndarray | None = None, expected: int | None = None) -> None:
        if n < 1:
            raise ProblemError("a stack needs problems of size n >= 1")
        check_size(n, n)
        self.path, self.fmt, self.n, self.n_eq = Path(path), fmt, n, int(n_eq)
        self.has_names, self.bounds, self.K = names, bounds, 0
        self._names: list[str] = []
        self._stack = ExitStack()
        keys = ["M", "q"] + (["lower", "upper"] if bounds == "per_problem" else [])
        c = max(1, H5_CHUNK_BYTES // (8 * n * n))
        if expected:
            c = min(c, expected)
        if fmt == "hdf5":
            import h5py

            # through a SafeSink (lcpcli.io.writing): a full disk is an error to report, never
            # a failed HDF5 flush (which segfaults at exit); closed by abort() or close()
            self.h5 = Hdf5Handle(self.path, "w")
            self.f = self.h5.file
            self._stack.callback(self.h5.close)
            self.d = {}
            for key in keys:
                row = (n, n) if key == "M" else (n,)
                self.d[key] = self.f.create_dataset(key, shape=(0, *row), maxshape=(None, *row),
                                                    chunks=(c, *row), dtype="f8")
            if names:
                self.d["names"] = self.f.create_dataset(
                    "names", shape=(0,), maxshape=(None,), chunks=(max(c, 1024),),
                    dtype=h5py.string_dtype("utf-8"))
            if bounds == "shared":
                self.f.create_dataset("lower", data=np.asarray(lower, dtype=np.float64))
                self.f.create_dataset("upper", data=np.asarray(upper, dtype=np.float64))
            if self.n_eq:
                self.f.attrs["n_eq"] = self.n_eq
        else:
            self.tmp = {key: self._stack.enter_context(tempfile.TemporaryFile(  # noqa: SIM115
                dir=self.path.parent, prefix=f".{self.path.name}.")) for key in keys}
            self.shared = (lower, upper)

    def append(self, M: np.ndarray, q: np.ndarray, names: list[str] | None = None,
               lower: np.ndarray | None = None, upper: np.ndarray | None = None) -> None:
        """Add problems: M (c, n, n), q (c, n), names (c) and per-problem bounds (c, n)."""
        c = len(M)
        data = {"M": M, "q": q}
        if self.bounds == "per_problem":
            data.update(lower=lower, upper=upper)
        if self.has_names:
            if names is None or len(names) != c:
                raise ProblemError("a stack with names needs one name per problem")
            self._names.extend(_check_names(list(names)))
        if self.fmt == "hdf5":
            k0, self.K = self.K, self.K + c
            for key, arr in data.items():
                d = self.d[key]
                d.resize(self.K, axis=0)
                d.write_direct(np.ascontiguousarray(arr, dtype=np.float64),
                               dest_sel=np.s_[k0:self.K])
            if self.has_names:
                d = self.d["names"]
                d.resize(self.K, axis=0)
                d[k0:self.K] = np.array(list(names or []), dtype=object)
            self.h5.check()  # stop at the first failed write
        else:
            self.K += c
            for key, arr in data.items():
                self.tmp[key].write(memoryview(np.ascontiguousarray(arr, dtype="<f8"))
                                    .cast("B"))

    def abort(self) -> None:
        """Stop without completing the file (the caller's atomic_path removes it); a write
        failure met while closing is not raised (the error on its way is)."""
        with contextlib.suppress(Exception):
            self._stack.close()

    def close(self) -> int:
        """Complete the file; returns the number of problems written."""
        try:
            if self.K < 1:
                raise ProblemError("no problem to stack")
            if self.fmt == "npz":
                self._write_npz()
        finally:
            self._stack.close()
        return self.K

    def _write_npz(self) -> None:
        K, n = self.K, self.n
        with zipfile.ZipFile(self.path, "w", compression=zipfile.ZIP_STORED,
                             allowZip64=True) as zf:
            for key, fh in self.tmp.items():
                shape = (K, n, n) if key == "M" else (K, n)
                with zf.open(f"{key}.npy", "w", force_zip64=True) as out:
                    _npy_header(out, shape, np.dtype("<f8"))
                    fh.seek(0)
                    shutil.copyfileobj(fh, out, 16 * 2**20)
            if self.has_names:
                width = max(1, max((len(s) for s in self._names), default=1))
                dtype = np.dtype(f"<U{width}")
                with zf.open("names.npy", "w", force_zip64=True) as out:
                    _npy_header(out, (K,), dtype)
                    step = max(1, _NAME_BLOCK_BYTES // dtype.itemsize)
                    for a in range(0, K, step):
                        out.write(np.array(self._names[a:a + step], dtype=dtype).tobytes())
            extra = {}
            if self.bounds == "shared":
                extra = {"lower": self.shared[0], "upper": self.shared[1]}
            if self.n_eq:
                extra["n_eq"] = np.asarray(self.n_eq, dtype=np.int64)
            for key, arr in extra.items():
                with zf.open(f"{key}.npy", "w", force_zip64=True) as out:
                    np.lib.format.write_array(out, np.asarray(arr), allow_pickle=False)


def _npy_header(out: IO[bytes], shape: tuple[int, ...], dtype: np.dtype) -> None:
    d = {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False, "shape": shape}
    try:
        np.lib.format.write_array_header_1_0(out, d)
    except ValueError:  # a header over 64 KiB
        np.lib.format.write_array_header_2_0(out, d)


def write_stack(path: str | Path, M: Any, q: Any, *, names: list[str] | None = None,
                lower: Any = None, upper: Any = None, n_eq: int = 0) -> None:
    """Write K problems ``w = M[k] z + q[k]`` as a stack (format by extension), atomically.

    ``M`` (K, n, n), ``q`` (K, n), ``names`` K strings, ``lower``/``upper`` (n,) shared or
    (K, n), ``n_eq`` shared.  HDF5: datasets chunked along K (about 1 MiB per chunk of M,
    uncompressed), names variable-length UTF-8, ``n_eq`` a root attribute.  NPZ: the layout
    ``np.savez`` writes (uncompressed members).
    """
    fmt = _stack_format(path)
    M = real_array(M, "M")
    q = real_array(q, "q")
    lo = None if lower is None else real_array(lower, "lower")
    up = None if upper is None else real_array(upper, "upper")
    info = _layout(str(path), fmt, M.shape, q.shape,
                   names_shape=None if names is None else (len(names),),
                   lower=None if lo is None else lo.shape, upper=None if up is None else up.shape,
                   n_eq=int(n_eq))
    with atomic_path(path) as tmp:
        w = StackWriter(tmp, fmt, info.n, n_eq=info.n_eq, names=names is not None,
                        bounds=info.bounds, lower=lo if info.bounds == "shared" else None,
                        upper=up if info.bounds == "shared" else None, expected=info.K)
        try:
            step = chunk_size(info.n)
            per = info.bounds == "per_problem"
            for a in range(0, info.K, step):
                b = min(info.K, a + step)
                w.append(M[a:b], q[a:b], None if names is None else [str(s) for s in names[a:b]],
                         lo[a:b] if per else None, up[a:b] if per else None)
        except BaseException:
            w.abort()
            raise
        w.close()


# ------------------------------------------------------------------- conversions
def check_member_name(name: str, what: str = "problem name") -> str:
    """A name usable as an HDF5 group or a file stem: not empty, no '/', no NUL, not '.' or
    '..' (ProblemError otherwise)."""
    if not name or "/" in name or "\0" in name or name in (".", ".."):
        raise ProblemError(f"{what} {name!r} cannot name a group or a file (empty, '.', '..', "
                           f"or holding '/' or NUL)")
    return name


def _folder_files(folder: Path) -> list[Path]:
    from lcpcli.io import PROBLEM_EXTENSIONS

    try:
        files = sorted(f for f in folder.iterdir()
                       if f.suffix.lower() in PROBLEM_EXTENSIONS and f.is_file())
    except OSError as exc:
        raise ProblemError(f"cannot list the folder ({exc.strerror or type(exc).__name__})",
                           str(folder)) from None
    if not files:
        raise ProblemError(f"no problem files in this folder ({', '.join(PROBLEM_EXTENSIONS)})",
                           str(folder))
    return files


def source_problems(source: str | Path) -> Iterator[tuple[str, Problem]]:
    """``(label, problem)`` for every problem of ``source``, streamed: a folder (its problem
    files, sorted, names = file stems), a stack (the naming rule), a multi-group HDF5 file
    (names = group names) or a one-problem file (name = its stem).  ``label`` says where the
    problem comes from (used in messages)."""
    from lcpcli.io import detect_format, list_problems, load

    path = Path(source)
    if str(source) != "-" and path.is_dir():
        for f in _folder_files(path):
            p = load(f)
            p.name = f.stem
            yield str(f), p
        return
    if str(source) != "-" and is_stack(source):
        for p in iter_problems(source):
            yield f"{source} ({p.name})", p
        return
    if str(source) != "-" and detect_format(source) == "hdf5":
        names = list_problems(source)
        if len(names) > 1:
            from lcpcli.io.hdf5_format import read_many

            for name, item in read_many(path, names):
                if isinstance(item, ProblemError):
                    raise item.with_source(f"{source} ({name})")
                item.name = name
                yield f"{source} ({name})", item
            return
    p = load(source)
    p.name = path.stem if str(source) != "-" else (p.name or "stdin")
    yield str(source), p


class _Builder:
    """Buffers problems of one size into chunks for a :class:`StackWriter`."""

    def __init__(self, path: Path, fmt: str) -> None:
        self.path, self.fmt = path, fmt
        self.writer: StackWriter | None = None
        self.buf: list[Problem] = []

    def add(self, label: str, p: Problem) -> None:
        if p.sparse:
            raise ProblemError("M is sparse; a stack holds dense matrices", label)
        if self.writer is None:
            self.first, self.n, self.n_eq = label, p.n, p.n_eq
            self.boxed = p.lower is not None
            self.step = chunk_size(p.n, budget_bytes=8 * 2**20)
            self.writer = StackWriter(self.path, self.fmt, p.n, n_eq=p.n_eq, names=True,
                                      bounds="per_problem" if self.boxed else None)
        elif p.n != self.n:
            raise ProblemError(f"n = {p.n}, but {self.first} has n = {self.n} (a stack holds "
                               f"problems of one size)", label)
        elif p.n_eq != self.n_eq:
            raise ProblemError(f"n_eq = {p.n_eq}, but {self.first} has n_eq = {self.n_eq} (a "
                               f"stack shares n_eq)", label)
        elif (p.lower is not None) != self.boxed:
            has, hasnt = ("has", "has none") if p.lower is not None else ("has no", "has")
            raise ProblemError(f"{has} bounds, but {self.first} {hasnt} (a stack holds one "
                               f"kind of problem)", label)
        self.buf.append(p)
        if len(self.buf) >= self.step:
            self.flush()

    def flush(self) -> None:
        if self.buf and self.writer is not None:
            b = self.buf
            self.writer.append(np.stack([p.M for p in b]), np.stack([p.q for p in b]),
                               [p.name for p in b],
                               np.stack([p.lower for p in b]) if self.boxed else None,
                               np.stack([p.upper for p in b]) if self.boxed else None)
        self.buf = []

    def close(self) -> int:
        if self.writer is None:
            raise ProblemError("no problem to stack")
        self.flush()
        return self.writer.close()


def stack_from_problems(problems: Iterable[Problem] | Iterable[tuple[str, Problem]],
                        path: str | Path) -> int:
    """Write the problems (dense, one size n, one n_eq, all with bounds or none) as a stack
    named by ``problem.name``, streaming chunk by chunk; atomically.  Items may be Problems
    or ``(label, Problem)`` pairs (the label names a refused problem).  Returns K."""
    fmt = _stack_format(path)
    with atomic_path(path) as tmp:
        builder = _Builder(tmp, fmt)
        try:
            for item in problems:
                label, p = (item if isinstance(item, tuple) else (item.name, item))
                builder.add(label, p)
        except BaseException:
            if builder.writer is not None:
                builder.writer.abort()
            raise
        return builder.close()


def copy_stack(source: str | Path, path: str | Path) -> int:
    """Copy a stack into a new stack file (re-chunked, either format), values as stored."""
    fmt = _stack_format(path)
    try:
        with open_stack(source) as r, atomic_path(path) as tmp:
            info, shared = r.info, r._shared
            w = StackWriter(tmp, fmt, info.n, n_eq=info.n_eq, names=info.has_names,
                            bounds=info.bounds, lower=None if shared is None else shared[0],
                            upper=None if shared is None else shared[1], expected=info.K)
            try:
                per = info.bounds == "per_problem"
                for ch in r.chunks():
                    w.append(ch.M, ch.q, ch.names, ch.lower if per else None,
                             ch.upper if per else None)
            except BaseException:
                w.abort()
                raise
            return w.close()
    except ProblemError as exc:
        raise exc.with_source(str(source)) from None


def write_stack_from(source: str | Path, path: str | Path) -> int:
    """``lcpcli convert IN OUT --stack``: a stack input is copied, anything else stacked
    (:func:`source_problems`).  Returns K."""
    if str(source) != "-" and is_stack(source):
        return copy_stack(source, path)
    return stack_from_problems(source_problems(source), path)


def write_groups(problems: Iterable[tuple[str, Problem]], path: str | Path) -> int:
    """One HDF5 group per problem, named by ``problem.name`` (unique, checked), streamed;
    written atomically.  Returns the number of problems."""
    from lcpcli.io.hdf5_format import write_group

    seen: set[str] = set()
    with atomic_path(path) as tmp, open_hdf5(tmp, "w") as f:
        for label, p in problems:
            check_member_name(p.name)
            if p.name in seen:
                raise ProblemError(f"two problems are named '{p.name}'; groups need unique "
                                   f"names", label)
            seen.add(p.name)
            write_group(f.create_group(p.name), p)
    return len(seen)


def source_names(source: str | Path) -> list[str]:
    """The names :func:`source_problems` gives, without reading the problems' data."""
    from lcpcli.io import list_problems

    path = Path(source)
    if path.is_dir():
        return [f.stem for f in _folder_files(path)]
    if is_stack(source):
        try:
            return list_names(source)
        except ProblemError as exc:
            raise exc.with_source(str(source)) from None
    names = list_problems(source)
    return names if len(names) > 1 else [path.stem]


def write_folder(source: str | Path, folder: str | Path, fmt: str, *,
                 force: bool = False) -> int:
    """One file per problem of ``source`` in ``folder`` (created if missing), named
    ``NAME.EXT`` (EXT from ``fmt``: json, npz, h5/hdf5, dat).  Every target is checked before
    anything is written (:func:`~lcpcli.io.writing.check_output`: an existing file is refused
    unless ``force``, an input never overwritten); the files are written all or nothing
    (:class:`~lcpcli.io.writing.StagedFiles`: a bad problem or a full disk leaves none)."""
    from lcpcli.io import _module, check_output, detect_format

    kind = detect_format("", fmt)
    ext = {"json": ".json", "npz": ".npz", "hdf5": ".h5", "dat": ".dat"}[kind]
    folder = Path(folder)
    check_output_folder(folder)
    names = source_names(source)
    seen: set[str] = set()
    for name in names:
        check_member_name(name)
        if name in seen:
            raise ProblemError(f"two problems are named '{name}'; files need unique names",
                               str(source))
        seen.add(name)
    created = None
    if not folder.exists():
        try:
            folder.mkdir()
        except OSError as exc:
            raise ProblemError(f"cannot create the folder ({exc.strerror or type(exc).__name__})",
                               str(folder)) from None
        created = folder
    targets = [folder / f"{name}{ext}" for name in names]
    with StagedFiles(created) as staged:  # all files, or none (and no folder we made)
        for t in targets:
            check_output(t, inputs=[source], force=force)
        write = _module(kind).write
        for (_label, p), t in zip(source_problems(source), targets, strict=True):
            tmp = staged.add(t)
            with writing(t):
                write(p, tmp)
        staged.commit()
    return len(targets)


def check_output_folder(folder: str | Path) -> None:
    """An output folder: an existing directory (not a link), or missing with an existing
    parent (ProblemError naming it otherwise)."""
    import os

    from lcpcli.io.files import file_kind

    try:
        st = os.lstat(folder)
    except FileNotFoundError:
        if not Path(folder).parent.is_dir():
            raise ProblemError(f"folder {Path(folder).parent} does not exist",
                               str(folder)) from None
        return
    except OSError as exc:
        raise ProblemError(f"cannot access it ({exc.strerror or type(exc).__name__})",
                           str(folder)) from None
    if not stat.S_ISDIR(st.st_mode):
        kind = "a regular file" if stat.S_ISREG(st.st_mode) else file_kind(st.st_mode)
        raise ProblemError(f"is {kind}, not a folder: --format writes one file per problem "
                           f"into a folder", str(folder))
