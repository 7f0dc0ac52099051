"""Batch throughput: many small problems as separate JSON files and as one HDF5 file.

Runs ``lcpcli solve INPUT --jobs J --output out.jsonl --json`` (the real command, in a fresh
process) and reads its summary: problems per second over the batch's own wall time (interpreter
start-up is reported apart), and the share of worker time spent reading, solving (lcpcli.solve:
method, certificate, result) and writing.  Peers measured in the same run:

* ``shell loop``: one ``lcpcli solve FILE --json`` process per file (what a user would script),
  timed on a sample of files;
* ``bare loop``: ``load`` + ``lcpcli.solve`` + ``to_dict`` in one Python loop (no batch
  machinery: the floor for one core).

Also the overhead for larger problems: (batch wall - sum of method seconds) / sum of method
seconds for n = 50 and n = 100.

    python benchmarks/bench_batch.py            # 10,000 problems of n = 12
    python benchmarks/bench_batch.py --quick    # 1,000 problems
    python benchmarks/bench_batch.py --vs OLD_CHECKOUT . --count 20000 --rounds 3
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from lcpcli.core.problem import Problem  # noqa: E402
from lcpcli.io import save  # noqa: E402
from lcpcli.io.hdf5_format import write_many  # noqa: E402


def random_problem(rng: np.random.Generator, n: int, name: str) -> Problem:
    """A random LCP with a positive definite M (one solution; Lemke needs about n/2 pivots)."""
    A = rng.standard_normal((n, n))
    return Problem.create(A @ A.T / n + np.eye(n), rng.standard_normal(n), name=name)


def run_cli(args: list[str], cwd: Path, root: Path = ROOT,
            extra_path: str = "") -> tuple[dict, float]:
    """The command with ``root``'s lcpcli (``extra_path`` first on PYTHONPATH: e.g. a folder
    whose ``orjson.py`` raises ImportError, to measure the standard-library fallback)."""
    paths = [p for p in (extra_path, str(root), os.environ.get("PYTHONPATH", "")) if p]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(paths))
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "lcpcli", *args], cwd=cwd, env=env,
                       capture_output=True, text=True)
    total = time.perf_counter() - t0
    if r.returncode not in (0, 1):
        raise SystemExit(f"lcpcli failed ({r.returncode}): {r.stderr}")
    return json.loads(r.stdout.splitlines()[-1]), total


def batch_case(label: str, inputs: list[str], jobs: int, cwd: Path, n_problems: int) -> dict:
    out = cwd / f"out_{label}_{jobs}.jsonl"
    summary, total = run_cli(["solve", *inputs, "-j", str(jobs), "-o", str(out), "--json"], cwd)
    t = summary["timings"]
    work = t["read_seconds"] + t["solve_seconds"] + t["write_seconds"]
    assert summary["summary"]["counts"].get("solved") == n_problems, summary["summary"]
    return {
        "input": label, "jobs": jobs, "problems": n_problems,
        "batch_wall_s": summary["wall_seconds"], "process_wall_s": total,
        "setup_s": summary["setup_seconds"],
        "startup_s": total - summary["wall_seconds"],
        "problems_per_s": n_problems / summary["wall_seconds"],
        "problems_per_s_after_setup": n_problems
        / (summary["wall_seconds"] - summary["setup_seconds"]),
        "share_read": t["read_seconds"] / work, "share_solve": t["solve_seconds"] / work,
        "share_write": t["write_seconds"] / work,
        "share_method_in_solve": t["method_seconds"] / max(t["solve_seconds"], 1e-12),
        "timings": t,
    }


def bare_loop(paths: list[Path]) -> float:
    """Problems per second of the plainest loop over the library (one core)."""
    from lcpcli.api import solve
    from lcpcli.io import load

    solve(load(paths[0]))  # kernel loaded outside the timing
    t0 = time.perf_counter()
    for p in paths:
        solve(load(p)).to_dict(file=str(p))
    return len(paths) / (time.perf_counter() - t0)


def shell_loop(paths: list[Path], cwd: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    t0 = time.perf_counter()
    for p in paths:
        subprocess.run([sys.executable, "-m", "lcpcli", "solve", str(p), "--json"], cwd=cwd,
                       env=env, capture_output=True, check=False)
    return len(paths) / (time.perf_counter() - t0)


def overhead_case(n: int, count: int, tmp: Path) -> dict:
    rng = np.random.default_rng(n)
    path = tmp / f"n{n}.h5"
    write_many([random_problem(rng, n, f"p{i:05d}") for i in range(count)], path)
    summary, _ = run_cli(["solve", str(path), "-j", "1", "-o", str(tmp / f"n{n}.jsonl"),
                          "--json"], tmp)
    t = summary["timings"]
    method = t["method_seconds"]
    wall = summary["wall_seconds"] - summary["setup_seconds"]
    return {"n": n, "problems": count, "batch_wall_s": summary["wall_seconds"],
            "setup_s": summary["setup_seconds"],
            "method_s": method, "solve_s": t["solve_seconds"], "read_s": t["read_seconds"],
            "write_s": t["write_seconds"],
            "overhead_ratio": (wall - method) / method,
            "overhead_ratio_vs_solve": (wall - t["solve_seconds"]) / t["solve_seconds"]}


def versus(roots: list[str], count: int, rounds: int, jobs: int) -> None:
    """``--vs OLD NEW``: the JSON batch of ``count`` files of n = 12 with each checkout's lcpcli,
    with orjson and with it made unimportable, interleaved round by round; best of ``rounds``."""
    rng = np.random.default_rng(12)
    best: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        folder = tmp / "json"
        folder.mkdir()
        for i in range(count):
            save(random_problem(rng, 12, f"p{i:05d}"), folder / f"p{i:05d}.json")
        blocker = tmp / "no_orjson"
        blocker.mkdir()
        (blocker / "orjson.py").write_text("raise ImportError('measuring without orjson')\n")
        for r in range(rounds):
            for codec, extra in (("orjson", ""), ("stdlib", str(blocker))):
                for k, root in enumerate(roots):
                    label = f"{root} {codec}"
                    summary, _ = run_cli(["solve", str(folder), "-j", str(jobs), "-o",
                                          str(tmp / f"out{k}.jsonl"), "--json"], tmp,
                                         Path(root), extra)
                    assert summary["summary"]["counts"].get("solved") == count
                    wall = summary["wall_seconds"]
                    best[label] = min(best.get(label, math.inf), wall)
                    print(f"round {r + 1} {label}: {wall:.3f} s, {count / wall:,.0f} problems/s "
                          f"(set-up {summary['setup_seconds']:.3f} s), load "
                          f"{os.getloadavg()[0]:.1f}", flush=True)
    for label, wall in best.items():
        print(f"best {label}: {wall:.3f} s, {count / wall:,.0f} problems/s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="1,000 problems instead of 10,000")
    ap.add_argument("--count", type=int, default=None)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "batch.json"))
    ap.add_argument("--vs", nargs="+", metavar="ROOT",
                    help="checkouts to compare on the JSON batch only (interleaved, best of "
                         "--rounds, with and without orjson)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    count = args.count or (1000 if args.quick else 10000)
    if args.vs:
        versus(args.vs, count, args.rounds, args.jobs)
        return
    rng = np.random.default_rng(12)
    problems = [random_problem(rng, 12, f"p{i:05d}") for i in range(count)]
    results: dict = {"count": count, "n": 12, "cpus": os.cpu_count(),
                     "load_average": os.getloadavg(), "cases": [], "peers": {},
                     "overhead": []}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        folder = tmp / "json"
        folder.mkdir()
        paths = []
        for p in problems:
            path = folder / f"{p.name}.json"
            save(p, path)
            paths.append(path)
        write_many(problems, tmp / "all.h5")
        for label, inputs in (("hdf5", [str(tmp / "all.h5")]), ("json", [str(folder)])):
            for jobs in (1, 2):
                case = batch_case(label, inputs, jobs, tmp, count)
                results["cases"].append(case)
                print(f"{label:5s} jobs={jobs}: {case['problems_per_s']:6.0f} problems/s "
                      f"({case['problems_per_s_after_setup']:.0f}/s after set-up); "
                      f"{case['batch_wall_s']:.2f} s batch of which {case['setup_s']:.2f} s "
                      f"set-up, + {case['startup_s']:.2f} s interpreter start; "
                      f"read {case['share_read']:.0%} solve {case['share_solve']:.0%} "
                      f"write {case['share_write']:.0%}", flush=True)
        sample = paths[: min(len(paths), 2000)]
        results["peers"]["bare_loop_json_per_s"] = bare_loop(sample)
        results["peers"]["shell_loop_per_s"] = shell_loop(paths[:8], tmp)
        best = max(c["problems_per_s"] for c in results["cases"] if c["input"] == "json")
        results["peers"]["batch_json_vs_shell_loop"] = \
            best / results["peers"]["shell_loop_per_s"]
        results["peers"]["batch_json_vs_bare_loop"] = \
            best / results["peers"]["bare_loop_json_per_s"]
        print(f"peers: bare library loop {results['peers']['bare_loop_json_per_s']:.0f}/s, "
              f"one process per file {results['peers']['shell_loop_per_s']:.2f}/s; "
              f"batch (JSON, best) is {results['peers']['batch_json_vs_bare_loop']:.2f}x the "
              f"bare loop and {results['peers']['batch_json_vs_shell_loop']:.0f}x the shell "
              f"loop", flush=True)
        for n, c in ((50, 300 if args.quick else 1000), (100, 100 if args.quick else 300)):
            o = overhead_case(n, c, tmp)
            results["overhead"].append(o)
            print(f"n={n:3d}: time outside the method (after set-up) = "
                  f"{o['overhead_ratio']:.2f} x the method time; outside lcpcli.solve = "
                  f"{o['overhead_ratio_vs_solve']:.2f} x",
                  flush=True)
    results["load_average_after"] = os.getloadavg()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"written {out}")


if __name__ == "__main__":
    main()
