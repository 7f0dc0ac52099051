"""`lcpcli solve STACK --scheduler ADDRESS`: chunks of a stack solved as Dask tasks give the
output of the local stacked path (same arrays, same rows), resume by chunk, and survive a
failed task (its chunk is solved by the client)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from lcpcli.batch import cluster
from lcpcli.batch.output import read_rows
from lcpcli.batch.records import SolveOptions
from lcpcli.batch.run import run_batch
from lcpcli.core.result import NOT_DONE
from lcpcli.io.stack import write_stack

distributed = pytest.importorskip("distributed")

CHUNK = 64  # 300 problems: 5 chunks, the last one short
ARRAYS = ("z", "w", "status", "error", "residual", "iterations")


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


@pytest.fixture
def stack(tmp_path, monkeypatch):
    import lcpcli.io.stack

    monkeypatch.setattr(lcpcli.io.stack, "chunk_size", lambda n, **_: CHUNK)
    M, q = pd_stack(300, 6)
    M[7] = 0.0  # no solution (Farkas): a verdict other than solved travels too
    q[7] = -1.0
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    return path


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=2,
                                  dashboard_address=":0") as lc, distributed.Client(lc) as c:
        yield c


def arrays(path) -> dict[str, np.ndarray]:
    with h5py.File(path) as f:
        return {k: f["s"][k][...] for k in ARRAYS if k in f["s"]}


def same_arrays(a, b) -> None:
    assert set(a) == set(b) and {"z", "status"} <= set(a)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def solve(path, out, **kw):
    return run_batch([str(path)], SolveOptions("auto", None, {}), output=out, jobs=2, **kw)


def test_dask_stack_equals_local(stack, tmp_path, client):
    local = solve(stack, tmp_path / "local.h5")
    counts = []
    with distributed.get_task_stream(client) as tasks:
        rep = solve(stack, tmp_path / "dask.h5", scheduler=client,
                    on_progress=lambda n, c: counts.append(n))
    assert rep.new == local.new == 300
    assert dict(rep.tally.counts) == dict(local.tally.counts) == {"solved": 299,
                                                                  "no_solution": 1}
    assert counts == [CHUNK] * 4 + [300 - 4 * CHUNK]  # progress per chunk, in stack order
    same_arrays(arrays(tmp_path / "dask.h5"), arrays(tmp_path / "local.h5"))
    ran = [t["key"] for t in tasks.data if "stack_chunk_task" in str(t["key"])]
    assert len(ran) == 5  # every chunk was a task on a worker


def test_dask_stack_rows_equal_local(stack, tmp_path, client):
    solve(stack, tmp_path / "local.jsonl")
    solve(stack, tmp_path / "dask.jsonl", scheduler=client)

    def strip(rows):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]

    assert strip(read_rows(tmp_path / "dask.jsonl")) == strip(read_rows(tmp_path / "local.jsonl"))


def test_dask_stack_resume_by_chunk(stack, tmp_path, client):
    out = tmp_path / "r.h5"
    solve(stack, out, scheduler=client)
    full = arrays(out)
    with h5py.File(out, "a") as f:
        f["s"]["status"][150:] = NOT_DONE
    rep = solve(stack, out, scheduler=client, resume=True)
    assert (rep.skipped, rep.new) == (150, 150)
    same_arrays(arrays(out), full)


def test_failed_task_is_solved_by_the_client(stack, tmp_path, client, monkeypatch):
    real = cluster.stack_chunk_task

    def flaky(path, info, start, *args):
        if start == CHUNK:
            raise OSError("worker lost")
        return real(path, info, start, *args)

    monkeypatch.setattr(cluster, "stack_chunk_task", flaky)
    solve(stack, tmp_path / "local.h5")
    rep = solve(stack, tmp_path / "dask.h5", scheduler=client)
    assert rep.new == 300
    same_arrays(arrays(tmp_path / "dask.h5"), arrays(tmp_path / "local.h5"))


def test_cli_stack_on_a_cluster(cli, tmp_path):
    """The command a user runs, against a scheduler reached over TCP."""
    path = tmp_path / "s.h5"
    write_stack(path, *pd_stack(40, 5, seed=3))
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1,
                                  protocol="tcp", dashboard_address=":0") as lc:
        res = cli("solve", str(path), "-o", str(tmp_path / "d.h5"), "--json",
                  "--scheduler", lc.scheduler_address)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[-1])["summary"]["counts"] == {"solved": 40}
    res = cli("solve", str(path), "-o", str(tmp_path / "l.h5"), "--json")
    assert res.returncode == 0, res.stderr
    same_arrays(arrays(tmp_path / "d.h5"), arrays(tmp_path / "l.h5"))
