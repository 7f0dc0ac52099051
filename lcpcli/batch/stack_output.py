"""Result files of stacked batches: stacked datasets (``.h5``, ``.npz``) or rows (``.jsonl``,
``.csv``), written chunk by chunk and resumable.

**HDF5** (``results.h5``): the root attribute ``lcpcli_stacked_results`` (1) marks the layout;
one group per input stack (named after the file's stem, ``stem~2`` on a clash), with
attributes ``source`` (the input as given), ``n``, ``K``, ``method``, ``tol`` and
``status_codes`` (JSON: status -> code), and datasets, indexed by the 0-based problem index:
``z``, ``w`` (K, n) float64, ``status`` (K,) int8 (:data:`lcpcli.core.result.STATUS_CODES`;
-1: not solved yet), ``iterations`` (K,) int64, ``error`` and ``residual`` (K,) float64 (NaN
where none), and ``names`` (K,) when the input has names.  Each chunk is written (``status``
last) and flushed before the next is read, and Ctrl-C / SIGTERM close the file cleanly, so
``--resume`` finds every finished chunk.  The datasets are allocated in full when the file is
created (``ALLOC_TIME_EARLY``), so writing a chunk changes data only, never HDF5's metadata: a
``kill -9`` leaves a readable file whose ``status`` says which problems finished (a chunk cut
in the middle has ``status`` -1 and is solved again).  A file that is still unreadable is
refused by ``--resume`` with a message (run again without it).

**NPZ** (``results.npz``, one input stack): the same arrays at the top level plus ``source``;
held in memory and written atomically when the batch ends (also on Ctrl-C / SIGTERM), so the
file on disk is always complete; ``--resume`` starts from it.

**Rows** (``.jsonl``/``.csv``): one row per problem, see :mod:`lcpcli.batch.stacked`; the
row's ``index`` is the position in the stack, which ``--resume`` uses.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.result import NOT_DONE, STATUS_CODES, status_counts

#: Root attribute marking an HDF5 file as stacked results.
MARK = "lcpcli_stacked_results"
_ARRAYS = ("z", "w", "status", "iterations", "error", "residual")


def _empty_arrays(K: int, n: int) -> dict[str, np.ndarray]:
    return {"z": np.full((K, n), np.nan), "w": np.full((K, n), np.nan),
            "status": np.full(K, NOT_DONE, np.int8), "iterations": np.zeros(K, np.int64),
            "error": np.full(K, np.nan), "residual": np.full(K, np.nan)}


def _chunk_arrays(res: Any) -> dict[str, np.ndarray]:
    return {"z": res.z, "w": res.w, "status": res.status, "iterations": res.iterations,
            "error": np.where(np.isfinite(res.error), res.error, np.nan),
            "residual": res.residual}


class Hdf5StackWriter:
    """Stacked results in an HDF5 file (see the module docstring)."""

    wants_rows = False

    def __init__(self, path: Path, infos: list[Any], resume: bool) -> None:
        import h5py

        from lcpcli.io import atomic_path

        self.path = path
        if resume and path.exists():
            try:
                self.file = h5py.File(path, "a")
            except OSError as exc:
                raise ProblemError(f"cannot be resumed: not a readable HDF5 file "
                                   f"({str(exc).splitlines()[0][:80]}; interrupted by kill -9?); "
                                   f"run again without --resume", str(path)) from None
            if self.file.attrs.get(MARK) != 1:
                self.file.close()
                raise ProblemError("is not a stacked result file of lcpcli; run without "
                                   "--resume to replace it", str(path))
        else:
            with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
                f.attrs[MARK] = 1
            self.file = h5py.File(path, "a")
        self.groups: dict[str, Any] = {}
        taken = set(self.file.keys())
        existing = {str(self.file[g].attrs.get("source", "")): self.file[g] for g in taken}
        for info in infos:
            g = existing.get(info.path)
            if g is not None:
                if (int(g.attrs["K"]), int(g.attrs["n"])) != (info.K, info.n):
                    raise ProblemError(f"holds results of {info.path} for K = "
                                       f"{int(g.attrs['K'])}, n = {int(g.attrs['n'])}, but the "
                                       f"input now has K = {info.K}, n = {info.n}; run without "
                                       f"--resume", str(path))
            else:
                g = self._create(info, taken)
            self.groups[info.path] = g

    def _create(self, info: Any, taken: set[str]) -> Any:
        import h5py

        base = Path(info.path).stem.replace("/", "_") or "stack"
        name, k = base, 1
        while name in taken:
            k += 1
            name = f"{base}~{k}"
        taken.add(name)
        g = self.file.create_group(name)
        K, n = info.K, info.n
        rows = max(1, min(K, (1 << 20) // max(8 * n, 8)))  # ~1 MiB chunks of z and w
        for key, value in _empty_arrays(0, n).items():
            shape = (K, n) if value.ndim == 2 else (K,)
            chunks = (rows, n) if value.ndim == 2 and n else (min(K, 1 << 16),)
            fill = NOT_DONE if key == "status" else (0 if key == "iterations" else np.nan)
            # every chunk allocated (and filled) now: later writes change data, never the
            # file's metadata, so a kill -9 between or during them leaves a readable file
            dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
            dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
            g.create_dataset(key, shape=shape, dtype=value.dtype, fillvalue=fill,
                             chunks=chunks if K and (value.ndim == 1 or n) else None, dcpl=dcpl)
        if info.has_names:
            g.create_dataset("names", shape=(K,), dtype=h5py.string_dtype())
        g.attrs.update({"source": info.path, "n": n, "K": K, "method": "", "tol": np.nan,
                        "status_codes": json.dumps({str(s): c for s, c in
                                                    STATUS_CODES.items()})})
        return g

    def done(self, info: Any) -> np.ndarray:
        return self.groups[info.path]["status"][...] != NOT_DONE

    def tally_done(self, info: Any, tally: Any) -> None:
        tally.add_counts(status_counts(self.groups[info.path]["status"][...]))

    def write(self, info: Any, positions: np.ndarray, names: list[str] | None, res: Any,
              rows: Any) -> None:
        g = self.groups[info.path]
        first, last = int(positions[0]), int(positions[-1])
        where: Any = slice(first, last + 1) if last - first + 1 == positions.size else positions
        arrays = _chunk_arrays(res)
        for key in ("z", "w", "iterations", "error", "residual", "status"):  # status last
            if key == "status" and names is not None and "names" in g:
                g["names"][where] = names
            g[key][where] = arrays[key]
        g.attrs["method"] = res.method
        g.attrs["tol"] = res.tol
        self.file.flush()

    def close(self) -> None:
        if self.file.id.valid:
            self.file.flush()
            self.file.close()


class NpzStackWriter:
    """Stacked results of one input in an NPZ file, written atomically at the end."""

    wants_rows = False

    def __init__(self, path: Path, infos: list[Any], resume: bool) -> None:
        if len(infos) != 1:
            raise OptionError(f"--output {path}: an .npz result file holds one stack; give one "
                              f"stacked input, or write .h5 (one group per stack)")
        info = self.info = infos[0]
        self.path = path
        self.arrays = _empty_arrays(info.K, info.n)
        self.names: list[str] | None = [""] * info.K if info.has_names else None
        self.method, self.tol = "", float("nan")
        if resume and path.exists():
            self._load(path, info)

    def _load(self, path: Path, info: Any) -> None:
        try:
            with np.load(path, allow_pickle=False) as data:
                if str(data["source"]) != info.path:
                    raise ProblemError(f"holds results of {data['source']}, not {info.path}; "
                                       f"run without --resume", str(path))
                for key, value in self.arrays.items():
                    got = data[key]
                    if got.shape != value.shape:
                        raise ProblemError(f"its {key} has shape {got.shape}, the input needs "
                                           f"{value.shape}; run without --resume", str(path))
                    value[...] = got
                if self.names is not None and "names" in data:
                    self.names = [str(x) for x in data["names"].tolist()]
        except (OSError, KeyError, ValueError) as exc:
            raise ProblemError(f"cannot be resumed ({str(exc).splitlines()[0][:80]}); run "
                               f"without --resume", str(path)) from None

    def done(self, info: Any) -> np.ndarray:
        return self.arrays["status"] != NOT_DONE

    def tally_done(self, info: Any, tally: Any) -> None:
        tally.add_counts(status_counts(self.arrays["status"]))

    def write(self, info: Any, positions: np.ndarray, names: list[str] | None, res: Any,
              rows: Any) -> None:
        for key, value in _chunk_arrays(res).items():
            self.arrays[key][positions] = value
        if names is not None and self.names is not None:
            for k, name in zip(positions.tolist(), names, strict=True):
                self.names[k] = name
        self.method, self.tol = res.method, res.tol

    def close(self) -> None:
        from lcpcli.io import atomic_path

        extra: dict[str, Any] = {"source": np.asarray(self.info.path),
                                 "method": np.asarray(self.method),
                                 "tol": np.asarray(self.tol)}
        if self.names is not None:
            extra["names"] = np.asarray(self.names, dtype=str)
        with atomic_path(self.path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **self.arrays, **extra)


class RowStackWriter:
    """Rows of stacked problems in a JSONL or CSV result file (the batch row writers)."""

    wants_rows = True

    def __init__(self, path: Path, infos: list[Any], resume: bool) -> None:
        from lcpcli.batch import output

        self.finished: dict[str, list[dict[str, Any]]] = {}
        if resume and path.exists():
            for row in output.read_rows(path):
                self.finished.setdefault(str(row.get("source", "")), []).append(row)
        self.writer = output.open_writer(path, resume=resume)

    def done(self, info: Any) -> np.ndarray:
        mask = np.zeros(info.K, bool)
        for row in self.finished.get(info.path, []):
            k = row.get("index")
            if isinstance(k, int) and 0 <= k < info.K:
                mask[k] = True
        return mask

    def tally_done(self, info: Any, tally: Any) -> None:
        seen: set[int] = set()
        for row in self.finished.get(info.path, []):
            k = row.get("index")
            if isinstance(k, int) and 0 <= k < info.K and k not in seen:
                seen.add(k)
                tally.add(row)

    def write(self, info: Any, positions: np.ndarray, names: list[str] | None, res: Any,
              rows: list[dict[str, Any]]) -> None:
        self.writer.write(rows)

    def close(self) -> None:
        self.writer.close()


def open_stack_writer(path: str | Any, infos: list[Any], *, resume: bool) -> Any:
    """The writer for a stacked batch's ``--output`` (kind by extension)."""
    from lcpcli.batch.output import checked_output

    path, kind = checked_output(path)
    if kind == "hdf5":
        return Hdf5StackWriter(path, infos, resume)
    if kind == "npz":
        return NpzStackWriter(path, infos, resume)
    return RowStackWriter(path, infos, resume)
