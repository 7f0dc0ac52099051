"""Batch result files: JSON Lines, CSV and HDF5, written incrementally and crash-safely.

The format follows the extension: ``.jsonl``/``.ndjson`` (one row per line, the ``solve
--json`` object plus ``source`` and ``problem``), ``.csv`` (the flat columns :data:`CSV_COLUMNS`)
or ``.h5``/``.hdf5`` (one group per problem with datasets ``z`` and ``w``; see
:class:`Hdf5Writer`).

Crash safety (Ctrl-C, SIGTERM, SIGHUP, ``kill -9``):

* JSONL and CSV are append-only text with one record per physical line.  Each row is written
  and flushed to the operating system as soon as it arrives (so ``kill -9`` of the process
  loses nothing already received) and the file is ``fsync``-ed at least every
  :data:`FSYNC_SECONDS` and at the end (so a machine crash loses at most that much).  A torn
  last line (no final newline) is ignored by :func:`read_rows` and cut off before ``--resume``
  appends.
* HDF5 is not safe to kill in the middle of a write, so ``results.h5`` is written together
  with a journal ``results.h5.journal`` (JSON Lines, as above).  Rows go to the journal first,
  then into the HDF5 file, which is flushed every :data:`FSYNC_SECONDS`.  A clean finish
  (including Ctrl-C, SIGTERM and SIGHUP, which are caught) closes the HDF5 file and deletes
  the journal.  After a ``kill -9`` the journal remains; ``--resume`` (and
  :func:`read_rows`) merge it, and if the HDF5 file was damaged mid-write it is rebuilt from
  what is readable plus the journal, atomically.

A new run (without ``--resume``) over an existing result file writes its rows to a temporary
file beside it and replaces the file only when the batch is complete (:class:`ReplacingWriter`):
a full disk, an error, Ctrl-C, SIGTERM or ``kill -9`` leave the previous file (and its journal)
as they were.  Without a previous file the rows are written in place as above, so an
interrupted first run is resumable.

Every file here is written through :mod:`lcpcli.io.writing`: result files and the journal are
opened without following links (a symbolic link is refused, never written through), a full
disk or a permission error is one line (``OutputError``, exit 2) and leaves the finished rows
resumable, and a resumed HDF5 file is checked for links out of it first.

Input identity: every written row carries ``input_hash``, a SHA-256 digest (16 bytes) of the
content of the file it was solved from (:func:`input_fingerprint`; a stacked row: of its chunk),
and a per-file batch's rows ``solve_options`` (method, tol and options, JSON).  ``--resume``
recomputes them and refuses a result file whose rows were computed from other data or with
other settings (or that has no fingerprints: written by an older lcpcli).  File names that
are not valid UTF-8 are kept: as ``\\udcXX`` escapes in JSON Lines and HDF5, as their original
bytes in CSV (Python's ``surrogateescape``).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import math
import os
import time
from abc import ABC, abstractmethod
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import OptionError, OutputError, ProblemError
from lcpcli.core.numeric import json_text
from lcpcli.io.files import open_input
from lcpcli.io.writing import (
    AppendFile,
    ForeignObjectError,
    Hdf5Handle,
    StagedFiles,
    atomic_path,
    check_dataset,
    check_hdf5_tree,
    open_hdf5,
    own_file,
    read_own_file,
    remove_file,
    restated,
    truncate_file,
    write_atomic_text,
    writing,
)

#: Longest time between two fsyncs of an output file.
FSYNC_SECONDS = 1.0
#: Flat columns of the CSV output.
CSV_COLUMNS = ("source", "problem", "status", "method", "n", "iterations", "seconds",
               "residual", "error", "message", "index", "input_hash", "solve_options")
#: The row field holding the fingerprint of the row's input (see the module docstring).
INPUT_HASH = "input_hash"
#: The row field holding the solve options of a per-file batch (method, tol, options as JSON:
#: :func:`lcpcli.batch.stack_output.options_fingerprint`), which ``--resume`` compares.
SOLVE_OPTIONS = "solve_options"
#: CSV columns an older lcpcli did not write (its rows come without these keys).
_NEWER_COLUMNS = (INPUT_HASH, SOLVE_OPTIONS)
_KINDS = {".jsonl": "jsonl", ".ndjson": "jsonl", ".csv": "csv", ".h5": "hdf5", ".hdf5": "hdf5",
          ".npz": "npz"}


def suffixes(kinds: tuple[str, ...] = ("jsonl", "csv", "hdf5")) -> str:
    """The accepted suffixes of the result ``kinds``, from :data:`_KINDS`, for messages:
    ``.jsonl/.ndjson, .csv or .h5/.hdf5``."""
    names = ["/".join(ext for ext, k in _KINDS.items() if k == kind) for kind in kinds]
    return ", ".join(names[:-1]) + " or " + names[-1] if len(names) > 1 else names[0]


def output_kind(path: str | os.PathLike[str]) -> str:
    """``jsonl``, ``csv``, ``hdf5`` or ``npz`` (stacked inputs only) from the extension;
    anything else is an OptionError."""
    ext = Path(path).suffix.lower()
    if ext not in _KINDS:
        raise OptionError(f"--output {path}: unknown result file type {ext or '(none)'} "
                          f"(expected {suffixes()}; {suffixes(('npz',))} for stacked "
                          f"inputs)")
    return _KINDS[ext]


def is_batch_output(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` names a batch result file (.jsonl, .ndjson, .csv, .h5, .hdf5, .npz)."""
    return Path(path).suffix.lower() in _KINDS


