"""Stacked result files read back as warm starts (``lcpcli solve STACK --z0 PREVIOUS``).

A stacked result file is what ``lcpcli solve STACK -o results.h5`` (or ``.npz``) writes
(:mod:`lcpcli.batch.stack_output`): per problem ``z`` (K, n), ``status`` (K,) and, from this
version on, ``basis`` (K, n) int8 (the codes of :attr:`lcpcli.core.result.Result.basis`, -1:
none).  :class:`StackResultFile` reads one back, chunk by chunk, under the reading rules of
every input (docs/files.md, "Reading"): a regular file; HDF5 read-only, with the root mark
:data:`RESULTS_MARK`, one stack (group) in it, every object reached through hard links (an
external link, virtual or external storage is refused, never opened), shapes and types
checked from the headers against the stack's ``K`` and ``n`` before any data is read; NPZ
with every member's ``.npy`` header checked the same way before it is decompressed.  Each
chunk read is checked too: status codes and basis codes only.  Errors are
:class:`~lcpcli.core.errors.ProblemError` naming the file (``--z0 PATH``).
"""

from __future__ import annotations

import hashlib
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import INDEX_KINDS, REAL_KINDS
from lcpcli.core.result import NOT_DONE, STATUS_CODES
from lcpcli.io.files import check_input_file, open_input
from lcpcli.io.npz_format import MAX_MEMBERS, ZIP_ERRORS, Member, zip_error

#: Root attribute that marks an HDF5 file as stacked results of lcpcli.
RESULTS_MARK = "lcpcli_stacked_results"
#: Codes a ``basis`` dataset may hold: none (-1), then ``L``, ``U``, ``F``
#: (:data:`lcpcli.core.result.BASIS_LETTERS`).
BASIS_CODES = (-1, 0, 1, 2)
_STATUS_CODES = np.array(sorted({*STATUS_CODES.values(), NOT_DONE}))
#: Codes checked per block when a file is opened (rows times n).
_CHECK_ROWS = 1 << 20
_NOT_RESULTS = ("is not a stacked result file of lcpcli (what 'lcpcli solve STACK -o "
                "results.h5' or '.npz' writes)")
#: The per-problem arrays of a stacked result file: the kinds of data type each may have, and
#: whether a problem's row holds ``n`` values (shape (K, n)) or one (shape (K,)).
RESULT_ARRAYS = {"z": (REAL_KINDS, True), "w": (REAL_KINDS, True),
                 "status": (INDEX_KINDS, False), "iterations": (INDEX_KINDS, False),
                 "error": (REAL_KINDS, False), "residual": (REAL_KINDS, False),
                 "basis": (INDEX_KINDS, True)}


def check_shapes(shapes: dict[str, tuple[int, ...] | None], K: int, n: int) -> None:
    """ProblemError unless each per-problem array's shape (None: absent) is what a stack of
    ``K`` problems of size ``n`` needs (:data:`RESULT_ARRAYS`)."""
    for key, shape in shapes.items():
        want = (K, n) if RESULT_ARRAYS[key][1] else (K,)
        if shape is not None and shape != want:
            raise ProblemError(f"its '{key}' has shape {shape}; the stack needs "
                               f"{want} (K = {K:,}, n = {n:,})")


@contextmanager
def result_members(path: str | Path) -> Iterator[dict[str, Member]]:
    """The ``.npy`` members of a stacked result NPZ by name (at most :data:`MAX_MEMBERS`
    entries; ``z`` and ``status`` required), each with its header read and checked against
    its zip entry's size, no data read yet: the caller checks shapes and types
    (:func:`read_results`) before it reads.  A damaged archive or member, met here or while
    the caller reads, is a one-line ProblemError (no source: the caller names the file)."""
    try:
        with open_input(path, "a stacked result file") as fh, zipfile.ZipFile(fh) as zf:
            infos = zf.infolist()
            if len(infos) > MAX_MEMBERS:
                raise ProblemError(f"holds {len(infos):,} zip entries; {_NOT_RESULTS}")
            entries = {i.filename[:-4]: i for i in infos if i.filename.endswith(".npy")}
            if "z" not in entries or "status" not in entries:
                raise ProblemError(_NOT_RESULTS)
            yield {key: Member(zf, info, key) for key, info in entries.items()}
    except ProblemError:
        raise
    except (*ZIP_ERRORS, ValueError) as exc:
        raise zip_error(exc) from None


