"""`lcpcli solve STACK`: stacked inputs solved chunk by chunk, stacked and row outputs, resume."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.api import solve_many
from lcpcli.batch.output import read_rows
from lcpcli.core.result import NOT_DONE, STATUS_CODES
from lcpcli.io.stack import write_stack


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


@pytest.fixture
def stack(tmp_path):
    M, q = pd_stack(300, 6)
    M[7] = 0.0  # M = 0, q with a negative entry: no solution (Farkas)
    q[7] = -1.0
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    return path, M, q


def summary(res) -> dict:
    return json.loads(res.stdout.splitlines()[-1])


def test_stack_to_stacked_hdf5_results(cli, stack, tmp_path):
    path, M, q = stack
    out = tmp_path / "r.h5"
    res = cli("solve", str(path), "-o", str(out), "--json", "-j", "2")
    assert res.returncode == 1, res.stderr  # one problem has no solution
    s = summary(res)
    assert s["summary"]["counts"] == {"no_solution": 1, "solved": 299}
    ref = solve_many(M, q)
    with h5py.File(out) as f:
        g = f["s"]
        assert g.attrs["source"] == str(path) and g.attrs["K"] == 300
        assert g["z"].shape == (300, 6) and g["status"].dtype == np.int8
        np.testing.assert_allclose(g["z"][...], ref.z, atol=1e-12)
        np.testing.assert_array_equal(g["status"][...], ref.status)
        assert g["status"][7] == STATUS_CODES["no_solution"]
        assert np.all(g["error"][...][ref.solved] <= 1e-8)
        assert json.loads(g.attrs["status_codes"])["solved"] == 0


def test_stack_rows_stream_and_row_files(cli, stack, tmp_path):
    path, M, q = stack
    res = cli("solve", str(path), "--json")
    rows = [json.loads(line) for line in res.stdout.splitlines()]
    assert len(rows) == 300
    assert rows[7]["status"] == "no_solution" and rows[7]["index"] == 7
    assert rows[0]["problem"] == "s[0]" and rows[0]["source"] == str(path)
    for ext in ("jsonl", "csv"):
        out = tmp_path / f"r.{ext}"
        res = cli("solve", str(path), "-o", str(out), "--json")
        assert res.returncode == 1
        got = read_rows(out)
        assert sorted(r["index"] for r in got) == list(range(300))


def test_npz_results_and_resume(cli, stack, tmp_path):
    path, M, q = stack
    out = tmp_path / "r.npz"
    assert cli("solve", str(path), "-o", str(out), "--json").returncode == 1
    with np.load(out) as d:
        status = d["status"].copy()
        arrays = {k: d[k].copy() for k in d.files}
    assert (status != NOT_DONE).all()
    # as if interrupted: the last 100 not done yet
    arrays["status"][200:] = NOT_DONE
    arrays["z"][200:] = np.nan
    np.savez(out, **arrays)
    res = cli("solve", str(path), "-o", str(out), "--json", "--resume")
    s = summary(res)
    assert s["skipped"] == 200 and s["new"] == 100
    assert s["summary"]["counts"] == {"no_solution": 1, "solved": 299}
    with np.load(out) as d:
        np.testing.assert_array_equal(d["status"], status)
        assert np.isfinite(d["z"]).all()


def test_hdf5_resume_by_chunk(cli, stack, tmp_path):
    path, M, q = stack
    out = tmp_path / "r.h5"
    cli("solve", str(path), "-o", str(out), "--json")
    with h5py.File(out, "a") as f:
        f["s"]["status"][150:] = NOT_DONE
    res = cli("solve", str(path), "-o", str(out), "--json", "--resume")
    s = summary(res)
    assert (s["skipped"], s["new"]) == (150, 150)
    assert s["summary"]["counts"]["solved"] == 299
    with h5py.File(out) as f:
        assert (f["s"]["status"][...] != NOT_DONE).all()


def test_jsonl_resume(cli, stack, tmp_path):
    path, M, q = stack
    out = tmp_path / "r.jsonl"
    cli("solve", str(path), "-o", str(out), "--json")
    lines = out.read_text().splitlines()
    out.write_text("\n".join(lines[:120]) + "\n" + lines[120][:30])  # a torn last line
    res = cli("solve", str(path), "-o", str(out), "--json", "--resume")
    s = summary(res)
    assert (s["skipped"], s["new"]) == (120, 180)
    assert sorted(r["index"] for r in read_rows(out)) == list(range(300))


def test_nan_problem_is_an_error_row_and_the_rest_is_solved(cli, tmp_path):
    M, q = pd_stack(20, 4)
    M[3, 0, 0] = np.nan
    path = tmp_path / "bad.h5"
    write_stack(path, M, q)
    res = cli("solve", str(path), "--json", "-o", str(tmp_path / "r.h5"))
    assert res.returncode == 2
    s = summary(res)
    assert s["summary"]["counts"] == {"error": 1, "solved": 19}
    assert "NaN" in s["summary"]["errors"][0]["message"]


def test_error_rows_of_a_stack_have_the_documented_shape(cli, tmp_path):
    """docs/batch.md: a row without a solution has n null and empty z and w; a stacked
    input's error row had z = w = [null, null, null, null]."""
    M, q = pd_stack(6, 4)
    M[1, 0, 0] = np.nan
    path = tmp_path / "bad.h5"
    write_stack(path, M, q)
    res = cli("solve", str(path), "--json")
    rows = {r["index"]: r for r in map(json.loads, res.stdout.splitlines())}
    assert rows[1]["status"] == "error" and rows[1]["n"] is None
    assert rows[1]["z"] == [] and rows[1]["w"] == [] and rows[1]["basis"] is None
    assert rows[0]["status"] == "solved" and len(rows[0]["z"]) == 4


