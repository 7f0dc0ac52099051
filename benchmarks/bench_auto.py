"""Benchmark: what ``auto`` costs on top of the method it ends up using.

    python benchmarks/bench_auto.py            # n = 50, 200, 1000 on random PD, PSD and P
    python benchmarks/bench_auto.py --quick    # n = 50, 200
    python benchmarks/bench_auto.py --n 50 200 1000 2000 --budget 5

For each family (random PD ``A A^T / n + I/2``, PSD of rank n/2 with a solvable q, and a
non-symmetric P-matrix with an indefinite symmetric part: the generators of
``bench_methods.py``) and size, ``auto`` and the method it chose are solved alternately
(interleaved, so that load on a shared machine hits both alike) until ``--budget`` seconds or
``--max-repeat`` pairs, after one untimed warm-up each.  Times are ``Result.seconds`` (the
method's own time as ``lcpcli.solve`` measures it: no file reading, kernels compiled before,
the final certification excluded), the median over the pairs.  Ratios:

* ``auto / chosen``: auto's seconds (its classification and planning, the chosen method, and
  its certification of that attempt) over the chosen method's seconds;
* ``auto - cert / chosen``: the same without ``info["certify_seconds"]`` (no longer reported:
  the dispatcher certifies every method run, auto's attempts and the chosen method alike,
  inside ``seconds``; the ratio then equals ``auto / chosen``);
* ``wall``: the wall time of the whole ``lcpcli.solve`` call (the final certification by
  ``lcpcli.api`` included: it certifies auto's answer again).

Writes ``benchmarks/results/auto.json``.  Run it against another checkout with
``PYTHONPATH=/path/to/checkout python benchmarks/bench_auto.py --out ...`` to compare.
"""

from __future__ import annotations

import os

# One BLAS thread, as in bench_methods.py (set before numpy is imported).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = os.environ.get("BENCH_THREADS", "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
if not os.environ.get("PYTHONPATH"):
    sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import lcpcli  # noqa: E402
from lcpcli.api import solve  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402

# after lcpcli: bench_methods puts its own checkout on sys.path (PYTHONPATH must win here)
_gens = importlib.import_module("bench_methods")
FAMILIES = {"pd": _gens.gen_pd, "psd": _gens.gen_psd, "p": _gens.gen_p}


def measure(p: Problem, budget: float, max_repeat: int) -> dict:
    """Interleaved timings of auto and of the method it chose on ``p``."""
    first = solve(p)  # warm-up (prepares the kernels)
    chosen = first.info.get("chosen")
    if not first.solved or chosen is None:
        return {"status": str(first.status), "chosen": chosen, "message": first.message}
    solve(p, chosen)
    auto_s, auto_nocert, chosen_s, attempts = [], [], [], set()
    wall_a, wall_c = [], []
    start = time.perf_counter()
    while len(auto_s) < max_repeat and (len(auto_s) < 5 or time.perf_counter() - start < budget):
        t0 = time.perf_counter()
        ra = solve(p)
        t1 = time.perf_counter()
        rc = solve(p, chosen)
        t2 = time.perf_counter()
        assert ra.solved and rc.solved and ra.info.get("chosen") == chosen
        auto_s.append(ra.seconds)
        auto_nocert.append(ra.seconds - ra.info.get("certify_seconds", 0.0))
        chosen_s.append(rc.seconds)
        wall_a.append(t1 - t0)
        wall_c.append(t2 - t1)
        attempts.add(len(ra.info["attempts"]))
    ta, tn, tc, wa, wc = (statistics.median(v)
                          for v in (auto_s, auto_nocert, chosen_s, wall_a, wall_c))
    return {"status": "solved", "chosen": chosen, "attempts": sorted(attempts),
            "repeats": len(auto_s), "auto_seconds": ta, "auto_nocert_seconds": tn,
            "chosen_seconds": tc, "ratio": ta / tc, "ratio_nocert": tn / tc,
            "wall_auto_seconds": wa, "wall_chosen_seconds": wc, "ratio_wall": wa / wc,
            "message": first.message}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 50, 200 only")
    ap.add_argument("--n", type=int, nargs="+", default=None, help="sizes (default 50 200 1000)")
    ap.add_argument("--budget", type=float, default=3.0,
                    help="seconds of timed pairs per problem (at least 5 pairs)")
    ap.add_argument("--max-repeat", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "auto.json")
    args = ap.parse_args(argv)
    sizes = args.n or ([50, 200] if args.quick else [50, 200, 1000])
    rows = []
    print(f"{'family':7} {'n':>5} {'chosen':14} {'auto ms':>9} {'chosen ms':>10} "
          f"{'auto/chosen':>11} {'auto-cert/chosen':>16} {'wall':>6} {'pairs':>5}")
    for fam, gen in FAMILIES.items():
        for n in sizes:
            rng = np.random.default_rng(args.seed + n)
            M, q = gen(n, rng)
            rec = {"family": fam, "n": n, **measure(Problem.create(M, q), args.budget,
                                                     args.max_repeat)}
            rows.append(rec)
            if rec["status"] != "solved":
                print(f"{fam:7} {n:5} not solved: {rec['message'][:80]}")
                continue
            print(f"{fam:7} {n:5} {rec['chosen']:14} {rec['auto_seconds'] * 1e3:9.3f} "
                  f"{rec['chosen_seconds'] * 1e3:10.3f} {rec['ratio']:11.2f} "
                  f"{rec['ratio_nocert']:16.2f} {rec['ratio_wall']:6.2f} {rec['repeats']:5}",
                  flush=True)
    meta = {"python": platform.python_version(), "machine": platform.machine(),
            "cpus": os.cpu_count(), "lcpcli": str(Path(lcpcli.__file__).parent),
            "blas_threads": os.environ["OPENBLAS_NUM_THREADS"],
            "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
