"""Benchmark of the mixed (MLCP) and box-LCP methods, with Siconos' MLCP solvers as peers.

Usage::

    python benchmarks/bench_mixed.py            # full: all MLCP files, box n = 10..2000
    python benchmarks/bench_mixed.py --quick    # short run: box n = 10..500, two peers
    python benchmarks/bench_mixed.py --no-peers

Part 1: every Siconos MLCP file (``shared/data/siconos/mlcp``, Rectangular excluded) with every
registered method whose kinds include ``mlcp``, and Siconos' MLCP solvers through
``shared/peers/siconos_peer.py`` on the same (M, q, n_eq).  Part 2: random box LCPs (symmetric
PD M, bounds with some infinite sides) with every method whose kinds include ``box``.

Times are the median method-only wall time over ``--repeat`` runs (ours: ``Result.seconds``,
after one untimed warm-up; Siconos: the peer's ``seconds_median``).  ``error`` is the project's
certificate (scaled natural residual) of the returned z, for our methods and for the peers'
z alike; a row is ``ok`` when that error is <= 1e-8.  BLAS runs single-threaded
(OPENBLAS_NUM_THREADS=1 unless set): on a shared machine threaded BLAS made small solves 10-30x
slower.  Results go to ``benchmarks/results/bench_mixed[_quick].json``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
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
from lcpcli.io import load  # noqa: E402
from lcpcli.solvers.registry import methods  # noqa: E402


def shared_dir() -> Path | None:
    for base in (ROOT.parent, ROOT.parent.parent, Path("/work")):
        if (base / "shared").is_dir():
            return base / "shared"
    return None


SHARED = shared_dir()
PEER = SHARED / "peers" / "siconos_peer.py" if SHARED else None
MLCP_DIR = SHARED / "data" / "siconos" / "mlcp" if SHARED else None
PEER_SOLVERS_FULL = ["MLCP_LCP_LEMKE", "MLCP_ENUM", "MLCP_DIRECT_ENUM", "MLCP_FB",
                     "MLCP_DIRECT_FB", "MLCP_PGS", "MLCP_PATH"]
PEER_SOLVERS_QUICK = ["MLCP_LCP_LEMKE", "MLCP_FB"]
TOL = 1e-8


def time_method(problem: Problem, method: str, repeat: int) -> dict:
    try:
        r = solve(problem, method)  # warm-up (JIT cache, imports)
    except Exception as exc:  # noqa: BLE001 - a method may refuse the problem
        return {"method": method, "status": "error", "message": str(exc)[:120]}
    times = [r.seconds]
    for _ in range(repeat - 1):
        r = solve(problem, method)
        times.append(r.seconds)
    return {"method": method, "status": r.status, "seconds": statistics.median(times),
            "error": r.error, "iterations": r.iterations, "ok": bool(r.error <= TOL),
            "message": r.message[:120]}


def run_peer(problem: Problem, solver: str, repeat: int, timeout: float) -> dict:
    if PEER is None or not PEER.exists() or not Path("/usr/bin/python3").exists():
        return {"method": f"siconos:{solver}", "status": "unavailable"}
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "p.npz"
        np.savez(f, M=np.asarray(problem.dense_M()), q=problem.q, n_eq=problem.n_eq)
        cmd = ["/usr/bin/python3", str(PEER), str(f), "--solver", solver, "--n-eq",
               str(problem.n_eq), "--repeat", str(repeat), "--timeout", str(timeout)]
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout + 30,
                               env={k: v for k, v in os.environ.items()
                                    if k != "PYTHONPATH"})
            out = json.loads(p.stdout.strip().splitlines()[-1])
        except (subprocess.TimeoutExpired, json.JSONDecodeError, IndexError):
            return {"method": f"siconos:{solver}", "status": "died/timeout"}
    row = {"method": f"siconos:{solver}", "info": out.get("info"),
           "seconds": out.get("seconds_median"), "peer_error": out.get("error_siconos")}
    z = out.get("z")
    if out.get("info") is None or z is None or any(v is None for v in z):
        row.update(status="failed", ok=False, message=str(out.get("error", ""))[:120])
        return row
    cert = certify(problem, np.asarray(z, dtype=float), TOL)
    row.update(status="success" if out["info"] == 0 else "failed", error=cert.error,
               ok=bool(out["info"] == 0 and cert.passed))
    return row


def bench_mlcp(quick: bool, peers: bool, repeat: int) -> list[dict]:
    rows: list[dict] = []
    if MLCP_DIR is None or not MLCP_DIR.is_dir():
        print("no Siconos MLCP data found; part 1 skipped")
        return rows
    ours = [name for name, m in methods().items() if "mlcp" in m.kinds]
    peer_list = PEER_SOLVERS_QUICK if quick else PEER_SOLVERS_FULL
    for f in sorted(MLCP_DIR.glob("*_mlcp.dat")):
        if f.name == "Rectangular_mlcp.dat":
            continue
        prob = load(f)
        for name in ours:
            rows.append({"problem": f.stem, "n": prob.n, "n_eq": prob.n_eq,
                         **time_method(prob, name, repeat)})
        if peers:
            for solver in peer_list:
                rows.append({"problem": f.stem, "n": prob.n, "n_eq": prob.n_eq,
                             **run_peer(prob, solver, repeat, 20.0 if quick else 60.0)})
    return rows


def random_box(n: int, seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T / n + 0.1 * np.eye(n)
    q = rng.standard_normal(n)
    lo = -rng.uniform(0.0, 1.0, n)
    up = rng.uniform(0.0, 1.0, n)
    k = rng.integers(0, 5, n)
    lo[k == 0] = -np.inf
    up[k == 1] = np.inf
    lo[k == 2], up[k == 2] = -np.inf, np.inf
    return Problem.create(M, q, lower=lo, upper=up, name=f"box_spd_n{n}")


def bench_box(sizes: list[int], repeat: int, budget: float) -> list[dict]:
    rows: list[dict] = []
    ours = [name for name, m in methods().items() if "box" in m.kinds]
    slow: set[str] = set()
    for n in sizes:
        prob = random_box(n, seed=n)
        for name in ours:
            if name in slow:
                rows.append({"problem": prob.name, "n": n, "method": name,
                             "status": "skipped (too slow at a smaller n)"})
                continue
            t0 = time.perf_counter()
            row = time_method(prob, name, repeat if n <= 500 else 1)
            if time.perf_counter() - t0 > budget:
                slow.add(name)
            rows.append({"problem": prob.name, "n": n, **row})
    return rows


def print_table(title: str, rows: list[dict]) -> None:
    print(f"\n{title}")
    print(f"{'problem':24s} {'n':>5s} {'method':24s} {'status':12s} {'time [ms]':>11s} "
          f"{'error':>9s} {'ok':>3s}")
    for r in rows:
        t = r.get("seconds")
        e = r.get("error")
        print(f"{r['problem']:24s} {r['n']:5d} {r['method']:24s} {str(r.get('status')):12s} "
              f"{(f'{t * 1e3:.3f}' if t is not None else '-'):>11s} "
              f"{(f'{e:.1e}' if e is not None else '-'):>9s} "
              f"{('yes' if r.get('ok') else 'no'):>3s}")


def ratios(rows: list[dict]) -> list[dict]:
    """Per problem: our fastest certified method vs Siconos' fastest successful solver."""
    out = []
    for prob in sorted({r["problem"] for r in rows}):
        rs = [r for r in rows if r["problem"] == prob]
        ours = [r for r in rs if not r["method"].startswith("siconos:") and r.get("ok")]
        theirs = [r for r in rs if r["method"].startswith("siconos:") and r.get("ok")]
        lemke = [r for r in theirs if r["method"] == "siconos:MLCP_LCP_LEMKE"]
        if not ours:
            continue
        best = min(ours, key=lambda r: r["seconds"])
        entry = {"problem": prob, "ours": best["method"], "ours_ms": best["seconds"] * 1e3}
        if theirs:
            peer = min(theirs, key=lambda r: r["seconds"])
            entry.update(peer=peer["method"], peer_ms=peer["seconds"] * 1e3,
                         ratio=best["seconds"] / peer["seconds"])
        if lemke:
            entry["ratio_vs_siconos_lemke"] = best["seconds"] / lemke[0]["seconds"]
        out.append(entry)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short run")
    ap.add_argument("--no-peers", action="store_true", help="skip the Siconos peers")
    ap.add_argument("--repeat", type=int, default=None, help="timed runs per case")
    ap.add_argument("--sizes", type=str, default=None, help="box sizes, e.g. 10,100,1000")
    args = ap.parse_args()
    repeat = args.repeat or (3 if args.quick else 7)
    sizes = ([int(s) for s in args.sizes.split(",")] if args.sizes else
             [10, 100, 500] if args.quick else [10, 100, 500, 1000, 2000])
    mlcp_rows = bench_mlcp(args.quick, not args.no_peers, repeat)
    print_table("MLCP files (Siconos test data)", mlcp_rows)
    rat = ratios(mlcp_rows)
    if rat:
        print("\nratio = our fastest certified time / Siconos' fastest successful solver "
              "(same run, same machine)")
        for e in rat:
            extra = (f"  vs {e['peer']} {e['peer_ms']:.3f} ms: ratio {e['ratio']:.2f}"
                     if "ratio" in e else "  (no Siconos solver succeeded)")
            if "ratio_vs_siconos_lemke" in e:
                extra += f"; vs Siconos Lemke-Schur {e['ratio_vs_siconos_lemke']:.2f}"
            print(f"{e['problem']:24s} {e['ours']:11s} {e['ours_ms']:9.3f} ms{extra}")
    box_rows = bench_box(sizes, repeat, budget=60.0 if args.quick else 300.0)
    print_table("random box LCPs (symmetric PD, some infinite bounds)", box_rows)
    out_dir = ROOT / "benchmarks" / "results"
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"bench_mixed{'_quick' if args.quick else ''}.json"
    payload = {"date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
               "machine": platform.platform(), "cpu_count": os.cpu_count(),
               "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"), "tol": TOL,
               "repeat": repeat, "mlcp": mlcp_rows, "ratios": rat, "box": box_rows}
    path.write_text(json.dumps(payload, indent=1, default=float) + "\n")
    print(f"\nwritten {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
