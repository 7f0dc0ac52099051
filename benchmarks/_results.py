"""What the benchmarks write: their rows with the machine facts of the run, as one JSON file."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np


def write_results(out: str | Path, rows: list[Any]) -> dict[str, Any]:
    """Write ``{"meta": ..., "rows": rows}`` to ``out`` (the date, Python and numpy versions,
    the load average and the CPU count beside the rows: figures from a shared machine are read
    with its load) and print where; returns the meta."""
    meta = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "python": platform.python_version(), "numpy": np.__version__,
            "load": os.getloadavg(), "nproc": os.cpu_count()}
    Path(out).write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")
    print(f"written {out}; load average {meta['load']}")
    return meta


def write_cases(out: Path | None, name: str, info: dict[str, Any], cases: list[Any]) -> None:
    """Write ``{"info": info, "cases": cases}`` (the device benchmarks' layout) to ``out``, else
    to ``$OUT/name`` when ``$OUT`` is set (a device run's result folder), else nowhere."""
    path = out or (Path(os.environ["OUT"]) / name if os.environ.get("OUT") else None)
    if path is not None:
        Path(path).write_text(json.dumps({"info": info, "cases": cases}, indent=1) + "\n")
        print(f"wrote {path}")
