"""Contact scenes at scale: build and solve times of ``contact-matrix`` (issue 15's goals).

    python benchmarks/bench_contact.py           # the goals (about a minute on a quiet machine)
    python benchmarks/bench_contact.py --quick   # smaller scenes (seconds)
    python benchmarks/bench_contact.py --hard    # also one frictional island of 10^4 contacts

Cases (scenes from :mod:`lcpcli.contact.examples`, seeds fixed):

* ``stacks``: 100 stacks of 3 boxes, ``--friction 4`` (1,200 contacts, 7,200 unknowns, 100
  islands): build time, solve time (auto per island) and their ratio (goal: solve <= 3 x build);
  the whole-scene LCP solved at once is timed on 10 stacks (it grows as n^2 per pivot);
* ``stacks-10k``: 834 stacks (10,008 contacts, K = 4; goal: solved in <= 10 s), with 2 processes
  (``jobs=2``), and warm-started: from its own impulses, and a "next step" (every velocity
  changed by about 1 %) solved cold and from the first step's impulses;
* ``lattice-100k``: 33 x 33 x 32 touching spheres, frictionless (102,432 contacts in one island;
  goal: the default solve works), also through the CLI (``contact-matrix SCENE.h5 --solve``),
  and warm-started as above;
* ``old-law``: a 15^3 sphere lattice (9,675 contacts) solved with the former law
  ``q = (1 + eps) v_rel^-`` on every contact and with the contact states: contacts ending
  approaching (``v_rel^+ < 0``) under each;
* ``samples``: every ``samples/scene_*.json`` (K = 0 and 4): contacts ending approaching.
* ``--hard``: a 15^3 sphere lattice with K = 4 (one island of 58,050 unknowns), time-limited.

Times are wall-clock ``time.perf_counter`` around :func:`lcpcli.contact.build` and
:func:`lcpcli.contact.solve` (median of ``--repeat`` runs after a warm-up that loads the
kernels).  BLAS runs single-threaded unless BENCH_THREADS says otherwise (a threaded OpenBLAS on a
shared machine made each island's 72 x 72 eigenvalue call 15x slower).  Writes
``benchmarks/results/contact.json``.
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
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from datetime import datetime, timezone  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lcpcli.api import solve as solve_lcp  # noqa: E402
from lcpcli.contact import build, load_scene, solve  # noqa: E402
from lcpcli.contact.examples import box_stacks, sphere_lattice  # noqa: E402
from lcpcli.contact.impact import approaching  # noqa: E402
from lcpcli.contact.scene import write_scene_hdf5  # noqa: E402
from lcpcli.core.problem import Problem  # noqa: E402


def timed(fn, repeat: int):
    """(median seconds, last value) of ``repeat`` calls."""
    times, value = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), value


def summary(impact) -> dict:
    res = impact.result
    methods: dict[str, int] = {}
    for r in impact.islands or []:
        methods[r["method"]] = methods.get(r["method"], 0) + 1
    return {"status": res.status, "error": res.certificate.error,
            "islands": len(impact.islands) if impact.islands is not None else None,
            "methods": methods, "approaching": int(impact.approaching.sum()),
            "min_v_after": float(impact.normal_velocity.min())}


def case_stacks(n: int, repeat: int) -> dict:
    scene = box_stacks(n, 3, seed=1)
    t_build, clcp = timed(lambda: build(scene, friction=4), repeat)
    t_solve, impact = timed(lambda: solve(clcp), repeat)
    out = {"case": f"stacks {n}x3 K=4", "contacts": scene.n_contacts, "unknowns": clcp.problem.n,
           "build_s": t_build, "solve_s": t_solve, "ratio": t_solve / t_build,
           **summary(impact)}
    small = build(box_stacks(10, 3, seed=1), friction=4)
    out["whole_10_stacks_s"], whole = timed(lambda: solve(small, islands=False), 1)
    out["islands_10_stacks_s"], _ = timed(lambda: solve(small), repeat)
    out["whole_10_stacks_status"] = whole.result.status
    return out


def next_step(scene, rel: float = 0.01, seed: int = 0):
    """The scene with every velocity changed by about ``rel`` (a stand-in for the next step)."""
    rng = np.random.default_rng(seed)
    return dataclasses.replace(
        scene, velocity=scene.velocity * (1 + rel * rng.normal(size=scene.velocity.shape)),
        omega=scene.omega * (1 + rel * rng.normal(size=scene.omega.shape)))


def warm_runs(clcp, impact, repeat: int) -> dict:
    """Warm starts: from the scene's own impulses, and a 1 % perturbed scene from them."""
    t_same, same = timed(lambda: solve(clcp, z0=impact.result.z), repeat)
    nxt = build(next_step(clcp.scene), friction=clcp.requested_friction)
    t_cold, cold = timed(lambda: solve(nxt), repeat)
    t_next, warm = timed(lambda: solve(nxt, z0=impact.result.z), repeat)
    return {"warm_same_s": t_same, "warm_same_status": same.result.status,
            "next_cold_s": t_cold, "next_cold_iterations": cold.result.iterations,
            "next_warm_s": t_next, "next_warm_status": warm.result.status,
            "next_warm_iterations": warm.result.iterations,
            "next_warm_islands": sum(r["warm"] for r in warm.islands)}