@pytest.mark.parametrize("bad,message", [("nan", "upper contains NaN"),
                                         ("crossed", "lower > upper")])
def test_a_bad_per_problem_bound_is_an_error_row_and_the_rest_is_solved(cli, tmp_path, bad,
                                                                        message):
    """Per-problem bounds (K, n) are problem data: one problem's NaN bound or crossed bounds
    refuse that problem alone, as a NaN in its M does (the whole stack ended in one line,
    exit 2, no result file)."""
    M, q = pd_stack(20, 4)
    lower, upper = np.zeros((20, 4)), np.ones((20, 4))
    if bad == "nan":
        upper[5, 2] = np.nan
    else:
        lower[5, 1] = 2.0
    path = tmp_path / "box.h5"
    write_stack(path, M, q, lower=lower, upper=upper)
    out = tmp_path / "r.h5"
    res = cli("solve", str(path), "--json", "-o", str(out))
    assert res.returncode == 2
    s = summary(res)
    assert s["summary"]["counts"] == {"error": 1, "solved": 19}
    assert message in s["summary"]["errors"][0]["message"]
    with h5py.File(out) as f:
        group = f[next(iter(f))]
        status = group["status"][:]
    assert status[5] == STATUS_CODES["error"] and (np.delete(status, 5) == 0).all()


@pytest.mark.parametrize("extra,match", [
    (["--timeout", "5"], "--timeout"),
    # --scheduler applies to stacks (tests/batch/test_dask_stacks.py): here none listens
    (["--scheduler", "tcp://localhost:1"], "cannot reach the Dask scheduler"),
])
def test_options_that_do_not_apply_to_stacks(cli, stack, extra, match):
    res = cli("solve", str(stack[0]), *extra)
    assert res.returncode == 2
    assert match in res.stderr and len(res.stderr.strip().splitlines()) == 1


def test_mixed_inputs_and_npz_outputs_refused(cli, stack, tmp_path, samples):
    path = stack[0]
    res = cli("solve", str(path), str(samples / "seed004.json"))
    assert res.returncode == 2 and "stacked" in res.stderr
    other = tmp_path / "t.npz"
    write_stack(other, *pd_stack(3, 6))
    res = cli("solve", str(path), str(other), "-o", str(tmp_path / "r.npz"))
    assert res.returncode == 2 and "one stack" in res.stderr
    res = cli("solve", str(samples / "seed004.json"), "-o", str(tmp_path / "r2.npz"))
    assert res.returncode == 2 and "stacked inputs only" in res.stderr
    assert not (tmp_path / "r2.npz").exists()


def test_two_stacks_into_one_hdf5_file(cli, stack, tmp_path):
    path = stack[0]
    other = tmp_path / "t.npz"
    write_stack(other, *pd_stack(3, 5), names=["a", "b", "c"])
    out = tmp_path / "r.h5"
    res = cli("solve", str(path), str(other), "-o", str(out), "--json", "-m", "lemke")
    assert summary(res)["summary"]["counts"] == {"no_solution": 1, "solved": 302}
    with h5py.File(out) as f:
        assert sorted(f) == ["s", "t"]
        assert [x.decode() for x in f["t"]["names"][...]] == ["a", "b", "c"]
        assert f["t"]["z"].shape == (3, 5)


