"""Impulse files: warm starts for ``contact-matrix --z0`` and what ``--impulses`` writes.

An impulses file written by ``contact-matrix --solve --impulses FILE`` holds the solution ``z``
and the names of its unknowns (``n[c]``, ``t<k>[c]``, ``lambda[c]``):

* ``.json``: ``{"format": "lcpcli-contact-impulses", "version": 1, "scene", "status",
  "unknowns": [...], "z": [...]}`` (``lcpcli solve --z0`` reads it too: it has ``"z"``);
* ``.npz``: arrays ``z`` and ``unknowns``.

``--z0 FILE`` accepts that file, the ``contact-matrix --json`` output (``impulses`` and
``unknowns``), and whatever :func:`lcpcli.io.warmstart.load_z0` reads (``lcpcli solve --json``
output, a JSON list, ``.npy``, ``.npz``).  When the file names its unknowns, values are matched
**by name** (a contact that is new gets 0, one that is gone is dropped: the scene of the next
step may differ); otherwise the vector must have the LCP's length.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import json_text

FORMAT = "lcpcli-contact-impulses"
#: Largest impulses file read (bytes); a contact-matrix --json output holds M as well.
MAX_BYTES = 2 * 2**30


def read_named(path: str | Path) -> tuple[np.ndarray, list[str] | None]:
    """Values and, when the file gives them, the names of the unknowns (ProblemError if bad)."""
    from lcpcli.io.warmstart import load_z0

    p = Path(path)
    src = f"--z0 {p}"
    if not p.is_file():
        raise ProblemError("no such file", src)
    if p.stat().st_size > MAX_BYTES:
        raise ProblemError(f"file larger than {MAX_BYTES // 2**30} GiB", src)
    suffix = p.suffix.lower()
    if suffix == ".npz":
        try:
            with np.load(p, allow_pickle=False) as data:
                if "z" in data.files and "unknowns" in data.files:
                    names = [str(x) for x in data["unknowns"]]
                    return _vector(data["z"], src), _names(names, len(data["z"]), src)
        except (ValueError, OSError) as exc:
            raise ProblemError(f"cannot read a vector ({str(exc).splitlines()[0][:100]})",
                               src) from None
        return load_z0(p), None
    if suffix == ".json":
        try:
            obj = json.loads(p.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ProblemError(f"not valid JSON ({type(exc).__name__})", src) from None
        if isinstance(obj, dict) and "unknowns" in obj and ("impulses" in obj or "z" in obj):
            values = obj["impulses"] if "impulses" in obj else obj["z"]
            if not isinstance(values, list) or any(
                    isinstance(x, bool) or not isinstance(x, (int, float)) for x in values):
                raise ProblemError("'impulses' / 'z' must be a list of numbers", src)
            return _vector(values, src), _names(obj["unknowns"], len(values), src)
    return load_z0(p), None


def _vector(values: Any, src: str) -> np.ndarray:
    z = np.asarray(values, dtype=np.float64).ravel()
    if not np.all(np.isfinite(z)):
        raise ProblemError("contains NaN or Inf", src)
    return z


def _names(names: Any, n: int, src: str) -> list[str]:
    if not isinstance(names, list) or len(names) != n or \
            not all(isinstance(x, str) for x in names):
        raise ProblemError(f"'unknowns' must be a list of {n} names", src)
    return names


def warm_start(path: str | Path, unknowns: list[str]) -> tuple[np.ndarray, str]:
    """``z0`` for an LCP with these unknowns, and a one-line note on how it was matched."""
    values, names = read_named(path)
    if names is None:
        if values.shape[0] != len(unknowns):
            raise ProblemError(f"has {values.shape[0]} values but the contact LCP has "
                               f"{len(unknowns)} unknowns (a file that names its unknowns, "
                               f"e.g. written by --impulses, is matched by name)",
                               f"--z0 {path}")
        return values, f"warm start: {values.shape[0]} values by position"
    given = dict(zip(names, values.tolist(), strict=True))
    z0 = np.array([given.get(nm, 0.0) for nm in unknowns])
    hits = sum(nm in given for nm in unknowns)
    return z0, (f"warm start: {hits} of {len(unknowns)} unknowns matched by name "
                f"({len(names) - hits} in the file unused)")


def check_impulses_path(path: str | Path) -> None:
    """ProblemError unless ``path`` can take an impulses file (extension, folder)."""
    p = Path(path)
    if p.suffix.lower() not in (".json", ".npz"):
        raise ProblemError("impulses file must end in .json or .npz", f"--impulses {p}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ProblemError(f"folder {folder} does not exist", f"--impulses {p}")


def write_impulses(path: str | Path, unknowns: list[str], z: np.ndarray, scene: str = "",
                   status: str = "") -> None:
    """Write an impulses file (``.json`` or ``.npz``, see the module docstring) atomically."""
    from lcpcli.io import atomic_path

    p = Path(path)
    check_impulses_path(p)
    suffix = p.suffix.lower()
    with atomic_path(p) as tmp:
        if suffix == ".json":
            tmp.write_text(json_text({"format": FORMAT, "version": 1, "scene": scene,
                                      "status": status, "unknowns": list(unknowns),
                                      "z": [float(x) for x in z]}) + "\n")
        else:
            with open(tmp, "wb") as fh:
                np.savez(fh, z=np.asarray(z, dtype=np.float64),
                         unknowns=np.array(list(unknowns), dtype=str))
