"""Batch result files: JSON Lines, CSV and HDF5, written incrementally and crash-safely.

The format follows the extension: ``.jsonl``/``.ndjson`` (one row per line, the ``solve
--json`` object plus ``source`` and ``problem``), ``.csv`` (the flat columns :data:`CSV_COLUMNS`)
or ``.h5``/``.hdf5`` (one group per problem with datasets ``z`` and ``w``; see
:class:`Hdf5Writer`).

Crash safety (Ctrl-C, SIGTERM, ``kill -9``):

* JSONL and CSV are append-only text with one record per physical line.  Each row is written
  and flushed to the operating system as soon as it arrives (so ``kill -9`` of the process
  loses nothing already received) and the file is ``fsync``-ed at least every
  :data:`FSYNC_SECONDS` and at the end (so a machine crash loses at most that much).  A torn
  last line (no final newline) is ignored by :func:`read_rows` and cut off before ``--resume``
  appends.
* HDF5 is not safe to kill in the middle of a write, so ``results.h5`` is written together
  with a journal ``results.h5.journal`` (JSON Lines, as above).  Rows go to the journal first,
  then into the HDF5 file, which is flushed every :data:`FSYNC_SECONDS`.  A clean finish
  (including Ctrl-C and SIGTERM, which are caught) closes the HDF5 file and deletes the journal.
  After a ``kill -9`` the journal remains; ``--resume`` (and :func:`read_rows`) merge it, and if
  the HDF5 file was damaged mid-write it is rebuilt from what is readable plus the journal,
  atomically.

A new run (without ``--resume``) replaces an existing output file.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import time
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any

from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.numeric import json_text

#: Longest time between two fsyncs of an output file.
FSYNC_SECONDS = 1.0
#: Flat columns of the CSV output.
CSV_COLUMNS = ("source", "problem", "status", "method", "n", "iterations", "seconds",
               "residual", "error", "message", "index")
_KINDS = {".jsonl": "jsonl", ".ndjson": "jsonl", ".csv": "csv", ".h5": "hdf5", ".hdf5": "hdf5",
          ".npz": "npz"}


def output_kind(path: str | os.PathLike[str]) -> str:
    """``jsonl``, ``csv``, ``hdf5`` or ``npz`` (stacked inputs only) from the extension;
    anything else is an OptionError."""
    ext = Path(path).suffix.lower()
    if ext not in _KINDS:
        raise OptionError(f"--output {path}: unknown result file type {ext or '(none)'} "
                          f"(expected .jsonl, .csv, .h5, or .npz for stacked inputs)")
    return _KINDS[ext]


def is_batch_output(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` names a batch result file (.jsonl, .ndjson, .csv, .h5, .hdf5, .npz)."""
    return Path(path).suffix.lower() in _KINDS


def row_key(row: dict[str, Any]) -> tuple[str, str]:
    return (str(row.get("source", "")), str(row.get("problem", "")))


# ----------------------------------------------------------------------------- reading
def _complete_lines(path: Path) -> tuple[list[bytes], int]:
    """The complete lines of a text file and the byte length they cover (torn tail dropped)."""
    data = path.read_bytes()
    end = data.rfind(b"\n") + 1
    return data[:end].splitlines(), end


def _complete_csv(path: Path) -> tuple[bytes, int]:
    """The complete CSV records of a file and the byte length they cover.

    A record ends at a newline outside quotes (names may hold quoted newlines), so a torn last
    record is recognised even when it was cut inside a quoted field.
    """
    data = path.read_bytes()
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


def _csv_value(col: str, text: str) -> Any:
    if text == "":
        return None if col not in ("source", "problem", "status", "method", "message") else ""
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
    text = data.decode("utf-8", errors="replace")
    rows = []
    for rec in csv.DictReader(io.StringIO(text, newline="")):
        if None in rec or any(c not in rec for c in CSV_COLUMNS):
            continue  # not a complete record
        try:
            rows.append({c: _csv_value(c, rec[c] or "") for c in CSV_COLUMNS})
        except ValueError:
            continue
    return rows


def read_hdf5(path: Path) -> list[dict[str, Any]]:
    """Rows of an HDF5 result file (raises ProblemError when it cannot be read)."""
    import h5py
    import numpy as np

    rows = []
    try:
        with h5py.File(path, "r") as f:
            for name in f:
                g = f[name]
                if "json" not in g.attrs:
                    continue
                row = json.loads(g.attrs["json"])
                row["z"] = [float(x) if math.isfinite(x) else None for x in np.asarray(g["z"])]
                row["w"] = [float(x) if math.isfinite(x) else None for x in np.asarray(g["w"])]
                rows.append(row)
    except (OSError, KeyError, RuntimeError, ValueError, TypeError, RecursionError) as exc:
        raise ProblemError(f"unreadable HDF5 result file ({str(exc).splitlines()[0][:100]})",
                           str(path)) from None
    return rows


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
    if kind == "jsonl":
        return read_jsonl(path) if path.exists() else []
    if kind == "csv":
        return read_csv(path) if path.exists() else []
    rows: list[dict[str, Any]] = []
    if path.exists():
        try:
            rows = read_hdf5(path)
        except ProblemError:
            rows = []
    jpath = journal_path(path)
    if jpath.exists():
        have = {row_key(r) for r in rows}
        rows += [r for r in read_jsonl(jpath) if row_key(r) not in have]
    return rows


# ----------------------------------------------------------------------------- writing
def _fresh_file(path: Path, text: str = "") -> None:
    """Replace ``path`` by a file holding ``text`` (atomically, via a temporary file)."""
    from lcpcli.io import write_atomic_text

    write_atomic_text(path, text)


