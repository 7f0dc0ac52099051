"""Stacked batches end to end, side by side with a Siconos loop in the same run.

Cases (each a fresh process, timed from start to exit: interpreter start, reading, solving,
certifying, writing the results):

* ``lcpcli``: ``lcpcli solve STACK.h5 -o results.h5 --json`` (every answer certified; the
  summary's counts are checked: all solved);
* ``lcpcli -j 1``: the same on one thread (per-core speed);
* ``siconos loop``: Debian's ``/usr/bin/python3`` loads the same problems from one NPZ file and
  calls Siconos' C Lemke (``linearComplementarity_driver``, SICONOS_LCP_LEMKE) in a loop, the
  process the issue measured (skipped when ``python3-siconos`` is not installed).

Problems: random positive definite LCPs, ``M = A A^T / n + I``, ``q ~ N(0, 1)`` (one solution
each; Lemke needs about n / 2 pivots).  Prints problems per second and the ratios.

    python benchmarks/bench_stack.py               # n = 12, K = 100,000 and n = 50, K = 20,000
    python benchmarks/bench_stack.py --quick       # K / 10
    python benchmarks/bench_stack.py --vs-solve-many --jobs 2 --rounds 7 [--roots A B]

``--vs-solve-many`` (issue 25, item 1): the stacked command line against ``solve_many`` on the
same arrays, both on ``--jobs`` threads, interleaved round by round (the machine may be
shared: the best of ``--rounds`` is kept for each).  The command line's rate counts the
batch's own wall time (``wall_seconds`` of its summary: reading, digests, solving,
certifying, writing ``-o results.h5``; not the interpreter's start), ``solve_many``'s the call
alone on arrays already in memory (a fresh process per round, as the command line).
``--roots`` compares checkouts (each a directory holding ``lcpcli/``) in the same rounds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lcpcli.io.stack import write_stack  # noqa: E402

SICONOS_PYTHON = "/usr/bin/python3"
SICONOS_LOOP = r"""
import sys, numpy as np, siconos.numerics as sn
d = np.load(sys.argv[1])
M, q = d["M"], d["q"]
K, n = q.shape
z, w = np.zeros(n), np.zeros(n)
ok = 0
for k in range(K):
    o = sn.SolverOptions(sn.SICONOS_LCP_LEMKE)
    info = sn.linearComplementarity_driver(sn.LCP(M[k], q[k]), z, w, o)
    ok += info == 0