def test_methods_without_a_batched_kernel_still_work(cli, tmp_path):
    path = tmp_path / "s.h5"
    write_stack(path, *pd_stack(5, 4))
    res = cli("solve", str(path), "-m", "newton", "--json", "-o", str(tmp_path / "r.h5"))
    assert res.returncode == 0, res.stderr
    assert summary(res)["summary"]["counts"] == {"solved": 5}


def test_progress_bar_only_on_a_terminal_and_never_with_no_color(cli, stack):
    path = str(stack[0])
    shown = cli("solve", path, env={"FORCE_TERMINAL": "1", "NO_COLOR": ""})
    assert "solving" in shown.stderr
    for env in ({"FORCE_TERMINAL": "1", "NO_COLOR": "1"}, {"FORCE_TERMINAL": "0"}):
        res = cli("solve", path, env=env)
        assert "solving" not in res.stderr, env


def test_hdf5_results_survive_kill_9_and_resume(cli, stack, tmp_path):
    """A writer killed (os._exit, no close) after one chunk and in the middle of the next
    leaves a readable results.h5; --resume solves what its status does not mark done."""
    import subprocess
    import sys

    path, M, q = stack
    out = tmp_path / "r.h5"
    code = f"""
import os
import numpy as np
from pathlib import Path
from lcpcli.api import solve_many
from lcpcli.batch.records import SolveOptions
from lcpcli.batch.stack_output import Hdf5StackWriter, chunk_digest, options_fingerprint
from lcpcli.io.stack import stack_info, open_stack

info = stack_info({str(path)!r})
opts = options_fingerprint(SolveOptions("auto", None, {{}}))
w = Hdf5StackWriter(Path({str(out)!r}), [info], resume=False, options=opts)
with open_stack(info.path) as r:
    digest = chunk_digest(r.read(0, min(info.K, w.chunk(info))), w.algorithm(info))
    part = r.read(0, 100)
res = solve_many(part.M, part.q, on_error="mark")
w.write(info, np.arange(100), None, res, None, 0, digest)
w.groups[info.path]["z"][100:200] = 7.0  # the next chunk, cut before its status
os._exit(9)
"""
    subprocess.run([sys.executable, "-c", code], check=False)
    with h5py.File(out) as f:
        assert (f["s"]["status"][...] != NOT_DONE).sum() == 100
    res = cli("solve", str(path), "-o", str(out), "--json", "--resume")
    s = summary(res)
    assert (s["skipped"], s["new"]) == (100, 200)
    with h5py.File(out) as f:
        np.testing.assert_allclose(f["s"]["z"][...], solve_many(M, q).z, atol=1e-12)


def test_problem_picks_one_stacked_problem(cli, tmp_path):
    M, q = pd_stack(4, 3, seed=5)
    for ext in ("h5", "npz"):
        path = tmp_path / f"named.{ext}"
        write_stack(path, M, q, names=["a", "b", "", "d"])
        for pick, k in (("b", 1), ("named[2]", 2), ("3", 3)):
            res = cli("solve", str(path), "--problem", pick, "--json")
            assert res.returncode == 0, res.stderr
            row = json.loads(res.stdout)
            np.testing.assert_allclose(row["z"], solve_many(M, q).z[k], atol=1e-12)
        res = cli("solve", str(path), "--problem", "zz")
        assert res.returncode == 2 and "no problem named 'zz'" in res.stderr


def test_reader_thread_keeps_order_forwards_errors_and_stops_with_the_consumer():
    """The read-ahead of the stacked path (batch.stacked._prefetched): items arrive in order,
    an exception of the reader arrives after the items made before it, and a consumer that
    stops early stops and joins the reader thread (no read outlives the batch)."""
    import threading

    from lcpcli.batch.stacked import _prefetched
    from lcpcli.core.errors import ProblemError

    def items(stop, fail_at=None, made=None):
        for i in range(50):
            if i == fail_at:
                raise ProblemError("damaged chunk")
            if made is not None:
                made.append(i)
            yield i

    assert list(_prefetched(lambda stop: items(stop), depth=1)) == list(range(50))
    got = []
    with pytest.raises(ProblemError, match="damaged chunk"):
        for i in _prefetched(lambda stop: items(stop, fail_at=7), depth=2):
            got.append(i)
    assert got == list(range(7))
    made: list[int] = []
    before = threading.active_count()
    parts = _prefetched(lambda stop: items(stop, made=made), depth=1)
    assert [next(parts), next(parts)] == [0, 1]
    parts.close()
    assert threading.active_count() == before  # the reader thread has ended
    assert len(made) <= 2 + 2  # it read at most the queue's depth ahead, plus one in hand


