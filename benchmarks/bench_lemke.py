"""Benchmark: tableau Lemke vs revised Lemke vs Siconos' Lemke.

Problems: ``M = A A^T + n I`` (A standard normal), ``q`` standard normal, fixed seed; all three
solve the same problem.  Times are medians over repeats after one untimed warm-up: ours are
``Result.seconds`` from :func:`lcpcli.solve` (the method alone, no I/O; wall time), plus the
CPU time of the method (``time.process_time``, steadier on a shared machine, used to pick the
faster of tableau/revised); Siconos' come from
``/usr/bin/python3 ../shared/peers/siconos_peer.py PROBLEM.npz --solver Lemke --repeat K``
(its ``seconds_median``, driver call only).  Errors are the project's certificate
(:func:`lcpcli.core.certificate.certify`) applied to every answer, Siconos' included.

    python benchmarks/bench_lemke.py            # n = 10, 50, 100, 500, 1000
    python benchmarks/bench_lemke.py --quick    # n = 10, 50, 100, 300, few repeats

Writes ``benchmarks/results/lemke.json``.
"""

from __future__ import annotations

import os

# One BLAS thread (ours and the peer's), as the other benchmarks: on a shared machine a
# multi-threaded OpenBLAS makes mid-size LU solves up to 100x slower; BENCH_THREADS=k overrides.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = os.environ.get("BENCH_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lcpcli.api import solve  # noqa: E402
from lcpcli.core.certificate import certify  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402
from lcpcli.solvers.registry import get_method  # noqa: E402

#: The shared Siconos runner, beside the checkout (``../shared``; ``LCPCLI_SHARED`` overrides).
PEER = Path(os.environ.get("LCPCLI_SHARED", ROOT.parent / "shared")) / "peers" / "siconos_peer.py"
METHODS = ("lemke-tableau", "lemke-revised")


def repeats_for(n: int, quick: bool) -> int:
    if quick:
        return 5 if n <= 100 else 2
    return 30 if n <= 100 else (7 if n <= 500 else 5)


def make_problem(n: int, seed: int) -> Problem:
    rng = np.random.default_rng(seed + n)
    A = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + n * np.eye(n), rng.standard_normal(n), name=f"rand{n}")


def time_ours(prob: Problem, method: str, k: int) -> dict:
    """Wall time (``Result.seconds``) and CPU time (process_time around the method's run)."""
    spec = get_method(method)
    res = solve(prob, method)  # warm-up (JIT load, caches)
    secs, cpu = [], []
    for _ in range(k):
        res = solve(prob, method)
        secs.append(res.seconds)
        t0 = time.process_time()
        spec.run(prob, tol=1e-8)
        cpu.append(time.process_time() - t0)
    return {"seconds_median": statistics.median(secs), "cpu_seconds_median":
            statistics.median(cpu), "error": res.error, "status": res.status,
            "pivots": res.iterations}


def time_siconos(prob: Problem, k: int, tmp: Path) -> dict:
    path = tmp / f"{prob.name}.npz"
    np.savez(path, M=prob.dense_M(), q=prob.q)
    try:
        out = subprocess.run(["/usr/bin/python3", str(PEER), str(path), "--solver", "Lemke",
                              "--repeat", str(k)], capture_output=True, text=True, timeout=900)
        line = out.stdout.strip().splitlines()[-1]
        d = json.loads(line)
    except (subprocess.SubprocessError, IndexError, json.JSONDecodeError, OSError) as exc:
        return {"seconds_median": None, "error": None, "status": f"peer failed: {exc}"}
    z = np.asarray(d.get("z") or [], dtype=float)
    err = certify(prob, z).error if z.shape == (prob.n,) else None
    ok = d.get("info") == 0 and z.shape == (prob.n,) and bool(np.all(np.isfinite(z)))
    return {"seconds_median": d.get("seconds_median"), "error": err,
            "error_siconos": d.get("error_siconos"), "status": "success" if ok else "failure",
            "pivots": d.get("iterations")}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, few repeats")
    ap.add_argument("--sizes", type=str, default=None, help="comma-separated n values")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--no-siconos", action="store_true", help="skip the Siconos peer")
    ap.add_argument("--output", type=Path, default=ROOT / "benchmarks" / "results" / "lemke.json")
    args = ap.parse_args(argv)
    sizes = ([int(s) for s in args.sizes.split(",")] if args.sizes else
             [10, 50, 100, 300] if args.quick else [10, 50, 100, 500, 1000])
    rows = []
    with tempfile.TemporaryDirectory() as td:
        for n in sizes:
            prob = make_problem(n, args.seed)
            k = repeats_for(n, args.quick)
            row: dict = {"n": n, "repeats": k}
            for m in METHODS:
                row[m] = time_ours(prob, m, k)
            if not args.no_siconos and PEER.exists():
                row["siconos-lemke"] = time_siconos(prob, k, Path(td))
            rows.append(row)
            print_row(row)
    faster = pick_faster(rows)
    payload = {"benchmark": "lemke", "problem": "M = A A^T + n I, q ~ N(0, 1)",
               "seed": args.seed, "rows": rows, "faster_overall": faster}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(payload, indent=2) + "\n")
    print(f"\nfaster of tableau/revised (sum of CPU-time medians over sizes): {faster}")
    print(f"wrote {args.output}")
    return 0


_HEADER = False


def print_row(row: dict) -> None:
    global _HEADER
    cols = [*METHODS, "siconos-lemke"]
    if not _HEADER:
        print(f"{'n':>6} {'pivots':>7} " + " ".join(f"{c + ' ms':>20}" for c in cols)
              + f" {'tab/sic':>8} {'rev/sic':>8} " + " ".join(f"{c + ' err':>20}" for c in cols))
        _HEADER = True
    sic = row.get("siconos-lemke", {}).get("seconds_median")

    def ms(c: str) -> str:
        s = row.get(c, {}).get("seconds_median")
        return f"{s * 1e3:20.4f}" if s else f"{'-':>20}"

    def ratio(c: str) -> str:
        s = row[c]["seconds_median"]
        return f"{s / sic:8.3f}" if sic else f"{'-':>8}"

    def err(c: str) -> str:
        e = row.get(c, {}).get("error")
        return f"{e:20.2e}" if e is not None else f"{'-':>20}"

    cpu = "  cpu ms: " + ", ".join(f"{m} {row[m]['cpu_seconds_median'] * 1e3:.4f}"
                                   for m in METHODS)
    print(f"{row['n']:>6} {row['lemke-tableau']['pivots']:>7} " + " ".join(ms(c) for c in cols)
          + f" {ratio('lemke-tableau')} {ratio('lemke-revised')} "
          + " ".join(err(c) for c in cols) + cpu, flush=True)


def pick_faster(rows: list[dict]) -> str:
    """The method with the smaller total CPU time over the sizes (wall time on a shared
    machine is dominated by other processes; CPU time is the steadier measure)."""
    tot = {m: sum(r[m]["cpu_seconds_median"] for r in rows) for m in METHODS}
    return min(tot, key=tot.get)


if __name__ == "__main__":
    sys.exit(main())
