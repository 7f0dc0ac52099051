"""Problem files: read and write JSON, NPZ, HDF5 and Siconos ``.dat``.

``load(path)`` returns a validated :class:`~lcpcli.core.problem.Problem`; every failure (missing
or non-regular file, unknown extension, malformed content, wrong shapes or types, NaN/Inf,
pickled NPZ, truncated HDF5, absurd sizes) raises :class:`~lcpcli.core.errors.ProblemError` with
a one-line message that names the file.  Readers check types (:mod:`lcpcli.core.numeric`),
shapes and sizes of every dataset from the file's headers before reading its data, and read
only regular files, text up to :data:`~lcpcli.io.files.MAX_TEXT_BYTES` (:mod:`lcpcli.io.files`).
Scenes (:mod:`lcpcli.contact.scene`) and warm starts (:mod:`lcpcli.io.warmstart`) are read with
the same helpers under the same rules, stated once in docs/files.md ("Reading").  A stacked file
is detected by the format readers (:class:`~lcpcli.io.files.StackedFile`) and read here with
:mod:`lcpcli.io.stack`.
``save(problem, path)`` writes atomically: a temporary file in the same folder is renamed over
the target only once it is complete, so a failed write leaves no partial file and never damages
an existing one; :func:`~lcpcli.io.writing.check_output` is what commands call first so that an
output is never an input, a link or a device.

Formats (chosen by extension, or ``fmt=``):

* ``.json``  ``{"M": [[...]], "q": [...]}`` plus optional ``name``, ``description``, ``n_eq``,
  ``lower``/``upper`` (``null`` = infinite), ``meta``; a sparse M is
  ``{"format": "csr"|"coo", "shape": [n, n], ...}``.  ``-`` reads JSON from stdin.
* ``.npz``   arrays ``M``, ``q`` (or sparse ``M_format``, ``M_shape``, ``M_data``, ...);
  loaded with ``allow_pickle=False``.
* ``.h5``/``.hdf5``  datasets ``M``, ``q`` at the root, or one group per problem; a sparse M is
  a group with ``format``/``shape`` attributes and ``data``/``indices``/``indptr`` (or
  ``row``/``col``) datasets.
* ``.dat``   Siconos numerics LCP/MLCP text files (M stored column-major).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem
from lcpcli.io.files import (
    MAX_TEXT_BYTES,
    StackedFile,
    check_input_file,
    decode_text,
    read_stdin_bytes,
)
from lcpcli.io.writing import (
    atomic_path,
    check_output,
    output_lock,
    write_atomic_text,
)

#: Problem file extensions and their formats (the one list: batch inputs use it too).
FORMATS = {
    ".json": "json",
    ".npz": "npz",
    ".h5": "hdf5",
    ".hdf5": "hdf5",
    ".hdf": "hdf5",
    ".dat": "dat",
}
#: The extensions of problem files (folders given to a batch are searched for these).
PROBLEM_EXTENSIONS = tuple(FORMATS)


def _name(path: str | os.PathLike[str]) -> str:
    """``Path(path).name``: the last component that is not empty or ``.`` (pathlib drops
    those; it keeps ``..``), ``""`` when there is none."""
    text = os.fspath(path)
    if os.altsep:
        text = text.replace(os.altsep, os.sep)
    i = len(text)
    while i > 0:
        j = text.rfind(os.sep, 0, i)
        part = text[j + 1:i]
        if part and part != ".":
            return part
        i = j if j >= 0 else 0
    return ""


def suffix(path: str | os.PathLike[str]) -> str:
    """``Path(path).suffix`` (pathlib's rule on the last component: from its last dot, unless
    that dot starts or ends it), without building a Path (a batch asks for 10^4+ files)."""
    name = _name(path)
    i = name.rfind(".")
    return name[i:] if 0 < i < len(name) - 1 else ""


def stem(path: str | os.PathLike[str]) -> str:
    """``Path(path).stem``: the last component without its :func:`suffix`."""
    name = _name(path)
    i = name.rfind(".")
    return name[:i] if 0 < i < len(name) - 1 else name


def detect_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """The format name for ``path`` (``fmt`` overrides the extension)."""
    if fmt:
        fmt = fmt.lower().lstrip(".")
        if fmt in ("h5", "hdf"):
            fmt = "hdf5"
        if fmt not in set(FORMATS.values()):
            raise ProblemError(f"unknown format '{fmt}' (expected json, npz, hdf5, dat)")
        return fmt
    if str(path) == "-":
        return "json"
    ext = suffix(path).lower()
    if ext not in FORMATS:
        shown = ext or "(none)"
        raise ProblemError(f"unknown file type {shown} (expected .json, .npz, .h5/.hdf5, .dat)")
    return FORMATS[ext]


def input_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """:func:`detect_format` of a file to read: a name without an extension that does not
    exist (``nonexist/``, a folder mistyped) is "no such file" (ProblemError), not "unknown
    file type (none)"."""
    try:
        return detect_format(path, fmt)
    except ProblemError:
        if not fmt and not suffix(path) and str(path) != "-" and not os.path.lexists(path):
            check_input_file(path)  # raises: no such file
        raise


