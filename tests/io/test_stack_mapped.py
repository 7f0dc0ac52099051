"""Stack rows read in place (lcpcli.io.stack.mapped): the same bytes as a copying read, for
every layout that allows it and none that does not, and a file truncated under the map is
one ProblemError, never a SIGBUS death (in Python, the digest's and the solver's threads)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from lcpcli.io.stack import open_stack, write_stack

ROOT = Path(__file__).resolve().parents[2]


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


def _h5py_default(path: Path, M: np.ndarray, q: np.ndarray) -> None:
    with h5py.File(path, "w") as f:  # what a user writes: contiguous datasets
        f["M"], f["q"] = M, q


def _h5py_compressed(path: Path, M: np.ndarray, q: np.ndarray) -> None:
    with h5py.File(path, "w") as f:
        f.create_dataset("M", data=M, chunks=(min(4, len(M)), *M.shape[1:]), compression="gzip")
        f.create_dataset("q", data=q, chunks=(min(4, len(q)), q.shape[1]), compression="gzip")


def _h5py_float32(path: Path, M: np.ndarray, q: np.ndarray) -> None:
    with h5py.File(path, "w") as f:
        f["M"], f["q"] = M.astype(np.float32), q.astype(np.float32)


def _reversed_chunks(path: Path, M: np.ndarray, q: np.ndarray) -> None:
    """Chunks of 3 problems written last first: each chunk is a run of its own (its
    successor lies before it in the file)."""
    with h5py.File(path, "w") as f:
        for key, x in (("M", M), ("q", q)):
            d = f.create_dataset(key, shape=x.shape, chunks=(min(3, len(x)), *x.shape[1:]),
                                 dtype="f8")
            for a in reversed(range(0, len(x), 3)):
                d[a:a + 3] = x[a:a + 3]


def _npz(path: Path, M: np.ndarray, q: np.ndarray) -> None:
    np.savez(path, M=M, q=q)


def _npz_compressed(path: Path, M: np.ndarray, q: np.ndarray) -> None:
    np.savez_compressed(path, M=M, q=q)


#: (writer, suffix, whether every row of M and q is read in place, some is)
LAYOUTS = {
    "write_stack": (lambda p, M, q: write_stack(p, M, q), ".h5", True, True),
    "h5py_default": (_h5py_default, ".h5", True, True),
    "reversed_chunks": (_reversed_chunks, ".h5", False, True),
    "compressed": (_h5py_compressed, ".h5", False, False),
    "float32": (_h5py_float32, ".h5", False, False),
    "npz": (_npz, ".npz", None, None),  # in place when the member is aligned to 8 bytes
    "npz_compressed": (_npz_compressed, ".npz", False, False),
}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_mapped_reads_equal_copying_reads(tmp_path_factory, layout, data):
    """Any chunk read by a mapped reader holds the bytes a copying reader reads; rows are
    views (read-only, with a check) exactly where the reader says it does not copy."""
    write, suffix, every, some = LAYOUTS[layout]
    K = data.draw(st.integers(1, 40), label="K")
    n = data.draw(st.integers(1, 6), label="n")
    M, q = pd_stack(K, n, seed=K * 7 + n)
    path = tmp_path_factory.mktemp("m") / f"s{suffix}"
    write(path, M, q)
    start = data.draw(st.integers(0, K - 1), label="start")
    stop = data.draw(st.integers(start + 1, K), label="stop")
    with open_stack(path, direct=True, mapped=True) as r, open_stack(path) as c:
        got, want = r.read(start, stop), c.read(start, stop)
        assert got.M.tobytes() == want.M.tobytes() and got.q.tobytes() == want.q.tobytes()
        in_place = not r.copies(start, stop)
        assert in_place == (not got.M.flags.writeable and not got.q.flags.writeable)
        assert (got.check is not None) == (not got.M.flags.writeable
                                           or not got.q.flags.writeable)
        if got.check is not None:
            got.check()  # the file is whole: no error
        if every:
            assert not r.copies(0, K) and in_place
        if some is False:
            assert r.copies(start, stop) and got.check is None and r.mapped_views == 0


def test_write_stack_files_are_read_in_place_and_chunks_apart_copied(tmp_path):
    M, q = pd_stack(50, 3)
    write_stack(tmp_path / "a.h5", M, q)
    _reversed_chunks(tmp_path / "b.h5", M, q)
    with open_stack(tmp_path / "a.h5", mapped=True) as a, \
            open_stack(tmp_path / "b.h5", mapped=True) as b:
        assert not a.copies(0, 50)
        assert not b.copies(3, 6) and b.copies(2, 4) and b.copies(0, 50)
        assert b.read(2, 4).check is None and b.read(3, 6).check is not None
        a.read(0, 50)
        assert a.mapped_views == 2  # M and q
    with open_stack(tmp_path / "a.h5") as plain:  # not asked: copies
        assert plain.copies(0, 50) and plain.read(0, 50).check is None


@settings(max_examples=25, deadline=None)
@given(order=st.permutations(range(5)), K=st.integers(9, 15))
@example(order=[0, 1, 2, 3, 4], K=15)  # in order: one run
@example(order=[1, 0, 2, 3, 4], K=15)
def test_whole_listing_agrees_with_the_full_one(tmp_path_factory, order, K):
    """h5_runs(whole=True), which stops at the first chunk out of place, says "one run"
    exactly when the full listing finds one run of every row; more chunks than
    MAX_LISTED_CHUNKS are not listed (copied)."""
    from lcpcli.io.stack import mapped

    path = tmp_path_factory.mktemp("w") / "c.h5"
    M = np.arange(K * 4, dtype=np.float64).reshape(K, 2, 2)
    with h5py.File(path, "w") as f:
        d = f.create_dataset("M", shape=M.shape, chunks=(3, 2, 2), dtype="f8")
        for i in order:  # chunks allocated in this order
            if 3 * i < K:
                d[3 * i:3 * i + 3] = M[3 * i:3 * i + 3]
    with h5py.File(path, "r") as f:
        full, whole = mapped.h5_runs(f["M"]), mapped.h5_runs(f["M"], whole=True)
        one = full is not None and full.starts == [0] and full.stops == [K]
        assert (whole is not None) == one
        if whole is not None:
            assert whole == full
        cap = mapped.MAX_LISTED_CHUNKS
        try:
            mapped.MAX_LISTED_CHUNKS = 2
            assert mapped.h5_runs(f["M"]) is None
        finally:
            mapped.MAX_LISTED_CHUNKS = cap


def test_map_stacks_off_copies_everything(tmp_path, monkeypatch):
    from lcpcli.io.stack import mapped

    M, q = pd_stack(10, 3)
    write_stack(tmp_path / "a.h5", M, q)
    monkeypatch.setattr(mapped, "MAP_STACKS", False)
    with open_stack(tmp_path / "a.h5", mapped=True) as r:
        assert r.copies(0, 10) and r.read(0, 10).check is None


def _run(code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, env=env, timeout=300)


def test_truncated_file_gives_zeros_and_an_error_in_every_thread_not_sigbus(tmp_path):
    """The file is truncated under chunks already handed out as views: numpy (this thread),
    the digest (C, GIL released) and solve_many's kernel (OpenMP threads) read zeros past the
    new end instead of dying of SIGBUS, and each chunk's check names the truncation; a chunk
    wholly before the new end stays valid.  In a subprocess: a guard that fails kills it."""
    M, q = pd_stack(2000, 12)
    path = tmp_path / "s.h5"
    with h5py.File(path, "w") as f:  # q first in the file, then M
        f["q"] = q
        f["M"] = M
        cut = f["M"].id.get_offset() + 1000 * 1152  # M of problems 0..999 stays
    code = f"""
    import os, numpy as np
    from lcpcli import solve_many
    from lcpcli.batch.digest import mxs128
    from lcpcli.core.errors import ProblemError
    from lcpcli.io.stack import open_stack
    path = {str(path)!r}
    with open_stack(path, direct=True, mapped=True) as r:
        head, tail = r.read(0, 100), r.read(100, 2000)
        assert head.check is not None and tail.check is not None
        faults = r._mapped.mapping.faults
        os.truncate(path, {cut})
        # each reader meets lost pages below the ones met before (a fault turns the map from
        # its page on into zeros): numpy in Python, the digest in C without the GIL, the
        # kernel in its OpenMP threads
        assert float(np.abs(tail.M[-1]).sum()) == 0.0 and faults() == 1
        mxs128(tail.M[1400:])
        assert faults() == 2
        solve_many(tail.M[:1400], tail.q[:1400], threads=2, on_error="mark")
        assert faults() >= 3
        head.check()  # problems 0..99: whole
        try:
            tail.check()
        except ProblemError as exc:
            print("error:", exc)
    """
    r = _run(code)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "error: was truncated while it was read (problems 100 to 1,999" in r.stdout
    assert r.stdout.count("error:") == 1


def test_truncation_inside_a_page_is_seen_without_a_fault(tmp_path):
    """Cut inside a page, the rest of that page reads zeros without any SIGBUS: the check
    sees it from the file's size."""
    from lcpcli.core.errors import ProblemError

    M, q = pd_stack(300, 4)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    with open_stack(path, direct=True, mapped=True) as r:
        part = r.read(0, 300)
        first = r._mapped.runs["M"].offsets[0]
        os.truncate(path, first + 8 * 16 * 150 + 1000)  # mid-page, inside M
        assert part.check is not None
        with pytest.raises(ProblemError, match="truncated while it was read"):
            part.check()