print(ok)
"""


def make_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    M = np.empty((K, n, n))
    q = rng.standard_normal((K, n))
    for start in range(0, K, 10_000):  # bounded temporaries
        A = rng.standard_normal((min(10_000, K - start), n, n))
        M[start:start + A.shape[0]] = A @ A.transpose(0, 2, 1) / n + np.eye(n)
    return M, q


def timed(cmd: list[str], cwd: Path, env: dict | None = None) -> tuple[float, str]:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"{cmd[:3]} failed ({r.returncode}): {r.stderr[-500:]}")
    return wall, r.stdout


def lcpcli_case(stack: Path, K: int, jobs: int | None, cwd: Path) -> dict:
    out = cwd / "results.h5"
    cmd = [sys.executable, "-m", "lcpcli", "solve", str(stack), "-o", str(out), "--json"]
    if jobs:
        cmd += ["-j", str(jobs)]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    walls, summary = [], {}
    for _ in range(3):
        wall, stdout = timed(cmd, cwd, env)
        walls.append(wall)
        summary = json.loads(stdout.splitlines()[-1])
    counts = summary["summary"]["counts"]
    if counts.get("solved") != K:
        raise SystemExit(f"not every problem was certified: {counts}")
    wall = min(walls)
    return {"wall_seconds": wall, "problems_per_second": K / wall,
            "batch_wall_seconds": summary["wall_seconds"], "timings": summary["timings"]}


def siconos_case(npz: Path, K: int, cwd: Path) -> dict | None:
    if not Path(SICONOS_PYTHON).exists():
        return None
    probe = subprocess.run([SICONOS_PYTHON, "-c", "import siconos.numerics"],
                           capture_output=True)
    if probe.returncode != 0:
        return None
    walls, ok = [], 0
    for _ in range(3):
        wall, stdout = timed([SICONOS_PYTHON, "-c", SICONOS_LOOP, str(npz)], cwd)
        walls.append(wall)
        ok = int(stdout.strip())
    wall = min(walls)
    return {"wall_seconds": wall, "problems_per_second": K / wall, "info_zero": ok}


SOLVE_MANY = r"""
import sys, time, numpy as np
from lcpcli import solve_many
M, q = np.load(sys.argv[1]), np.load(sys.argv[2])
t = time.perf_counter()
r = solve_many(M, q, threads=int(sys.argv[3]))
print(time.perf_counter() - t, r.counts().get("solved", 0))
"""


def vs_solve_many(cases: list[tuple[int, int]], jobs: int, rounds: int, roots: list[Path],
                  out: str) -> None:
    """The stacked command line against solve_many, interleaved (see the module docstring)."""
    results: dict = {"cpus": os.cpu_count(), "jobs": jobs, "rounds": rounds, "cases": []}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for n, K in cases:
            M, q = make_stack(K, n)
            stack, m_npy, q_npy = tmp / f"stack{n}.h5", tmp / "M.npy", tmp / "q.npy"
            write_stack(stack, M, q)
            np.save(m_npy, M)
            np.save(q_npy, q)
            del M, q
            best: dict[str, float] = {}
            loads = [os.getloadavg()[0]]
            for _ in range(rounds):
                for root in roots:
                    env = dict(os.environ, PYTHONPATH=str(root))
                    cmd = [sys.executable, "-m", "lcpcli", "solve", str(stack), "-o",
                           str(tmp / "results.h5"), "--json", "-j", str(jobs)]
                    _, stdout = timed(cmd, tmp, env)
                    summary = json.loads(stdout.splitlines()[-1])
                    if summary["summary"]["counts"].get("solved") != K:
                        raise SystemExit(f"not every problem was certified: {summary}")
                    key = f"cli {root}"
                    best[key] = min(best.get(key, np.inf), summary["wall_seconds"])
                env = dict(os.environ, PYTHONPATH=str(roots[0]))
                _, stdout = timed([sys.executable, "-c", SOLVE_MANY, str(m_npy), str(q_npy),
                                   str(jobs)], tmp, env)
                seconds, solved = stdout.split()
                if int(solved) != K:
                    raise SystemExit(f"solve_many certified {solved} of {K}")
                best["solve_many"] = min(best.get("solve_many", np.inf), float(seconds))
                loads.append(os.getloadavg()[0])
            row = {"n": n, "K": K, "seconds": best, "load_average": [min(loads), max(loads)],
                   "per_second": {k: K / v for k, v in best.items()},
                   "ratio_to_solve_many": {k: best["solve_many"] / v for k, v in best.items()}}
            results["cases"].append(row)
            print(f"n = {n}, K = {K:,}, --jobs {jobs}, best of {rounds}: " + "; ".join(
                f"{k} {v:.3f} s ({K / v:,.0f}/s, {best['solve_many'] / v:.2f}x solve_many)"
                for k, v in best.items()) + f"; load average {min(loads):.1f}-{max(loads):.1f}",
                flush=True)
            stack.unlink()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a tenth of the problems")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "stack.json"))
    ap.add_argument("--vs-solve-many", action="store_true",
                    help="the stacked command line against solve_many on the same arrays")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--roots", nargs="*", type=Path, default=[ROOT])
    args = ap.parse_args()
    scale = 10 if args.quick else 1
    cases = [(12, 100_000 // scale), (50, 20_000 // scale)]
    if args.vs_solve_many:
        out = args.out if "--out" in sys.argv else str(
            ROOT / "benchmarks" / "results" / "stack_vs_solve_many.json")
        vs_solve_many(cases, args.jobs, args.rounds, [r.resolve() for r in args.roots], out)
        return
    results = {"cpus": os.cpu_count(), "cases": []}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for n, K in cases:
            M, q = make_stack(K, n)
            stack, npz = tmp / f"stack{n}.h5", tmp / f"stack{n}.npz"
            write_stack(stack, M, q)
            np.savez(npz, M=M, q=q)
            del M, q
            row = {"n": n, "K": K, "lcpcli": lcpcli_case(stack, K, None, tmp),
                   "lcpcli_1_thread": lcpcli_case(stack, K, 1, tmp),
                   "siconos_loop": siconos_case(npz, K, tmp)}
            sic = row["siconos_loop"]
            line = (f"n = {n:3d}, K = {K:7,d}: lcpcli {row['lcpcli']['wall_seconds']:.2f} s "
                    f"({row['lcpcli']['problems_per_second']:,.0f} /s), 1 thread "
                    f"{row['lcpcli_1_thread']['wall_seconds']:.2f} s")
            if sic is not None:
                row["speedup_vs_siconos"] = sic["wall_seconds"] / row["lcpcli"]["wall_seconds"]
                line += (f"; siconos loop {sic['wall_seconds']:.2f} s "
                         f"({sic['problems_per_second']:,.0f} /s, info 0 on {sic['info_zero']:,}):"
                         f" lcpcli {row['speedup_vs_siconos']:.1f}x faster")
            print(line, flush=True)
            results["cases"].append(row)
            for f in (stack, npz):
                f.unlink()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
