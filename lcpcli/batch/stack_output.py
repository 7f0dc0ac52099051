"""Result files of stacked batches: stacked datasets (``.h5``, ``.npz``) or rows (``.jsonl``,
``.csv``), written chunk by chunk and resumable.

**HDF5** (``results.h5``): the root attribute ``lcpcli_stacked_results`` (1) marks the layout;
one group per input stack (named after the file's stem, ``stem~2`` on a clash), with
attributes ``source`` (the input as given), ``n``, ``K``, ``method``, ``tol`` and
``status_codes`` (JSON: status -> code), and datasets, indexed by the 0-based problem index:
``z``, ``w`` (K, n) float64, ``status`` (K,) int8 (:data:`lcpcli.core.result.STATUS_CODES`;
-1: not solved yet), ``iterations`` (K,) int64, ``error`` and ``residual`` (K,) float64 (NaN
where none), ``basis`` (K, n) int8 (each problem's final basis, the codes of
:attr:`lcpcli.core.result.Result.basis`: 0 ``L``, 1 ``U``, 2 ``F``; -1 where none: not solved
yet, or an ``error`` problem; what ``solve STACK --z0 THIS_FILE`` starts from), ``names`` (K,)
when the input has names, and the input's fingerprint (below).
Each chunk's data are written and flushed, then its digest and ``status``, and flushed again,
before the next chunk's results are written (one writer thread writes the chunks in order while the
next chunk is solved and the one after it read: :mod:`lcpcli.batch.stacked`); Ctrl-C, SIGTERM or
SIGHUP close the file cleanly, so ``--resume`` finds every finished chunk. The file is created
complete (every group and dataset) in a temporary file renamed over the output, so a full disk at
the start leaves the previous file as it was; a full disk later leaves a resumable file (``status``
-1 marks what is not done) and one line ``PATH: no space left on device (...)``, exit 2. The
datasets are allocated in full when the file is created (``ALLOC_TIME_EARLY``), so writing a chunk
changes data only, never HDF5's metadata: a ``kill -9`` leaves a readable file whose ``status``
says which problems finished (a chunk cut in the middle has ``status`` -1 and is solved again). A
file that is still unreadable is refused by ``--resume`` with a message (run again without it).

**Fingerprint** (``--resume`` never keeps results of other data): each group records
``chunk`` (problems per chunk), ``chunk_digest`` (chunks, 16) uint8, the digest of each
finished chunk's input bytes (M, q, bounds and names: :func:`chunk_digest`; zeros: none yet),
``digest`` (its algorithm, :mod:`lcpcli.batch.digest`: ``mxs128`` in new files; a file
without it was written with ``sha256``, which ``--resume`` then verifies and goes on with) and
``solve_options`` (JSON: method, tol, options).  ``--resume`` reads the chunks that hold
finished problems again and refuses, with one line, a file whose digests or options differ
from this run's, a file that names a digest this lcpcli does not know, and a file without
them (written by an older lcpcli: run without ``--resume``); a problem counts as done only
when its chunk's digest is recorded.

**NPZ** (``results.npz``, one input stack): the same arrays at the top level plus ``source``
(and ``digest``, as the attribute);
held in memory and written atomically when the batch ends (also on Ctrl-C / SIGTERM / SIGHUP),
so the file on disk is always complete; ``--resume`` starts from it.

**Rows** (``.jsonl``/``.csv``): one row per problem, see :mod:`lcpcli.batch.stacked`; the
row's ``index`` is the position in the stack, which ``--resume`` uses, and its ``input_hash``
the ``sha256`` digest of its chunk (chunks of :func:`lcpcli.io.stack.chunk_size` problems).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.batch import output
from lcpcli.batch.digest import LEGACY, STACKED, digest_of, recorded_algorithm
from lcpcli.batch.output import (
    DIGEST_BYTES,
    INPUT_HASH,
    checked_output,
    hdf5_text,
    output_kind,
)
from lcpcli.batch.records import RERUN, no_fingerprints, other_settings
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.numeric import REAL_KINDS
from lcpcli.core.result import NOT_DONE, STATUS_CODES, status_counts
from lcpcli.io import stack as io_stack
from lcpcli.io.files import MAX_NAME_BYTES
from lcpcli.io.hdf5_format import H5_ERRORS
from lcpcli.io.npz_format import Member
from lcpcli.io.stack.results import RESULTS_MARK, read_results, result_members
from lcpcli.io.writing import (
    Hdf5Handle,
    atomic_file,
    atomic_path,
    check_hdf5_tree,
    open_hdf5,
    own_file,
    writing,
)

#: Root attribute marking an HDF5 file as stacked results.
MARK = RESULTS_MARK
_ARRAYS = ("z", "w", "status", "iterations", "error", "residual", "basis")
#: The fill of ``basis`` where a problem has none (not solved yet, or an ``error`` problem).
NO_BASIS = -1
#: What a write failure leaves in a stacked result file (the message says it).
KEPT = "the finished problems are kept (status -1 marks the others): free space, then run " \
       "again with --resume"


def chunk_digest(part: Any, algorithm: str) -> bytes:
    """The fingerprint of a chunk of a stack (:class:`lcpcli.io.stack.StackChunk`) by the
    digest ``algorithm`` (:mod:`lcpcli.batch.digest`): :func:`lcpcli.batch.digest.digest_of`
    of the little-endian float64 bytes of M, q, lower and upper (``-`` for a bound the chunk
    has not) and, when it has names, of their UTF-8 bytes joined by NUL."""
    pieces: list[Any] = []
    for arr in (part.M, part.q, part.lower, part.upper):
        pieces.append(b"-" if arr is None else np.ascontiguousarray(arr, dtype="<f8"))
    if part.names is not None:
        pieces.append("\0".join(part.names).encode("utf-8", "surrogateescape"))
    return digest_of(algorithm, pieces)


def options_fingerprint(opts: Any, warm_digest: str | None = None) -> str:
    """The solve options a result was computed with (JSON: method, tol, options, and with a
    warm start (``--z0 PREVIOUS``) ``warm``: the SHA-256 digest of that file's bytes)."""
    record = {"method": opts.method, "tol": opts.tol, "options": opts.options}
    if warm_digest is not None:
        record["warm"] = warm_digest
    return json.dumps(record, sort_keys=True, default=repr)


def _text(text: Any) -> str:

    return hdf5_text(text)


def _check_status(status: np.ndarray, path: Path) -> None:
    """ProblemError when ``status`` holds a value that is no status code (a damaged file)."""
    codes = np.array(sorted(set(STATUS_CODES.values()) | {NOT_DONE}))
    bad = status[~np.isin(status, codes)]
    if bad.size:
        raise ProblemError(f"cannot be resumed: its status holds {int(bad[0])}, which is no "
                           f"status code (a damaged or foreign file); {RERUN}", str(path))


def _check_layout(g: Any, info: Any, path: Path) -> None:
    """ProblemError unless every dataset of the group ``g`` that a resumed batch reads or
    writes has the shape and the kind of type :meth:`Hdf5StackWriter._create` gives it (from
    the headers: a damaged or foreign file is refused before anything is read or written)."""
    import h5py

    expected = {key: (value.dtype.kind, (info.K, *value.shape[1:]))
                for key, value in _empty_arrays(0, info.n).items()}
    expected["chunk_digest"] = ("u", (_chunks(info.K, int(g.attrs["chunk"])), DIGEST_BYTES))
    for key, (kind, shape) in expected.items():
        d = g.get(key)
        ok = isinstance(d, h5py.Dataset) and d.shape == shape and (
            d.dtype.kind == kind or (kind in "iu" and d.dtype.kind in "iu"))
        if not ok:
            what = "missing" if d is None else f"of {getattr(d, 'dtype', 'no type')} and " \
                f"shape {getattr(d, 'shape', None)}"
            want = "floats" if kind == "f" else "integers"
            raise ProblemError(f"cannot be resumed: its '{key}' of {info.path} is {what}, not "
                               f"{want} of shape {shape} (a damaged or foreign file); {RERUN}",
                               str(path))
    names = g.get("names")
    if names is not None and not (isinstance(names, h5py.Dataset) and names.shape == (info.K,)
                                  and h5py.check_string_dtype(names.dtype) is not None):
        raise ProblemError(f"cannot be resumed: its 'names' of {info.path} are not {info.K} "
                           f"strings (a damaged or foreign file); {RERUN}", str(path))


def _done_mask(status: np.ndarray, digests: np.ndarray, chunk: int) -> np.ndarray:
    """Finished problems: a status code, in a chunk whose digest is recorded."""
    recorded = digests.any(axis=1)
    return (status != NOT_DONE) & np.repeat(recorded, chunk)[:status.size]


def _recorded(status: np.ndarray, digests: np.ndarray, chunk: int) -> dict[int, bytes]:
    done = _done_mask(status, digests, chunk)
    chunks = np.unique(np.flatnonzero(done) // chunk)
    return {int(c): bytes(digests[c]) for c in chunks.tolist()}


def _empty_arrays(K: int, n: int) -> dict[str, np.ndarray]:
    return {"z": np.full((K, n), np.nan), "w": np.full((K, n), np.nan),
            "status": np.full(K, NOT_DONE, np.int8), "iterations": np.zeros(K, np.int64),
            "error": np.full(K, np.nan), "residual": np.full(K, np.nan),
            "basis": np.full((K, n), NO_BASIS, np.int8)}


def _chunk_arrays(res: Any) -> dict[str, np.ndarray]:
    return {"z": res.z, "w": res.w, "status": res.status, "iterations": res.iterations,
            "error": np.where(np.isfinite(res.error), res.error, np.nan),
            "residual": res.residual,
            "basis": np.full(res.z.shape, NO_BASIS, np.int8) if res.basis is None
            else res.basis}


#: M (bytes) of one chunk of a stacked batch (:func:`batch_chunk`) where its threads all get
#: work: half :func:`lcpcli.io.stack.chunk_size`'s 32 MiB.  Each chunk read goes into memory
#: the process has not touched yet until the two chunk buffers are made, and the kernel
#: zeroes every such page first (on the 2-core reference machine: 60-120 ms of CPU for two
#: chunks of 32 MiB, 0.03-0.05 s less CPU in all at n = 12 with 16 MiB; smaller chunks cost
#: more again at n = 50, per chunk).
BATCH_CHUNK_BYTES = 16 * 2**20
#: M (bytes) of one chunk of a stacked batch whose stack is read in place
#: (:attr:`lcpcli.io.stack.StackInfo.in_place`: no buffer is filled, so no new memory): fewer
#: chunks, fewer of the serial steps between two kernel calls.  Measured on the reference
#: machine (in-process timelines, --jobs 2): n = 50, K = 20,000 0.31-0.33 s with 16 MiB,
#: 0.30-0.39 s with 32, 0.26-0.29 s with 64, 0.26 s with 128; n = 12, K = 100,000 0.15-0.17 s
#: with 16 MiB, 0.126-0.134 s with 64, 0.128-0.139 s with 128.
IN_PLACE_CHUNK_BYTES = 64 * 2**20


def result_row_bytes(n: int) -> int:
    """About the bytes of one problem's results in memory while its chunk is solved and
    written: z and w (8n each), the basis (n), status, iterations, error, residual and the
    kernel's certificate fields (64)."""
    return 17 * n + 64


def _in_place_budget(n: int) -> int:
    """The bytes of M of a chunk read in place: at most :data:`IN_PLACE_CHUNK_BYTES`, and
    at most as many problems as have that many bytes of results (which outweigh M below
    n = 5: a chunk of n = 1 holds 0.83 million problems, not 8 million)."""
    m = max(8, 8 * n * n)
    return min(IN_PLACE_CHUNK_BYTES, IN_PLACE_CHUNK_BYTES * m // result_row_bytes(n))


#: Largest M (bytes) of one chunk of a stacked batch that :func:`batch_chunk` grows for its
#: threads (two chunks are in memory at once: one read ahead, one solved).
MAX_CHUNK_BYTES = 256 * 2**20
#: Problems per thread a chunk holds at least where that fits :data:`MAX_CHUNK_BYTES` (the
#: kernels hand out problems 16 at a time).
PER_THREAD = 16


#: Most problems in one chunk of a stacked batch whose problems are solved one at a time
#: through the one-problem pipeline (a method without a batched kernel: ``per_problem``):
#: a chunk is written, counted by the progress bar and kept after Ctrl-C as a whole, and
#: 58,254 problems of n = 12 solved by ``-m newton`` (30 s) were all lost to a Ctrl-C
#: after 4 s, with the bar at 0 until the end.
PER_PROBLEM_CHUNK = 1024


def batch_chunk(n: int, threads: int, in_place: bool = False, per_problem: bool = False
                ) -> int:
    """Problems per chunk of a stacked batch of size-n problems on ``threads`` threads
    (``per_problem``: at most :data:`PER_PROBLEM_CHUNK`):
    :func:`lcpcli.io.stack.chunk_size` for :data:`BATCH_CHUNK_BYTES` of M (for a stack read
    ``in_place``, :data:`IN_PLACE_CHUNK_BYTES` of M, and of results: :func:`_in_place_budget`),
    or more for large n, so that every
    thread gets :data:`PER_THREAD` problems while M stays within :data:`MAX_CHUNK_BYTES`.
    A result file records its chunk (``--resume`` reads it from there, whatever ``--jobs``);
    row outputs, which do not, use :func:`chunk_size` alone."""
    # looked up at call time: a test may replace it
    base = io_stack.chunk_size(n, budget_bytes=_in_place_budget(n) if in_place
                               else BATCH_CHUNK_BYTES)
    chunk = max(base, min(PER_THREAD * threads, MAX_CHUNK_BYTES // max(8, 8 * n * n)))
    return min(chunk, PER_PROBLEM_CHUNK) if per_problem else chunk


def new_chunk(output: str | Any | None, n: int, threads: int, in_place: bool = False,
              per_problem: bool = False) -> int:
    """The chunk of a new result file of kind ``output`` (by extension; None: no file) for
    stacks of size n on ``threads`` threads: what :func:`open_stack_writer` records
    (:func:`batch_chunk`; row files :func:`lcpcli.io.stack.chunk_size`, which they do not
    record).  A batch that resumes nothing starts reading in these chunks before the file
    exists."""
    if output is not None and wants_rows(output):
        return io_stack.chunk_size(n)
    return batch_chunk(n, threads, in_place, per_problem)


def new_algorithm(output: str | Any) -> str:
    """The digest (:mod:`lcpcli.batch.digest`) of a new result file of kind ``output`` (by
    extension): :data:`~lcpcli.batch.digest.STACKED` for stacked datasets,
    :data:`~lcpcli.batch.digest.LEGACY` for rows; what its writer's ``algorithm`` says."""
    return LEGACY if wants_rows(output) else STACKED


def wants_rows(output: str | Any) -> bool:
    """Whether the writer of ``output`` (by extension) takes rows (``.jsonl``, ``.csv``)
    rather than stacked arrays (``.h5``, ``.npz``): :attr:`RowStackWriter.wants_rows`."""
    return output_kind(output) not in ("hdf5", "npz")


def _chunks(K: int, chunk: int) -> int:
    return max(1, -(-K // chunk))


#: Largest HDF5 storage chunk (bytes) of ``z`` and ``w`` in a new stacked result file (a
#: batch chunk's z holds 32 MiB / n bytes: :func:`lcpcli.io.stack.chunk_size`).
STORAGE_BYTES = 8 * 2**20


def storage_rows(chunk: int, K: int, n: int) -> int:
    """Rows of each HDF5 storage chunk of the per-problem datasets of a new result file whose
    batch chunk is ``chunk``: at most ``K``, and a divisor of ``chunk`` (writing a batch chunk
    then fills whole storage chunks: none is read back, merged and written again), the
    largest that keeps a chunk of ``z`` within :data:`STORAGE_BYTES`; when no divisor comes
    within half of that, ``chunk`` split evenly (storage chunks then straddle batch chunks)."""
    row_bytes = 8 * max(n, 1)
    least = max(1, -(-chunk * row_bytes // STORAGE_BYTES))  # parts a batch chunk needs
    parts = next((k for k in range(least, 2 * least + 1) if chunk % k == 0), least)
    return max(1, min(K, -(-chunk // parts)))


#: How a stacked result file is opened for writing: without HDF5's chunk cache.  A batch chunk
#: fills whole storage chunks (:func:`storage_rows`), which HDF5 then writes straight from the
#: result arrays; through the cache (1 MiB by default) each storage chunk that fits it was
#: first copied into a buffer allocated for it (new memory, page faults) and written at the
#: flush.  Measured: writing the 24 chunks of n = 50, K = 20,000, 21-23 -> 13 ms, the 7 of
#: n = 12, K = 100,000, 18-22 -> 8 ms, page faults 4,400 -> 50 and 5,900 -> 350.
NO_CHUNK_CACHE = {"rdcc_nbytes": 0}


class Hdf5StackWriter:
    """Stacked results in an HDF5 file (see the module docstring)."""

    wants_rows = False

    def __init__(self, path: Path, infos: list[Any], resume: bool, options: str = "{}",
                 threads: int = 1, per_problem: bool = False) -> None:
        self.path, self.options, self.threads = path, options, threads
        self.per_problem = per_problem  # new groups' chunk (batch_chunk)
        #: ``(method, tol)`` last written to each group's attributes (by :meth:`write`)
        self.stamped: dict[str, tuple[str, float]] = {}
        #: each group's datasets by name, once opened (:meth:`_datasets`)
        self.opened: dict[str, dict[str, Any]] = {}
        if not (resume and own_file(path) is not None):  # a link is refused by own_file
            with atomic_path(path) as tmp, open_hdf5(tmp, "w") as f:  # complete, or nothing
                f.attrs[MARK] = 1
                taken: set[str] = set()
                for info in infos:
                    self._create(f, info, taken, batch_chunk(info.n, threads, info.in_place,
                                                             per_problem))
        try:
            self.h5 = Hdf5Handle(path, "r+", **NO_CHUNK_CACHE)
        except ProblemError as exc:
            raise ProblemError(f"cannot be resumed: {str(exc).removeprefix(f'{path}: ')} "
                               f"(interrupted by kill -9?); {RERUN}", str(path)) from None
        self.file = self.h5.file
        try:
            missing = self._open_groups(infos)
        except BaseException:
            self.h5.close()
            raise
        if missing:  # new inputs: a new file with their groups added, renamed over this one
            self.h5.close()
            self._add_groups(missing)
            self.h5 = Hdf5Handle(path, "r+", **NO_CHUNK_CACHE)
            self.file = self.h5.file
            try:
                self._open_groups(infos)
            except BaseException:
                self.h5.close()
                raise

    def _open_groups(self, infos: list[Any]) -> list[Any]:
        """Check the file and the groups of ``infos`` it holds; the infos it lacks."""
        f, path = self.file, self.path
        check_hdf5_tree(f, path)  # nothing in it reaches outside the file
        if f.attrs.get(MARK) != 1:
            raise ProblemError("is not a stacked result file of lcpcli; run without "
                               "--resume to replace it", str(path))
        self.groups: dict[str, Any] = {}
        self.chunk_of: dict[str, int] = {}
        self.algorithm_of: dict[str, str] = {}
        existing = {str(f[g].attrs.get("source", "")): f[g] for g in f}
        missing = []
        for info in infos:
            g = existing.get(_text(info.path))
            if g is None:
                missing.append(info)
                continue
            try:
                self._check_group(g, info)
            except ProblemError:
                raise
            except H5_ERRORS as exc:  # an attribute of another type, a group for a dataset
                first = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
                raise ProblemError(f"cannot be resumed: its results of {info.path} are "
                                   f"unreadable ({first}): a damaged or foreign file; {RERUN}",
                                   str(path)) from None
            self.groups[info.path] = g
            self.chunk_of[info.path] = int(g.attrs["chunk"])
            self.algorithm_of[info.path] = recorded_algorithm(g.attrs.get("digest"), path,
                                                              info.path)
        return missing

    def _add_groups(self, infos: list[Any]) -> None:
        """Groups for new inputs of a resumed file, added in a copy renamed over it (never in
        place: a full disk in the middle must not damage the results it holds)."""
        with atomic_path(self.path) as tmp, open_hdf5(tmp, "w") as dst:
            src = Hdf5Handle(self.path, "r")
            try:
                for key, value in src.file.attrs.items():
                    dst.attrs[key] = value
                for name in src.file:
                    src.file.copy(src.file[name], dst, name=name)
            finally:
                src.close()
            taken = set(dst.keys())
            for info in infos:
                self._create(dst, info, taken,
                             batch_chunk(info.n, self.threads, info.in_place, self.per_problem))

    def _check_group(self, g: Any, info: Any) -> None:
        path = self.path
        if (int(g.attrs["K"]), int(g.attrs["n"])) != (info.K, info.n):
            raise ProblemError(f"holds results of {info.path} for K = {int(g.attrs['K'])}, "
                               f"n = {int(g.attrs['n'])}, but the input now has K = {info.K}, "
                               f"n = {info.n}; {RERUN}", str(path))
        if "basis" not in g:
            raise ProblemError(f"holds results of {info.path} without their basis (written "
                               f"by an older lcpcli); {RERUN}", str(path))
        if "chunk_digest" not in g or "chunk" not in g.attrs or "solve_options" not in g.attrs:
            raise no_fingerprints(path, info.path)
        if str(g.attrs["solve_options"]) != self.options:
            raise other_settings(path, info.path, str(g.attrs["solve_options"]), self.options)
        chunk = int(g.attrs["chunk"])
        if chunk < 1 or getattr(g["chunk_digest"], "shape", None) != (
                _chunks(info.K, chunk), DIGEST_BYTES) \
                or getattr(g["status"], "shape", None) != (info.K,):
            raise ProblemError(f"cannot be resumed: its fingerprint of {info.path} does not "
                               f"fit the input's K = {info.K}; {RERUN}", str(path))
        _check_layout(g, info, path)
        _check_status(g["status"][...], path)

    def _create(self, f: Any, info: Any, taken: set[str], chunk: int) -> Any:
        import h5py

        base = _text(Path(info.path).stem).replace("/", "_") or "stack"
        name, k = base, 1
        while name in taken:
            k += 1
            name = f"{base}~{k}"
        taken.add(name)
        g = f.create_group(name)
        K, n = info.K, info.n
        rows = storage_rows(chunk, K, n)
        arrays = _empty_arrays(0, n)
        arrays["chunk_digest"] = np.zeros((0, DIGEST_BYTES), np.uint8)
        for key, value in arrays.items():
            size = _chunks(K, chunk) if key == "chunk_digest" else K
            shape = (size, value.shape[1]) if value.ndim == 2 else (size,)
            chunks = (rows, n) if value.ndim == 2 and n else (rows,)
            if key == "chunk_digest":
                chunks = (min(size, 1 << 12), DIGEST_BYTES)
            fill = NOT_DONE if key == "status" else NO_BASIS if key == "basis" else \
                (0 if key in ("iterations", "chunk_digest") else np.nan)
            # every chunk allocated (and filled) now: later writes change data, never the
            # file's metadata, so a kill -9 between or during them leaves a readable file
            dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
            dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
            g.create_dataset(key, shape=shape, dtype=value.dtype, fillvalue=fill,
                             chunks=chunks if K and (value.ndim == 1 or n) else None, dcpl=dcpl)
        if info.has_names:
            g.create_dataset("names", shape=(K,), dtype=h5py.string_dtype())
        g.attrs.update({"source": _text(info.path), "n": n, "K": K, "method": "", "tol": np.nan,
                        "chunk": chunk, "digest": STACKED, "solve_options": self.options,
                        "status_codes": json.dumps({str(s): c for s, c in
                                                    STATUS_CODES.items()})})
        return g

    def chunk(self, info: Any) -> int:
        return self.chunk_of[info.path]

    def algorithm(self, info: Any) -> str:
        """The digest of ``info``'s chunks (:mod:`lcpcli.batch.digest`): what its group
        records."""
        return self.algorithm_of[info.path]

    def recorded(self, info: Any) -> dict[int, bytes]:
        g = self.groups[info.path]
        return _recorded(g["status"][...], g["chunk_digest"][...], self.chunk(info))

    def done(self, info: Any) -> np.ndarray:
        g = self.groups[info.path]
        return _done_mask(g["status"][...], g["chunk_digest"][...], self.chunk(info))

    def tally_done(self, info: Any, tally: Any) -> None:
        status = self.groups[info.path]["status"][...]
        tally.add_counts(status_counts(np.where(self.done(info), status, NOT_DONE)))

    def _datasets(self, info: Any) -> dict[str, Any]:
        """The datasets of ``info``'s group, opened once (opening one by name costs about
        0.4 ms in h5py, eight of them per chunk written)."""
        sets = self.opened.get(info.path)
        if sets is None:
            g = self.groups[info.path]
            sets = self.opened[info.path] = {key: g[key] for key in g}
        return sets

    def write(self, info: Any, positions: np.ndarray, names: list[str] | None, res: Any,
              rows: Any, chunk_no: int, digest: bytes) -> None:
        g, sets = self.groups[info.path], self._datasets(info)
        first, last = int(positions[0]), int(positions[-1])
        where: Any = slice(first, last + 1) if last - first + 1 == positions.size else positions
        arrays = _chunk_arrays(res)
        with writing(self.path, KEPT):
            for key in ("z", "w", "iterations", "error", "residual", "basis"):
                sets[key][where] = arrays[key]
            if names is not None and "names" in sets:
                sets["names"][where] = [_text(s) for s in names]
            self.h5.flush()  # the data reach the file before what vouches for them
            sets["chunk_digest"][chunk_no] = np.frombuffer(digest, np.uint8)
            sets["status"][where] = arrays["status"]
            if self.stamped.get(info.path) != (res.method, res.tol):  # metadata: when new
                g.attrs["method"] = res.method
                g.attrs["tol"] = res.tol
                self.stamped[info.path] = (res.method, res.tol)
            self.h5.flush()
        self.h5.check(KEPT)
        self.h5.start_writeback()  # the close's fsync then waits for the last chunk only

    def close(self) -> None:
        self.h5.close(KEPT)


class NpzStackWriter:
    """Stacked results of one input in an NPZ file, written atomically at the end."""

    wants_rows = False

    def __init__(self, path: Path, infos: list[Any], resume: bool, options: str = "{}",
                 threads: int = 1, per_problem: bool = False) -> None:
        if len(infos) != 1:
            raise OptionError(f"--output {path}: an .npz result file holds one stack; give one "
                              f"stacked input, or write .h5 (one group per stack)")
        info = self.info = infos[0]
        self.path, self.options = path, options
        self.arrays = _empty_arrays(info.K, info.n)
        self.chunk_size = batch_chunk(info.n, threads, info.in_place, per_problem)
        self.digest = STACKED
        self.digests = np.zeros((_chunks(info.K, self.chunk_size), DIGEST_BYTES), np.uint8)
        self.names: list[str] | None = [""] * info.K if info.has_names else None
        self.method, self.tol = "", float("nan")
        if resume and own_file(path) is not None:
            self._load(path, info)

    def _load(self, path: Path, info: Any) -> None:
        """The results in ``path`` (read through :func:`lcpcli.io.stack.results.result_members`:
        every member's header checked against K and n before its data is read)."""
        try:
            with result_members(path) as members:
                self._load_members(members, path, info)
        except ProblemError as exc:
            if exc.source:
                raise
            raise ProblemError(f"cannot be resumed ({str(exc)[:160]}); {RERUN}",
                               str(path)) from None
        _check_status(self.arrays["status"], path)

    def _load_members(self, members: dict[str, Member], path: Path, info: Any) -> None:
        def text(key: str) -> str:
            return members[key].text(key, MAX_NAME_BYTES)

        for key in ("source", "method", "tol"):
            if key not in members:
                raise ProblemError(f"has no '{key}'")
        if text("source") != info.path:
            raise ProblemError(f"holds results of {text('source')}, not {info.path}; "
                               f"{RERUN}", str(path))
        if "basis" not in members:
            raise ProblemError(f"holds results of {info.path} without their basis "
                               f"(written by an older lcpcli); {RERUN}", str(path))
        if not {"chunk_digest", "chunk", "solve_options"} <= set(members):
            raise no_fingerprints(path, info.path)
        options = text("solve_options")
        if options != self.options:
            raise other_settings(path, info.path, options, self.options)
        chunk = members["chunk"].scalar_int("chunk")
        digests = members["chunk_digest"]
        if chunk < 1 or digests.shape != (_chunks(info.K, chunk), DIGEST_BYTES) \
                or digests.dtype.kind not in "iu":
            raise ProblemError(f"cannot be resumed: its fingerprint does not fit the "
                               f"input's K = {info.K}; {RERUN}", str(path))
        self.digest = recorded_algorithm(
            text("digest") if "digest" in members else None, path, info.path)
        tol = members["tol"]
        if tol.size != 1 or tol.dtype.kind not in REAL_KINDS:
            raise ProblemError(f"'tol' must be one number (got {tol.dtype} of shape "
                               f"{tol.shape})")
        names = members.get("names") if self.names is not None else None
        if names is not None and (names.shape != (info.K,) or names.dtype.kind not in "US"
                                  or names.dtype.itemsize > 4 * MAX_NAME_BYTES):
            raise ProblemError(f"its 'names' ({names.dtype}, shape {names.shape}) are not "
                               f"the names of {info.K:,} problems")
        arrays = read_results(members, tuple(self.arrays), info.K, info.n)
        missing = sorted(set(self.arrays) - set(arrays))
        if missing:
            raise ProblemError(f"has no '{missing[0]}'")
        self.chunk_size = chunk
        self.digests = digests.read().astype(np.uint8)
        self.method, self.tol = text("method"), float(tol.read().reshape(-1)[0])
        for key, value in self.arrays.items():
            value[...] = arrays[key]
        if names is not None:
            self.names = [str(x) for x in names.read().tolist()]

    def chunk(self, info: Any) -> int:
        return self.chunk_size

    def algorithm(self, info: Any) -> str:
        return self.digest

    def recorded(self, info: Any) -> dict[int, bytes]:
        return _recorded(self.arrays["status"], self.digests, self.chunk_size)

    def done(self, info: Any) -> np.ndarray:
        return _done_mask(self.arrays["status"], self.digests, self.chunk_size)

    def tally_done(self, info: Any, tally: Any) -> None:
        tally.add_counts(status_counts(np.where(self.done(info), self.arrays["status"],
                                                NOT_DONE)))

    def write(self, info: Any, positions: np.ndarray, names: list[str] | None, res: Any,
              rows: Any, chunk_no: int, digest: bytes) -> None:
        for key, value in _chunk_arrays(res).items():
            self.arrays[key][positions] = value
        if names is not None and self.names is not None:
            for k, name in zip(positions.tolist(), names, strict=True):
                self.names[k] = name
        self.digests[chunk_no] = np.frombuffer(digest, np.uint8)
        self.method, self.tol = res.method, res.tol

    def close(self) -> None:
        extra: dict[str, Any] = {"source": np.asarray(self.info.path),
                                 "method": np.asarray(self.method),
                                 "tol": np.asarray(self.tol),
                                 "chunk": np.asarray(self.chunk_size),
                                 "chunk_digest": self.digests,
                                 "digest": np.asarray(self.digest),
                                 "solve_options": np.asarray(self.options)}
        if self.names is not None:
            extra["names"] = np.asarray(self.names, dtype=str)
        with atomic_file(self.path) as fh:  # complete, or the previous file as it was
            np.savez(fh, **self.arrays, **extra)


class RowStackWriter:
    """Rows of stacked problems in a JSONL or CSV result file (the batch row writers); each
    row's ``input_hash`` is the digest of its chunk."""

    wants_rows = True

    def __init__(self, path: Path, infos: list[Any], resume: bool, options: str = "{}") -> None:

        self.path = path
        self.options = options  # each row's solve_options: --resume refuses other settings
        self.finished: dict[str, list[dict[str, Any]]] = {}
        if resume and own_file(path) is not None:
            for row in output.read_rows(path):
                self.finished.setdefault(str(row.get("source", "")), []).append(row)
        self.writer = output.open_writer(path, resume=resume)

    def chunk(self, info: Any) -> int:
        return io_stack.chunk_size(info.n)

    def algorithm(self, info: Any) -> str:
        return LEGACY

    def _rows(self, info: Any) -> list[dict[str, Any]]:
        return [r for r in self.finished.get(info.path, [])
                if isinstance(r.get("index"), int) and 0 <= r["index"] < info.K]

    def recorded(self, info: Any) -> dict[int, bytes]:

        chunk, out = self.chunk(info), {}
        for row in self._rows(info):
            if INPUT_HASH not in row or output.SOLVE_OPTIONS not in row:
                raise no_fingerprints(self.path, info.path)
            if str(row[output.SOLVE_OPTIONS]) != self.options:
                raise other_settings(self.path, info.path, str(row[output.SOLVE_OPTIONS]),
                                     self.options)
            try:
                digest = bytes.fromhex(str(row[INPUT_HASH]))
            except ValueError:
                digest = b""
            c = row["index"] // chunk
            if len(digest) != DIGEST_BYTES or out.setdefault(c, digest) != digest:
                raise ProblemError(f"cannot be resumed: the fingerprints of {info.path}'s "
                                   f"problems {c * chunk}.. disagree (a damaged file); "
                                   f"{RERUN}", str(self.path))
        return out

    def done(self, info: Any) -> np.ndarray:
        mask = np.zeros(info.K, bool)
        for row in self._rows(info):
            mask[row["index"]] = True
        return mask

    def tally_done(self, info: Any, tally: Any) -> None:
        seen: set[int] = set()
        for row in self._rows(info):
            k = row["index"]
            if k not in seen:
                seen.add(k)
                tally.add(row)

    def write(self, info: Any, positions: np.ndarray, names: list[str] | None, res: Any,
              rows: list[dict[str, Any]], chunk_no: int, digest: bytes) -> None:

        self.writer.write([{**row, INPUT_HASH: digest.hex(), output.SOLVE_OPTIONS: self.options}
                           for row in rows])

    def close(self) -> None:
        self.writer.close()


def open_stack_writer(path: str | Any, infos: list[Any], *, resume: bool,
                      options: str = "{}", threads: int = 1, per_problem: bool = False) -> Any:
    """The writer for a stacked batch's ``--output`` (kind by extension); ``options`` is the
    :func:`options_fingerprint` of the run; ``threads`` and ``per_problem`` the solver's
    (:func:`batch_chunk`)."""

    path, kind = checked_output(path)
    if kind == "hdf5":
        return Hdf5StackWriter(path, infos, resume, options, threads, per_problem)
    if kind == "npz":
        return NpzStackWriter(path, infos, resume, options, threads, per_problem)
    return RowStackWriter(path, infos, resume, options)