def test_truncated_and_regrown_file_is_refused_too(tmp_path):
    """Cut, then written to its old size again before the check: the pages met while the
    file was short read zeros, so the chunk is refused all the same (in a subprocess)."""
    M, q = pd_stack(500, 8)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    r = _run(f"""
    import os, numpy as np
    from lcpcli.core.errors import ProblemError
    from lcpcli.io.stack import open_stack
    path = {str(path)!r}
    size = os.path.getsize(path)
    with open_stack(path, direct=True, mapped=True) as r:
        part = r.read(0, 500)
        os.truncate(path, 8192)
        assert float(np.abs(part.M[-1]).sum()) == 0.0
        os.truncate(path, size)  # as long as before, zeros
        try:
            part.check()
        except ProblemError as exc:
            print("error:", exc)
    """)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "error: lost data while it was read (problems 0 to 499" in r.stdout


def test_other_sigbus_still_ends_the_process(tmp_path):
    """The guard takes only faults inside its own maps: a SIGBUS sent by kill, or a fault
    in another map of a truncated file, still ends the process by SIGBUS."""
    M, q = pd_stack(20, 3)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    kill = _run(f"""
    import os, signal
    from lcpcli.io.stack import open_stack
    with open_stack({str(path)!r}, mapped=True) as r:
        r.read(0, 20)
        os.kill(os.getpid(), signal.SIGBUS)
    """)
    assert kill.returncode == -signal.SIGBUS
    other = tmp_path / "other.bin"
    other.write_bytes(b"\1" * 3 * 4096)
    fault = _run(f"""
    import mmap, os
    from lcpcli.io.stack import open_stack
    with open_stack({str(path)!r}, mapped=True) as r:
        r.read(0, 20)
        with open({str(other)!r}, "rb") as fh:
            m = mmap.mmap(fh.fileno(), 0, prot=mmap.PROT_READ)
            os.truncate({str(other)!r}, 0)
            print(m[2 * 4096])
    """)
    assert fault.returncode == -signal.SIGBUS, fault.stderr[-1000:]


