"""What the certificate costs: the check of an n = 10 answer, and its share of a Lemke solve.

Goals (issue 11): certifying an n = 10 answer <= 5 us; at n = 1000 the check <= 5% of the Lemke
solve.  Run on demand (never a timed test):

    python benchmarks/bench_certificate.py [--repeat 200] [--json results.json]

For each n: random PD problems (A A^T / n + I) with a planted solution; the time of
``certify(problem, z)`` (the Python entry: compiled kernel + Certificate record), of the kernel
alone (``_certificate.certify_arrays``), and of ``lcpcli.solve(problem, "lemke")`` for the same
problem, as medians over the repeats.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import lcpcli  # noqa: E402
from lcpcli.core import _certificate  # noqa: E402
from lcpcli.core.certificate import certify  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402


def planted(n: int, seed: int) -> tuple[Problem, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T / n + np.eye(n)
    z = np.where(rng.random(n) < 0.5, rng.uniform(0.5, 2.0, n), 0.0)
    q = np.where(z > 0, 0.0, rng.uniform(0.5, 2.0, n)) - M @ z
    return Problem.create(M, q), z


def median_seconds(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,100,1000")
    ap.add_argument("--repeat", type=int, default=200)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    rows = []
    for n in [int(s) for s in args.sizes.split(",")]:
        p, z = planted(n, n)
        r = lcpcli.solve(p, "lemke")
        assert r.solved, r.message
        w = np.empty(n)
        rep = max(5, args.repeat // max(1, n // 100))
        t_cert = median_seconds(lambda p=p, r=r: certify(p, r.z), rep)
        t_kern = median_seconds(lambda p=p, r=r, w=w: _certificate.certify_arrays(
            p.M, p.q, r.z, 0, None, None, w), rep)
        t_solve = median_seconds(lambda p=p: lcpcli.solve(p, "lemke"), max(3, rep // 10))
        rows.append({"n": n, "certify_us": t_cert * 1e6, "kernel_us": t_kern * 1e6,
                     "lemke_solve_us": t_solve * 1e6, "share": t_cert / t_solve})
        print(f"n = {n:5d}: certify {t_cert * 1e6:9.2f} us (kernel {t_kern * 1e6:9.2f} us), "
              f"lemke solve {t_solve * 1e6:11.1f} us, certificate share {t_cert / t_solve:6.1%}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