def row_key(row: dict[str, Any]) -> tuple[str, str]:
    return (str(row.get("source", "")), str(row.get("problem", "")))


# ----------------------------------------------------------------------------- reading
def _complete_lines(path: Path) -> tuple[list[bytes], int]:
    """The complete lines of a text file and the byte length they cover (torn tail dropped)."""
    data = read_own_file(path)
    end = data.rfind(b"\n") + 1
    return data[:end].splitlines(), end


def _complete_csv(path: Path) -> tuple[bytes, int]:
    """The complete CSV records of a file and the byte length they cover.

    A record ends at a newline outside quotes (names may hold quoted newlines), so a torn last
    record is recognised even when it was cut inside a quoted field.
    """
    data = read_own_file(path)
    end = pos = quotes = 0
    for line in data.split(b"\n")[:-1]:  # the last piece has no newline: torn or empty
        quotes += line.count(b'"')
        pos += len(line) + 1
        if quotes % 2 == 0:
            end = pos
    return data[:end], end


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    """Rows of a JSONL file; a torn last line and undecodable lines are skipped."""
    rows = []
    for line in _complete_lines(path)[0]:
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except (ValueError, RecursionError):  # JSON and UTF-8 errors, absurd nesting
            continue
        if isinstance(obj, dict):
            rows.append(obj)
    return rows


def is_row(obj: Any) -> bool:
    """Whether ``obj`` (a parsed JSON line) is a result row: an object with ``source`` and
    ``problem`` (every row lcpcli writes has both)."""
    return isinstance(obj, dict) and "source" in obj and "problem" in obj


def check_own_jsonl(path: Path) -> None:
    """Refuse (ProblemError) to resume a JSON Lines file that is not a result file of lcpcli:
    a complete line that is not a row (:func:`is_row`), or a torn last line that cannot be
    the start of one.  Checked before anything is appended or cut off."""
    data = read_own_file(path)
    end = data.rfind(b"\n") + 1
    for number, line in enumerate(data[:end].splitlines(), 1):
        if not line.strip():
            continue
        try:
            ok = is_row(json.loads(line))
        except (ValueError, RecursionError):
            ok = False
        if not ok:
            raise ProblemError(f"cannot be resumed: line {number} is not a result row of "
                               f"lcpcli (not a result file?); run again without --resume, or "
                               f"give another --output", str(path))
    if data[end:].strip() and not data[end:].lstrip().startswith(b"{"):
        raise ProblemError("cannot be resumed: its last line is neither a result row of lcpcli "
                           "nor the start of one (not a result file?); run again without "
                           "--resume, or give another --output", str(path))