def case_stacks_10k(n: int, repeat: int) -> dict:
    scene = box_stacks(n, 3, seed=1)
    t_build, clcp = timed(lambda: build(scene, friction=4), repeat)
    t_solve, impact = timed(lambda: solve(clcp), repeat)
    t_jobs, par = timed(lambda: solve(clcp, jobs=2), repeat)
    return {"case": f"stacks {n}x3 K=4", "contacts": scene.n_contacts,
            "unknowns": clcp.problem.n, "build_s": t_build, "solve_s": t_solve,
            "ratio": t_solve / t_build, "jobs2_s": t_jobs, "jobs2_status": par.result.status,
            **warm_runs(clcp, impact, repeat), **summary(impact)}


def case_lattice(shape: tuple[int, int, int], repeat: int, cli: bool) -> dict:
    scene = sphere_lattice(*shape, seed=1)
    t_build, clcp = timed(lambda: build(scene), repeat)
    t_solve, impact = timed(lambda: solve(clcp), repeat)
    out = {"case": f"lattice {'x'.join(map(str, shape))} frictionless",
           "contacts": scene.n_contacts, "unknowns": clcp.problem.n, "build_s": t_build,
           "solve_s": t_solve, "ratio": t_solve / t_build, **warm_runs(clcp, impact, repeat),
           **summary(impact)}
    if cli:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "lattice.h5"
            write_scene_hdf5(scene, path)
            env = dict(os.environ, PYTHONPATH=str(ROOT))
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "lcpcli", "contact-matrix", str(path),
                                   "--solve"], capture_output=True, text=True, env=env)
            out["cli_s"] = time.perf_counter() - t0
            out["cli_exit"] = proc.returncode
    return out


def case_old_law(shape: tuple[int, int, int]) -> dict:
    """The same lattice under the former law (restitution on every contact) and the states."""
    scene = sphere_lattice(*shape, seed=1)
    clcp = build(scene)
    asm = clcp.assembly
    q_old = (1.0 + scene.restitution) * asm.v_rel
    res = solve_lcp(Problem.create(clcp.problem.M, q_old), "auto")
    v_after_old = res.w - scene.restitution * asm.v_rel  # w = v+ + eps v- under the old law
    new = solve(clcp)
    old_app = approaching(v_after_old, asm.v_rel)
    return {"case": f"lattice {'x'.join(map(str, shape))}: old law vs contact states",
            "contacts": scene.n_contacts, "separating": int((asm.v_rel > 0).sum()),
            "old_status": res.status, "old_approaching": int(old_app.sum()),
            "old_min_v_after": float(v_after_old.min()),
            "new_status": new.result.status, "new_approaching": int(new.approaching.sum()),
            "new_min_v_after": float(new.normal_velocity.min())}


def case_samples() -> list[dict]:
    rows = []
    for path in sorted((ROOT / "samples").glob("scene_*.json")):
        scene = load_scene(path)
        for k in (0, 2 if scene.dimension == 2 else 4):
            clcp = build(scene, friction=k)
            impact = solve(clcp)
            rows.append({"sample": path.name, "K": clcp.friction, "unknowns": clcp.problem.n,
                         "status": impact.result.status,
                         "approaching": int(impact.approaching.sum()),
                         "min_v_after": float(impact.normal_velocity.min())})
    return rows


def case_hard(limit: float) -> dict:
    """One frictional island of 9,675 contacts (58,050 unknowns), in a child process."""
    code = (f"import sys, time; sys.path.insert(0, {str(ROOT)!r})\n"
            "from lcpcli.contact import build, solve\n"
            "from lcpcli.contact.examples import sphere_lattice\n"
            "c = build(sphere_lattice(15, 15, 15, seed=1), friction=4)\n"
            "t = time.perf_counter(); i = solve(c)\n"
            "print(i.result.status, time.perf_counter() - t, i.result.message[:200])\n")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=limit)
        return {"case": "lattice 15^3 K=4 (one island)", "wall_s": time.perf_counter() - t0,
                "output": proc.stdout.strip()[-300:]}
    except subprocess.TimeoutExpired:
        return {"case": "lattice 15^3 K=4 (one island)", "wall_s": None,
                "output": f"not finished in {limit:.0f} s"}


def machine() -> dict:
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    return {"date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "commit": commit,
            "nproc": os.cpu_count(), "load": os.getloadavg()[0],
            "python": platform.python_version(), "numpy": np.__version__,
            "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller scenes")
    ap.add_argument("--hard", action="store_true", help="also the frictional lattice")
    ap.add_argument("--hard-limit", type=float, default=300.0, help="seconds for --hard")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "contact.json"))
    args = ap.parse_args()
    solve(build(box_stacks(2, 3, seed=2), friction=4))  # warm-up: kernels, imports
    solve(build(sphere_lattice(3, 3, 3, seed=2)))
    quick = args.quick
    report = {"machine": machine(), "cases": []}

    def add(row: dict) -> None:
        report["cases"].append(row)
        print(json.dumps(row), flush=True)

    add(case_stacks(20 if quick else 100, args.repeat))
    add(case_stacks_10k(100 if quick else 834, args.repeat))
    add(case_lattice((10, 10, 10) if quick else (33, 33, 32), 1 if not quick else args.repeat,
                     cli=True))
    add(case_old_law((8, 8, 8) if quick else (15, 15, 15)))
    report["samples"] = case_samples()
    print(json.dumps(report["samples"]), flush=True)
    if args.hard:
        add(case_hard(args.hard_limit))
    report["machine"]["load_end"] = os.getloadavg()[0]
    Path(args.out).write_text(json.dumps(report, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
