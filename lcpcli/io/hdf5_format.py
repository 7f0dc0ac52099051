"""HDF5 problem files (h5py).

Layout: datasets ``M`` and ``q`` at the root (one problem), or one group per problem, each
holding ``M`` and ``q``.  Optional per problem: datasets ``lower``/``upper``; attributes
``name``, ``description``, ``n_eq`` and ``meta`` (a JSON string).  A sparse ``M`` is a group
with attributes ``format`` (csr/csc/coo) and ``shape`` and datasets ``data`` plus
``indices``/``indptr`` or ``row``/``col``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import INDEX_KINDS, REAL_KINDS, check_dtype, json_text
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.files import (
    MAX_JSON_DEPTH,
    MAX_NAME_BYTES,
    MAX_TEXT_BYTES,
    StackedFile,
    check_depth,
    check_h5_chunks,
    parse_json,
    stored_text,
)
from lcpcli.io.sparse import (
    check_part_sizes,
    parse_format,
    parse_shape,
    sparse_from_parts,
    sparse_parts,
)
from lcpcli.io.writing import open_hdf5

#: A reader's hook for the caller's work budget: called with n of a dense M from its header.
DenseCheck = Callable[[int], None] | None
#: The errors h5py raises on damaged or unexpected content (turned into one-line messages).
H5_ERRORS = (OSError, KeyError, RuntimeError, TypeError, ValueError, AttributeError)


def open_file(path: Path, **kwargs: Any) -> Any:
    """The file opened read-only (``kwargs`` go to ``h5py.File``, e.g. the chunk cache).

    The access helpers below are the HDF5 half of the reading layer, for problems and scenes
    alike: :func:`child` follows hard and soft links only (an external or user-defined link is
    refused, never opened), :func:`dataset` refuses data kept in other files (external storage,
    virtual datasets) and checks the type from the header, :func:`read_float` reads a checked
    dataset (whose shape the caller has checked) as float64.  :func:`dataset` also refuses chunks
    far larger than their data (:func:`~lcpcli.io.files.check_h5_chunks`).
    """
    import h5py

    try:
        return h5py.File(path, "r", **kwargs)
    except OSError as exc:
        reason = str(exc).split("(")[0].strip() or "unreadable"
        raise ProblemError(f"not a readable HDF5 file ({reason})") from None


def damaged(exc: BaseException) -> ProblemError:
    """The one-line error of what h5py raised (:data:`H5_ERRORS`); a ProblemError (a refusal
    of the reading layer: ProblemError is a ValueError) is returned as it is, whole."""
    if isinstance(exc, ProblemError):
        return exc
    first = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
    return ProblemError(f"damaged HDF5 data ({first})")


def _has(g: Any, name: str) -> bool:
    """Whether ``g`` has a link called ``name`` (without following it)."""
    try:
        return g.get(name, getlink=True) is not None
    except H5_ERRORS:
        return False


def child(g: Any, name: str, label: str) -> Any:
    """The object linked as ``name`` in ``g``; external links are refused, never opened."""
    import h5py

    link = g.get(name, getlink=True)
    if link is None:
        return None
    if isinstance(link, h5py.ExternalLink):
        raise ProblemError(f"'{label}' is an external link (to {link.filename}); the data "
                           f"must be stored in the file itself")
    if not isinstance(link, (h5py.HardLink, h5py.SoftLink)):
        raise ProblemError(f"'{label}' is a user-defined link; refused")
    node = g.get(name)
    if node is None:
        raise ProblemError(f"'{label}' is a dangling link")
    return node


def _is_problem(node: Any) -> bool:
    import h5py

    return isinstance(node, h5py.Group) and _has(node, "q") and _has(node, "M")


def _problem_groups(f: Any) -> list[str]:
    import h5py

    names = []
    for name in f:
        link = f.get(name, getlink=True)
        if isinstance(link, (h5py.HardLink, h5py.SoftLink)) and _is_problem(f.get(name)):
            names.append(name)
    return names


def is_stacked_root(f: Any) -> bool:
    """Whether the root holds a stack: a dataset M of 3 dimensions, linked in the file (the one
    HDF5 test; :func:`lcpcli.io.stack.is_stack` uses it).  Reads headers only; never raises."""
    import h5py

    try:
        link = f.get("M", getlink=True)
        node = f.get("M") if isinstance(link, (h5py.HardLink, h5py.SoftLink)) else None
        return isinstance(node, h5py.Dataset) and node.shape is not None \
            and len(node.shape) == 3
    except H5_ERRORS:
        return False


def list_problems(path: Path) -> list[str]:
    """The problems in the file: the root problem's name when M and q sit at the root, else the
    group names; a stack raises :class:`~lcpcli.io.files.StackedFile` (``lcpcli.io`` lists it
    with :mod:`lcpcli.io.stack`)."""
    with open_file(path) as f:
        try:
            if _is_problem(f):
                if is_stacked_root(f):
                    raise StackedFile()
                return [attr_text(f, "name", MAX_NAME_BYTES) or path.stem]
            return _problem_groups(f)
        except ProblemError:
            raise
        except H5_ERRORS as exc:
            raise damaged(exc) from None


def group_names(path: Path) -> list[str]:
    """The problems' group names; empty when the problem sits at the root (one problem, named
    by its ``name`` attribute or the file's stem) or the file is a stack."""
    with open_file(path) as f:
        try:
            return [] if _is_problem(f) else _problem_groups(f)
        except H5_ERRORS as exc:
            raise damaged(exc) from None