@pytest.mark.parametrize("K, n", [(1, 1), (30, 4), (257, 12)])
def test_lcpcli_npz_stacks_are_read_in_place_and_stay_plain_npz(tmp_path, K, n):
    """write_stack's NPZ members start at a multiple of 64 (a padded local header): every
    row array is read in place, and numpy and zipfile read the file as before."""
    rng = np.random.default_rng(K)
    M, q = rng.standard_normal((K, n, n)), rng.standard_normal((K, n))
    lo, up = -rng.random((K, n)), rng.random((K, n))
    names = [f"p{i}" for i in range(K)]
    path = tmp_path / "s.npz"
    write_stack(path, M, q, names=names, lower=lo, upper=up)
    with zipfile.ZipFile(path) as zf:
        assert zf.testzip() is None
    with np.load(path) as d:
        assert d["M"].tobytes() == M.tobytes() and d["upper"].tobytes() == up.tobytes()
        assert list(d["names"]) == names
    with open_stack(path, mapped=True) as r:
        assert r.info.in_place and not r.copies(0, K)
        part = r.read(0, K)
        assert sorted(r._mapped.runs) == ["M", "lower", "q", "upper"]
        assert all(v.offsets[0] % 64 == 0 for v in r._mapped.runs.values())
        for got, want in ((part.M, M), (part.q, q), (part.lower, lo), (part.upper, up)):
            assert not got.flags.writeable and got.tobytes() == want.tobytes()
        assert part.names == names


def test_npz_members_read_in_place_when_aligned(tmp_path):
    """np.savez members are stored uncompressed: read in place when their data start at a
    multiple of 8 bytes in the file, copied otherwise; the same bytes either way."""
    M, q = pd_stack(30, 4)
    path = tmp_path / "s.npz"
    np.savez(path, M=M, q=q)
    with zipfile.ZipFile(path) as zf:
        assert all(i.compress_type == zipfile.ZIP_STORED for i in zf.infolist())
    with open_stack(path, mapped=True) as r:
        part = r.read(0, 30)
        assert part.M.tobytes() == M.tobytes() and part.q.tobytes() == q.tobytes()
        runs = {} if r._mapped is None else r._mapped.runs
        for key in ("M", "q"):
            if key in runs:
                assert runs[key].offsets[0] % 8 == 0