def test_pipelined_stack_equals_solve_many_chunk_by_chunk(tmp_path, monkeypatch):
    """Reading in a thread beside the solver changes no result: many chunks, every array of
    the result file equals solve_many's on the whole stack, and the digests equal those of
    the chunks read alone."""
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.batch.stack_output import chunk_digest
    from lcpcli.io.stack import open_stack

    M, q = pd_stack(1000, 5, seed=4)
    path, out = tmp_path / "s.h5", tmp_path / "r.h5"
    write_stack(path, M, q)
    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 96)
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    ref = solve_many(M, q, "lemke")
    with h5py.File(out, "r") as f:
        g = f["s"]
        np.testing.assert_array_equal(g["z"][...], ref.z)
        np.testing.assert_array_equal(g["status"][...], ref.status)
        np.testing.assert_array_equal(g["iterations"][...], ref.iterations)
        digests = g["chunk_digest"][...]
        assert g.attrs["digest"] == "mxs128"  # a new file's
    with open_stack(path) as reader:
        for c in range(digests.shape[0]):
            part = reader.read(c * 96, min(1000, (c + 1) * 96))
            assert bytes(digests[c]) == chunk_digest(part, "mxs128")


@settings(max_examples=200, deadline=None)
@given(n=st.integers(0, 3000), threads=st.integers(1, 256))
def test_batch_chunk_gives_every_thread_work_within_the_memory_cap(n, threads):
    """Chunks of a stacked batch come from n and the thread count: at least chunk_size(n)
    for BATCH_CHUNK_BYTES of M, PER_THREAD problems per thread where M then stays within
    MAX_CHUNK_BYTES, and never more than both."""
    from lcpcli.batch.stack_output import (
        BATCH_CHUNK_BYTES,
        MAX_CHUNK_BYTES,
        PER_THREAD,
        batch_chunk,
    )
    from lcpcli.io.stack import chunk_size

    c, per = batch_chunk(n, threads), max(8, 8 * n * n)
    base = chunk_size(n, budget_bytes=BATCH_CHUNK_BYTES)
    assert c >= base >= 1
    assert c >= PER_THREAD * threads or c * per > MAX_CHUNK_BYTES - per
    assert c == base or c * per <= MAX_CHUNK_BYTES


def test_resume_with_other_jobs_uses_the_recorded_chunk(tmp_path, monkeypatch):
    """A result file records its chunk: resumed with another --jobs (another batch_chunk), the
    finished chunks are kept, the others solved, and the file ends equal to a run in one go."""
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch

    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 4)  # batch_chunk: 16 per thread
    M, q = pd_stack(300, 5, seed=5)
    path, out, ref = tmp_path / "s.h5", tmp_path / "r.h5", tmp_path / "ref.h5"
    write_stack(path, M, q)
    opts = SolveOptions(method="lemke")
    run_batch([str(path)], opts, output=ref, jobs=1)
    run_batch([str(path)], opts, output=out, jobs=1)
    with h5py.File(out, "r+") as f:
        assert int(f["s"].attrs["chunk"]) == 16
        f["s"]["status"][100:] = NOT_DONE  # as if stopped after problem 99
        f["s"]["chunk_digest"][7:] = 0
    report = run_batch([str(path)], opts, output=out, jobs=8, resume=True)  # batch_chunk 128
    assert report.skipped == 100 and report.new == 200
    with h5py.File(out, "r") as f, h5py.File(ref, "r") as g:
        assert int(f["s"].attrs["chunk"]) == 16
        for key in ("z", "status", "chunk_digest"):
            np.testing.assert_array_equal(f["s"][key][...], g["s"][key][...])


def test_writer_thread_writes_in_order_and_hands_errors_to_the_main_thread():
    """The writes of a stacked batch run in a thread of their own (batch.stacked._WriteBehind):
    in the order handed over, each finished before close() returns; the first failing write
    is raised in the main thread (by the next submit or by close) and no later write runs."""
    import threading
    import time

    from lcpcli.batch.stacked import _WriteBehind
    from lcpcli.core.errors import OutputError

    done: list[int] = []
    threads: set[str] = set()

    def write(fn):
        threads.add(threading.current_thread().name)
        fn()

    def slow(i):
        def fn():
            time.sleep(0.002 * (i % 3))
            done.append(i)
        return fn

    writes = _WriteBehind(write)
    for i in range(20):
        writes.submit(slow(i))
    writes.close()
    assert done == list(range(20))
    assert threads == {"lcpcli-stack-writer"} and not writes.thread.is_alive()

    done.clear()
    writes = _WriteBehind(write)

    def full_disk():
        raise OutputError("r.h5", "no space left on device")

    writes.submit(slow(0))
    writes.submit(full_disk)
    with pytest.raises(OutputError, match="no space left"):
        try:
            for i in range(1, 50):
                writes.submit(slow(i))
                time.sleep(0.001)
        finally:
            writes.close()  # as the batch does: the error is raised once, by submit here
    assert done == [0] and not writes.thread.is_alive()


