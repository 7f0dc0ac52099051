"""Impulse files: warm starts for ``contact-matrix --z0`` and what ``--impulses`` writes.

An impulses file written by ``contact-matrix --solve --impulses FILE`` holds the solution ``z``
and the names of its unknowns (``n[c]``, ``t<k>[c]``, ``lambda[c]``):

* ``.json``: ``{"format": "lcpcli-contact-impulses", "version": 1, "scene", "status",
  "unknowns": [...], "z": [...]}`` (``lcpcli solve --z0`` reads it too: it has ``"z"``);
* ``.npz``: arrays ``z`` and ``unknowns``.

``--z0 FILE`` accepts that file, the ``contact-matrix --json`` output (``impulses`` and
``unknowns``), and whatever else :func:`lcpcli.io.warmstart.read_warm_start` reads
(``lcpcli solve --json`` output, a JSON list, ``.npy``, ``.npz``), under the reading rules of
every input (docs/files.md: at most 256 MiB of JSON, like any JSON file).  When the file names
its unknowns, values are matched **by name** (a contact that is new gets 0, one that is gone is
dropped: the scene of the next step may differ); otherwise the vector must have the LCP's
length.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import json_text
from lcpcli.io import atomic_path

FORMAT = "lcpcli-contact-impulses"


def read_named(path: str | Path, n: int | None = None) -> tuple[np.ndarray, list[str] | None]:
    """Values and, when the file gives them, the names of the unknowns (ProblemError if bad).

    One reader for every warm start (:func:`lcpcli.io.warmstart.read_warm_start`): the same
    reading rules as problem files (docs/files.md, "Reading"); ``n``, the LCP's unknowns,
    bounds the values declared (matched by name: a few more) before any is decompressed.
    """
    from lcpcli.io.warmstart import read_warm_start

    return read_warm_start(path, n=n, by_name=True)


def warm_start(path: str | Path, unknowns: list[str]) -> tuple[np.ndarray, str]:
    """``z0`` for an LCP with these unknowns, and a one-line note on how it was matched."""
    values, names = read_named(path, len(unknowns))
    if names is None:
        if values.shape[0] != len(unknowns):
            raise ProblemError(f"has {values.shape[0]} values but the contact LCP has "
                               f"{len(unknowns)} unknowns (a file that names its unknowns, "
                               f"e.g. written by --impulses, is matched by name)",
                               f"--z0 {path}")
        return values, f"warm start: {values.shape[0]} values by position"
    z0, hits = match_by_name(values, names, unknowns)
    return z0, (f"warm start: {hits} of {len(unknowns)} unknowns matched by name "
                f"({len(names) - hits} in the file unused)")


def match_by_name(values: np.ndarray, names: list[str],
                  unknowns: list[str]) -> tuple[np.ndarray, int]:
    """``z0`` for an LCP with ``unknowns`` from ``values`` named ``names`` (an unknown that is
    new gets 0, a name that is gone is dropped), and how many matched."""
    given = dict(zip(names, np.asarray(values).tolist(), strict=True))
    z0 = np.array([given.get(nm, 0.0) for nm in unknowns])
    return z0, sum(nm in given for nm in unknowns)


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