def _csv_value(col: str, text: str) -> Any:
    if text == "":
        return None if col not in ("source", "problem", "status", "method", "message") else ""
    if col in _NEWER_COLUMNS:
        return text
    if col in ("n", "iterations", "index"):
        return int(text)
    if col in ("seconds", "residual", "error"):
        return float(text)
    return text


def read_csv(path: Path) -> list[dict[str, Any]]:
    """Rows of a CSV result file (typed: ints, floats, None for empty numbers)."""
    data, _ = _complete_csv(path)
    if not data:
        return []
    text = data.decode("utf-8", errors="surrogateescape")  # names as written (raw bytes)
    rows = []
    for rec in csv.DictReader(io.StringIO(text, newline="")):
        # a file of an older lcpcli lacks the newer columns: its rows come without the keys
        columns = [c for c in CSV_COLUMNS if c in rec]
        if None in rec or any(c not in rec for c in CSV_COLUMNS if c not in _NEWER_COLUMNS):
            continue  # not a complete record
        try:
            rows.append({c: _csv_value(c, rec[c] or "") for c in columns})
        except ValueError:
            continue
    return rows


#: What a group of an HDF5 result file may hold when its ``json`` attribute is missing: the
#: row's write was interrupted (``kill -9``; the journal beside the file has the row).
_INTERRUPTED_GROUP = frozenset({"z", "w", "certificate"})


def _not_ours(what: str, path: Path) -> ForeignObjectError:
    return ForeignObjectError(f"cannot be resumed: {what} (a damaged or foreign file, not a "
                              f"result file of lcpcli); run again without --resume, or give "
                              f"another --output", str(path))


def read_hdf5(path: Path) -> list[dict[str, Any]]:
    """Rows of an HDF5 result file (raises ProblemError when it cannot be read, and
    :class:`ForeignObjectError` when it holds anything but result groups: a dataset or a
    problem at its root, a ``json`` attribute that is not a row, ``z`` or ``w`` that are
    not vectors of the row's length)."""
    import h5py

    rows = []
    try:
        handle = Hdf5Handle(path, "r")
    except ProblemError as exc:
        raise ProblemError(f"unreadable HDF5 result file ({exc})", str(path)) from None
    try:
        f = handle.file
        check_hdf5_tree(f, path, datasets=False)  # no link out of the file is followed
        for name in f:
            g = f[name]
            if not isinstance(g, h5py.Group):
                raise _not_ours(f"'{name}' is not a result group", path)
            if "json" not in g.attrs:
                if set(g) <= _INTERRUPTED_GROUP:
                    continue  # an interrupted write: the journal has the row
                raise _not_ours(f"group '{name}' holds no result row", path)
            try:
                row = json.loads(g.attrs["json"])
            except (ValueError, TypeError, RecursionError):
                row = None
            if not is_row(row):
                raise _not_ours(f"the row of group '{name}' is not a result row", path)
            n = row.get("n")
            for key in ("z", "w"):
                d = g.get(key)
                if not isinstance(d, h5py.Dataset) or d.shape is None or d.dtype.kind != "f" \
                        or tuple(d.shape) not in ((0,), (n,)):
                    raise _not_ours(f"'{name}/{key}' is not a vector of the row's n = {n}",
                                    path)
                check_dataset(d, path)  # nor storage out of it
                row[key] = [float(x) if math.isfinite(x) else None for x in d[()]]
            rows.append(row)
    except ForeignObjectError:
        raise
    except (OSError, KeyError, RuntimeError, ValueError, TypeError, RecursionError) as exc:
        raise ProblemError(f"unreadable HDF5 result file ({str(exc).splitlines()[0][:100]})",
                           str(path)) from None
    finally:
        handle.close()
    return rows


#: Bytes kept of a fingerprint (the first of its SHA-256 digest).
DIGEST_BYTES = 16