def test_reading_into_given_buffers_equals_a_fresh_read(tmp_path):
    """StackReader.read(start, stop, out=(M, q)) fills the leading rows of the buffers a batch
    reuses from chunk to chunk: the chunk equals a read into new arrays, for every range and
    both formats; buffers that cannot hold the chunk as C-contiguous float64 are refused."""
    from lcpcli.io.stack import open_stack

    M, q = pd_stack(37, 4, seed=9)
    for ext in ("h5", "npz"):
        path = tmp_path / f"s.{ext}"
        write_stack(path, M, q)
        bufs = (np.full((10, 4, 4), np.nan), np.full((10, 4), np.nan))
        with open_stack(path) as reader:
            for start in range(0, 37, 10):
                stop = min(37, start + 10)
                got, fresh = reader.read(start, stop, bufs), reader.read(start, stop)
                np.testing.assert_array_equal(got.M, fresh.M)
                np.testing.assert_array_equal(got.q, fresh.q)
                assert got.M.base is bufs[0] or got.M is bufs[0]
            with pytest.raises(ValueError, match="do not hold"):
                reader.read(0, 11, bufs)
            with pytest.raises(ValueError, match="do not hold"):
                reader.read(0, 5, (np.empty((10, 4, 4), np.float32), bufs[1]))


def test_output_that_cannot_be_made_stops_the_early_reader(tmp_path, monkeypatch):
    """A batch that resumes nothing starts reading before its output file exists (the file
    is made once the first chunk is read, while it is solved); when making that file fails,
    the error is the batch's and no reader thread is left running."""
    import threading

    import lcpcli.batch.stack_output as stack_output
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.core.errors import OutputError

    M, q = pd_stack(500, 5, seed=2)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)

    running: list[str] = []

    def fail(*args, **kwargs):
        running.extend(t.name for t in threading.enumerate())
        raise OutputError("r.h5", "no space left on device")

    monkeypatch.setattr(stack_output, "open_stack_writer", fail)
    with pytest.raises(OutputError, match="no space left"):
        run_batch([str(path)], SolveOptions(method="lemke"), output=tmp_path / "r.h5", jobs=2)
    assert "lcpcli-stack-opener" in running  # made in its thread, after the first read
    assert not [t for t in threading.enumerate() if t.name.startswith("lcpcli-stack")]


def test_output_file_is_made_while_the_first_chunk_is_solved(tmp_path, monkeypatch):
    """Resuming nothing, the result file is made in a thread: the first chunk is solved
    before a slow making of the file ends, and the file ends equal to solve_many's results
    with a digest per chunk."""
    import threading
    import time

    import lcpcli.batch.stack_output as stack_output
    import lcpcli.batch.stacked as stacked
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch

    M, q = pd_stack(400, 5, seed=6)
    path, out = tmp_path / "s.h5", tmp_path / "r.h5"
    write_stack(path, M, q)
    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 100)
    events: list[str] = []
    made = threading.Event()
    real_open, real_solve = stack_output.open_stack_writer, stacked.solve_read

    def slow_open(*args, **kwargs):
        time.sleep(0.5)
        writer = real_open(*args, **kwargs)
        events.append("made")
        made.set()
        return writer

    def solve(*args, **kwargs):
        if not made.is_set():
            events.append("solved before the file was made")
        return real_solve(*args, **kwargs)

    monkeypatch.setattr(stack_output, "open_stack_writer", slow_open)
    monkeypatch.setattr(stacked, "solve_read", solve)
    report = run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    assert report.new == 400 and events[0] == "solved before the file was made"
    ref = solve_many(M, q, "lemke")
    with h5py.File(out, "r") as f:
        g = f["s"]
        np.testing.assert_array_equal(g["z"][...], ref.z)
        np.testing.assert_array_equal(g["status"][...], ref.status)
        assert int(g.attrs["chunk"]) == 100 and g["chunk_digest"][...].any(axis=1).all()


