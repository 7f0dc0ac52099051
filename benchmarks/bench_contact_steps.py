"""Benchmark: warm-started contact sequences (issue 26), warm against cold in the same run.

    python benchmarks/bench_contact_steps.py                 # both cases
    python benchmarks/bench_contact_steps.py --stacks 20 --steps 100 --next-stacks 834

* ``falling``: ``--stacks`` stacks of 3 boxes (``lcpcli.contact.examples.box_stacks``, K = 4
  friction directions) stepped ``--steps`` times by :func:`lcpcli.contact.stepping.simulate`
  (dt = 0.01 s, gravity, positions integrated with the post-impact velocities), once cold and
  once with every step warm-started from the previous step's impulses (matched by unknown
  name).  Reported: the total solve time (:func:`lcpcli.contact.solve`, LCP build excluded),
  the mean pivots per step (summed over the islands), the islands the warm start answered, the
  steps solved, and the median time of the steps both runs solved.
* ``next``: ``--next-stacks`` stacks (834: 10,008 contacts, 60,048 unknowns), the "next step"
  of benchmarks/bench_contact.py (every velocity changed by about 1 %) solved cold, from the
  first step's impulses and basis (``Impact.basic``: ``warm``) and from the impulses alone
  (their support as the basis: ``warm_support``), interleaved, ``--repeat`` times (medians).

Writes ``benchmarks/results/contact_steps.json``.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = os.environ.get("BENCH_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from lcpcli.contact import build, solve  # noqa: E402
from lcpcli.contact.examples import box_stacks  # noqa: E402
from lcpcli.contact.stepping import simulate  # noqa: E402


def falling(stacks: int, steps: int) -> dict[str, object]:
    scene = box_stacks(stacks, 3, seed=1)
    runs = {kind: simulate(scene, steps, warm=kind == "warm") for kind in ("cold", "warm")}
    both = [k for k in range(steps)
            if all(runs[kind][k].status == "solved" for kind in runs)]
    out: dict[str, object] = {"case": f"falling {stacks}x3, {steps} steps",
                              "unknowns": build(scene, friction=4).problem.n}
    for kind, st in runs.items():
        out[kind] = {"total_solve_s": sum(s.seconds for s in st),
                     "mean_pivots_per_step": statistics.mean(s.pivots for s in st),
                     "mean_warm_islands": statistics.mean(s.warm_islands for s in st),
                     "islands": st[0].islands,
                     "steps_solved": sum(s.status == "solved" for s in st),
                     "median_step_s_both_solved": statistics.median(
                         st[k].seconds for k in both) if both else None}
    out["ratio_total"] = out["warm"]["total_solve_s"] / out["cold"]["total_solve_s"]
    out["ratio_pivots"] = (out["warm"]["mean_pivots_per_step"]
                           / out["cold"]["mean_pivots_per_step"])
    return out


def next_step(stacks: int, repeat: int) -> dict[str, object]:
    scene = box_stacks(stacks, 3, seed=1)
    clcp = build(scene, friction=4)
    first = solve(clcp)
    rng = np.random.default_rng(0)
    nxt = build(dataclasses.replace(
        scene, velocity=scene.velocity * (1 + 0.01 * rng.normal(size=scene.velocity.shape)),
        omega=scene.omega * (1 + 0.01 * rng.normal(size=scene.omega.shape))), friction=4)
    kinds = {"cold": {}, "warm": {"z0": first.result.z, "basis0": first.basic},
             "warm_support": {"z0": first.result.z}}
    times: dict[str, list[float]] = {k: [] for k in kinds}
    res = {}
    for _ in range(repeat):
        for kind, start in kinds.items():
            t = time.perf_counter()
            res[kind] = solve(nxt, **start)
            times[kind].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    return {"case": f"next step, {stacks} stacks", "unknowns": nxt.problem.n,
            "cold_s": med["cold"], "warm_s": med["warm"], "ratio": med["warm"] / med["cold"],
            "warm_support_s": med["warm_support"],
            "ratio_support": med["warm_support"] / med["cold"],
            "status": {k: str(r.result.status) for k, r in res.items()},
            "warm_islands": {k: sum(r["warm"] for r in res[k].islands)
                             for k in ("warm", "warm_support")},
            "islands": len(res["warm"].islands),
            "mean_iterations": {k: statistics.mean(r["iterations"] for r in res[k].islands)
                                for k in res}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stacks", type=int, default=20)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--next-stacks", type=int, default=834)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" /
                                         "contact_steps.json"))
    args = ap.parse_args()
    rows = [falling(args.stacks, args.steps), next_step(args.next_stacks, args.repeat)]
    for row in rows:
        print(json.dumps(row, default=str))
    meta = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "python": platform.python_version(), "numpy": np.__version__,
            "load": os.getloadavg(), "nproc": os.cpu_count()}
    Path(args.out).write_text(json.dumps({"meta": meta, "rows": rows}, indent=1,
                                         default=str) + "\n")
    print(f"written {args.out}; load average {meta['load']}")


if __name__ == "__main__":
    main()
