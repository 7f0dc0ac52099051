"""Benchmark: start-up of one-liners against the python + numpy floor.

Commands (each run ``--runs`` times, round-robin so that a change in the machine's load hits
all of them alike; the median wall time is reported):

* ``python -c "import numpy"``                       the floor
* ``lcpcli solve samples/seed004.json``              rich table on stdout
* ``echo '{...}' | lcpcli solve - --json``          the stdin one-liner
* ``lcpcli --help``
* ``python -c pass``                                 the interpreter alone

``lcpcli`` is run as ``python -m lcpcli`` with this checkout first on PYTHONPATH (what the
tests run; the installed console script adds nothing measurable).  ``--first-run`` also times
the first run after removing lcpcli's ``__pycache__`` folders (bytecode not yet written, as
right after an install that did not precompile) against the second.

    python benchmarks/bench_startup.py [--runs 7] [--first-run]

Writes ``benchmarks/results/startup.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STDIN = '{"M": [[2,1],[1,2]], "q": [-5,-6]}'

COMMANDS = {
    "python -c 'import numpy'": ([sys.executable, "-c", "import numpy"], None),
    "lcpcli solve samples/seed004.json": (
        [sys.executable, "-m", "lcpcli", "solve", "samples/seed004.json"], None),
    "echo ... | lcpcli solve - --json": (
        [sys.executable, "-m", "lcpcli", "solve", "-", "--json"], STDIN),
    "lcpcli --help": ([sys.executable, "-m", "lcpcli", "--help"], None),
    "python -c pass": ([sys.executable, "-c", "pass"], None),
}


def env() -> dict[str, str]:
    e = dict(os.environ)
    e["PYTHONPATH"] = str(ROOT) + os.pathsep + e.get("PYTHONPATH", "")
    e.pop("PYTHONPROFILEIMPORTTIME", None)
    return e


def run_once(argv: list[str], stdin: str | None) -> float:
    t0 = time.perf_counter()
    p = subprocess.run(argv, input=stdin, capture_output=True, text=True, cwd=ROOT, env=env())
    t = time.perf_counter() - t0
    if p.returncode not in (0, 1):
        raise RuntimeError(f"{argv}: exit {p.returncode}: {p.stderr[-500:]}")
    return t


def clear_bytecode() -> None:
    for d in (ROOT / "lcpcli").rglob("__pycache__"):
        shutil.rmtree(d, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--first-run", action="store_true")
    ap.add_argument("--output", type=Path, default=ROOT / "benchmarks" / "results" /
                    "startup.json")
    args = ap.parse_args(argv)
    first = {}
    if args.first_run:
        cmd, stdin = COMMANDS["lcpcli solve samples/seed004.json"]
        for _ in range(3):
            clear_bytecode()
            t1 = run_once(cmd, stdin)
            t2 = run_once(cmd, stdin)
            first.setdefault("first", []).append(t1)
            first.setdefault("second", []).append(t2)
    for cmd, stdin in COMMANDS.values():  # warm the OS caches
        run_once(cmd, stdin)
    times: dict[str, list[float]] = {k: [] for k in COMMANDS}
    for _ in range(args.runs):
        for k, (cmd, stdin) in COMMANDS.items():
            times[k].append(run_once(cmd, stdin))
    med = {k: statistics.median(v) for k, v in times.items()}
    floor = med["python -c 'import numpy'"]
    print(f"median of {args.runs} runs (round-robin); load {os.getloadavg()[0]:.1f}")
    for k, t in med.items():
        print(f"{k:40s} {t * 1e3:8.1f} ms  {t / floor:5.2f}x numpy floor")
    if first:
        f, s = statistics.median(first["first"]), statistics.median(first["second"])
        print(f"first run without bytecode {f * 1e3:.1f} ms, second {s * 1e3:.1f} ms "
              f"(medians of 3)")
    payload = {"benchmark": "startup", "runs": args.runs, "median_s": med,
               "ratio_to_numpy": {k: t / floor for k, t in med.items()},
               "first_run_s": first, "load": os.getloadavg()[0],
               "when": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(payload, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
