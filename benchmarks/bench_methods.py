"""Benchmark: every LCP method on random PD, PSD rank-deficient, P-matrix and sparse contact-like
problems; time and certified error per (method, problem), with Siconos peers in the same run.

    python benchmarks/bench_methods.py            # default run (a few minutes at most)
    python benchmarks/bench_methods.py --quick    # seconds
    python benchmarks/bench_methods.py --full     # dense up to n = 5000, sparse up to 1e5
    python benchmarks/bench_methods.py --no-peers # skip Siconos

Timings are the method's own wall time as ``lcpcli.solve`` measures it (kernels compiled before,
no file reading, certification excluded); the median of the repeats.  ``error`` is the
project's certified error (:mod:`lcpcli.core.certificate`) of the returned z; for a Siconos peer
it is the same certificate applied to the z the peer returned (so the errors are comparable).  A
method whose previous size took more than ``--budget`` seconds is skipped at larger sizes (shown
as "skip").
Writes ``benchmarks/results/methods.json``.
"""

from __future__ import annotations

import os

# One BLAS thread: on a shared machine a multi-threaded OpenBLAS makes small dense solves up to
# 1000x slower (threads spin against each other); set before numpy is imported.  Override with
# BENCH_THREADS=k.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = os.environ.get("BENCH_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lcpcli.api import solve  # noqa: E402
from lcpcli.core.certificate import certify  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402

METHODS = ["lemke", "murty", "pgs", "psor", "newton", "newton-min", "ip", "auto"]
#: Our method -> the Siconos solver that implements the same algorithm.
PEERS = {"lemke": "LCP_LEMKE", "murty": "LCP_MURTY", "pgs": "LCP_PGS", "psor": "LCP_PSOR",
         "newton": "LCP_NEWTON_FB_FBLSA", "newton-min": "LCP_NEWTONMIN"}
#: The shared Siconos runner, beside the checkout (``../shared``).
PEER_SCRIPT = ROOT.parent / "shared" / "peers" / "siconos_peer.py"
#: Largest n given to the dense pivoting methods (they densify a sparse M).
PIVOT_MAX_N = 5000
#: Methods that are not meant for a class (they would only burn the budget); not run there.
NOT_FOR = {"psd": {"murty"}, "contact": {"murty"}}


# ---------------------------------------------------------------------------- problem families
def gen_pd(n: int, rng: np.random.Generator):
    A = rng.standard_normal((n, n))
    return A @ A.T / n + 0.5 * np.eye(n), rng.standard_normal(n)


