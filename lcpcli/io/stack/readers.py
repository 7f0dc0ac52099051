"""Reading stacked problem files (the layout of :mod:`lcpcli.io.stack.layout`): detection
from headers (:func:`is_stack`), the HDF5 and NPZ sources, :class:`StackReader` and the
functions built on it."""

from __future__ import annotations

import math
import os
import struct
import zipfile
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import kind_name
from lcpcli.core.problem import Problem, default_bound
from lcpcli.io.files import MAX_NAME_BYTES, check_input_file, open_input, too_big
from lcpcli.io.npz_format import MAX_MEMBERS, ZIP_ERRORS, Member, read_npy_header, zip_error
from lcpcli.io.stack.layout import (
    _CHUNK_BUDGET,
    _NAME_BLOCK_BYTES,
    H5_CACHE_BYTES,
    H5_CACHE_SLOTS,
    MAX_NAMES_DECLARED,
    StackChunk,
    StackInfo,
    _check_names,
    _layout,
    _stack_format,
    chunk_size,
    problem_name,
    stacked_message,
)
from lcpcli.io.stack.mapped import MappedStack, Runs, h5_runs, in_place, map_stack, npz_runs


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

        with open_input(path) as fh, zipfile.ZipFile(fh) as zf, zf.open("M.npy") as m:
            shape, _dtype = read_npy_header(m)
            return len(shape) == 3
    except Exception:  # noqa: BLE001 - a cheap test: the normal reader reports the problem
        return False




def _row_keys(info: StackInfo) -> list[str]:
    """The arrays read row by row: M, q and the bounds stored per problem ((K, n))."""
    return ["M", "q"] + [label for label, shape in (("lower", info.lower_shape),
                                                    ("upper", info.upper_shape))
                         if shape is not None and len(shape) == 2]


