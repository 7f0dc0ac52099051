"""Conversions between stacked files, folders of problem files and multi-group HDF5 files
(``lcpcli convert``), all or nothing."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem
from lcpcli.io import PROBLEM_EXTENSIONS, _module, check_output, detect_format, load
from lcpcli.io.files import file_kind
from lcpcli.io.stack.layout import _stack_format, chunk_size
from lcpcli.io.stack.readers import is_stack, iter_problems, list_names, open_stack
from lcpcli.io.stack.writer import StackWriter
from lcpcli.io.writing import StagedFiles, atomic_path, open_hdf5, writing


# ------------------------------------------------------------------- conversions
def check_member_name(name: str, what: str = "problem name") -> str:
    """A name usable as an HDF5 group or a file stem: not empty, no '/', no NUL, not '.' or
    '..' (ProblemError otherwise)."""
    if not name or "/" in name or "\0" in name or name in (".", ".."):
        raise ProblemError(f"{what} {name!r} cannot name a group or a file (empty, '.', '..', "
                           f"or holding '/' or NUL)")
    return name


def _folder_files(folder: Path) -> list[Path]:

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


def _hdf5_groups(source: str | Path) -> list[str]:
    """The group names of an HDF5 file of groups (one or more); empty for anything else (a
    problem at an HDF5 file's root, another format, stdin)."""
    if str(source) == "-" or detect_format(source) != "hdf5":
        return []
    from lcpcli.io.hdf5_format import group_names

    return group_names(Path(source))


def source_problems(source: str | Path) -> Iterator[tuple[str, Problem]]:
    """``(label, problem)`` for every problem of ``source``, streamed: a folder (its problem
    files, sorted, names = file stems), a stack (the naming rule), an HDF5 file of groups
    (names = group names, one group or more) or a one-problem file (name = its stem).
    ``label`` says where the problem comes from (used in messages)."""

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
    names = _hdf5_groups(source)
    if names:
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

    path = Path(source)
    if path.is_dir():
        return [f.stem for f in _folder_files(path)]
    if is_stack(source):
        try:
            return list_names(source)
        except ProblemError as exc:
            raise exc.with_source(str(source)) from None
    return _hdf5_groups(source) or [path.stem]


def write_folder(source: str | Path, folder: str | Path, fmt: str, *,
                 force: bool = False) -> int:
    """One file per problem of ``source`` in ``folder`` (created if missing), named
    ``NAME.EXT`` (EXT from ``fmt``: json, npz, h5/hdf5, dat).  Every target is checked before
    anything is written (:func:`~lcpcli.io.writing.check_output`: an existing file is refused
    unless ``force``, an input never overwritten); the files are written all or nothing
    (:class:`~lcpcli.io.writing.StagedFiles`: a bad problem or a full disk leaves none)."""

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
            try:
                with writing(t):
                    write(p, tmp)
            except ProblemError as exc:  # what the format cannot hold: named by its file
                raise exc.with_source(str(t)) from None
        staged.commit()
    return len(targets)


def check_output_folder(folder: str | Path) -> None:
    """An output folder: an existing directory (not a link), or missing with an existing
    parent (ProblemError naming it otherwise; `-`, stdout, is never a folder)."""


    if str(folder) == "-":
        raise ProblemError("is stdout, not a folder: give the folder's name", "-")
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