def gen_psd(n: int, rng: np.random.Generator):
    r = max(1, n // 2)
    B = rng.standard_normal((n, r))
    M = B @ B.T / r
    z = np.where(rng.random(n) < 0.5, rng.random(n), 0.0)
    w = np.where(z > 0, 0.0, rng.random(n))
    return M, w - M @ z


def gen_p(n: int, rng: np.random.Generator):
    """Non-symmetric P-matrix (H-matrix with positive diagonal) with indefinite symmetric part."""
    M = 0.02 / n * rng.standard_normal((n, n))
    k = np.arange(0, n - 1, 2)
    M[k, k + 1] = 3.0
    M[k + 1, k] = 0.0
    M[np.diag_indices(n)] = 1.0 + 0.2 * rng.random(n)
    return M, rng.standard_normal(n)


def gen_contact(n: int, rng: np.random.Generator):
    """Sparse M = J W J^T + 1e-6 I, q = J v - 0.1: each contact couples a body with one of its
    next three neighbours along a chain of n/2 bodies (local contacts, as in a pile or a chain;
    random far-away couplings would make sparse LU fill in like a dense matrix)."""
    n_bodies = max(2, n // 2)
    dof = 3 * n_bodies
    a = rng.integers(0, n_bodies, n)
    b = (a + 1 + rng.integers(0, 3, n)) % n_bodies
    rows = np.repeat(np.arange(n), 6)
    cols = np.concatenate([3 * a[:, None] + np.arange(3), 3 * b[:, None] + np.arange(3)],
                          axis=1).ravel()
    vals = rng.standard_normal(6 * n) * np.tile([1, 1, 1, -1, -1, -1], n)
    J = sp.csr_matrix((vals, (rows, cols)), shape=(n, dof))
    W = sp.diags(1.0 / (0.5 + rng.random(dof)))
    M = (J @ W @ J.T + 1e-6 * sp.identity(n)).tocsr()
    return M, J @ rng.standard_normal(dof) - 0.1


FAMILIES = {"pd": gen_pd, "psd": gen_psd, "p": gen_p, "contact": gen_contact}


# ---------------------------------------------------------------------------- running
def run_ours(p: Problem, method: str, repeat: int, caps: dict[str, int]) -> dict:
    times, r = [], None
    opts = {"max_iter": caps[method]} if method in caps else {}
    for _ in range(repeat):
        r = solve(p, method, **opts)
        times.append(r.seconds)
    assert r is not None
    out = {"status": r.status, "seconds": statistics.median(times), "error": r.error,
           "iterations": r.iterations}
    if method == "auto":
        out["chosen"] = r.info.get("chosen")
    return out


def run_peer(p: Problem, solver: str, repeat: int, timeout: float) -> dict | None:
    py = shutil.which("python3", path="/usr/bin")
    if py is None or not PEER_SCRIPT.exists() or p.sparse:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "p.npz"
        np.savez(f, M=p.M, q=p.q)
        try:
            cp = subprocess.run([py, str(PEER_SCRIPT), str(f), "--solver", solver, "--repeat",
                                 str(repeat), "--tol", "1e-8", "--timeout", str(timeout)],
                                capture_output=True, text=True, timeout=timeout + 30)
        except subprocess.TimeoutExpired:
            return {"status": "timeout", "seconds": None, "error": None}
    try:
        d = json.loads(cp.stdout.strip().splitlines()[-1])
    except (json.JSONDecodeError, IndexError):
        return {"status": "error", "seconds": None, "error": None}
    z = d.get("z")
    err = None
    if z is not None and all(v is not None for v in z):
        err = certify(p, np.asarray(z, dtype=float)).error
    ok = d.get("info") == 0 and err is not None
    return {"status": "success" if ok else f"info={d.get('info')}",
            "seconds": d.get("seconds_median"), "error": err,
            "iterations": d.get("iterations")}


def sizes_for(args: argparse.Namespace) -> dict[str, list[int]]:
    if args.quick:
        dense, sparse = [10, 100], [1000]
    elif args.full:
        dense, sparse = [10, 100, 1000, 2000, 5000], [1000, 10_000, 100_000]
    else:
        dense, sparse = [10, 100, 1000], [1000, 10_000]
    return {"pd": dense, "psd": dense, "p": dense, "contact": sparse}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--budget", type=float, default=None,
                    help="skip a method at larger sizes once it took this long (s)")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--families", default=",".join(FAMILIES),
                    help="comma-separated subset of pd, psd, p, contact")
    ap.add_argument("--max-sweeps", type=int, default=1000,
                    help="PGS/PSOR sweep limit in the default and quick runs (default 1000)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "methods.json"))
    args = ap.parse_args(argv)
    budget = args.budget or (2.0 if args.quick else 6.0 if not args.full else 30.0)
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    peer_max_n = 1000 if not args.full else 2000
    # iteration caps so that a slowly converging method ends (as unsolved) within the run
    caps = {} if args.full else {"pgs": args.max_sweeps, "psor": args.max_sweeps}
    from lcpcli.solvers.registry import get_method

    for m in methods:  # compile / load kernels outside every timed region
        spec = get_method(m)
        if spec.prepare:
            spec.prepare()
    rows = []
    t_start = time.perf_counter()
    wanted = {f.strip() for f in args.families.split(",")}
    for fam, sizes in sizes_for(args).items():
        if fam not in wanted:
            continue
        slow: set[str] = set()
        for n in sizes:
            rng = np.random.default_rng(1000 + n)
            M, q = FAMILIES[fam](n, rng)
            p = Problem.create(M, q, name=f"{fam}-{n}")
            repeat = 5 if n <= 100 else (3 if n <= 1000 else 1)
            for m in methods:
                if m in NOT_FOR.get(fam, set()):
                    continue
                if m in ("lemke", "murty") and n > PIVOT_MAX_N:
                    continue  # dense O(n^2) per pivot: not for this size
                if m in slow:
                    rows.append({"family": fam, "n": n, "method": m, "status": "skip"})
                    continue
                t0 = time.perf_counter()
                res = run_ours(p, m, repeat, caps)
                if time.perf_counter() - t0 > budget * repeat:
                    slow.add(m)
                row = {"family": fam, "n": n, "method": m, **res}
                if not args.no_peers and m in PEERS and not p.sparse and n <= peer_max_n:
                    peer = run_peer(p, PEERS[m], 1 if n >= 1000 else repeat,
                                    timeout=max(10.0, 2 * budget))
                    if peer is not None:
                        row["peer"] = {"solver": "siconos " + PEERS[m], **peer}
                        if peer.get("seconds") and res["seconds"]:
                            row["ratio_vs_peer"] = res["seconds"] / peer["seconds"]
                rows.append(row)
                print_row(row)
    total = time.perf_counter() - t_start
    out = {"benchmark": "methods", "python": platform.python_version(),
           "machine": platform.machine(), "processor": platform.processor(),
           "args": vars(args), "total_seconds": total, "rows": rows}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1, allow_nan=False, default=_json))
    print_table(rows)
    print(f"\ntotal {total:.1f} s; wrote {args.out}")
    return 0