def test_first_chunks_are_read_while_the_method_is_looked_up(tmp_path, monkeypatch):
    """A batch that resumes nothing starts reading its first stack with the batch, before
    the method is looked up (EarlyReads): that one reader thread then serves the whole stack
    and the results equal solve_many's; with an unknown method the batch fails as before and
    leaves no reader running; reads that do not fit the batch (another chunk) are not
    taken."""
    import threading

    import lcpcli.io.stack as stack_mod
    import lcpcli.solvers.request as request
    from lcpcli.batch import stacked
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.core.errors import OptionError
    from lcpcli.io.stack import stack_info

    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 64)
    M, q = pd_stack(300, 5, seed=12)
    path, out = tmp_path / "s.h5", tmp_path / "r.h5"
    write_stack(path, M, q)
    read, looked_up = threading.Event(), []
    read_part, method_of = stacked.read_part, request.method_of
    starts: list[int] = []

    def reading(reader, start, stop, **kw):
        starts.append(start)
        read.set()
        return read_part(reader, start, stop, **kw)

    def looking_up(name):
        looked_up.append(read.wait(10))  # the first chunk was read meanwhile
        return method_of(name)

    monkeypatch.setattr(stacked, "read_part", reading)
    monkeypatch.setattr(request, "method_of", looking_up)
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    assert looked_up[0] is True
    assert starts == list(range(0, 300, 64))  # one reader, each chunk read once
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["s"]["z"][...], solve_many(M, q, "lemke").z)
    with pytest.raises(OptionError):
        run_batch([str(path)], SolveOptions(method="no-such-method"), output=out, jobs=2)
    assert not [t for t in threading.enumerate() if t.name.startswith("lcpcli-stack")]
    early = stacked.early_reads([str(path)], out, 2, None)
    info = stack_info(path)
    assert early.take(info, 63, "mxs128") is None  # another chunk: read again
    assert early.take(info, 64, "sha256") is None
    assert early.take(info, 64, "mxs128") is not None
    assert early.take(info, 64, "mxs128") is None  # taken once
    early.close()
    assert stacked.early_reads([str(tmp_path / "p.json")], out, 2, None) is None


@pytest.mark.parametrize("ext", ["h5", "jsonl"])
def test_interrupted_stacked_batch_keeps_its_finished_chunks_and_resumes(tmp_path, monkeypatch,
                                                                         ext):
    """Ctrl-C in the middle of a stacked batch (raised in the main thread after the third
    chunk was solved, its write possibly still running in the writer thread): every chunk
    handed to the writer is written whole before the file closes, and --resume ends with
    the results of a run in one go."""
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch

    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 50)
    M, q = pd_stack(500, 4, seed=8)
    path, out, ref = tmp_path / "s.h5", tmp_path / f"r.{ext}", tmp_path / f"ref.{ext}"
    write_stack(path, M, q)
    opts = SolveOptions(method="lemke")
    run_batch([str(path)], opts, output=ref, jobs=2)
    seen = []

    def stop_after_three(count, counts):
        seen.append(count)
        if len(seen) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch([str(path)], opts, output=out, jobs=2, on_progress=stop_after_three)
    report = run_batch([str(path)], opts, output=out, jobs=2, resume=True)
    assert report.skipped >= 150 and report.skipped + report.new == 500
    if ext == "h5":
        with h5py.File(out, "r") as f, h5py.File(ref, "r") as g:
            for key in ("z", "status", "chunk_digest", "basis"):
                np.testing.assert_array_equal(f["s"][key][...], g["s"][key][...])
    else:
        def by_index(p):
            return {r["index"]: (r["z"], r["status"], r["input_hash"]) for r in read_rows(p)}
        assert by_index(out) == by_index(ref)


