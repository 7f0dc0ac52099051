"""HDF5 problem files (h5py).

Layout: datasets ``M`` and ``q`` at the root (one problem), or one group per problem, each
holding ``M`` and ``q``.  Optional per problem: datasets ``lower``/``upper``; attributes
``name``, ``description``, ``n_eq`` and ``meta`` (a JSON string).  A sparse ``M`` is a group
with attributes ``format`` (csr/csc/coo) and ``shape`` and datasets ``data`` plus
``indices``/``indptr`` or ``row``/``col``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem, check_size
from lcpcli.io.sparse import sparse_from_parts, sparse_parts


def _open(path: Path) -> Any:
    import h5py

    try:
        return h5py.File(path, "r")
    except OSError as exc:
        reason = str(exc).split("(")[0].strip() or "unreadable"
        raise ProblemError(f"not a readable HDF5 file ({reason})") from None


def _is_problem(node: Any) -> bool:
    import h5py

    return isinstance(node, h5py.Group) and "q" in node and "M" in node


def _problem_groups(f: Any) -> list[str]:
    import h5py

    return [name for name, node in f.items() if isinstance(node, h5py.Group) and _is_problem(node)]


def list_problems(path: Path) -> list[str]:
    """The problems in the file: ``["/"]`` when M and q sit at the root, else group names."""
    with _open(path) as f:
        if _is_problem(f):
            return [str(f.attrs.get("name", "")) or path.stem]
        return _problem_groups(f)


def read(path: Path, problem: str | None = None) -> Problem:
    with _open(path) as f:
        try:
            if _is_problem(f) and problem is None:
                return _read_group(f, path.stem)
            groups = _problem_groups(f)
            if problem is None:
                if len(groups) == 1:
                    return _read_group(f[groups[0]], groups[0])
                if not groups:
                    raise ProblemError("no problem found (expected datasets M and q at the root "
                                       "or in groups)")
                raise ProblemError(f"holds {len(groups)} problems ({_names(groups)}); "
                                   f"pick one with --problem NAME")
            if problem not in groups:
                raise ProblemError(f"no problem named '{problem}' (problems: {_names(groups)})")
            return _read_group(f[problem], problem)
        except (OSError, KeyError, RuntimeError) as exc:
            raise ProblemError(f"damaged HDF5 data ({str(exc).splitlines()[0][:100]})") from None


def _names(groups: list[str], limit: int = 20) -> str:
    shown = ", ".join(groups[:limit])
    return shown + (f", ... ({len(groups) - limit} more)" if len(groups) > limit else "")


def _read_group(g: Any, default_name: str) -> Problem:
    import h5py

    node = g["M"]
    if isinstance(node, h5py.Group):
        parts: dict[str, Any] = {k: node.attrs[k] for k in ("format", "shape") if k in node.attrs}
        if "data" in node:
            check_size(*[int(x) for x in np.asarray(parts.get("shape", (0, 0))).ravel()[:2]],
                       sparse=True, nnz=int(node["data"].shape[0]))
        for k in ("data", "indices", "indptr", "row", "col"):
            if k in node:
                parts[k] = node[k][()]
        M: Any = sparse_from_parts(parts, "M")
    else:
        if len(node.shape) == 2:
            check_size(*node.shape)
        M = node[()]
    q = g["q"][()]
    attrs = g.attrs
    meta: dict[str, Any] = {}
    if "meta" in attrs:
        try:
            meta = json.loads(_text(attrs["meta"]))
        except json.JSONDecodeError:
            raise ProblemError("attribute 'meta' is not a JSON string") from None
    return Problem.create(M, q, n_eq=int(attrs.get("n_eq", 0)),
                          lower=g["lower"][()] if "lower" in g else None,
                          upper=g["upper"][()] if "upper" in g else None,
                          name=_text(attrs.get("name", "")) or default_name,
                          description=_text(attrs.get("description", "")), meta=meta)


def _text(x: Any) -> str:
    if isinstance(x, bytes):
        return x.decode()
    return str(x)


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
    if problem.name:
        g.attrs["name"] = problem.name
    if problem.description:
        g.attrs["description"] = problem.description
    if problem.meta:
        g.attrs["meta"] = json.dumps(problem.meta)


def write(problem: Problem, path: Path) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        write_group(f, problem)


def write_many(problems: list[Problem], path: Path) -> None:
    """One group per problem (named by ``problem.name``, which must be unique)."""
    import h5py

    names = [p.name for p in problems]
    if len(set(names)) != len(names) or not all(names):
        raise ProblemError("problems written to one HDF5 file need unique, non-empty names")
    with h5py.File(path, "w") as f:
        for p in problems:
            write_group(f.create_group(p.name), p)


def read_many(path: Path, names: list[str]) -> Any:
    """Yield ``(name, Problem or ProblemError)`` for ``names``, opening the file once.

    A name that is not a problem group falls back to the root problem when M and q sit at the
    root (the name :func:`list_problems` gives it).  Used by batch runs; errors are yielded,
    not raised, so one damaged group does not stop the others.
    """
    try:
        f = _open(path)
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
                node = f.get(name)
                if node is not None and _is_problem(node):
                    yield name, _read_group(node, name)
                elif root:
                    yield name, _read_group(f, path.stem)
                else:
                    yield name, ProblemError(f"no problem named '{name}'")
            except ProblemError as exc:
                yield name, exc
            except (OSError, KeyError, RuntimeError, ValueError) as exc:
                yield name, ProblemError(
                    f"damaged HDF5 data ({str(exc).splitlines()[0][:100]})")


def _read_plain_group(f: Any, name: str) -> Problem | None:
    """Fast path of :func:`read_many` for the common group: dense ``M`` and ``q`` only.

    Uses h5py's low-level API (about 5x less overhead per group than the high-level one,
    which dominates for small problems).  Returns None, so that the general reader runs,
    when the group has anything else that matters (bounds, ``n_eq``, ``meta``, a sparse or
    non-numeric ``M``).  The problem is named after the group.
    """
    import h5py

    key = name.encode()
    if not f.id.links.exists(key):
        return None
    gid = h5py.h5o.open(f.id, key)
    if not isinstance(gid, h5py.h5g.GroupID):
        return None
    links = gid.links
    if not (links.exists(b"M") and links.exists(b"q")) or links.exists(b"lower") \
            or links.exists(b"upper"):
        return None
    if h5py.h5a.exists(gid, b"n_eq") or h5py.h5a.exists(gid, b"meta"):
        return None
    arrays = []
    for part, ndim in ((b"M", (2,)), (b"q", (1, 2))):
        d = h5py.h5o.open(gid, part)
        if not isinstance(d, h5py.h5d.DatasetID) or d.dtype.kind not in "fiu" \
                or len(d.shape) not in ndim:
            return None
        if part == b"M":
            check_size(*d.shape)
        out = np.empty(d.shape, dtype=np.float64)
        if out.size:
            d.read(h5py.h5s.ALL, h5py.h5s.ALL, out)
        arrays.append(out)
    return Problem.create(arrays[0], arrays[1], name=name)