# ------------------------------------------------------------------------------ HDF5
class _H5Source:
    """The HDF5 side of a reader: checked datasets, read by slices.  ``direct``: no chunk
    cache where the data are stored unfiltered (each read goes from the file into the
    caller's array, not through the cache and a second copy; a storage chunk cut by two read
    chunks is then read in two parts, none twice); filtered (compressed) data keep the
    cache."""

    def __init__(self, path: Path, direct: bool = False) -> None:
        from lcpcli.io import hdf5_format as h5

        self.path = path
        self.f = h5.open_file(path, rdcc_nbytes=0 if direct else H5_CACHE_BYTES,
                              rdcc_nslots=H5_CACHE_SLOTS, rdcc_w0=1.0)
        try:
            self._scan(path)
            if direct and self._filtered():
                self.f.close()
                self.f = h5.open_file(path, rdcc_nbytes=H5_CACHE_BYTES,
                                      rdcc_nslots=H5_CACHE_SLOTS, rdcc_w0=1.0)
                self._scan(path)
        except BaseException:
            self.f.close()
            raise

    def _filtered(self) -> bool:
        """Whether a dataset read by rows (M, q, bounds) is stored through filters."""
        return any(d is not None and d.id.get_create_plist().get_nfilters() > 0
                   for key, d in self.d.items() if key != "names")

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
                                upper=shape("upper"), n_eq=h5.attr_int(f, "n_eq") or 0)
            self.info = replace(self.info, in_place=in_place(
                [h5_runs(self.d[key], whole=True) for key in _row_keys(self.info)],
                self.info.K))
            if names is not None and self.info.K * longest > MAX_NAMES_DECLARED:

                raise too_big(self.info.K * longest, MAX_NAMES_DECLARED,
                              "the declared 'names' (rows x longest name or fill value)")
        except ProblemError:
            raise
        except h5.H5_ERRORS as exc:
            raise h5.damaged(exc) from None

    def map(self, keys: list[str]) -> MappedStack | None:
        """The arrays ``keys`` mapped where their rows are (:mod:`lcpcli.io.stack.mapped`),
        through the file descriptor HDF5 reads (a file opened by the default driver only)."""
        from lcpcli.io import hdf5_format as h5

        try:
            if self.f.driver != "sec2":
                return None
            runs = {key: h5_runs(self.d[key]) for key in keys}
            return map_stack(self.path, int(self.f.id.get_vfd_handle()), runs)
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
        self.path = path
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
        self.info = replace(self.info, in_place=in_place(
            [self._runs(key) for key in _row_keys(self.info)], self.info.K))

    def _runs(self, key: str) -> Runs | None:
        m, base = self.m[key], self.offsets[key]
        return npz_runs(m.shape, m.dtype, m.fortran, None if base is None else base + m.header_len)

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

    def map(self, keys: list[str]) -> MappedStack | None:
        """The members ``keys`` mapped where stored uncompressed (:mod:`.mapped`)."""
        return map_stack(self.path, self.fh.fileno(), {key: self._runs(key) for key in keys})

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

    def __init__(self, path: str | Path, direct: bool = False, mapped: bool = False) -> None:
        self.path = Path(path)
        #: The file as given: the ``FILE:`` of the errors of reading its chunks.
        self.source = str(path)
        self._mapped: MappedStack | None = None
        self._stack = ExitStack()
        try:
            fmt = _stack_format(path)
            check_input_file(path)
            if fmt == "hdf5":
                src: Any = _H5Source(self.path, direct)
                self._stack.callback(src.close)
            else:
                src = _NpzSource(self.path, self._stack)
            self._src = src
            self.info: StackInfo = src.info
            n = self.info.n
            #: The bounds shared by every problem ((n,): stored so, or filled by the one-sided
            #: bounds rule); a bound stored per problem is read with each chunk.
            self._side: dict[str, np.ndarray] = {}
            if self.info.bounds is not None:
                for label, shape in (("lower", self.info.lower_shape),
                                     ("upper", self.info.upper_shape)):
                    if shape is None:
                        self._side[label] = default_bound(label, n)
                    elif shape == (n,):
                        self._side[label] = np.empty(n)
                        src.whole(label, self._side[label])
            self._shared: tuple[np.ndarray, np.ndarray] | None = None
            if self.info.bounds == "shared":
                self._shared = (self._side["lower"], self._side["upper"])
            if mapped:
                self._mapped = self._map()
        except BaseException:
            self._stack.close()
            raise

    def __enter__(self) -> StackReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._stack.close()

    def _map(self) -> MappedStack | None:
        """The row arrays mapped (:mod:`lcpcli.io.stack.mapped`), once the first row of
        each array's first run read in place is found equal to the same row read by the
        format's own reader (a check of the offsets the format gave); None when nothing is
        mappable."""
        mapped = self._src.map(_row_keys(self.info))
        if mapped is None:
            return None
        n = self.info.n
        for key, runs in list(mapped.runs.items()):
            first = runs.starts[0]
            got = mapped.view(key, first, first + 1)
            want = np.empty((1, n, n) if key == "M" else (1, n))
            self._src.rows(key, first, first + 1, want)
            if got is None or got[0].tobytes() != want.tobytes():
                del mapped.runs[key]
        mapped.views = 0
        return mapped if mapped.runs else None

    @property
    def mapped_views(self) -> int:
        """Arrays of chunks read in place so far (:meth:`read`), 0 when nothing is mapped."""
        return 0 if self._mapped is None else self._mapped.views

    def copies(self, start: int, stop: int) -> bool:
        """Whether :meth:`read` of problems ``start .. stop - 1`` copies M or q (into its
        ``out`` buffers), rather than handing out views of the mapped file."""
        m = self._mapped
        return m is None or any(key not in m.runs or m.runs[key].find(start, stop) is None
                                for key in ("M", "q"))

    def _check_range(self, start: int, stop: int) -> None:
        if not 0 <= start <= stop <= self.info.K:
            raise IndexError(f"problems {start}..{stop - 1} are outside 0..{self.info.K - 1}")

    def read_names(self, start: int, stop: int) -> list[str] | None:
        """The stored names of problems ``start .. stop-1`` (None when the file has none)."""
        self._check_range(start, stop)
        try:
            return self._src.names(start, stop) if self.info.has_names else None
        except ProblemError as exc:
            raise exc.with_source(self.source) from None

    def read(self, start: int, stop: int,
             out: tuple[np.ndarray, np.ndarray] | None = None) -> StackChunk:
        """Problems ``start .. stop-1``: float64 C-contiguous arrays (values not checked).
        ``out``: float64 C-contiguous buffers ``(M, q)`` of at least ``stop - start`` rows that
        the chunk's ``M`` and ``q`` are read into (their leading rows; a batch reuses them from
        chunk to chunk instead of allocating, and faulting in, new memory for each).  A reader
        opened ``mapped`` hands out read-only views of the file instead where the rows are
        mappable (:mod:`lcpcli.io.stack.mapped`; ``out`` is then not used for them) and
        the chunk's ``check`` (call it once done with the chunk's data) raises when the file
        was truncated under them."""
        self._check_range(start, stop)
        c, n = stop - start, self.info.n
        spans: list[tuple[int, int]] = []

        def place(key: str, shape: tuple[int, ...], buffer: np.ndarray | None) -> np.ndarray:
            got = None if self._mapped is None else self._mapped.view(key, start, stop)
            if got is not None:
                spans.append(got[1:])
                return got[0]
            arr = np.empty(shape) if buffer is None else buffer
            try:
                self._src.rows(key, start, stop, arr)
            except ProblemError as exc:  # damaged or truncated data: name the file
                raise exc.with_source(self.source) from None
            return arr

        bufs: list[np.ndarray | None] = [None, None]
        if out is not None:
            bufs = [out[0][:c], out[1][:c]]
            M, q = bufs
            if M.shape != (c, n, n) or q.shape != (c, n) or M.dtype != np.float64 \
                    or q.dtype != np.float64 or not (M.flags.c_contiguous
                                                     and q.flags.c_contiguous):
                raise ValueError(f"read buffers {out[0].shape}, {out[1].shape} do not hold "
                                 f"{c} problems of n = {n} as C-contiguous float64")
        M = place("M", (c, n, n), bufs[0])
        q = place("q", (c, n), bufs[1])
        bounds: list[np.ndarray | None] = [None, None]
        if self.info.bounds is not None:
            for j, label in enumerate(("lower", "upper")):
                if label in self._side:
                    bounds[j] = np.repeat(self._side[label][None, :], c, axis=0)
                else:
                    bounds[j] = place(label, (c, n), None)
        lower, upper = bounds
        check = None
        if spans:
            mapped = self._mapped
            assert mapped is not None

            def check() -> None:
                mapped.check(spans, start, stop)

        return StackChunk(start, M, q, self.read_names(start, stop), lower, upper, check)

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


def open_stack(path: str | Path, *, direct: bool = False, mapped: bool = False
               ) -> StackReader:
    """Open and check a stack file (every rule of :func:`stack_info`).  ``direct``: for
    reading in large chunks, in order (a stacked batch): HDF5 data stored unfiltered are read
    without the chunk cache (:class:`_H5Source`).  ``mapped``: rows stored so are read in
    place, as views of the file mapped into memory (:mod:`lcpcli.io.stack.mapped`; each
    chunk's ``check`` must then be called once its data are used)."""
    return StackReader(path, direct, mapped)


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