def test_each_write_is_handed_over_after_its_tally_and_before_the_next_solve(tmp_path,
                                                                             monkeypatch):
    """The main thread hands chunk k's write to the writer thread once its own work on chunk
    k is done (the tally) and right before chunk k + 1 is solved, the last chunk's at once:
    the writer never runs beside the main thread's work between two solves.  Writes stay in
    order and the results equal solve_many's; a read that fails after a chunk was solved
    still leaves that chunk written (status and digest recorded), the later ones not."""
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch import stacked
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.core.errors import ProblemError

    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 70)
    M, q = pd_stack(300, 4, seed=11)  # chunks of 70: 4 full, the last of 20
    path, out = tmp_path / "s.h5", tmp_path / "r.h5"
    write_stack(path, M, q)
    events: list[tuple[str, int]] = []
    solve_read, tally, submit = stacked.solve_read, stacked.add_to_tally, \
        stacked._WriteBehind.submit

    def solving(part, *a, **kw):
        events.append(("solve", part.start // 70))
        return solve_read(part, *a, **kw)

    def tallying(tally_, source, stem, positions, *a):
        events.append(("tally", int(positions[0]) // 70))
        return tally(tally_, source, stem, positions, *a)

    def submitting(self, fn):
        events.append(("submit", fn.__defaults__[4]))  # its chunk_no
        return submit(self, fn)

    monkeypatch.setattr(stacked, "solve_read", solving)
    monkeypatch.setattr(stacked, "add_to_tally", tallying)
    monkeypatch.setattr(stacked._WriteBehind, "submit", submitting)
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    want = [e for c in range(4) for e in (("solve", c), ("tally", c), ("submit", c))]
    assert events == want + [("solve", 4), ("submit", 4), ("tally", 4)]
    ref = solve_many(M, q, "lemke")
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["s"]["z"][...], ref.z)
        np.testing.assert_array_equal(f["s"]["status"][...], ref.status)
        assert f["s"]["chunk_digest"][...].any(axis=1).all()

    read_part = stacked.read_part

    def failing(reader, start, stop, **kw):
        if start >= 140:
            raise ProblemError("the disk went away")
        return read_part(reader, start, stop, **kw)

    monkeypatch.setattr(stacked, "read_part", failing)
    with pytest.raises(ProblemError, match="disk went away"):
        run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    with h5py.File(out, "r") as f:
        status, digests = f["s"]["status"][...], f["s"]["chunk_digest"][...]
    np.testing.assert_array_equal(status[:140], ref.status[:140])
    assert (status[140:] == NOT_DONE).all()
    assert digests[:2].any(axis=1).all() and not digests[2:].any()


@settings(max_examples=300, deadline=None)
@given(values=st.lists(st.sampled_from([0.0, 1.0, 2.5, -1.0, float("inf"), -float("inf")])
                       | st.floats(allow_nan=False), max_size=120),
       k=st.integers(0, 8))
def test_worst_of_a_chunk_equals_a_stable_sort(values, k):
    """The tally's worst errors of a chunk (a partition, not a full sort) are the first k of
    the stable descending sort, ties in position order."""
    from lcpcli.batch.stacked import _largest_first

    v = np.asarray(values, dtype=float)
    assert np.array_equal(_largest_first(v, k), np.argsort(-v, kind="stable")[:k])


@settings(max_examples=300, deadline=None)
@given(n=st.integers(0, 3000), threads=st.integers(1, 64), K=st.integers(1, 10**7))
def test_storage_chunks_of_results_fit_the_batch_chunks(n, threads, K):
    """The HDF5 storage chunk of z, w, status, ... divides the batch chunk (each chunk's write
    covers whole storage chunks) where a divisor within a factor 2 of the size cap exists,
    never exceeds K or twice the cap, and is at least one row."""
    from lcpcli.batch.stack_output import STORAGE_BYTES, batch_chunk, storage_rows

    chunk = batch_chunk(n, threads)
    rows = storage_rows(chunk, K, n)
    assert 1 <= rows <= K
    assert rows * 8 * max(n, 1) <= 2 * STORAGE_BYTES or rows == 1
    if chunk * 8 * max(n, 1) <= STORAGE_BYTES:
        assert rows == min(K, chunk)  # one storage chunk per batch chunk


def test_chunk_buffers_come_from_the_memory_pool(tmp_path, monkeypatch):
    """A large stack's two chunk buffers are the blocks that the memory pool faulted in
    ahead (here with chunks of 4 KiB of M); the results equal solve_many's; a block too
    small, or none left, leaves the allocation to the caller.  (Chunks copied: rows read in
    place, lcpcli.io.stack.mapped, need no buffer.)"""
    from lcpcli.batch import stack_output, stacked
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.io.stack import mapped

    monkeypatch.setattr(mapped, "MAP_STACKS", False)
    monkeypatch.setattr(stack_output, "BATCH_CHUNK_BYTES", 4096)
    M, q = pd_stack(1000, 5, seed=6)
    path, out = tmp_path / "s.h5", tmp_path / "r.h5"
    write_stack(path, M, q)
    given: list[int] = []
    take = stacked.MemoryPool.take

    def counted(self, nbytes):
        block = take(self, nbytes)
        if block is not None:
            given.append(block.nbytes)
        return block

    monkeypatch.setattr(stacked.MemoryPool, "take", counted)
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=1)  # 20 a chunk
    assert given == [4096, 4096]
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["s"]["z"][...], solve_many(M, q, "lemke").z)
    pool = stacked.MemoryPool(1, 64)
    assert pool.take(65) is None
    block = pool.take(64)
    assert block is not None and block.nbytes == 64 and not block.any()
    assert pool.take(8) is None
    assert stacked.memory_pool([str(tmp_path / "small.json")]) is None


def test_the_cli_lets_idle_threads_sleep_unless_told_otherwise(monkeypatch, capsys):
    """``lcpcli`` sets OMP_WAIT_POLICY and OPENBLAS_THREAD_TIMEOUT for what it loads (idle
    OpenMP and OpenBLAS threads sleep instead of spinning beside a stacked batch's reader and
    writer), and keeps a value the user set."""
    import os

    from lcpcli.cli import QUIET_THREADS, main

    monkeypatch.delenv("OMP_WAIT_POLICY", raising=False)
    monkeypatch.setenv("OPENBLAS_THREAD_TIMEOUT", "9")
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert os.environ["OMP_WAIT_POLICY"] == QUIET_THREADS["OMP_WAIT_POLICY"] == "PASSIVE"
    assert os.environ["OPENBLAS_THREAD_TIMEOUT"] == "9"


def _small_npz_results(cli, tmp_path):
    """A stack of K = 12, n = 3 and its finished .npz results."""
    M, q = pd_stack(12, 3)
    path = tmp_path / "small.h5"
    write_stack(path, M, q)
    out = tmp_path / "R.npz"
    assert cli("solve", str(path), "-o", str(out), "--json").returncode == 0
    with np.load(out) as d:
        arrays = {k: d[k].copy() for k in d.files}
    return path, out, arrays


def _rezip(out, members: dict[str, bytes], compression: int) -> None:
    import zipfile

    with zipfile.ZipFile(out, "w", compression) as zf:
        for key, data in members.items():
            zf.writestr(f"{key}.npy", data)


def _npy(value) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.asanyarray(value), allow_pickle=False)
    return buf.getvalue()