def new_digest(data: bytes = b"") -> Any:
    """The hash of every input fingerprint: SHA-256 (hardware-accelerated on current CPUs,
    1.3 GB/s here against 0.6 for BLAKE2b), of which :data:`DIGEST_BYTES` are kept;
    ``data``: its first bytes."""
    return hashlib.sha256(data)


def input_fingerprint(path: str | os.PathLike[str]) -> str | None:
    """The ``input_hash`` of a row: the fingerprint (hex) of the content of the regular file
    ``path``, read in blocks; None when it cannot be read (the row is then an error)."""
    h = new_digest()
    try:
        with open_input(path) as fh:
            while block := fh.read(1 << 20):
                h.update(block)
    except (ProblemError, OSError):
        return None
    return h.digest()[:DIGEST_BYTES].hex()


def content_fingerprint(data: bytes) -> str:
    """:func:`input_fingerprint` of a file whose content ``data`` is already read (a batch
    worker hashes the bytes it parsed instead of reading the file again)."""
    return new_digest(data).digest()[:DIGEST_BYTES].hex()


def journal_path(path: Path) -> Path:
    """The journal beside an HDF5 result file."""
    return path.with_name(path.name + ".journal")


def read_rows(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Every finished row of a result file (any kind), tolerant of an interrupted writer.

    For HDF5 the journal of an interrupted run is merged; if the HDF5 file itself is damaged,
    the journal's rows are returned alone.
    """
    path = Path(path)
    kind = output_kind(path)
    exists = own_file(path) is not None  # a link or a device is refused, never followed
    if kind == "jsonl":
        return read_jsonl(path) if exists else []
    if kind == "csv":
        return read_csv(path) if exists else []
    rows: list[dict[str, Any]] = []
    if exists:
        try:
            rows = read_hdf5(path)
        except ForeignObjectError:
            raise
        except ProblemError:
            rows = []
    jpath = journal_path(path)
    if own_file(jpath) is not None:
        have = {row_key(r) for r in rows}
        rows += [r for r in read_jsonl(jpath) if row_key(r) not in have]
    return rows


# ----------------------------------------------------------------------------- writing
def _fresh_file(path: Path, text: str = "") -> None:
    """Replace ``path`` by a file holding ``text`` (atomically, via a temporary file)."""
    write_atomic_text(path, text)


def _truncate_torn_tail(path: Path, csv_records: bool = False) -> None:
    """Cut a torn last line or CSV record (an interrupted write) so appends start afresh."""
    _, end = _complete_csv(path) if csv_records else _complete_lines(path)
    st = own_file(path)
    if st is not None and end != st.st_size:
        truncate_file(path, end)


class _LineWriter(ABC):
    """Append-only text file: write + flush per row, fsync at most every FSYNC_SECONDS."""

    #: Records may span lines (quoted newlines in CSV): torn tails are found record-wise.
    multiline = False

    def __init__(self, path: Path, resume: bool, header: str = "", *,
                 staged: bool = False) -> None:
        self.path = path
        if staged:  # an empty temporary file of a ReplacingWriter: written in place
            pass
        elif resume and own_file(path) is not None:  # a link: refused, never appended to
            first = _complete_lines(path)[0][:1]
            if header and first and first[0] + b"\n" != header.encode():
                raise ProblemError(f"cannot be resumed: its first line is not the header "
                                   f"{header.strip()!r} of this lcpcli (an older version's, or "
                                   f"not a result file); run again without --resume", str(path))
            if not header:  # JSON Lines: every line a row (never cut a foreign file's line)
                check_own_jsonl(path)
            _truncate_torn_tail(path, self.multiline)
        else:
            _fresh_file(path, header)
        self.file = AppendFile(path)  # O_NOFOLLOW; a failed write is cut back, one line
        if header and self.file.end == 0:
            self.file.write(header, rows=0)
        self.last_sync = time.monotonic()

    @abstractmethod
    def _line(self, row: dict[str, Any]) -> str:
        """One row as a line of text (the subclass's format)."""

    def write(self, rows: list[dict[str, Any]]) -> None:
        self.file.write("".join(self._line(r) for r in rows), rows=len(rows))
        if time.monotonic() - self.last_sync >= FSYNC_SECONDS:
            self.sync()

    def sync(self) -> None:
        self.file.sync()
        self.last_sync = time.monotonic()

    def close(self, complete: bool = True) -> None:
        """Close (``complete``: whether the batch ended; rows written in place stay either
        way, resumable)."""
        self.file.close()


class JsonlWriter(_LineWriter):
    """One JSON object per line."""

    def __init__(self, path: Path, resume: bool, *, staged: bool = False) -> None:
        super().__init__(path, resume, staged=staged)

    def _line(self, row: dict[str, Any]) -> str:
        return json_text(row) + "\n"


def _csv_text(col: str, value: Any) -> str:
    """A CSV cell: names kept exactly (the csv module quotes commas, quotes and newlines, so
    ``--resume`` finds them again); the message on one line."""
    if value is None:
        return ""
    if isinstance(value, float):  # non-finite: empty, as JSON's null (core.numeric's rule)
        return repr(value) if math.isfinite(value) else ""
    if col == "message":
        return " ".join(str(value).split())
    return str(value)


class CsvWriter(_LineWriter):
    """Flat columns (:data:`CSV_COLUMNS`), one record per row, header first (RFC 4180 quoting:
    a name holding a newline spans two physical lines inside quotes)."""

    multiline = True

    def __init__(self, path: Path, resume: bool, *, staged: bool = False) -> None:
        super().__init__(path, resume, header=",".join(CSV_COLUMNS) + "\n", staged=staged)
        self.buffer = io.StringIO()
        self.csv = csv.writer(self.buffer, lineterminator="\n")
        # the csv module quotes a field holding the line terminator, not a lone "\r"
        self.csv_quoted = csv.writer(self.buffer, lineterminator="\n", quoting=csv.QUOTE_ALL)

    def _line(self, row: dict[str, Any]) -> str:
        self.buffer.seek(0)
        self.buffer.truncate()
        cells = [_csv_text(c, row.get(c)) for c in CSV_COLUMNS]
        writer = self.csv_quoted if any("\r" in cell for cell in cells) else self.csv
        writer.writerow(cells)
        return self.buffer.getvalue()


def hdf5_text(text: Any) -> str:
    """``text`` as HDF5 can store it (UTF-8): bytes of a name that are not valid UTF-8 (kept by
    ``os.fsdecode`` as lone surrogates) are written as ``\\xNN`` escapes."""
    return str(text).encode("utf-8", "backslashreplace").decode("utf-8")


def _group_name(problem: str) -> str:
    name = hdf5_text(problem).replace("/", "_").strip() or "problem"
    return "_" + name if name in (".", "..") else name


class Hdf5Writer:
    """One group per problem, named after the problem (``name~2``, ... on a clash).

    Each group holds datasets ``z`` and ``w`` (NaN where the JSON has null), attributes
    ``source``, ``problem``, ``status``, ``method``, ``n``, ``iterations``, ``seconds``,
    ``residual``, ``error``, ``message`` (NaN/-1 for missing numbers), a sub-group
    ``certificate`` whose attributes are the certificate's fields, and the attribute ``json``:
    the row without z and w, from which :func:`read_hdf5` rebuilds the JSONL row exactly.
    """

    def __init__(self, path: Path, resume: bool, *, staged: bool = False) -> None:
        self.path = path
        jpath = journal_path(path)
        self.journal: JsonlWriter | None = None
        if staged:  # the empty temporary file of a ReplacingWriter: no journal (a kill -9
            self.h5 = Hdf5Handle(path, "w")  # leaves the previous file, this one is dropped)
        else:
            # resumed: a linked result or journal is refused (own_file), never followed
            if resume and (own_file(path) is not None or own_file(jpath) is not None):
                self._recover(path, jpath)
            else:
                remove_file(jpath)  # a stale journal (a link: the link, never its target)
                self._create_empty(path)
            self.journal = JsonlWriter(jpath, resume=True)
            self.h5 = Hdf5Handle(path, "r+")  # O_NOFOLLOW; written through a SafeSink
        self.file = self.h5.file
        self.names = set(self.file.keys())
        self.last_flush = time.monotonic()

    @staticmethod
    def _create_empty(path: Path, rows: list[dict[str, Any]] | None = None) -> None:
        with atomic_path(path) as tmp, open_hdf5(tmp, "w") as f:
            names: set[str] = set()
            for row in rows or []:
                _write_group(f, row, names)

    def _recover(self, path: Path, jpath: Path) -> None:
        """Make the HDF5 file hold every row of the file and of the journal (after a kill -9:
        the journal is there); without a journal, check that nothing in it leads outside."""
        exists = own_file(path) is not None
        if exists and own_file(jpath) is None:
            try:
                handle = Hdf5Handle(path, "r")
            except ProblemError:  # no journal: not an interrupted result file of lcpcli
                raise _not_ours("not a readable HDF5 file, and no journal beside it",
                                path) from None
            try:
                check_hdf5_tree(handle.file, path, datasets=False)
            finally:
                handle.close()
            return
        try:
            rows = read_hdf5(path) if exists else []
            damaged = not exists
        except ForeignObjectError:
            raise
        except ProblemError:
            rows, damaged = [], True
        have = {row_key(r) for r in rows}
        extra = [r for r in (read_jsonl(jpath) if own_file(jpath) is not None else [])
                 if row_key(r) not in have]
        if damaged or extra:  # rebuilt atomically: a failure leaves the file and journal
            self._create_empty(path, rows + extra)

    def write(self, rows: list[dict[str, Any]]) -> None:
        if self.journal is not None:
            self.journal.write(rows)  # first: the rows survive a failure of the HDF5 file
        with writing(self.path, self.KEPT):
            for row in rows:
                _write_group(self.file, row, self.names)
        self.h5.check(self.KEPT)
        if time.monotonic() - self.last_flush >= FSYNC_SECONDS:
            self.sync()

    #: What a write failure leaves (the message says it).
    KEPT = "the finished rows are kept in the journal beside it: free space, then run again " \
           "with --resume"

    def sync(self) -> None:
        if self.journal is not None:
            self.journal.sync()
        self.h5.flush()
        self.last_flush = time.monotonic()

    def close(self, complete: bool = True) -> None:
        """Close the HDF5 file, then remove the journal (``complete`` as for
        :meth:`_LineWriter.close`: Ctrl-C and SIGTERM close cleanly too)."""
        if self.h5.sink.fd < 0:
            return
        try:
            self.h5.close(self.KEPT)  # the HDF5 file first: the journal is its backup
        finally:
            if self.journal is not None:
                self.journal.close()
        if self.journal is not None:
            remove_file(journal_path(self.path))  # only once the HDF5 file is complete


class ReplacingWriter:
    """A new batch over an existing result file: the rows go to a temporary file beside it
    (:class:`lcpcli.io.writing.StagedFiles`: ``O_CREAT | O_EXCL | O_NOFOLLOW``), which is
    renamed over it by :meth:`close` with ``complete``; any other end (a write failure, an
    error, Ctrl-C, SIGTERM) removes the temporary file, so the previous file -- and an HDF5
    file's journal -- stay byte for byte as they were (a ``kill -9`` leaves the temporary file
    ``.NAME.XXXXXXXX.tmp`` beside them, nothing else).  Write failures name the result file."""

    #: What a write failure leaves (the message says it).
    KEPT = "the previous file is kept as it was: free space, then run again"

    def __init__(self, path: Path, kind: str) -> None:
        self.path, self.kind = path, kind
        self.staged: StagedFiles | None = StagedFiles()
        tmp = self.staged.add(path)
        try:
            with self._failures():
                cls = {"jsonl": JsonlWriter, "csv": CsvWriter}.get(kind, Hdf5Writer)
                self.inner: Any = cls(tmp, resume=False, staged=True)
        except BaseException:
            self.staged.abort()
            raise

    @contextlib.contextmanager
    def _failures(self) -> Iterator[None]:
        """A write failure of the temporary file, restated for the result file."""
        try:
            yield
        except OutputError as exc:
            raise restated(exc, self.path, self.KEPT) from None

    def write(self, rows: list[dict[str, Any]]) -> None:
        with self._failures():
            self.inner.write(rows)

    def sync(self) -> None:
        with self._failures():
            self.inner.sync()

    def close(self, complete: bool = True) -> None:
        """With ``complete`` (the batch ended): replace the result file; otherwise drop the
        temporary file and keep the previous one."""
        staged, self.staged = self.staged, None
        if staged is None:
            return
        try:
            if not complete:
                with contextlib.suppress(Exception):  # the error on its way is the one to report
                    self.inner.close(complete=False)
                return
            with self._failures():
                self.inner.close()
                if self.kind == "hdf5":  # the previous file's journal: its rows are not ours
                    remove_file(journal_path(self.path))
                staged.commit()
        finally:
            staged.abort()  # nothing left after a commit


def _write_group(f: Any, row: dict[str, Any], names: set[str]) -> None:

    base = _group_name(row.get("problem", ""))
    name, k = base, 1
    while name in names:
        k += 1
        name = f"{base}~{k}"
    names.add(name)
    g = f.create_group(name)
    nan = float("nan")
    g.create_dataset("z", data=np.array([nan if x is None else x for x in row.get("z") or []],
                                        dtype=np.float64))
    g.create_dataset("w", data=np.array([nan if x is None else x for x in row.get("w") or []],
                                        dtype=np.float64))
    for col in ("source", "problem", "status", "method", "message"):
        g.attrs[col] = hdf5_text(row.get(col) or "")
    for col in ("n", "iterations"):
        g.attrs[col] = -1 if row.get(col) is None else int(row[col])
    for col in ("seconds", "residual", "error"):
        g.attrs[col] = nan if row.get(col) is None else float(row[col])
    cert = row.get("certificate")
    if isinstance(cert, dict):
        cg = g.create_group("certificate")
        for k2, v in cert.items():
            cg.attrs[k2] = nan if v is None else v
    rest = {k2: v for k2, v in row.items() if k2 not in ("z", "w")}
    g.attrs["json"] = json_text(rest)


def checked_output(path: str | os.PathLike[str]) -> tuple[Path, str]:
    """``(path, kind)`` of a batch result file whose folder exists (else OptionError)."""
    path = Path(path)
    kind = output_kind(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"--output {path}: folder {folder} does not exist")
    return path, kind


def replaced_when_complete(path: str | os.PathLike[str], resume: bool) -> bool:
    """Whether a new batch writes beside ``path`` and replaces it only once complete
    (:class:`ReplacingWriter`): a previous result file exists and this is no ``--resume``."""
    return not resume and os.path.lexists(path)


def open_writer(path: str | os.PathLike[str], *, resume: bool = False,
                keep_previous: bool = False) -> Any:
    """A writer for ``path`` (kind from the extension): ``write(rows)``, ``sync()``,
    ``close(complete=True)``.

    Without ``resume`` an existing file is replaced: at once, or with ``keep_previous`` only
    when ``close(complete=True)`` ends the batch (:class:`ReplacingWriter`); with ``resume``,
    rows are appended after the finished ones (a torn tail is cut, an HDF5 file is repaired
    from its journal).
    """
    path, kind = checked_output(path)
    if kind != "npz" and keep_previous and replaced_when_complete(path, resume):
        return ReplacingWriter(path, kind)
    if kind == "jsonl":
        return JsonlWriter(path, resume)
    if kind == "csv":
        return CsvWriter(path, resume)
    if kind == "npz":
        raise OptionError(f"--output {path}: an .npz result file is written for stacked inputs "
                          f"only (see docs/batch.md); use {suffixes()}")
    return Hdf5Writer(path, resume)
