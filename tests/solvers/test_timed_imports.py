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

method, warm, sparse, n = sys.argv[1], sys.argv[2] == "warm", sys.argv[3] == "sparse", 80
rng = np.random.default_rng(7)
A = rng.standard_normal((n, n))
M, q = A @ A.T + n * np.eye(n), rng.standard_normal(n)
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
new = sorted(set().union(*snapshots) - snapshots[0]) if snapshots else ["no clock read"]
print(json.dumps({"status": str(res.status), "method": res.method, "new": new}))
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
