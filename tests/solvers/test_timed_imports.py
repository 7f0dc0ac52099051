"""``Result.seconds`` never counts an import: nothing is imported while a solve is timed.

Each case runs in a fresh interpreter (the first solve of a process is the one that would pay
the import), with lcpcli.solve's clock wrapped to record the modules loaded between its reads.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = r"""
import json, sys
import numpy as np
import lcpcli
from lcpcli import api

snapshots = []
clock = api.perf_counter
def watched():  # every clock read of lcpcli.solve: the timed region lies between them
    snapshots.append(set(sys.modules))
    return clock()
api.perf_counter = watched

from lcpcli.solvers.methods import auto, lemke
window = set()
timed = auto.timed_imports
def watched_imports(problem, *loaders):  # what a run loads as it goes, timed apart
    before = set(sys.modules)
    seconds = timed(problem, *loaders)
    window.update(set(sys.modules) - before)
    return seconds
auto.timed_imports = lemke.timed_imports = watched_imports

method, warm, sparse, n = sys.argv[1], sys.argv[2] == "warm", sys.argv[3] == "sparse", 80
rng = np.random.default_rng(7)
A = rng.standard_normal((n, n))
M, q = A @ A.T + n * np.eye(n), rng.standard_normal(n)
if sys.argv[3] == "indefinite":  # Lemke fails: auto falls back to methods that factorise
    M = np.random.default_rng(1).standard_normal((n, n))
    q = np.random.default_rng(1).standard_normal((n, n))[0]
if sparse:
    import scipy.sparse as sp
    M = sp.csr_matrix(np.where(np.abs(M) > 2.0, M, 0.0) + n * np.eye(n))
p = lcpcli.Problem.create(M, q)
if warm:
    prev = lcpcli.solve(p, method)
    snapshots.clear()
    res = lcpcli.solve(lcpcli.Problem.create(M, q * 1.01), method, warm=prev)
else:
    res = lcpcli.solve(p, method)
new = sorted(set().union(*snapshots) - snapshots[0] - window) if snapshots else ["clock?"]
print(json.dumps({"status": str(res.status), "method": res.method, "new": new,
                  "window": len(window), "import_seconds": res.info.get("import_seconds", 0.0),
                  "attempts": len(res.info.get("attempts", []))}))
"""


@pytest.mark.parametrize("method,warm,storage", [
    ("bpp", "cold", "dense"), ("ip", "cold", "dense"), ("newton", "cold", "dense"),
    ("newton-min", "cold", "dense"), ("lemke", "cold", "dense"), ("auto", "cold", "dense"),
    ("murty", "cold", "dense"), ("dantzig", "cold", "dense"),
    ("murty", "warm", "dense"), ("dantzig", "warm", "dense"), ("bpp", "warm", "dense"),
    ("auto", "warm", "dense"), ("lemke", "warm", "dense"),
    ("ip", "cold", "sparse"), ("newton", "cold", "sparse"),
])
def test_no_import_while_a_solve_is_timed(method, warm, storage):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", SCRIPT, method, warm, storage],
                         capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["status"] == "solved"
    assert got["new"] == [], f"{method} ({warm}, {storage}) imported {got['new']} while timed"
    assert got["window"] == 0  # only auto's fallback loads anything inside its run


def test_auto_fallback_imports_are_left_out_of_seconds():
    """Lemke fails on this indefinite M: auto's next steps factorise, and what they import
    loads inside auto's preload window, whose time is reported as info["import_seconds"] and
    left out of seconds; nothing else is imported between the clock reads."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", SCRIPT, "auto", "cold", "indefinite"],
                         capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["attempts"] > 1, "the case must make auto fall back"
    assert got["new"] == [], f"auto imported {got['new']} outside its preload window"
    assert got["window"] > 0 and got["import_seconds"] > 0