def read(path: Path, problem: str | None = None, check_dense: DenseCheck = None) -> Problem:
    """One problem (``problem``: a group name); a stack raises
    :class:`~lcpcli.io.files.StackedFile` (``lcpcli.io.load`` reads it with
    :mod:`lcpcli.io.stack`).  The file is opened once.  ``check_dense(n)`` is called with the
    size of a dense M from its header, before its data is read (a caller's work budget)."""
    with open_file(path) as f:
        try:
            if _is_problem(f) and is_stacked_root(f):
                raise StackedFile()
            if _is_problem(f) and problem is None:
                return _read_group(f, path.stem, check_dense)
            groups = _problem_groups(f)
            if problem is None:
                if len(groups) == 1:
                    return _read_group(f[groups[0]], groups[0], check_dense)
                if not groups:
                    raise ProblemError("no problem found (expected datasets M and q at the root "
                                       "or in groups)")
                raise ProblemError(f"holds {len(groups)} problems ({_names(groups)}); "
                                   f"pick one with --problem NAME")
            if problem not in groups:
                raise ProblemError(f"no problem named '{problem}' (problems: {_names(groups)})")
            return _read_group(f[problem], problem, check_dense)
        except ProblemError:
            raise
        except H5_ERRORS as exc:
            raise damaged(exc) from None


def _names(groups: list[str], limit: int = 20) -> str:
    shown = ", ".join(groups[:limit])
    return shown + (f", ... ({len(groups) - limit} more)" if len(groups) > limit else "")


# ------------------------------------------------------------------ checked access
def dataset(g: Any, name: str, label: str, kinds: str | None = REAL_KINDS) -> Any:
    """A dataset of ``g`` stored in this file, of an accepted type (nothing read yet).

    ``kinds=None`` skips the type check (the caller checks a non-numeric type itself).
    """
    import h5py

    node = child(g, name, label)
    if node is None:
        return None
    if not isinstance(node, h5py.Dataset):
        raise ProblemError(f"'{label}' is a group, expected a dataset")
    if node.shape is None:
        raise ProblemError(f"'{label}' is an empty (null) dataset")
    if node.is_virtual or node.id.get_create_plist().get_external_count():
        raise ProblemError(f"'{label}' keeps its data in other files (virtual or external "
                           f"storage); refused")
    check_h5_chunks(node.id, label)
    if kinds is not None:
        check_dtype(node.dtype, f"'{label}'", kinds=kinds)
    return node


def read_float(d: Any) -> np.ndarray:
    """A checked dataset's data as float64 (HDF5 converts integer types on the way)."""
    out = np.empty(d.shape, dtype=np.float64)
    if out.size:
        d.read_direct(out)
    return out


def read_index(d: Any) -> np.ndarray:
    out = np.empty(d.shape, dtype=np.int64)
    if out.size:
        d.read_direct(out)
    return out


def _vector(g: Any, name: str, n: int) -> np.ndarray | None:
    """Dataset ``name`` as a vector of length ``n`` (shape checked before reading)."""
    d = dataset(g, name, name)
    if d is None:
        return None
    shape = tuple(d.shape)
    if len(shape) > 2 or math.prod(shape) != n or (len(shape) == 2 and 1 not in shape
                                                   and n != 1):
        raise ProblemError(f"{name} has shape {shape} but M is {n} x {n}")
    return read_float(d).reshape(-1)


def _attr_id(g: Any, key: str) -> Any:
    import h5py

    if key not in g.attrs:
        return None
    return h5py.h5a.open(g.id, key.encode())


def attr_int(g: Any, key: str) -> int | None:
    aid = _attr_id(g, key)
    if aid is None:
        return None
    shape = aid.shape
    if shape is None or math.prod(shape) != 1 or aid.dtype.kind not in INDEX_KINDS:
        raise ProblemError(f"attribute '{key}' must be one integer (got {aid.dtype} "
                           f"of shape {shape})")
    return int(np.asarray(g.attrs[key]).reshape(-1)[0])