def _module(fmt: str) -> Any:
    if fmt == "json":
        from lcpcli.io import json_format as mod
    elif fmt == "npz":
        from lcpcli.io import npz_format as mod
    elif fmt == "hdf5":
        from lcpcli.io import hdf5_format as mod
    else:
        from lcpcli.io import siconos_dat as mod
    return mod


def load(path: str | os.PathLike[str], problem: str | None = None, *,
         fmt: str | None = None, check_dense: Callable[[int], None] | None = None,
         content: list[bytes] | None = None) -> Problem:
    """Read one problem from ``path`` (``-`` = JSON on stdin); ``problem`` picks an HDF5 group.

    Only regular files are read (see :mod:`lcpcli.io.files`); sizes, shapes and data types are
    checked from headers before the data is read.  ``check_dense(n)`` (a caller's work budget,
    :mod:`lcpcli.core.limits`) is called with the size of a dense M before it is read, from
    the header in HDF5 and NPZ files (a lazily allocated 15,000 x 15,000 M costs nothing), after
    parsing in the text formats; a sparse M is not checked.  ``content``: a list that receives
    the bytes a JSON file was parsed from (a batch fingerprints them instead of reading the
    file a second time).
    """
    source = str(path)
    try:
        kind = input_format(path, fmt)
        if problem is not None and kind not in ("hdf5", "npz"):
            raise ProblemError("--problem applies to HDF5 files and stacked files only")
        if source == "-":
            from lcpcli.io import json_format

            text = decode_text(read_stdin_bytes(MAX_TEXT_BYTES), "UTF-8 JSON text")
            prob = json_format.read_text(text, default_name="stdin")
        else:
            prob = _read_file(path, kind, problem, check_dense, content)
        if check_dense is not None and not prob.sparse:
            check_dense(prob.n)  # text formats and stacks: after reading (HDF5/NPZ: done)
        return prob
    except ProblemError as exc:
        raise exc.with_source(source) from None
    except PermissionError:
        raise ProblemError("permission denied", source) from None
    except MemoryError:
        raise ProblemError("not enough memory to read the problem", source) from None
    except RecursionError:
        raise ProblemError("data nested too deeply", source) from None


def _read_file(path: str | os.PathLike[str], kind: str, problem: str | None,
               check_dense: Callable[[int], None] | None,
               content: list[bytes] | None = None) -> Problem:
    """:func:`load` of a file of format ``kind`` (a stack handed to :mod:`lcpcli.io.stack`)."""
    if kind == "json":  # no Path built: a batch reads 10^4+ small JSON files
        return _module(kind).read(path, content, default_name=stem(path))
    if kind == "hdf5":  # the other readers open it with io.files.open_input, which checks
        check_input_file(path)
    p = path if isinstance(path, Path) else Path(path)
    if problem is not None and kind == "npz":  # an NPZ holds one problem, or a stack
        from lcpcli.io.stack import is_stack

        if not is_stack(p):
            raise ProblemError("--problem applies to HDF5 files and stacked files only")
        return _read_stacked(p, problem)
    try:
        if kind == "hdf5":
            return _module(kind).read(p, problem, check_dense)
        if kind == "npz":
            return _module(kind).read(p, check_dense)
        return _module(kind).read(p)
    except StackedFile:  # the format reader found a stack: the stack reader takes over
        return _read_stacked(p, problem)


def _read_stacked(path: Path, problem: str | None) -> Problem:
    """One problem of a stacked file (several without ``problem``: refused, see
    :func:`lcpcli.io.stack.read_single`)."""
    from lcpcli.io.stack import read_single

    return read_single(path, problem)


def list_problems(path: str | os.PathLike[str]) -> list[str]:
    """Names of the problems a file holds (HDF5: the groups; a stacked file: its K names, see
    :mod:`lcpcli.io.stack`; other formats: one name)."""
    kind = detect_format(path)
    if kind == "hdf5":
        from lcpcli.io import hdf5_format

        try:
            check_input_file(path)
            try:
                return hdf5_format.list_problems(Path(path))
            except StackedFile:
                from lcpcli.io.stack import list_names

                return list_names(path)
        except ProblemError as exc:
            raise exc.with_source(str(path)) from None
    if kind == "npz":
        from lcpcli.io.stack import is_stack, list_names

        if is_stack(path):
            try:
                return list_names(path)
            except ProblemError as exc:
                raise exc.with_source(str(path)) from None
    return [Path(path).stem]


def save(problem: Problem, path: str | os.PathLike[str], *, fmt: str | None = None) -> None:
    """Write ``problem`` to ``path`` atomically (``-`` writes JSON to stdout)."""
    kind = detect_format(path, fmt)
    if str(path) == "-":
        from lcpcli.io import json_format

        sys.stdout.write(json_format.dumps(problem) + "\n")
        return
    writer = _module(kind).write
    with atomic_path(Path(path)) as tmp:
        writer(problem, tmp)


Reader = Callable[..., Problem]

__all__ = ["FORMATS", "MAX_TEXT_BYTES", "PROBLEM_EXTENSIONS", "atomic_path", "check_output",
           "detect_format", "list_problems", "load", "output_lock", "save",
           "write_atomic_text"]
