"""Benchmark of the enumeration method against Siconos' LCP_ENUM (same problems, same run).

Problems: random positive definite nonsymmetric M (a P-matrix: exactly one solution, so every
cone must be visited to prove there is no other), q ~ 3 N(0, 1), seeded by n.

Measured (wall time of the method only; the Cython kernel is compiled at install):

* ``ours_all``: :func:`lcpcli.analysis.enumeration.enumerate_cones`, all 2^n cones (the proof of
  uniqueness); ``ours_first``: the same, stopping at the first solution (``solve -m enum``);
* ``siconos_all``: Siconos ENUM with ``iparam[11] = 1`` (multiple solutions: visits every cone;
  it then reports info = 1, which is expected); ``siconos_first``: Siconos ENUM as shipped
  (stops at the first solution, in its own cone order).

Run:  python benchmarks/bench_enumerate.py [--quick | --full] [--timeout S]
(``--quick``: n = 8, 12; default: n = 12, 16, 20; ``--full`` adds n = 24 and 26).
Writes ``benchmarks/results/enumerate.json`` and prints a table with the time ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lcpcli.analysis.enumeration import enumerate_cones  # noqa: E402
from lcpcli.core.certificate import certify  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402

#: The shared Siconos runner, beside the checkout (``../shared``).
PEER = ROOT.parent / "shared" / "peers" / "siconos_peer.py"
SICONOS_PYTHON = "/usr/bin/python3"


def make_problem(n: int) -> Problem:
    rng = np.random.default_rng(1000 + n)
    A = rng.standard_normal((n, n))
    C = rng.standard_normal((n, n))
    M = A @ A.T + 0.1 * np.eye(n) + (C - C.T)
    q = 3.0 * rng.standard_normal(n)
    return Problem.create(M, q, name=f"random_pd_{n}")


def run_ours(p: Problem, stop_at_first: bool, repeat: int) -> dict:
    times = []
    res = None
    for _ in range(repeat):
        t = time.perf_counter()
        res = enumerate_cones(p, stop_at_first=stop_at_first, max_n=40)
        times.append(time.perf_counter() - t)
    assert res is not None
    z = res.solutions[0].z if res.solutions else np.zeros(p.n)
    cert = certify(p, z)
    return {"seconds": float(np.median(times)), "verdict": res.verdict,
            "solutions": len(res.solutions), "cones_examined": res.examined,
            "error": cert.error, "residual": cert.residual, "z": z}


def run_siconos(path: Path, multiple: bool, timeout: float) -> dict:
    if not PEER.exists() or not Path(SICONOS_PYTHON).exists():
        return {"seconds": None, "error": None, "note": "Siconos peer not available"}
    cmd = [SICONOS_PYTHON, str(PEER), str(path), "--solver", "ENUM", "--repeat", "1",
           "--warmup", "0", "--timeout", str(timeout)]
    if multiple:
        cmd += ["--iparam", "11=1"]
    t = time.perf_counter()
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout + 30)
    except subprocess.TimeoutExpired:
        return {"seconds": None, "timed_out": True, "limit": timeout}
    wall = time.perf_counter() - t
    try:
        data = json.loads(out.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        return {"seconds": None, "timed_out": wall >= timeout, "limit": timeout,
                "note": out.stderr.strip()[-200:]}
    if data.get("seconds_median") is None:
        return {"seconds": None, "timed_out": True, "limit": timeout,
                "note": str(data.get("error", ""))[:200]}
    return {"seconds": data["seconds_median"], "info": data.get("info"),
            "residual": data.get("residual_min_norm"), "z": data.get("z")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 8, 12 only")
    ap.add_argument("--full", action="store_true", help="also n = 24 and 26")
    ap.add_argument("--timeout", type=float, default=120.0,
                    help="seconds before a Siconos run is abandoned (default 120)")
    ap.add_argument("--no-siconos", action="store_true", help="skip the peer")
    ap.add_argument("--output", default=str(ROOT / "benchmarks" / "results" / "enumerate.json"))
    args = ap.parse_args()
    sizes = [8, 12] if args.quick else [12, 16, 20] + ([24, 26] if args.full else [])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            p = make_problem(n)
            path = Path(tmp) / f"p{n}.npz"
            np.savez(path, M=p.M, q=p.q)
            repeat = 3 if n <= 16 else 1
            ours_all = run_ours(p, False, repeat)
            ours_first = run_ours(p, True, repeat)
            if args.no_siconos:
                sic_all = sic_first = {"seconds": None, "note": "skipped"}
            else:
                sic_first = run_siconos(path, False, args.timeout)
                sic_all = run_siconos(path, True, args.timeout)
            agree = None
            if sic_first.get("z") is not None:
                agree = float(np.max(np.abs(np.asarray(sic_first["z"]) - ours_all["z"])))
            row = {"n": n, "cones": 2**n,
                   "ours_all_s": ours_all["seconds"], "ours_first_s": ours_first["seconds"],
                   "ours_first_cones": ours_first["cones_examined"],
                   "ours_verdict": ours_all["verdict"], "ours_error": ours_all["error"],
                   "ours_residual": ours_all["residual"],
                   "siconos_all_s": sic_all.get("seconds"),
                   "siconos_first_s": sic_first.get("seconds"),
                   "siconos_residual": sic_first.get("residual"),
                   "siconos_timed_out": bool(sic_all.get("timed_out")
                                             or sic_first.get("timed_out")),
                   "timeout_s": args.timeout, "z_max_diff_vs_siconos": agree}
            for mode in ("all", "first"):
                a, b = row[f"ours_{mode}_s"], row[f"siconos_{mode}_s"]
                row[f"speedup_{mode}"] = (b / a) if (a and b) else None
                if b is None and row["siconos_timed_out"] and a:
                    row[f"speedup_{mode}_at_least"] = args.timeout / a
            rows.append(row)
            _print_row(row)
    out = {"benchmark": "enumerate", "machine": f"{platform.machine()}, {os.cpu_count()} cores",
           "python": platform.python_version(), "when": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                                      time.gmtime()),
           "problems": "random positive definite nonsymmetric M (P-matrix), q = 3 N(0,1)",
           "rows": rows}
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    Path(args.output).write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.output}")


def _fmt(x: float | None, timed_out: bool = False, limit: float = 0.0) -> str:
    if x is None:
        return f"> {limit:.0f} s" if timed_out else "-"
    return f"{x:.4f} s"


def _print_row(r: dict) -> None:
    if not getattr(_print_row, "done", False):
        print(f"{'n':>3} {'cones':>10} | {'ours all':>11} {'Siconos all':>12} {'ratio':>7} | "
              f"{'ours first':>11} {'Siconos 1st':>12} {'ratio':>7} | {'our error':>9} "
              f"{'verdict':>7}")
        _print_row.done = True  # type: ignore[attr-defined]
    to = r["siconos_timed_out"]
    sa = _fmt(r["siconos_all_s"], to, r["timeout_s"])
    sf = _fmt(r["siconos_first_s"], to, r["timeout_s"])
    ra, rf = (f"{r[f'speedup_{m}']:.1f}x" if r[f"speedup_{m}"] else
              f">{r[f'speedup_{m}_at_least']:.0f}x" if r.get(f"speedup_{m}_at_least") else "-"
              for m in ("all", "first"))
    print(f"{r['n']:>3} {r['cones']:>10,} | {_fmt(r['ours_all_s']):>11} {sa:>12} {ra:>7} | "
          f"{_fmt(r['ours_first_s']):>11} {sf:>12} {rf:>7} | {r['ours_error']:>9.1e} "
          f"{r['ours_verdict']:>7}", flush=True)


if __name__ == "__main__":
    main()