def attr_text(g: Any, key: str, limit: int) -> str:
    """A string attribute (fixed or variable length), at most ``limit`` bytes; '' if absent."""
    import h5py

    aid = _attr_id(g, key)
    if aid is None:
        return ""
    shape = aid.shape
    is_text = aid.dtype.kind in "SU" or h5py.check_string_dtype(aid.dtype) is not None
    if shape is None or math.prod(shape) != 1 or not is_text:
        raise ProblemError(f"attribute '{key}' must be one string (got {aid.dtype} "
                           f"of shape {shape})")
    value = g.attrs[key]
    if isinstance(value, np.ndarray):
        value = value.reshape(-1)[0]
    if isinstance(value, bytes):
        value = value.decode("utf-8", errors="replace")
    value = str(value)
    if len(value) > limit:
        raise ProblemError(f"attribute '{key}' is longer than {limit:,} bytes")
    return value


def _read_matrix(g: Any, check_dense: DenseCheck = None) -> Any:
    import h5py

    node = child(g, "M", "M")
    if isinstance(node, h5py.Group):
        return _read_sparse(node)
    d = dataset(g, "M", "M")
    if len(d.shape) == 3:
        raise ProblemError(f"M has shape {tuple(d.shape)}: a stack of problems (M of shape "
                           f"(K, n, n)) is stored at the root of its own file, not in a group")
    if len(d.shape) != 2:
        raise ProblemError(f"M must be a 2-D matrix, got shape {tuple(d.shape)}")
    check_size(*d.shape)
    if check_dense is not None:
        check_dense(int(d.shape[0]))
    return read_float(d)


def _read_sparse(node: Any) -> Any:
    """A sparse M group: attributes, then every part's type and length, then the data."""
    if "format" not in node.attrs:
        raise ProblemError("sparse M: missing attribute 'format'")
    fmt = parse_format(attr_text(node, "format", 16))
    aid = _attr_id(node, "shape")
    if aid is None:
        raise ProblemError("sparse M: missing attribute 'shape'")
    if aid.shape is None or math.prod(aid.shape) != 2 or aid.dtype.kind not in INDEX_KINDS:
        raise ProblemError("sparse M: attribute 'shape' must be two integers")
    shape = parse_shape(np.asarray(node.attrs["shape"]).reshape(-1))
    heads = {}
    for k in ("data", "indices", "indptr", "row", "col"):
        d = dataset(node, k, f"M/{k}", REAL_KINDS if k == "data" else INDEX_KINDS)
        if d is not None:
            if len(d.shape) != 1:
                raise ProblemError(f"sparse M: '{k}' must be 1-D, got shape {tuple(d.shape)}")
            heads[k] = d
    check_part_sizes(fmt, shape, {k: int(d.shape[0]) for k, d in heads.items()})
    parts: dict[str, Any] = {"format": fmt, "shape": shape}
    for k, d in heads.items():
        parts[k] = read_float(d) if k == "data" else read_index(d)
    return sparse_from_parts(parts, "M")


def _read_group(g: Any, default_name: str, check_dense: DenseCheck = None) -> Problem:
    M = _read_matrix(g, check_dense)
    n = M.shape[0]
    q = _vector(g, "q", n)
    lower = _vector(g, "lower", n)
    upper = _vector(g, "upper", n)
    meta: dict[str, Any] = {}
    text = attr_text(g, "meta", MAX_TEXT_BYTES)
    if text:
        meta = parse_json(text)
        if not isinstance(meta, dict):
            raise ProblemError("attribute 'meta' must be a JSON object")
        check_depth(meta, "attribute 'meta'", MAX_JSON_DEPTH)
    n_eq = attr_int(g, "n_eq")
    return Problem.create(M, q, n_eq=n_eq or 0, lower=lower, upper=upper,
                          name=attr_text(g, "name", MAX_NAME_BYTES) or default_name,
                          description=attr_text(g, "description", MAX_NAME_BYTES), meta=meta)


def write_group(g: Any, problem: Problem) -> None:
    """Store ``problem`` in the (empty) h5py group ``g``."""
    if problem.sparse:
        parts = sparse_parts(problem.M)
        mg = g.create_group("M")
        mg.attrs["format"] = parts["format"]
        mg.attrs["shape"] = np.asarray(parts["shape"], dtype=np.int64)
        for k in ("data", "indices", "indptr"):
            mg.create_dataset(k, data=parts[k])
    else:
        g.create_dataset("M", data=problem.M)
    g.create_dataset("q", data=problem.q)
    if problem.lower is not None:
        g.create_dataset("lower", data=problem.lower)
        g.create_dataset("upper", data=problem.upper)
    if problem.n_eq:
        g.attrs["n_eq"] = problem.n_eq
    for label in ("name", "description"):
        if getattr(problem, label):
            stored_text(getattr(problem, label), label, "HDF5")
            g.attrs[label] = getattr(problem, label)
    if problem.meta:
        g.attrs["meta"] = json_text(problem.meta)


