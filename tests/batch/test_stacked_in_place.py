"""Stacked batches reading their stacks in place (lcpcli.io.stack.mapped): the same result
files as copying reads, the path really taken, resume across the two, and a stack truncated
during the run is one line and exit 2, never a SIGBUS death."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import h5py
import numpy as np
import pytest

from lcpcli.io.stack import write_stack

ROOT = Path(__file__).resolve().parents[2]


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


def _arrays(path: Path) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    with h5py.File(path, "r") as f:
        def visit(name: str, obj: object) -> None:
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()].tobytes()
        f.visititems(visit)
    return out


def _reversed_chunks(path: Path, M: np.ndarray, q: np.ndarray, rows: int = 100) -> None:
    """M and q in storage chunks of ``rows`` problems written last first: a batch chunk
    inside one storage chunk is read in place, one across two is copied."""
    with h5py.File(path, "w") as f:
        for key, x in (("M", M), ("q", q)):
            d = f.create_dataset(key, shape=x.shape, chunks=(rows, *x.shape[1:]), dtype="f8")
            for a in reversed(range(0, len(x), rows)):
                d[a:a + rows] = x[a:a + rows]


@pytest.mark.parametrize("layout", ["write_stack", "npz", "reversed_chunks"])
def test_in_place_batch_equals_copying_batch_and_is_taken(tmp_path, monkeypatch, layout):
    """Every dataset of the result file (z, w, status, basis, digests, ...) is bit for bit
    the same whether the chunks were read in place or copied (all of them, or some: chunks
    in place and copied into buffers in turn); the batch's stats count the chunks read in
    place (none when mapping is off)."""
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.io.stack import mapped

    M, q = pd_stack(700, 5, seed=3)
    M[11] = 0.0  # no solution: through the one-problem pipeline, on the mapped rows
    q[11] = -1.0
    path = tmp_path / ("s.npz" if layout == "npz" else "s.h5")
    if layout == "write_stack":
        write_stack(path, M, q)
    elif layout == "npz":
        np.savez(path, M=M, q=q)
    else:
        _reversed_chunks(path, M, q)
    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 64)
    reports = {}
    for on in (True, False):
        monkeypatch.setattr(mapped, "MAP_STACKS", on)
        reports[on] = run_batch([str(path)], SolveOptions(method="lemke"),
                                output=tmp_path / f"r{on}.h5", jobs=2)
    chunks = -(-700 // 64)
    monkeypatch.setattr(mapped, "MAP_STACKS", True)
    with stack_mod.open_stack(path, mapped=True) as r:
        expected = sum(not r.copies(a, min(700, a + 64)) for a in range(0, 700, 64))
    if layout == "write_stack":
        assert expected == chunks  # write_stack's files are read in place
    if layout == "reversed_chunks":
        assert 0 < expected < chunks  # some in place, some copied
    assert reports[True].stats.in_place_chunks == expected
    assert reports[False].stats.in_place_chunks == 0
    assert reports[True].tally.counts == reports[False].tally.counts
    assert _arrays(tmp_path / "rTrue.h5") == _arrays(tmp_path / "rFalse.h5")


def test_stacks_read_in_place_are_read_in_larger_chunks(tmp_path, monkeypatch):
    """A stack stored for reading in place (StackInfo.in_place, from the metadata) is read
    in chunks of IN_PLACE_CHUNK_BYTES of M, which its result file records; a copied one in
    chunks of BATCH_CHUNK_BYTES; the results are the same."""
    from lcpcli.batch import stack_output
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.io.stack import mapped, stack_info

    monkeypatch.setattr(stack_output, "BATCH_CHUNK_BYTES", 8 * 5 * 5 * 40)  # 40 problems
    monkeypatch.setattr(stack_output, "IN_PLACE_CHUNK_BYTES", 8 * 5 * 5 * 125)  # 125
    M, q = pd_stack(500, 5, seed=9)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    for on, chunk in ((True, 125), (False, 40)):
        monkeypatch.setattr(mapped, "MAP_STACKS", on)
        assert stack_info(path).in_place == on
        assert stack_output.batch_chunk(5, 2, stack_info(path).in_place) == chunk
        report = run_batch([str(path)], SolveOptions(method="lemke"),
                           output=tmp_path / f"r{on}.h5", jobs=2)
        assert report.stats.in_place_chunks == (4 if on else 0)
        with h5py.File(tmp_path / f"r{on}.h5", "r") as f:
            assert int(f["s"].attrs["chunk"]) == chunk
    got, want = _arrays(tmp_path / "rTrue.h5"), _arrays(tmp_path / "rFalse.h5")
    assert {k: v for k, v in got.items() if "digest" not in k} == \
        {k: v for k, v in want.items() if "digest" not in k}  # digests: per chunk


@pytest.mark.parametrize("n", [1, 2, 3, 5, 12, 50, 200, 1000])
def test_in_place_chunks_share_their_bytes_between_m_and_the_results(n):
    """A chunk read in place holds at most IN_PLACE_CHUNK_BYTES of M and as much of results
    (unless every thread's PER_THREAD problems need more), as many problems as that allows,
    and never fewer than a copied chunk where M outweighs the results."""
    from lcpcli.batch.stack_output import (
        BATCH_CHUNK_BYTES,
        IN_PLACE_CHUNK_BYTES,
        PER_THREAD,
        batch_chunk,
        result_row_bytes,
    )

    per = max(max(8, 8 * n * n), result_row_bytes(n))  # the larger share
    c = batch_chunk(n, 2, True)
    assert c * per <= IN_PLACE_CHUNK_BYTES or c == PER_THREAD * 2
    assert (c + 1) * per > IN_PLACE_CHUNK_BYTES or c == PER_THREAD * 2
    if 8 * n * n >= result_row_bytes(n):
        assert c >= min(batch_chunk(n, 2), BATCH_CHUNK_BYTES // (8 * n * n))


def test_in_place_needs_every_row_in_one_run(tmp_path):
    """StackInfo.in_place: contiguous float64 (write_stack, h5py's default) yes; compressed,
    float32 or chunks apart in the file no."""
    from lcpcli.io.stack import stack_info

    M, q = pd_stack(30, 3)
    write_stack(tmp_path / "a.h5", M, q)
    with h5py.File(tmp_path / "b.h5", "w") as f:
        f["M"], f["q"] = M, q
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f.create_dataset("M", data=M, chunks=(3, 3, 3), compression="gzip")
        f["q"] = q
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f["M"], f["q"] = M.astype(np.float32), q
    with h5py.File(tmp_path / "e.h5", "w") as f:  # chunks written last first
        d = f.create_dataset("M", shape=M.shape, chunks=(10, 3, 3), dtype="f8")
        for a in (20, 10, 0):
            d[a:a + 10] = M[a:a + 10]
        f["q"] = q
    assert [stack_info(tmp_path / f"{x}.h5").in_place for x in "abcde"] == \
        [True, True, False, False, False]


def test_memory_pool_stops_when_the_stack_is_read_in_place(tmp_path, monkeypatch):
    """A stack read in place takes no chunk buffer: the memory pool started for it is told
    to stop; a stack that is copied takes its buffers from the pool as before."""
    from lcpcli.batch import stack_output, stacked
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.io.stack import mapped

    monkeypatch.setattr(stack_output, "BATCH_CHUNK_BYTES", 4096)
    M, q = pd_stack(400, 5, seed=8)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    calls: list[str] = []
    take, cancel = stacked.MemoryPool.take, stacked.MemoryPool.cancel

    def taking(self, nbytes):
        calls.append("take")
        return take(self, nbytes)

    def cancelling(self):
        calls.append("cancel")
        cancel(self)

    monkeypatch.setattr(stacked.MemoryPool, "take", taking)
    monkeypatch.setattr(stacked.MemoryPool, "cancel", cancelling)
    for on in (True, False):
        calls.clear()
        monkeypatch.setattr(mapped, "MAP_STACKS", on)
        report = run_batch([str(path)], SolveOptions(method="lemke"),
                           output=tmp_path / f"r{on}.h5", jobs=1)
        assert report.tally.counts == {"solved": 400}
        if on:  # told to stop before it starts (the early reader), never asked for a block
            assert calls and set(calls) == {"cancel"}
        else:
            assert calls == ["take", "take"]


def test_memory_pool_not_started_gives_no_block_and_never_starts_after_cancel():
    from lcpcli.batch.stacked import MemoryPool

    pool = MemoryPool(2, MemoryPool.STEP, start=False)
    assert pool.take(16) is None and pool.thread is None
    pool.cancel()
    pool.start()
    assert pool.thread is None and pool.take(16) is None
    started = MemoryPool(2, MemoryPool.STEP, start=False)
    started.start()
    assert [started.take(16).nbytes for _ in range(2)] == [MemoryPool.STEP] * 2


def test_memory_pool_cancelled_gives_none_for_blocks_not_made():
    """Cancelled before its thread writes anything, the pool makes no block: each take is
    None (the caller allocates), and none blocks."""
    import threading

    from lcpcli.batch.stacked import MemoryPool

    gate = threading.Event()

    class Gated(MemoryPool):
        def _run(self, count: int) -> None:
            gate.wait()
            super()._run(count)

    pool = Gated(3, 4 * MemoryPool.STEP)
    pool.cancel()
    gate.set()
    pool.thread.join()
    assert [pool.take(16) for _ in range(4)] == [None] * 4


def test_resume_checks_in_place_digests_against_copied_ones(tmp_path, monkeypatch):
    """A run stopped after some chunks read in place resumes with copying reads (and the
    other way round): the recorded digests are of the same bytes, so the identity check
    passes and the finished file equals a run in one go."""
    import lcpcli.io.stack as stack_mod
    from lcpcli.batch import stacked
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.io.stack import mapped

    M, q = pd_stack(500, 4, seed=5)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 50)
    run_batch([str(path)], SolveOptions(method="lemke"), output=tmp_path / "whole.h5",
              jobs=1)
    solve_read = stacked.solve_read
    seen: list[int] = []

    def stop_at_the_fourth(part, *args, **kwargs):
        seen.append(part.start)
        if len(seen) == 4:
            raise KeyboardInterrupt
        return solve_read(part, *args, **kwargs)

    for first in (True, False):
        out = tmp_path / f"part{first}.h5"
        seen.clear()
        monkeypatch.setattr(mapped, "MAP_STACKS", first)
        monkeypatch.setattr(stacked, "solve_read", stop_at_the_fourth)
        with pytest.raises(KeyboardInterrupt):
            run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=1)
        monkeypatch.setattr(stacked, "solve_read", solve_read)
        monkeypatch.setattr(mapped, "MAP_STACKS", not first)
        report = run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=1,
                           resume=True)
        assert report.skipped == 150 and report.new == 350
        assert report.stats.in_place_chunks == (7 if not first else 0)
        got, want = _arrays(out), _arrays(tmp_path / "whole.h5")
        assert got == want


def test_digest_of_a_chunk_lost_under_it_is_refused_through_the_write():
    """The reader thread's digest checks the chunk after hashing it: a chunk whose file
    was truncated meanwhile makes result() (the chunk's write) raise the one-line error,
    naming the stack."""
    from lcpcli.batch.stacked import _Digest
    from lcpcli.core.errors import ProblemError
    from lcpcli.io.stack import StackChunk

    def lost() -> None:
        raise ProblemError("was truncated while it was read (problems 0 to 1 ...)")

    M, q = pd_stack(2, 3)
    fine = StackChunk(0, M, q, None, None, None, None)
    digest = _Digest("mxs128", "s.h5")
    digest.compute(fine)
    assert len(digest.result()) == 16
    digest = _Digest("mxs128", "s.h5")
    with pytest.raises(ProblemError):
        digest.compute(StackChunk(0, M, q, None, None, None, lost))
    with pytest.raises(ProblemError, match=r"^s\.h5: was truncated while it was read"):
        digest.result()


#: Runs the command line in a process of its own, truncating the stack right before its
#: second chunk is solved (the reader has handed that chunk over as views already).
TRUNCATING_RUN = """
import os, sys
import lcpcli.io.stack as stack_mod
from lcpcli.batch import stacked
stack_mod.chunk_size = lambda n, **kw: 200
path, cut = sys.argv[1], int(sys.argv[2])
solve_read, seen = stacked.solve_read, []

def solve_then_cut(part, *args, **kwargs):
    seen.append(part.start)
    if len(seen) == 2:
        os.truncate(path, cut)
    return solve_read(part, *args, **kwargs)

stacked.solve_read = solve_then_cut
from lcpcli.cli import main
sys.argv = ["lcpcli", "solve", path, *sys.argv[3:]]
main()
"""


@pytest.mark.parametrize("output", ["r.h5", "r.jsonl", None])
def test_stack_truncated_during_the_run_is_one_line_and_exit_2(tmp_path, output):
    """The stack is cut inside M of the second chunk right before that chunk is solved:
    the kernel's threads (and the digest) read zeros where the file has gone, and the batch
    stops with ``lcpcli: error: FILE: was truncated while it was read ...`` and exit 2, with
    the first chunk's results written (resumable), never with a signal."""
    M, q = pd_stack(1000, 12, seed=2)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    with h5py.File(path, "r") as f:
        cut = f["M"].id.get_offset() + 300 * 12 * 12 * 8  # problems 0..299 of M stay
    args = [str(path), str(cut), "-j", "2"]
    if output is not None:
        args += ["-o", str(tmp_path / output)]
    r = subprocess.run([sys.executable, "-c", textwrap.dedent(TRUNCATING_RUN), *args],
                       capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), cwd=tmp_path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and lines[0].startswith(f"lcpcli: error: {path}: was truncated "
                                                   f"while it was read (problems 200 to 399")
    if output == "r.h5":
        with h5py.File(tmp_path / output, "r") as f:
            status = f["s"]["status"][()]
        assert (status[:200] >= 0).all()  # the first chunk: written
        assert (status[200:] < 0).all()  # the truncated one and after: not
    if output == "r.jsonl":
        rows = [json.loads(x) for x in (tmp_path / output).read_text().splitlines()]
        assert sorted(row["index"] for row in rows) == list(range(200))