def read_results(members: dict[str, Member], keys: tuple[str, ...], K: int, n: int
                 ) -> dict[str, np.ndarray]:
    """The per-problem arrays ``keys`` present in ``members`` (:func:`result_members`), every
    one's type and shape checked from its header before any is read."""
    present = {key: members[key] for key in keys if key in members}
    for key, member in present.items():
        member.check(f"'{key}'", RESULT_ARRAYS[key][0])
    check_shapes({key: m.shape for key, m in present.items()}, K, n)
    return {key: m.read() for key, m in present.items()}


class ResultChunk(NamedTuple):
    """Problems ``start .. stop-1`` of a stacked result file."""

    z: np.ndarray  # (k, n) float64
    status: np.ndarray  # (k,) int8, codes of STATUS_CODES (-1: not solved)
    basis: np.ndarray | None  # (k, n) int8, codes of BASIS_CODES; None: the file has none


def is_stack_results(path: str | Path) -> bool:
    """Whether ``path`` names a stacked result file by its kind: an HDF5 file (``.h5``,
    ``.hdf5``: a warm-start vector is never one), or an NPZ with a ``status`` member.  Reads
    the zip directory at most; never raises (the reader reports what is wrong)."""
    suffix = Path(path).suffix.lower()
    if suffix in (".h5", ".hdf5"):
        return True
    if suffix != ".npz":
        return False
    try:
        with open_input(path, "a stacked result file") as fh, zipfile.ZipFile(fh) as zf:
            return "status.npy" in zf.namelist()
    except Exception:  # noqa: BLE001 - a cheap test: the normal reader reports the problem
        return False


def file_digest(path: str | Path) -> str:
    """The SHA-256 digest (hex) of a file's bytes, read through :func:`open_input`."""
    h = hashlib.sha256()
    with open_input(path, "a stacked result file") as fh:
        while block := fh.read(1 << 20):
            h.update(block)
    return h.hexdigest()


