"""Stack data read in place: the file mapped into memory, rows handed out as read-only views.

A stacked batch reads each chunk of ``M``, ``q`` (and per-problem bounds) as numpy views of
the file's pages in the page cache instead of copying them into buffers (a copy of every byte
of M, 400 MB for n = 50, K = 20,000, on a core the solver needs).  Rows are *mappable* where
they are stored as little-endian float64 in C order, unfiltered, at an offset that is a
multiple of 8, and in runs of rows that follow one another in the file (:func:`h5_runs`,
:func:`npz_runs`): an HDF5 dataset stored contiguous (what :func:`lcpcli.io.stack.write_stack`
and h5py's defaults write), or chunked in chunks of whole rows that lie one after another in
the file; an NPZ member stored uncompressed at an offset that is a multiple of 8 (as
``write_stack`` writes them; ``np.savez`` puts M at byte 183 and q at no multiple of 8
either: copied).  A chunk read across two runs, or from anything else (compressed, other
types, external storage), is copied as before.

**Truncation.**  A page of the map past the end of a file truncated during the run raises
SIGBUS in the thread that touches it; the guard of :mod:`lcpcli.io.stack._mapped` turns
that page and the rest of the map into zeros and records where (no signal death, in any
thread: the compiled solver's, the digest's, numpy's).  Every chunk read in place carries
:meth:`MappedStack.check` (``StackChunk.check``), which the batch calls once the chunk's
results and digest are computed and before they are written: it raises a one-line
:class:`ProblemError` when any byte of the chunk may not have been the file's when it was
read (a page of it was replaced, or the file is now shorter than the chunk's end: the part
of a page past the new end reads as zeros without a fault).  What it does not see: a file
rewritten in place with other data of the same length (a copying read would mix the old and
the new data the same way).
"""

from __future__ import annotations

import bisect
import os
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.io.files import _open_regular

#: Read stack rows in place where they are mappable (:mod:`lcpcli.io.stack.mapped`); False:
#: always copy (tests compare the two).
MAP_STACKS = True
#: The one dtype read in place (the rows' dtype in memory: float64, little-endian).
MAPPED_DTYPE = np.dtype("<f8")


@dataclass(frozen=True)
class Runs:
    """Where rows of one array lie in the file: ``starts[i] .. stops[i] - 1`` (row indices,
    sorted, not overlapping) begin at byte ``offsets[i]``; ``row`` is one row's shape."""

    row: tuple[int, ...]
    starts: list[int]
    stops: list[int]
    offsets: list[int]

    @property
    def row_bytes(self) -> int:
        return int(np.prod(self.row, dtype=np.int64)) * MAPPED_DTYPE.itemsize

    def find(self, start: int, stop: int) -> int | None:
        """The file offset of rows ``start .. stop - 1`` when one run holds them, else None."""
        i = bisect.bisect_right(self.starts, start) - 1
        if i < 0 or stop > self.stops[i]:
            return None
        return self.offsets[i] + (start - self.starts[i]) * self.row_bytes


def _usable(dtype: Any, offset: int | None) -> bool:
    return offset is not None and np.dtype(dtype) == MAPPED_DTYPE and offset % 8 == 0


#: Most storage chunks of one dataset whose places :func:`h5_runs` lists (its callback costs
#: ~10 us a chunk: 385 chunks 4 ms); a dataset in more chunks is copied.
MAX_LISTED_CHUNKS = 65_536


def h5_runs(d: Any, whole: bool = False) -> Runs | None:
    """The :class:`Runs` of the h5py dataset ``d`` (shape (K, ...)), or None when no row of
    it is mappable: not float64 little-endian, filtered, external or virtual, compact,
    chunked in chunks that split a row or in more than :data:`MAX_LISTED_CHUNKS`.
    ``whole``: only whether one run holds every row (None otherwise), the listing stopped at
    the first chunk that does not follow the one before."""
    import h5py

    if not _usable(d.dtype, 0):
        return None
    dcpl = d.id.get_create_plist()
    if dcpl.get_nfilters() or dcpl.get_external_count():
        return None
    K, row = int(d.shape[0]), tuple(int(x) for x in d.shape[1:])
    row_bytes = int(np.prod(row, dtype=np.int64)) * 8
    layout = dcpl.get_layout()
    if layout == h5py.h5d.CONTIGUOUS:
        offset = d.id.get_offset()
        return Runs(row, [0], [K], [offset]) if _usable(d.dtype, offset) else None
    if layout != h5py.h5d.CHUNKED or tuple(d.chunks[1:]) != row or \
            not hasattr(d.id, "chunk_iter") or d.id.get_num_chunks() > MAX_LISTED_CHUNKS:
        return None
    c = int(d.chunks[0])
    chunks: list[tuple[int, int, int]] = []  # (first row, byte offset, bytes)

    def add(info: Any) -> bool | None:
        first, offset = int(info.chunk_offset[0]), int(info.byte_offset)
        if whole and (first != c * len(chunks) or (chunks and offset != chunks[-1][1]
                                                   + c * row_bytes)):
            return True  # stops the listing: not one run
        chunks.append((first, offset, int(info.size)))
        return None

    d.id.chunk_iter(add)
    chunks.sort()
    starts: list[int] = []
    stops: list[int] = []
    offsets: list[int] = []
    for first, offset, size in chunks:
        if size != c * row_bytes or not _usable(d.dtype, offset):
            continue
        last = min(K, first + c)
        if stops and stops[-1] == first and \
                offsets[-1] + (first - starts[-1]) * row_bytes == offset:
            stops[-1] = last
        else:
            starts.append(first)
            stops.append(last)
            offsets.append(offset)
    if not starts or (whole and (starts != [0] or stops != [K])):
        return None
    return Runs(row, starts, stops, offsets)


