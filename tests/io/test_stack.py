"""Stacked problem files (lcpcli.io.stack): round trips, chunked reads, header-only refusals."""

from __future__ import annotations

import zipfile

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.core.errors import ProblemError
from lcpcli.io import list_problems, load
from lcpcli.io.stack import (
    MAX_STACK_PROBLEMS,
    StackInfo,
    StackWriter,
    chunk_size,
    is_stack,
    iter_problems,
    open_stack,
    stack_info,
    write_stack,
)

RNG = np.random.default_rng(7)


def data(K: int = 7, n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    M = RNG.normal(size=(K, n, n)) + 4 * np.eye(n)
    return M, RNG.normal(size=(K, n))


def refused(path, text: str) -> None:
    assert is_stack(path) in (True, False)  # never raises
    with pytest.raises(ProblemError) as err:
        stack_info(path)
    msg = str(err.value)
    assert "\n" not in msg and text in msg, msg


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_round_trip_names_and_chunks(tmp_path, ext):
    M, q = data(50, 3)
    names = [f"p{k}" for k in range(50)]
    path = tmp_path / f"s.{ext}"
    write_stack(path, M, q, names=names)
    assert is_stack(path)
    info = stack_info(path)
    assert info == StackInfo(str(path), "hdf5" if ext == "h5" else "npz", 50, 3, 0, True, None)
    with open_stack(path) as r:
        whole = r.read(0, 50)
        np.testing.assert_array_equal(whole.M, M)
        np.testing.assert_array_equal(whole.q, q)
        assert whole.names == names and whole.lower is None
        for a, b in [(0, 1), (1, 17), (17, 49), (49, 50), (3, 3), (40, 10 + 35)]:
            ch = r.read(a, b)
            assert ch.start == a and ch.M.flags.c_contiguous and ch.M.dtype == np.float64
            np.testing.assert_array_equal(ch.M, M[a:b])
            np.testing.assert_array_equal(ch.q, q[a:b])
            assert ch.names == names[a:b]
        with pytest.raises(IndexError):
            r.read(10, 51)
    problems = list(iter_problems(path))
    assert [p.name for p in problems] == names
    np.testing.assert_array_equal(problems[13].M, M[13])
    assert list_problems(path) == names


def test_npz_compressed_and_default_names(tmp_path):
    M, q = data(30, 5)
    path = tmp_path / "c.npz"
    np.savez_compressed(path, M=M.astype(np.float32), q=q.astype(np.int32))
    with open_stack(path) as r:
        for a, b in [(0, 4), (4, 20), (2, 3), (25, 30)]:  # backwards too
            ch = r.read(a, b)
            np.testing.assert_array_equal(ch.M, M[a:b].astype(np.float32))
            np.testing.assert_array_equal(ch.q, q[a:b].astype(np.int32))
            assert ch.names is None
    assert [p.name for p in iter_problems(path)][:2] == ["c[0]", "c[1]"]


@settings(max_examples=15, deadline=None)
@given(K=st.integers(1, 40), n=st.integers(1, 6), c=st.integers(1, 41),
       ext=st.sampled_from(["h5", "npz"]))
def test_chunked_reads_equal_whole_read(tmp_path_factory, K, n, c, ext):
    path = tmp_path_factory.mktemp("h") / f"s.{ext}"
    M, q = data(K, n)
    write_stack(path, M, q)
    with open_stack(path) as r:
        parts = [r.read(a, min(K, a + c)) for a in range(0, K, c)]
    np.testing.assert_array_equal(np.concatenate([p.M for p in parts]), M)
    np.testing.assert_array_equal(np.concatenate([p.q for p in parts]), q)


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_bounds_shared_and_per_problem_and_n_eq(tmp_path, ext):
    M, q = data(6, 3)
    lo, up = -np.ones(3), np.array([1.0, np.inf, 2.0])
    write_stack(tmp_path / f"a.{ext}", M, q, lower=lo, upper=up)
    assert stack_info(tmp_path / f"a.{ext}").bounds == "shared"
    with open_stack(tmp_path / f"a.{ext}") as r:
        ch = r.read(2, 5)
        np.testing.assert_array_equal(ch.lower, np.tile(lo, (3, 1)))
        np.testing.assert_array_equal(ch.upper, np.tile(up, (3, 1)))
    LO = -RNG.random((6, 3))
    UP = RNG.random((6, 3))
    write_stack(tmp_path / f"b.{ext}", M, q, lower=LO, upper=UP)
    assert stack_info(tmp_path / f"b.{ext}").bounds == "per_problem"
    ps = list(iter_problems(tmp_path / f"b.{ext}"))
    np.testing.assert_array_equal(ps[4].lower, LO[4])
    np.testing.assert_array_equal(ps[5].upper, UP[5])
    write_stack(tmp_path / f"c.{ext}", M, q, n_eq=2)
    assert stack_info(tmp_path / f"c.{ext}").n_eq == 2
    assert {p.n_eq for p in iter_problems(tmp_path / f"c.{ext}")} == {2}


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_load_one_or_refuse_many(tmp_path, ext):
    M, q = data(1, 3)
    write_stack(tmp_path / f"one.{ext}", M, q, names=["only"])
    p = load(tmp_path / f"one.{ext}")
    assert p.name == "only"
    np.testing.assert_array_equal(p.M, M[0])
    M, q = data(3, 3)
    write_stack(tmp_path / f"three.{ext}", M, q)
    with pytest.raises(ProblemError, match="holds 3 stacked problems; solve them as a batch"):
        load(tmp_path / f"three.{ext}")


def test_nan_values_are_read_and_refused_per_problem(tmp_path):
    M, q = data(3, 2)
    M[1, 0, 0] = np.nan
    write_stack(tmp_path / "n.h5", M, q)
    with open_stack(tmp_path / "n.h5") as r:
        assert np.isnan(r.read(0, 3).M[1, 0, 0])
    with pytest.raises(ProblemError, match=r"problem 1 \(n\[1\]\)"):
        list(iter_problems(tmp_path / "n.h5"))


def test_chunk_size():
    assert chunk_size(1000) == 4 and chunk_size(10**5) == 1 and chunk_size(2) == 2**20
    assert chunk_size(4, budget_bytes=1) == 1


# ------------------------------------------------------------------------- refusals
def h5(path, **arrays):
    with h5py.File(path, "w") as f:
        for k, v in arrays.items():
            f.create_dataset(k, data=v)
    return path


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_header_refusals(tmp_path, ext):
    M, q = data(4, 3)

    def make(name, **arrays):
        path = tmp_path / f"{name}.{ext}"
        if ext == "h5":
            return h5(path, **arrays)
        np.savez(path, **arrays)
        return path

    refused(make("q", M=M, q=np.zeros((4, 4))), "q has shape (4, 4); expected (4, 3)")
    refused(make("k0", M=np.zeros((0, 3, 3)), q=np.zeros((0, 3))), "holds no problem")
    refused(make("sq", M=np.zeros((4, 3, 2)), q=q), "square")
    refused(make("cx", M=M.astype(complex), q=q), "'M' holds complex numbers")
    refused(make("bo", M=M, q=q > 0), "'q' holds booleans")
    refused(make("nm", M=M, q=q, names=np.arange(4)), "'names' holds integers; expected strings")
    refused(make("nk", M=M, q=q, names=np.array([b"a", b"b"])), "names has shape (2,)")
    refused(make("lo", M=M, q=q, lower=np.zeros((4, 2))), "lower has shape (4, 2)")
    refused(make("up", M=M, q=q, upper=np.zeros(2)), "upper has shape (2,)")
    refused(make("bn", M=M, q=q, lower=np.zeros(5), upper=np.ones(5)), "lower has shape (5,)")
    if ext == "npz":
        refused(make("ne", M=M, q=q, n_eq=np.asarray(4)), "n_eq = 4 is outside 0..3")
        refused(make("ob", M=M, q=np.array([[1, "x"]] * 4, dtype=object)), "pickled")
    else:
        path = make("ne", M=M, q=q)
        with h5py.File(path, "a") as f:
            f.attrs["n_eq"] = -1
        refused(path, "n_eq = -1 is outside 0..3")


def test_h5_huge_declared_stack(tmp_path):
    path = tmp_path / "big.h5"
    with h5py.File(path, "w") as f:  # nothing written: 8 EB declared, a few KB on disk
        f.create_dataset("M", shape=(10**9, 1000, 1000), chunks=(1, 1000, 1000), dtype="f8")
        f.create_dataset("q", shape=(10**9, 1000), chunks=(1, 1000), dtype="f8")
    assert is_stack(path)
    refused(path, f"M declares 1,000,000,000 problems (limit {MAX_STACK_PROBLEMS:,})")
    # within the limit: declared 80 TB, read lazily one chunk at a time
    with h5py.File(path, "w") as f:
        f.create_dataset("M", shape=(10**7, 1000, 1000), chunks=(1, 1000, 1000), dtype="f8")
        f.create_dataset("q", shape=(10**7, 1000), chunks=(1, 1000), dtype="f8")
    with open_stack(path) as r:
        assert r.info.K == 10**7
        ch = r.read(10**7 - 2, 10**7)
        assert ch.M.shape == (2, 1000, 1000) and not ch.M.any()


def test_h5_dense_size_limit_from_header(tmp_path):
    path = tmp_path / "wide.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("M", shape=(2, 20000, 20000), chunks=(1, 100, 100), dtype="f8")
        f.create_dataset("q", shape=(2, 20000), dtype="f8")
    refused(path, "dense 20000 x 20000 matrix would need")


def test_h5_external_link_and_virtual_dataset_refused(tmp_path):
    M, q = data(3, 2)
    other = h5(tmp_path / "other.h5", M=M, q=q)
    path = tmp_path / "ext.h5"
    with h5py.File(path, "w") as f:
        f["M"] = h5py.ExternalLink(str(other), "M")
        f.create_dataset("q", data=q)
    refused(path, "'M' is an external link")
    assert not is_stack(path)
    path = tmp_path / "virt.h5"
    layout = h5py.VirtualLayout(shape=M.shape, dtype="f8")
    layout[:] = h5py.VirtualSource(str(other), "M", shape=M.shape)
    with h5py.File(path, "w") as f:
        f.create_virtual_dataset("M", layout)
        f.create_dataset("q", data=q)
    refused(path, "virtual or external storage")


def test_h5_names_of_fixed_and_variable_length(tmp_path):
    M, q = data(3, 2)
    path = h5(tmp_path / "fixed.h5", M=M, q=q, names=np.array([b"a", b"bb", b""]))
    assert [p.name for p in iter_problems(path)] == ["a", "bb", "fixed[2]"]


def test_npz_member_larger_than_its_zip_entry(tmp_path):
    M, q = data(2, 2)
    path = tmp_path / "lie.npz"
    with zipfile.ZipFile(path, "w") as zf:
        header = np.lib.format.header_data_from_array_1_0(M)
        header["shape"] = (2000, 2, 2)
        with zf.open("M.npy", "w") as out:
            np.lib.format.write_array_header_1_0(out, header)
            out.write(M.tobytes())
        with zf.open("q.npy", "w") as out:
            np.lib.format.write_array(out, q)
    assert is_stack(path)
    refused(path, "array 'M' is damaged: its header declares")


def test_npz_fortran_order_and_not_a_stack(tmp_path):
    M, q = data(3, 2)
    np.savez(tmp_path / "f.npz", M=np.asfortranarray(M), q=q)
    refused(tmp_path / "f.npz", "Fortran order")
    np.savez(tmp_path / "plain.npz", M=M[0], q=q[0])
    assert not is_stack(tmp_path / "plain.npz")
    assert not is_stack(tmp_path / "missing.h5")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    assert not is_stack(tmp_path / "junk.npz")
    refused(tmp_path / "junk.npz", "not a valid NPZ file")
    refused(tmp_path / "plain.npz", "a stack needs M of shape (K, n, n)")


def test_write_stack_checks_its_arguments(tmp_path):
    M, q = data(3, 2)
    with pytest.raises(ProblemError, match="q has shape"):
        write_stack(tmp_path / "x.h5", M, q[:, :1])
    with pytest.raises(ProblemError, match="booleans"):
        write_stack(tmp_path / "x.h5", M > 0, q)
    with pytest.raises(ProblemError, match=r"\.npz"):
        write_stack(tmp_path / "x.json", M, q)
    assert not (tmp_path / "x.h5").exists()
    write_stack(tmp_path / "x.h5", M, q)
    with h5py.File(tmp_path / "x.h5") as f:
        # contiguous, uncompressed: a batch reads the rows in place (lcpcli.io.stack.mapped)
        assert f["M"].chunks is None and f["M"].compression is None


def test_stack_writer_told_the_count_stores_contiguous_and_holds_to_it(tmp_path):
    """Told the count (``expected``), the HDF5 writer makes M and q at their size, stored
    contiguous (read in place by a batch); appending more, or closing with fewer, is a
    ValueError; without a count M is chunked and grows."""
    M, q = data(5, 3)
    w = StackWriter(tmp_path / "a.h5", "hdf5", 3, expected=5)
    w.append(M[:2], q[:2])
    w.append(M[2:], q[2:])
    assert w.close() == 5
    with h5py.File(tmp_path / "a.h5") as f:
        assert f["M"].chunks is None and f["q"].chunks is None
        assert f["M"][()].tobytes() == M.tobytes() and f["q"][()].tobytes() == q.tobytes()
    w = StackWriter(tmp_path / "b.h5", "hdf5", 3, expected=2)
    with pytest.raises(ValueError, match="more problems appended"):
        w.append(M[:3], q[:3])
    w.abort()
    w = StackWriter(tmp_path / "c.h5", "hdf5", 3, expected=4)
    w.append(M[:3], q[:3])
    with pytest.raises(ValueError, match="3 problems appended, not the 4"):
        w.close()
    w = StackWriter(tmp_path / "d.h5", "hdf5", 3)
    w.append(M, q)
    w.close()
    with h5py.File(tmp_path / "d.h5") as f:
        assert f["M"].chunks is not None and f["M"].shape == (5, 3, 3)


BOUND_SHAPES = st.sampled_from([None, "shared", "per_problem"])
BOUND_VALUES = st.sampled_from([-np.inf, -1.5, -0.5, 0.0, 0.5, 2.0, np.inf])


def _bound(draw, shape: str | None, K: int, n: int) -> np.ndarray | None:
    if shape is None:
        return None
    dims = (n,) if shape == "shared" else (K, n)
    return np.array(draw(st.lists(BOUND_VALUES, min_size=int(np.prod(dims)),
                                  max_size=int(np.prod(dims))))).reshape(dims)


@st.composite
def stacks_with_bounds(draw):
    K, n = draw(st.integers(1, 3)), draw(st.integers(1, 3))
    A = RNG.normal(size=(K, n, n))
    M = A @ A.transpose(0, 2, 1) + np.eye(n)  # positive definite: every box LCP is solvable
    q = RNG.normal(size=(K, n))
    lower = _bound(draw, draw(BOUND_SHAPES), K, n)
    upper = _bound(draw, draw(BOUND_SHAPES), K, n)
    n_eq = draw(st.sampled_from([0, 0, 1, n, n + 1, -1]))
    return M, q, lower, upper, n_eq


def _row(b: np.ndarray | None, k: int) -> np.ndarray | None:
    return None if b is None else (b if b.ndim == 1 else b[k])


@settings(max_examples=60, deadline=None)
@given(case=stacks_with_bounds(), ext=st.sampled_from(["h5", "npz"]))
def test_stacked_file_solve_many_and_problem_create_agree_on_bounds_and_n_eq(
        tmp_path_factory, case, ext):
    """One rule for one-sided bounds and n_eq (core.problem.default_bound / check_n_eq): a
    stacked file, lcpcli.solve_many and Problem.create accept the same data and, when they
    do, mean the same problems (a missing lower bound 0, a missing upper bound +inf)."""
    from lcpcli import solve_many
    from lcpcli.core.certificate import certify
    from lcpcli.core.problem import Problem

    M, q, lower, upper, n_eq = case
    K = q.shape[0]
    try:
        created = [Problem.create(M[k], q[k], n_eq=n_eq, lower=_row(lower, k),
                                  upper=_row(upper, k)) for k in range(K)]
    except ProblemError:
        created = None
    path = tmp_path_factory.mktemp("s") / f"s.{ext}"
    arrays = {"M": M, "q": q, **({"lower": lower} if lower is not None else {}),
              **({"upper": upper} if upper is not None else {})}
    if ext == "h5":
        with h5py.File(path, "w") as f:
            for key, value in arrays.items():
                f.create_dataset(key, data=value)
            if n_eq:
                f.attrs["n_eq"] = n_eq
    else:
        np.savez(path, **arrays, **({"n_eq": np.asarray(n_eq)} if n_eq else {}))
    try:
        read = list(iter_problems(path))
    except ProblemError:
        read = None
    try:
        res = solve_many(M, q, "auto", lower=lower, upper=upper, n_eq=n_eq)
    except ProblemError:
        res = None
    assert (created is None) == (read is None) == (res is None), (created, read, res)
    if created is None:
        return
    for k, (p, r) in enumerate(zip(created, read, strict=True)):
        assert r.n_eq == p.n_eq == n_eq
        for a, b in ((p.lower, r.lower), (p.upper, r.upper)):
            assert (a is None) == (b is None)
            if a is not None:
                np.testing.assert_array_equal(a, b)
        # solve_many's answer k is certified for the problem Problem.create made
        assert res.statuses()[k].value == "solved"
        assert certify(p, res.z[k], res.tol).passed


@pytest.mark.parametrize("n_eq", [True, 1.0, "1", None])
def test_n_eq_must_be_an_integer_everywhere(tmp_path, n_eq):
    """The n_eq rule (core.problem.check_n_eq) is one: Problem.create, solve_many and
    write_stack refuse the same non-integers."""
    from lcpcli import solve_many
    from lcpcli.core.problem import Problem

    M, q = data(2, 3)
    with pytest.raises(ProblemError, match="n_eq must be an integer"):
        Problem.create(M[0], q[0], n_eq=n_eq)
    with pytest.raises(ProblemError, match="n_eq must be an integer"):
        solve_many(M, q, "auto", n_eq=n_eq)
    with pytest.raises(ProblemError, match="n_eq must be an integer"):
        write_stack(tmp_path / "s.h5", M, q, n_eq=n_eq)


@settings(max_examples=25, deadline=None)
@given(K=st.integers(1, 60), n=st.integers(1, 4), rows=st.integers(1, 7),
       step=st.integers(1, 25), gzip=st.booleans(), data=st.data())
def test_direct_reading_equals_cached_reading(tmp_path_factory, K, n, rows, step, gzip, data):
    """A stacked batch reads with ``direct=True`` (no chunk cache for unfiltered data; the
    cache kept for compressed data): every chunk, cut anywhere across the storage chunks,
    holds the same values as the cached reader's and as the arrays written."""
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    M, q = rng.standard_normal((K, n, n)), rng.standard_normal((K, n))
    path = tmp_path_factory.mktemp("direct") / "s.h5"
    with h5py.File(path, "w") as f:
        kw = {"compression": "gzip"} if gzip else {}
        f.create_dataset("M", data=M, chunks=(min(rows, K), n, n), **kw)
        f.create_dataset("q", data=q, chunks=(min(rows, K), n), **kw)
    with open_stack(path, direct=True) as d, open_stack(path) as c:
        for start in range(0, K, step):
            stop = min(K, start + step)
            a, b = d.read(start, stop), c.read(start, stop)
            np.testing.assert_array_equal(a.M, M[start:stop])
            np.testing.assert_array_equal(a.q, b.q)
            np.testing.assert_array_equal(a.M, b.M)


@pytest.mark.parametrize("compression", [zipfile.ZIP_DEFLATED, zipfile.ZIP_LZMA])
def test_chunk_read_errors_name_the_file(tmp_path, compression):
    """A compressed stack damaged or truncated after it was opened: reading a chunk raises a
    one-line ProblemError that starts with the file (it said ``array 'M' is truncated``
    alone, or escaped as zlib.error / LZMAError)."""
    rng = np.random.default_rng(2)
    path = tmp_path / "s.npz"
    with zipfile.ZipFile(path, "w", compression) as zf:
        for key, arr in (("M", np.eye(3) + rng.random((2000, 3, 3))),
                         ("q", rng.random((2000, 3)))):
            with zf.open(f"{key}.npy", "w") as fh:
                np.lib.format.write_array(fh, arr)
    info = zipfile.ZipFile(path).getinfo("M.npy")
    middle = info.header_offset + 30 + len(info.filename) + info.compress_size // 2
    whole = path.read_bytes()
    data = bytearray(whole)
    with open_stack(path) as reader:
        for i in range(middle, middle + 20):
            data[i] ^= 0xA5
        path.write_bytes(bytes(data))
        with pytest.raises(ProblemError, match=f"^{path}: not a valid NPZ file"):
            reader.read(0, reader.info.K)
    path.write_bytes(whole)
    with open_stack(path) as reader, open(path, "r+b") as fh:
        fh.truncate(middle)
        with pytest.raises(ProblemError, match=f"^{path}: "):
            reader.read(0, reader.info.K)
