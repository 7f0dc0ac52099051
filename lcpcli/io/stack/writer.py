"""Writing stacked problem files (the layout of :mod:`lcpcli.io.stack.layout`) chunk by
chunk: :class:`StackWriter`, :func:`write_stack`."""

from __future__ import annotations

import contextlib
import shutil
import struct
import tempfile
import time
import zipfile
from contextlib import ExitStack
from pathlib import Path
from typing import IO, Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import real_array
from lcpcli.core.problem import check_size, default_bound
from lcpcli.io.stack.layout import (
    _NAME_BLOCK_BYTES,
    H5_CHUNK_BYTES,
    _check_names,
    _layout,
    _stack_format,
    chunk_size,
)
from lcpcli.io.writing import Hdf5Handle, atomic_path


# ---------------------------------------------------------------------------- writer
class StackWriter:
    """Write a stack chunk by chunk to ``path`` (a new file; callers go through
    :func:`~lcpcli.io.writing.atomic_path`).  ``fmt`` is "hdf5" or "npz"; ``bounds`` is None,
    "shared" (give ``lower``/``upper`` of shape (n,) here) or "per_problem" (give them with
    every :meth:`append`).  ``expected``: the number of problems that will be appended, when
    known (HDF5: M, q and per-problem bounds are then made at that size, stored contiguous;
    appending more, or closing with fewer, is a ValueError).  :meth:`close` completes the
    file and returns K.
    """

    def __init__(self, path: Path, fmt: str, n: int, *, n_eq: int = 0, names: bool = False,
                 bounds: str | None = None, lower: np.ndarray | None = None,
                 upper: np.ndarray | None = None, expected: int | None = None) -> None:
        if n < 1:
            raise ProblemError("a stack needs problems of size n >= 1")
        check_size(n, n)
        self.path, self.fmt, self.n, self.n_eq = Path(path), fmt, n, int(n_eq)
        self.has_names, self.bounds, self.K = names, bounds, 0
        self.expected = expected
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
                if expected:  # one block each, in place in the file (lcpcli.io.stack.mapped)
                    self.d[key] = self.f.create_dataset(key, shape=(expected, *row), dtype="f8",
                                                        dcpl=_allocated_at_once())
                else:
                    self.d[key] = self.f.create_dataset(key, shape=(0, *row),
                                                        maxshape=(None, *row),
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
                if d.shape[0] < self.K:
                    if self.expected:
                        raise ValueError(f"more problems appended than the {self.expected:,} "
                                         f"expected")
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
            elif self.expected and self.expected != self.K:
                raise ValueError(f"{self.K:,} problems appended, not the {self.expected:,} "
                                 f"expected")
        finally:
            self._stack.close()
        return self.K

    def _write_npz(self) -> None:
        K, n = self.K, self.n
        with zipfile.ZipFile(self.path, "w", compression=zipfile.ZIP_STORED,
                             allowZip64=True) as zf:
            for key, fh in self.tmp.items():
                shape = (K, n, n) if key == "M" else (K, n)
                with zf.open(_aligned_member(zf, f"{key}.npy"), "w", force_zip64=True) as out:
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


#: Where the data of the row arrays of an NPZ stack start: at a multiple of this many bytes of
#: the file (a batch reads float64 rows in place only at a multiple of 8,
#: :mod:`lcpcli.io.stack.mapped`; numpy's own header already ends at a multiple of 64 of the
#: member).
NPZ_ALIGN = 64
#: The id of the extra field that pads a member's local zip header (an id no reader knows:
#: each skips it; "lc").
_PAD_FIELD = 0x636C


def _aligned_member(zf: zipfile.ZipFile, name: str) -> zipfile.ZipInfo:
    """A stored member ``name``, about to be written at the current end of ``zf`` with
    zip64 sizes (``force_zip64``), whose local header is padded by an extra field so that
    the ``.npy`` data after numpy's header start at a multiple of :data:`NPZ_ALIGN`."""
    info = zipfile.ZipInfo(name, date_time=time.localtime(time.time())[:6])
    info.compress_type = zipfile.ZIP_STORED
    assert zf.fp is not None
    # local header (30), the name, the pad field's own 4 bytes, the zip64 sizes (20)
    fixed = 30 + len(name.encode("utf-8")) + 4 + 20
    pad = -(zf.fp.tell() + fixed) % NPZ_ALIGN
    info.extra = struct.pack("<HH", _PAD_FIELD, pad) + bytes(pad)
    return info


def _allocated_at_once() -> Any:
    """The HDF5 creation properties of a dataset whose size is known: stored contiguous,
    allocated when it is made (its bytes follow one another in the file: read in place by a
    batch, :mod:`lcpcli.io.stack.mapped`; chunked storage puts the chunk index's blocks
    between chunks), no fill value written first."""
    import h5py

    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    dcpl.set_fill_time(h5py.h5d.FILL_TIME_NEVER)
    return dcpl


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
    (K, n) (one of them alone: the other by the one-sided bounds rule, stored), ``n_eq``
    shared.  HDF5: M, q and per-problem bounds stored contiguous (uncompressed, one block
    each: read in place by a batch), names variable-length UTF-8, ``n_eq`` a root
    attribute.  NPZ: the layout ``np.savez`` writes (uncompressed members).
    """
    fmt = _stack_format(path)
    M = real_array(M, "M")
    q = real_array(q, "q")
    lo = None if lower is None else real_array(lower, "lower")
    up = None if upper is None else real_array(upper, "upper")
    info = _layout(str(path), fmt, M.shape, q.shape,
                   names_shape=None if names is None else (len(names),),
                   lower=None if lo is None else lo.shape, upper=None if up is None else up.shape,
                   n_eq=n_eq)
    if info.bounds is not None:  # both stored: a missing one by the one-sided bounds rule
        shape = (info.n,) if info.bounds == "shared" else (info.K, info.n)
        lo = default_bound("lower", shape) if lo is None else \
            np.ascontiguousarray(np.broadcast_to(lo, shape))
        up = default_bound("upper", shape) if up is None else \
            np.ascontiguousarray(np.broadcast_to(up, shape))
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
