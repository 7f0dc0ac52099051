"""A batch under an operator's hands: resources the batch takes whatever it is asked for.

``--jobs`` is a request, not an order: a batch never starts more worker processes than
:data:`lcpcli.batch.pool.MAX_WORKERS_PER_CORE` per core (each is an interpreter with numpy
and the kernels), nor more than it has chunks of work.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np

from lcpcli.batch import pool
from lcpcli.batch.records import SolveOptions
from lcpcli.batch.run import run_batch
from lcpcli.core.problem import Problem
from lcpcli.io import save

ROOT = Path(__file__).resolve().parents[2]


def test_jobs_beyond_the_cores_start_at_most_the_limit(tmp_path, monkeypatch):
    """``-j 12`` on a one-core machine: at most 4 worker processes ever exist, and the
    batch still solves every problem (``-j 100000`` once started a process per problem
    until the machine's memory was gone)."""
    rng = np.random.default_rng(7)
    for i in range(30):
        A = rng.standard_normal((4, 4))
        save(Problem.create(A @ A.T + np.eye(4), rng.standard_normal(4)), tmp_path / f"p{i}.json")
    monkeypatch.setattr(pool, "default_threads", lambda: 1)
    alive: set[int] = set()
    most = [0]
    real_init, real_stop = pool._Worker.__init__, pool._Worker.stop

    def init(self, ctx, opts):  # type: ignore[no-untyped-def]
        real_init(self, ctx, opts)
        alive.add(id(self))
        most[0] = max(most[0], len(alive))

    def stop(self, kill=False):  # type: ignore[no-untyped-def]
        real_stop(self, kill)
        alive.discard(id(self))

    monkeypatch.setattr(pool._Worker, "__init__", init)
    monkeypatch.setattr(pool._Worker, "stop", stop)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = run_batch([str(tmp_path)], SolveOptions(method="lemke"), jobs=12)
    assert report.tally.as_dict()["counts"] == {"solved": 30}
    assert 1 <= most[0] <= pool.MAX_WORKERS_PER_CORE
    assert not alive  # every worker stopped
    assert any("--jobs 12: at most 4 worker processes" in str(w.message) for w in caught)


def test_jobs_within_the_limit_say_nothing(tmp_path):
    save(Problem.create(np.eye(2), -np.ones(2)), tmp_path / "a.json")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = run_batch([str(tmp_path / "a.json")], SolveOptions(), jobs=1)
    assert report.exit_code == 0
    assert not [w for w in caught if "--jobs" in str(w.message)]


def test_a_deleted_current_folder_is_one_line_and_exit_2(tmp_path):
    """Worker processes start in their parent's folder: run from a folder deleted meanwhile
    (a cron job's, a removed build folder), ``--jobs 2`` was an internal error (exit 3:
    multiprocessing's FileNotFoundError); now one line, exit 2.  ``--jobs 1`` needs no
    folder and solves."""
    for name in ("a", "b"):
        save(Problem.create(np.eye(2), -np.ones(2)), tmp_path / f"{name}.json")
    gone = tmp_path / "gone"
    gone.mkdir()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    files = f"{shlex.quote(str(tmp_path / 'a.json'))} {shlex.quote(str(tmp_path / 'b.json'))}"

    def run(jobs: int) -> subprocess.CompletedProcess[str]:
        script = (f"cd {shlex.quote(str(gone))} && rmdir {shlex.quote(str(gone))} && "
                  f"exec {shlex.quote(sys.executable)} -m lcpcli solve {files} -j {jobs} -q")
        gone.mkdir(exist_ok=True)
        return subprocess.run(["sh", "-c", script], env=env, capture_output=True, text=True,
                              timeout=120)

    r = run(2)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith("lcpcli: error: the current folder no longer exists")
    assert len(r.stderr.splitlines()) == 1
    assert run(1).returncode == 0