def npz_runs(shape: tuple[int, ...], dtype: Any, fortran: bool, offset: int | None
             ) -> Runs | None:
    """The :class:`Runs` of an NPZ member of ``shape`` whose data start at byte ``offset``
    of the file (None: stored compressed), or None when not mappable."""
    if fortran or not _usable(dtype, offset):
        return None
    return Runs(tuple(shape[1:]), [0], [int(shape[0])], [int(offset)])  # type: ignore[list-item]


def in_place(runs: list[Runs | None], K: int) -> bool:
    """Whether each of ``runs`` (one per row array) holds every row of K in one run, and
    mapping is on (:data:`MAP_STACKS`): a reader opened ``mapped`` then copies no chunk."""
    return MAP_STACKS and all(r is not None and r.starts == [0] and r.stops == [K]
                              for r in runs)


class MappedStack:
    """The file ``fd`` (open, owned by this object: closed with it) mapped read-only whole
    (:class:`lcpcli.io.stack._mapped.Mapping`), with the :class:`Runs` of each array
    (``runs``: key -> Runs; runs past the end of the file are dropped).  Views keep the map
    alive; :meth:`check` keeps the file open to see its size."""

    def __init__(self, fd: int, runs: dict[str, Runs]) -> None:
        from lcpcli.io.stack._mapped import Mapping

        self.fd = fd
        weakref.finalize(self, os.close, fd)
        size = os.fstat(fd).st_size
        self.runs: dict[str, Runs] = {}
        for key, r in runs.items():
            keep = [i for i in range(len(r.starts))
                    if r.offsets[i] + (r.stops[i] - r.starts[i]) * r.row_bytes <= size]
            if keep:
                self.runs[key] = Runs(r.row, [r.starts[i] for i in keep],
                                      [r.stops[i] for i in keep], [r.offsets[i] for i in keep])
        self.mapping = Mapping(self.fd, size)
        self.views = 0  # chunks of rows handed out as views (counted for tests, stats)

    def view(self, key: str, start: int, stop: int) -> tuple[np.ndarray, int, int] | None:
        """Rows ``start .. stop - 1`` of array ``key`` as a read-only view of the map, and
        the file bytes they span (``first``, ``end``); None when they are not mappable.  The
        pages are mapped now (read from the disk if needed), in this thread."""
        r = self.runs.get(key)
        offset = None if r is None else r.find(start, stop)
        if offset is None or r is None:
            return None
        nbytes = (stop - start) * r.row_bytes
        self.mapping.populate(offset, nbytes)  # an error here: check() reports the rows
        arr = np.frombuffer(self.mapping, MAPPED_DTYPE, count=nbytes // 8, offset=offset)
        self.views += 1
        return arr.reshape((stop - start, *r.row)), offset, offset + nbytes

    def check(self, spans: list[tuple[int, int]], start: int, stop: int) -> None:
        """ProblemError when a byte of ``spans`` (file ranges ``[first, end)`` read in place
        for problems ``start .. stop - 1``) may not have been the file's: the file is now
        shorter than one of them, or a page of them was lost to a truncation (module
        docstring).  Call it after the last read of those bytes."""
        lost = self.mapping.lost()
        size = os.fstat(self.fd).st_size
        for _first, end in spans:
            if end > size:
                raise ProblemError(f"was truncated while it was read (problems {start:,} to "
                                   f"{stop - 1:,} are no longer all in it, now "
                                   f"{size:,} bytes); run again on the complete file")
            if 0 <= lost < end:  # a SIGBUS, the size whole again: regrown, or a disk error
                raise ProblemError(f"lost data while it was read (problems {start:,} to "
                                   f"{stop - 1:,}: the file was truncated and written again, "
                                   f"or the disk failed to read it); run again")


def map_stack(path: str | os.PathLike[str], reading: int, runs: dict[str, Runs | None]
              ) -> MappedStack | None:
    """A :class:`MappedStack` of the file at ``path`` for the mappable ``runs`` (None
    values: not mappable), or None when nothing is mappable, mapping is off
    (:data:`MAP_STACKS`), the path is now another file than the one the format reader reads
    through the descriptor ``reading`` (whose offsets ``runs`` are), or the system refuses the
    map or its guard (then every chunk is copied).  The file is opened again by the reading
    layer's rules (:mod:`lcpcli.io.files`), not ``reading`` duplicated: HDF5's lock on that
    one ends when the reader closes, whatever views are still alive."""
    have = {k: r for k, r in runs.items() if r is not None}
    if not MAP_STACKS or not have:
        return None
    fd, st = _open_regular(path, "a stack file")
    try:
        was = os.fstat(reading)
        if (st.st_dev, st.st_ino) != (was.st_dev, was.st_ino):
            os.close(fd)
            return None
    except BaseException:
        os.close(fd)
        raise
    try:
        mapped = MappedStack(fd, have)  # owns fd from here (closed when collected)
    except (OSError, ImportError, ValueError):
        return None
    return mapped if mapped.runs else None