def _refused_resume(cli, path, out, match):
    before = out.read_bytes()
    res = cli("solve", str(path), "-o", str(out), "--json", "--resume")
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"lcpcli: error: {out}: cannot be resumed")
    assert match in lines[0], lines[0]
    assert out.read_bytes() == before  # untouched


@pytest.mark.parametrize("compression", ["deflate", "lzma"])
def test_npz_resume_refuses_a_damaged_compressed_member(cli, tmp_path, compression):
    import zipfile

    path, out, arrays = _small_npz_results(cli, tmp_path)
    method = {"deflate": zipfile.ZIP_DEFLATED, "lzma": zipfile.ZIP_LZMA}[compression]
    _rezip(out, {k: _npy(v) for k, v in arrays.items()}, method)
    with zipfile.ZipFile(out) as zf:
        info = zf.getinfo("w.npy")
    raw = bytearray(out.read_bytes())
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    for i in range(start + info.compress_size // 2, start + info.compress_size - 2):
        raw[i] ^= 0x5A  # the member's compressed data damaged (its header intact)
    out.write_bytes(bytes(raw))
    _refused_resume(cli, path, out, "not a valid NPZ file")


def test_npz_resume_checks_member_headers_before_reading_their_data(cli, tmp_path):
    import zipfile

    path, out, arrays = _small_npz_results(cli, tmp_path)
    members = {k: _npy(v) for k, v in arrays.items()}
    members["z"] = _npy(np.zeros((5000, 3)))  # another K: refused from its header ...
    _rezip(out, members, zipfile.ZIP_DEFLATED)
    with zipfile.ZipFile(out) as zf:
        info = zf.getinfo("z.npy")
    raw = bytearray(out.read_bytes())
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    raw[start + info.compress_size - 4] ^= 0xFF  # ... its data (bad CRC) never decompressed
    out.write_bytes(bytes(raw))
    _refused_resume(cli, path, out, "'z' has shape (5000, 3)")


def test_npz_resume_refuses_a_member_longer_than_its_header(cli, tmp_path):
    import zipfile

    path, out, arrays = _small_npz_results(cli, tmp_path)
    members = {k: _npy(v) for k, v in arrays.items()}
    members["z"] += b"\0" * 1000
    _rezip(out, members, zipfile.ZIP_STORED)
    _refused_resume(cli, path, out, "array 'z' is damaged")