def _json(x):  # type: ignore[no-untyped-def]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    raise TypeError(type(x))


def _fmt_t(s: float | None) -> str:
    if s is None:
        return "-"
    return f"{s * 1e3:.3g} ms" if s < 1 else f"{s:.3g} s"


def _fmt_e(e: float | None) -> str:
    return "-" if e is None or not np.isfinite(e) else f"{e:.1e}"


def print_row(r: dict) -> None:
    if r.get("status") == "skip":
        return
    peer = r.get("peer")
    extra = ""
    if peer:
        extra = (f" | {peer['solver']}: {peer['status']} {_fmt_t(peer['seconds'])} "
                 f"err {_fmt_e(peer['error'])}")
    chosen = f" ({r['chosen']})" if r.get("chosen") else ""
    print(f"{r['family']:8s} n={r['n']:<7d} {r['method']:11s} {r['status']:9s} "
          f"{_fmt_t(r['seconds']):>10s} err {_fmt_e(r['error'])}{chosen}{extra}", flush=True)


def print_table(rows: list[dict]) -> None:
    try:
        from rich.console import Console
        from rich.table import Table
    except ImportError:  # pragma: no cover
        return
    t = Table(title="LCP methods: median time (status, certified error); x = ours / Siconos")
    for col in ("family", "n", "method", "status", "time", "error", "iters", "siconos",
                "siconos err", "x"):
        t.add_column(col, justify="right" if col not in ("family", "method", "status") else "left")
    for r in rows:
        if r.get("status") == "skip":
            t.add_row(r["family"], str(r["n"]), r["method"], "skip", "", "", "", "", "", "")
            continue
        peer = r.get("peer") or {}
        ratio = r.get("ratio_vs_peer")
        t.add_row(r["family"], str(r["n"]), r["method"] + (f"->{r['chosen']}"
                                                           if r.get("chosen") else ""),
                  r["status"], _fmt_t(r["seconds"]), _fmt_e(r["error"]), str(r["iterations"]),
                  (f"{peer.get('status')} {_fmt_t(peer.get('seconds'))}" if peer else ""),
                  _fmt_e(peer.get("error")) if peer else "",
                  f"{ratio:.2g}" if ratio else "")
    Console().print(t)


if __name__ == "__main__":
    raise SystemExit(main())