def _truncate_torn_tail(path: Path, csv_records: bool = False) -> None:
    """Cut a torn last line or CSV record (an interrupted write) so appends start afresh."""
    _, end = _complete_csv(path) if csv_records else _complete_lines(path)
    if end != path.stat().st_size:
        with open(path, "r+b") as f:
            f.truncate(end)
            f.flush()
            os.fsync(f.fileno())


class _LineWriter(ABC):
    """Append-only text file: write + flush per row, fsync at most every FSYNC_SECONDS."""

    #: Records may span lines (quoted newlines in CSV): torn tails are found record-wise.
    multiline = False

    def __init__(self, path: Path, resume: bool, header: str = "") -> None:
        self.path = path
        if resume and path.exists():
            _truncate_torn_tail(path, self.multiline)
            if header and path.stat().st_size == 0:
                path.write_text(header)
        else:
            _fresh_file(path, header)
        self.file = open(path, "a", encoding="utf-8", newline="")  # noqa: SIM115
        self.last_sync = time.monotonic()

    @abstractmethod
    def _line(self, row: dict[str, Any]) -> str:
        """One row as a line of text (the subclass's format)."""

    def write(self, rows: list[dict[str, Any]]) -> None:
        self.file.write("".join(self._line(r) for r in rows))
        self.file.flush()
        if time.monotonic() - self.last_sync >= FSYNC_SECONDS:
            self.sync()

    def sync(self) -> None:
        self.file.flush()
        os.fsync(self.file.fileno())
        self.last_sync = time.monotonic()

    def close(self) -> None:
        if not self.file.closed:
            self.sync()
            self.file.close()


class JsonlWriter(_LineWriter):
    """One JSON object per line."""

    def __init__(self, path: Path, resume: bool) -> None:
        super().__init__(path, resume)

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

    def __init__(self, path: Path, resume: bool) -> None:
        super().__init__(path, resume, header=",".join(CSV_COLUMNS) + "\n")
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


def _group_name(problem: str) -> str:
    name = str(problem).replace("/", "_").strip() or "problem"
    return "_" + name if name in (".", "..") else name


class Hdf5Writer:
    """One group per problem, named after the problem (``name~2``, ... on a clash).

    Each group holds datasets ``z`` and ``w`` (NaN where the JSON has null), attributes
    ``source``, ``problem``, ``status``, ``method``, ``n``, ``iterations``, ``seconds``,
    ``residual``, ``error``, ``message`` (NaN/-1 for missing numbers), a sub-group
    ``certificate`` whose attributes are the certificate's fields, and the attribute ``json``:
    the row without z and w, from which :func:`read_hdf5` rebuilds the JSONL row exactly.
    """

    def __init__(self, path: Path, resume: bool) -> None:
        import h5py

        self.path = path
        jpath = journal_path(path)
        if resume and (path.exists() or jpath.exists()):
            self._recover(path, jpath)
        else:
            if jpath.exists():
                jpath.unlink()
            self._create_empty(path)
        self.journal = JsonlWriter(jpath, resume=True)
        self.file = h5py.File(path, "a")
        self.names = set(self.file.keys())
        self.last_flush = time.monotonic()

    @staticmethod
    def _create_empty(path: Path, rows: list[dict[str, Any]] | None = None) -> None:
        import h5py

        from lcpcli.io import atomic_path

        with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
            names: set[str] = set()
            for row in rows or []:
                _write_group(f, row, names)

    def _recover(self, path: Path, jpath: Path) -> None:
        """Make the HDF5 file hold every row of the file and of the journal."""
        try:
            rows = read_hdf5(path) if path.exists() else []
            damaged = not path.exists()
        except ProblemError:
            rows, damaged = [], True
        have = {row_key(r) for r in rows}
        extra = [r for r in (read_jsonl(jpath) if jpath.exists() else [])
                 if row_key(r) not in have]
        if damaged:
            self._create_empty(path, rows + extra)
        elif extra:
            import h5py

            with h5py.File(path, "a") as f:
                names = set(f.keys())
                for row in extra:
                    _write_group(f, row, names)

    def write(self, rows: list[dict[str, Any]]) -> None:
        self.journal.write(rows)
        for row in rows:
            _write_group(self.file, row, self.names)
        if time.monotonic() - self.last_flush >= FSYNC_SECONDS:
            self.sync()

    def sync(self) -> None:
        self.journal.sync()
        self.file.flush()
        self.last_flush = time.monotonic()

    def close(self) -> None:
        if self.file.id.valid:
            self.file.flush()
            self.file.close()
            self.journal.close()
            journal_path(self.path).unlink(missing_ok=True)


def _write_group(f: Any, row: dict[str, Any], names: set[str]) -> None:
    import numpy as np

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
        g.attrs[col] = str(row.get(col) or "")
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


def open_writer(path: str | os.PathLike[str], *, resume: bool = False) -> Any:
    """A writer for ``path`` (kind from the extension): ``write(rows)``, ``sync()``, ``close()``.

    Without ``resume`` an existing file is replaced; with it, rows are appended after the
    finished ones (a torn tail is cut, an HDF5 file is repaired from its journal).
    """
    path, kind = checked_output(path)
    if kind == "jsonl":
        return JsonlWriter(path, resume)
    if kind == "csv":
        return CsvWriter(path, resume)
    if kind == "npz":
        raise OptionError(f"--output {path}: an .npz result file is written for stacked inputs "
                          f"only (see docs/batch.md); use .jsonl, .csv or .h5")
    return Hdf5Writer(path, resume)


def done_keys(path: str | os.PathLike[str]) -> set[tuple[str, str]]:
    """The ``(source, problem)`` pairs already in a result file (for ``--resume``)."""
    return {row_key(r) for r in read_rows(path)}