def write(problem: Problem, path: Path) -> None:
    """Write ``problem`` into the new file ``path`` (through :func:`lcpcli.io.writing.open_hdf5`:
    a full disk is an OutputError, never a failed HDF5 flush)."""

    with open_hdf5(path, "w") as f:
        write_group(f, problem)


def write_many(problems: list[Problem], path: Path) -> None:
    """One group per problem (named by ``problem.name``, which must be unique)."""

    names = [p.name for p in problems]
    if len(set(names)) != len(names) or not all(names):
        raise ProblemError("problems written to one HDF5 file need unique, non-empty names")
    with open_hdf5(path, "w") as f:
        for p in problems:
            write_group(f.create_group(p.name), p)


def read_many(path: Path, names: list[str]) -> Any:
    """Yield ``(name, Problem or ProblemError)`` for ``names``, opening the file once.

    A name that is not a problem group falls back to the root problem when M and q sit at the
    root (the name :func:`list_problems` gives it).  Used by batch runs; errors are yielded,
    not raised, so one damaged group does not stop the others.
    """
    try:
        f = open_file(path)
    except ProblemError as exc:
        for name in names:
            yield name, exc
        return
    with f:
        root = _is_problem(f)
        for name in names:
            try:
                fast = _read_plain_group(f, name)
                if fast is not None:
                    yield name, fast
                    continue
                node = child(f, name, name) if _has(f, name) else None
                if node is not None and _is_problem(node):
                    yield name, _read_group(node, name)
                elif root:
                    yield name, _read_group(f, path.stem)
                else:
                    yield name, ProblemError(f"no problem named '{name}'")
            except ProblemError as exc:
                yield name, exc
            except H5_ERRORS as exc:
                yield name, damaged(exc)


def _read_plain_group(f: Any, name: str) -> Problem | None:
    """Fast path of :func:`read_many` for the common group: dense ``M`` and ``q`` only.

    Uses h5py's low-level API with as few HDF5 calls as the checks allow (h5py's high-level
    API costs about 5x more per group, which dominates for small problems).  Returns None,
    so that the general reader runs, when the group has anything else that matters (bounds,
    ``n_eq``, ``meta``, a sparse or non-numeric ``M``, a soft or external link, data stored
    outside this file).  The problem is named after the group.
    """
    import h5py

    key = name.encode()
    if not _hard_link(f.id, key):
        return None
    gid = h5py.h5o.open(f.id, key)
    if not isinstance(gid, h5py.h5g.GroupID):
        return None
    links = gid.links
    if not (_hard_link(gid, b"M") and _hard_link(gid, b"q")) or links.exists(b"lower") \
            or links.exists(b"upper"):
        return None
    if h5py.h5a.exists(gid, b"n_eq") or h5py.h5a.exists(gid, b"meta"):
        return None
    arrays = []
    n = 0
    for part, ndim in ((b"M", (2,)), (b"q", (1, 2))):
        d = h5py.h5o.open(gid, part)
        if not isinstance(d, h5py.h5d.DatasetID):
            return None
        shape = d.shape  # each property call asks HDF5 again: read them once
        # the type class, not d.dtype (which builds a numpy dtype: 15 us per dataset)
        if shape is None or len(shape) not in ndim or d.get_type().get_class() not in (
                h5py.h5t.INTEGER, h5py.h5t.FLOAT):  # REAL_KINDS: signed, unsigned, float
            return None
        # contiguous data in this file has an offset; chunked, compact, external, virtual or
        # unallocated data has none: then the creation properties decide
        if d.get_offset() is None:
            plist = d.get_create_plist()
            if plist.get_layout() == h5py.h5d.VIRTUAL or plist.get_external_count():
                return None
            check_h5_chunks(d, part.decode())
        if part == b"M":
            check_size(*shape)
            n = shape[0]
        elif math.prod(shape) != n:
            return None  # the general reader says what is wrong
        out = np.empty(shape, dtype=np.float64)
        if out.size:
            d.read(h5py.h5s.ALL, h5py.h5s.ALL, out, mtype=h5py.h5t.NATIVE_DOUBLE)
        arrays.append(out)
    return Problem.create(arrays[0], arrays[1], name=name)


def _hard_link(gid: Any, key: bytes) -> bool:
    """Whether ``key`` names a hard link of the group ``gid`` (soft/external: the slow path)."""
    import h5py

    try:  # one HDF5 call (h5py raises RuntimeError for a missing name or path component;
        # anything wrong with the file is left to the general reader, which names it)
        return gid.links.get_info(key).type == h5py.h5l.TYPE_HARD
    except (KeyError, RuntimeError):
        return False
