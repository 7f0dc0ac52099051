"""Impulse files: warm starts for ``contact-matrix --z0`` and what ``--impulses`` writes.

An impulses file written by ``contact-matrix --solve --impulses FILE`` holds the solution ``z``
and the names of its unknowns (``n[c]``, ``t<k>[c]``, ``lambda[c]``):

* ``.json``: ``{"format": "lcpcli-contact-impulses", "version": 1, "scene", "status",
  "unknowns": [...], "z": [...], "basic": [...]}`` (``lcpcli solve --z0`` reads it too: it
  has ``"z"``);
* ``.npz``: arrays ``z``, ``unknowns`` and ``basic``.

``basic`` (booleans, one per unknown; absent from files of earlier versions): z_i basic in the
basis the solve's pivoting ended on (:attr:`lcpcli.contact.Impact.basic`).  ``--z0`` starts
the next step's pivoting from it, matched by name like the impulses (a new contact's unknowns
start nonbasic); a file without it starts from the impulses' support ``{z0_i > 0}``.

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
from lcpcli.io.warmstart import read_warm_basis

FORMAT = "lcpcli-contact-impulses"


def warm_start(path: str | Path,
               unknowns: list[str]) -> tuple[np.ndarray, np.ndarray | None, str]:
    """``z0`` for an LCP with these unknowns, its basis when the file gives one (booleans,
    matched by name; else None), and a one-line note on how it was matched."""
    values, names, basic = read_warm_basis(path, n=len(unknowns), by_name=True)
    if names is None:
        if values.shape[0] != len(unknowns):
            raise ProblemError(f"has {values.shape[0]} values but the contact LCP has "
                               f"{len(unknowns)} unknowns (a file that names its unknowns, "
                               f"e.g. written by --impulses, is matched by name)",
                               f"--z0 {path}")
        return values, None, f"warm start: {values.shape[0]} values by position"
    z0, hits = match_by_name(values, names, unknowns)
    basis0 = None if basic is None else match_by_name(basic.astype(np.float64), names,
                                                       unknowns)[0] > 0.5
    with_basis = " with its basis" if basis0 is not None else ""
    return z0, basis0, (f"warm start{with_basis}: {hits} of {len(unknowns)} unknowns matched "
                        f"by name ({len(names) - hits} in the file unused)")


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
                   status: str = "", basic: np.ndarray | None = None) -> None:
    """Write an impulses file (``.json`` or ``.npz``, see the module docstring) atomically;
    ``basic``: the basis the solve ended on (:attr:`lcpcli.contact.Impact.basic`), if any."""

    p = Path(path)
    check_impulses_path(p)
    suffix = p.suffix.lower()
    with atomic_path(p) as tmp:
        if suffix == ".json":
            record = {"format": FORMAT, "version": 1, "scene": scene, "status": status,
                      "unknowns": list(unknowns), "z": [float(x) for x in z]}
            if basic is not None:
                record["basic"] = [bool(x) for x in basic]
            tmp.write_text(json_text(record) + "\n")
        else:
            arrays = {"z": np.asarray(z, dtype=np.float64),
                      "unknowns": np.array(list(unknowns), dtype=str)}
            if basic is not None:
                arrays["basic"] = np.asarray(basic, dtype=bool)
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