class StackResultFile:
    """A stacked result file of ``K`` problems of size ``n``, opened for chunked reads
    (:meth:`read`); a context manager.  ProblemError (naming ``--z0 PATH``) when the file is
    not such a file, holds another K or n, or reaches outside itself."""

    def __init__(self, path: str | Path, K: int, n: int) -> None:
        self.path, self.K, self.n = Path(path), K, n
        self.source = f"--z0 {path}"
        self._h5: Any = None
        self._arrays: dict[str, np.ndarray] = {}
        try:
            check_input_file(self.path, "a stacked result file")
            suffix = self.path.suffix.lower()
            if suffix in (".h5", ".hdf5"):
                self._open_hdf5()
            elif suffix == ".npz":
                self._open_npz()
            else:
                raise ProblemError(_NOT_RESULTS)
            self._check_codes()
        except ProblemError as exc:
            self.close()
            raise exc.with_source(self.source) from None
        except (*ZIP_ERRORS, ValueError) as exc:
            self.close()
            first = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
            raise ProblemError(f"cannot read a stacked result file ({first})",
                               self.source) from None

    # ------------------------------------------------------------------------- opening
    def _sizes(self, K: int | None, n: int | None) -> None:
        if (K, n) != (self.K, self.n):
            raise ProblemError(f"holds results for K = {K}, n = {n}, but the stack has "
                               f"K = {self.K:,}, n = {self.n:,}")

    def _open_hdf5(self) -> None:
        import h5py

        from lcpcli.io import hdf5_format as h5

        self._h5 = f = h5.open_file(self.path)
        try:
            if h5.attr_int(f, RESULTS_MARK) != 1:
                raise ProblemError(_NOT_RESULTS)
            names = list(f.keys())
            if len(names) != 1:
                raise ProblemError(f"holds the results of {len(names)} stacks; --z0 takes "
                                   f"the result file of one stack")
            g = h5.child(f, names[0], names[0])
            if not isinstance(g, h5py.Group):
                raise ProblemError(_NOT_RESULTS)
            self._sizes(h5.attr_int(g, "K"), h5.attr_int(g, "n"))
            self._d = {"z": h5.dataset(g, "z", "z"),
                       "status": h5.dataset(g, "status", "status", kinds=INDEX_KINDS),
                       "basis": h5.dataset(g, "basis", "basis", kinds=INDEX_KINDS)}
            if self._d["z"] is None or self._d["status"] is None:
                raise ProblemError(_NOT_RESULTS)
            check_shapes({k: None if d is None else tuple(int(x) for x in d.shape)
                          for k, d in self._d.items()}, self.K, self.n)
        except h5.H5_ERRORS as exc:  # a refusal of the reading layer passes through whole
            raise h5.damaged(exc) from None

    def _open_npz(self) -> None:
        with result_members(self.path) as members:
            self._arrays = read_results(members, ("z", "status", "basis"), self.K, self.n)

    # ------------------------------------------------------------------------- reading
    def _rows(self, key: str, start: int, stop: int, dtype: Any) -> np.ndarray | None:
        if self._h5 is None:
            a = self._arrays.get(key)
            return None if a is None else np.asarray(a[start:stop], dtype=dtype)
        from lcpcli.io import hdf5_format as h5

        d = self._d[key]
        if d is None:
            return None
        out = np.empty((stop - start, *d.shape[1:]), dtype=dtype)
        if out.size:
            try:
                d.read_direct(out, source_sel=np.s_[start:stop])
            except h5.H5_ERRORS as exc:
                raise h5.damaged(exc) from None
        return out

    def read(self, start: int, stop: int) -> ResultChunk:
        """Problems ``start .. stop-1`` (``0 <= start <= stop <= K``), checked."""
        if not 0 <= start <= stop <= self.K:
            raise ValueError(f"rows {start}..{stop} outside 0..{self.K}")
        try:
            z = self._rows("z", start, stop, np.float64)
            status, basis = self._codes(start, stop)
        except ProblemError as exc:
            raise exc.with_source(self.source) from None
        return ResultChunk(z, status, basis)

    def _codes(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray | None]:
        """``status`` and ``basis`` of rows ``start .. stop-1``, their codes checked."""
        status = self._rows("status", start, stop, np.int64)
        basis = self._rows("basis", start, stop, np.int64)
        bad = status[~np.isin(status, _STATUS_CODES)]
        if bad.size:
            raise ProblemError(f"its status holds {int(bad[0])}, which is no status code")
        if basis is not None:
            bad = basis[~np.isin(basis, BASIS_CODES)]
            if bad.size:
                raise ProblemError(f"its basis holds {int(bad[0])}, which is no basis code "
                                   f"(-1 none, 0 L, 1 U, 2 F)")
        return status.astype(np.int8), None if basis is None else basis.astype(np.int8)

    def _check_codes(self) -> None:
        """Every status and basis code checked before any problem is solved (blocks of
        :data:`_CHECK_ROWS` rows), so that a damaged file stops the run before it writes."""
        step = max(1, _CHECK_ROWS // max(1, self.n))
        for start in range(0, self.K, step):
            self._codes(start, min(self.K, start + step))

    def close(self) -> None:
        if self._h5 is not None:
            self._h5.close()
            self._h5 = None

    def __enter__(self) -> StackResultFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
