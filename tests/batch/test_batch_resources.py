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
import pytest

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


def test_a_stack_solved_one_at_a_time_keeps_each_small_chunk(tmp_path, monkeypatch):
    """A stack whose method has no batched kernel (``-m newton``) goes through the
    one-problem pipeline: its chunks are at most PER_PROBLEM_CHUNK problems, so the progress
    moves and an interruption keeps every finished chunk (one chunk of 58,254 problems of
    n = 12 held all of them: a Ctrl-C after 4 s of 30 kept none, the bar stayed at 0).
    Resumed, the file equals an uninterrupted run's."""
    import h5py

    from lcpcli.batch import stack_output
    from lcpcli.io.stack import write_stack

    monkeypatch.setattr(stack_output, "PER_PROBLEM_CHUNK", 8)
    rng = np.random.default_rng(11)
    K, n = 21, 5
    A = rng.standard_normal((K, n, n))
    write_stack(tmp_path / "s.h5", A @ A.transpose(0, 2, 1) + n * np.eye(n),
                rng.standard_normal((K, n)))
    opts = SolveOptions(method="newton")
    steps: list[int] = []

    def stop_after_first(count: int, counts: dict) -> None:
        steps.append(count)
        raise KeyboardInterrupt

    out = tmp_path / "r.h5"
    with pytest.raises(KeyboardInterrupt):
        run_batch([str(tmp_path / "s.h5")], opts, jobs=1, output=str(out),
                  on_progress=stop_after_first)
    assert steps == [8]
    with h5py.File(out) as f:
        assert int(f["s"].attrs["chunk"]) == 8
        assert (f["s"]["status"][:8] >= 0).all() and (f["s"]["status"][8:] == -1).all()
    report = run_batch([str(tmp_path / "s.h5")], opts, jobs=1, output=str(out), resume=True,
                       on_progress=lambda count, counts: steps.append(count))
    assert report.skipped == 8 and steps == [8, 8, 5]
    whole = tmp_path / "whole.h5"
    run_batch([str(tmp_path / "s.h5")], opts, jobs=1, output=str(whole))
    with h5py.File(out) as a, h5py.File(whole) as b:
        for name in ("z", "w", "status", "iterations", "basis", "chunk_digest"):
            np.testing.assert_array_equal(a["s"][name][...], b["s"][name][...])


def test_a_stack_with_a_batched_kernel_keeps_its_large_chunks(tmp_path):
    from lcpcli.batch import stack_output
    from lcpcli.batch.stacked import one_at_a_time

    assert one_at_a_time("newton") and one_at_a_time("murty")
    assert not one_at_a_time("lemke") and not one_at_a_time("pgs")
    assert not one_at_a_time("auto")  # planned on the first chunk, after the chunk is chosen
    assert stack_output.batch_chunk(12, 2, per_problem=True) == stack_output.PER_PROBLEM_CHUNK
    assert stack_output.batch_chunk(12, 2) > stack_output.PER_PROBLEM_CHUNK


def test_a_stack_of_a_kind_no_batched_kernel_handles_gets_small_chunks(tmp_path, monkeypatch):
    """The kind counts too: an MLCP stack has no batched kernel (every method, auto included,
    solves it one problem at a time), a box stack only the sweeping ones; such stacks got the
    large chunks (the ops audit: Ctrl-C kept nothing of a whole chunk)."""
    import h5py

    from lcpcli.batch import stack_output
    from lcpcli.batch.stacked import one_at_a_time
    from lcpcli.io.stack import write_stack

    assert one_at_a_time("auto", "mlcp") and one_at_a_time("lemke", "mlcp")
    assert one_at_a_time("lemke", "box") and not one_at_a_time("pgs", "box")
    assert not one_at_a_time("auto", "box") and not one_at_a_time("auto", "lcp")
    monkeypatch.setattr(stack_output, "PER_PROBLEM_CHUNK", 8)
    rng = np.random.default_rng(12)
    K, n = 21, 5
    A = rng.standard_normal((K, n, n))
    write_stack(tmp_path / "m.h5", A @ A.transpose(0, 2, 1) + n * np.eye(n),
                rng.standard_normal((K, n)), n_eq=2)
    out = tmp_path / "r.h5"
    run_batch([str(tmp_path / "m.h5")], SolveOptions(method="auto"), jobs=1, output=str(out))
    with h5py.File(out) as f:
        assert int(f["m"].attrs["chunk"]) == 8
        assert (f["m"]["status"][...] == 0).all()
