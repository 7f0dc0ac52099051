"""Problem files: round trips, every format, sparse storage, validation errors."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import MAX_DENSE_ENTRIES, Problem
from lcpcli.io import list_problems, load, save
from lcpcli.io.hdf5_format import write_many


def same(a: Problem, b: Problem) -> None:
    Ma = a.M.toarray() if a.sparse else a.M
    Mb = b.M.toarray() if b.sparse else b.M
    np.testing.assert_array_equal(Ma, Mb)
    np.testing.assert_array_equal(a.q, b.q)
    assert (a.n_eq, a.name, a.description, a.meta, a.sparse) == \
        (b.n_eq, b.name, b.description, b.meta, b.sparse)
    for x, y in ((a.lower, b.lower), (a.upper, b.upper)):
        if x is None:
            assert y is None
        else:
            np.testing.assert_array_equal(x, y)


PROBLEMS = {
    "dense": lambda: Problem.create(np.array([[2.0, 1 / 3], [1e-300, 2e10]]), [-5.5, 1e-17],
                                    name="dense", description="ünïcode ok", meta={"k": [1, 2]}),
    "sparse": lambda: Problem.create(sp.random(30, 30, density=0.1, random_state=1,
                                               format="csr") + sp.eye(30),
                                     np.linspace(-1, 1, 30), name="sparse"),
    "mlcp": lambda: Problem.create(np.eye(3) + 0.5, [1.0, -2.0, 0.5], n_eq=1, name="mlcp"),
    "box": lambda: Problem.create(np.eye(3) * 2, [1.0, -2.0, 0.5], lower=[-1, 0, -np.inf],
                                  upper=[1, np.inf, 4], name="box"),
}


@pytest.mark.parametrize("kind", sorted(PROBLEMS))
def test_round_trip_json_npz_hdf5_json(tmp_path, kind):
    p0 = PROBLEMS[kind]()
    save(p0, tmp_path / "a.json")
    p1 = load(tmp_path / "a.json")
    save(p1, tmp_path / "b.npz")
    p2 = load(tmp_path / "b.npz")
    save(p2, tmp_path / "c.h5")
    p3 = load(tmp_path / "c.h5")
    save(p3, tmp_path / "d.json")
    p4 = load(tmp_path / "d.json")
    for p in (p1, p2, p3, p4):
        same(p0, p)


@pytest.mark.parametrize("kind", ["dense", "mlcp"])
def test_round_trip_siconos_dat(tmp_path, kind):
    p0 = PROBLEMS[kind]()
    save(p0, tmp_path / f"{kind}.dat")
    p1 = load(tmp_path / f"{kind}.dat")
    np.testing.assert_array_equal(p0.M, p1.M)
    np.testing.assert_array_equal(p0.q, p1.q)
    assert p1.n_eq == p0.n_eq


DAT_CASES = {
    "lcp": lambda: Problem.create(np.array([[2.0, 1.0], [1.0, 3.0]]), [-5.0, -6.0]),
    "lcp_1x1": lambda: Problem.create(np.array([[2.0]]), [-1.0]),
    "lcp_sparse_1x1": lambda: Problem.create(sp.csr_matrix(np.array([[2.0]])), [-1.0]),
    "sparse": PROBLEMS["sparse"],
    "mlcp": PROBLEMS["mlcp"],
    "mlcp_1_1": lambda: Problem.create(np.array([[2.0, 1.0], [-1.0, 3.0]]), [1.0, -2.0],
                                       n_eq=1),
    "all_equalities": lambda: Problem.create(np.eye(2) * 3, [1.0, -2.0], n_eq=2),
}


@pytest.mark.parametrize("name", ["q.dat", "mlcp.dat", "x_mlcp.dat", "lcp.dat"])
@pytest.mark.parametrize("kind", sorted(DAT_CASES))
def test_dat_round_trip_whatever_the_file_name(tmp_path, kind, name):
    """LCP or MLCP is told from a .dat file's numbers, never from its name."""
    p0 = DAT_CASES[kind]()
    save(p0, tmp_path / name)
    p1 = load(tmp_path / name)
    M0 = p0.M.toarray() if p0.sparse else p0.M
    M1 = p1.M.toarray() if p1.sparse else p1.M
    np.testing.assert_array_equal(M0, M1)
    np.testing.assert_array_equal(p0.q, p1.q)
    assert (p1.kind, p1.n_eq) == (p0.kind, p0.n_eq)


def test_siconos_dat_files_read_the_same_under_any_name(tmp_path, siconos):
    for f in sorted(siconos.glob("*/*.dat")):
        if f.name == "Rectangular_mlcp.dat":
            continue
        copy = tmp_path / "q.dat"
        copy.write_bytes(f.read_bytes())
        p0, p1 = load(f), load(copy)
        assert (p0.kind, p0.n_eq) == (p1.kind, p1.n_eq), f.name
        assert p0.kind == ("mlcp" if f.parent.name == "mlcp" else "lcp"), f.name
        np.testing.assert_array_equal(p0.q, p1.q)


def test_convert_then_solve_round_trips_dat(tmp_path, cli, samples):
    for sample, kind in (("mlcp_small.json", "mlcp"), ("degenerate.json", "lcp")):
        (tmp_path / "in.json").write_bytes((samples / sample).read_bytes())
        out = tmp_path / f"{kind}_out.dat"
        r = cli("convert", str(tmp_path / "in.json"), str(out))
        assert r.returncode == 0, r.stderr
        r = cli("solve", str(out), "--json")
        assert r.returncode == 0, (sample, r.stderr)
        assert load(out).kind == kind
    (tmp_path / "q.dat").write_bytes((samples / "mlcp_small.dat").read_bytes())
    r = cli("solve", str(tmp_path / "q.dat"))
    assert r.returncode == 0, r.stderr


def test_dense_dat_repeated_size_must_match(tmp_path):
    (tmp_path / "x.dat").write_text("2\n0\n2\n2\n2 3\n1 0 0 1\n1 1\n")
    with pytest.raises(ProblemError, match="repeated size"):
        load(tmp_path / "x.dat")


def test_box_problem_cannot_be_written_as_dat(tmp_path):
    with pytest.raises(ProblemError, match="box"):
        save(PROBLEMS["box"](), tmp_path / "x.dat")
    assert not list(tmp_path.iterdir())  # no partial file left behind


def test_siconos_block_files_equal_their_dense_copies(siconos):
    for name in ("deudeu", "ortiz", "trivial"):
        dense = load(siconos / "lcp" / f"lcp_{name}.dat")
        block = load(siconos / "lcp" / f"lcp_{name}_block.dat")
        np.testing.assert_array_equal(dense.M, block.M)
        np.testing.assert_array_equal(dense.q, block.q)


def test_siconos_dat_is_column_major(siconos):
    p = load(siconos / "lcp" / "lcp_exp_murty.dat")
    # upper triangular, 1 on the diagonal, 2 above
    assert np.allclose(np.tril(p.M, -1), 0) and np.allclose(np.diag(p.M), 1)
    assert np.allclose(p.M[np.triu_indices(6, 1)], 2)


def test_siconos_mlcp_files_both_storages_agree(siconos):
    for f in sorted((siconos / "mlcp").glob("*.dat")):
        if f.name == "Rectangular_mlcp.dat":
            with pytest.raises(ProblemError, match="square"):
                load(f)
            continue
        p = load(f)
        assert p.kind == "mlcp" and 0 < p.n_eq < p.n


def test_npz_sparse_coo_and_csr(tmp_path):
    M = sp.random(20, 20, density=0.2, random_state=3, format="coo") + sp.eye(20)
    M = M.tocoo()
    q = np.ones(20)
    np.savez(tmp_path / "coo.npz", M_format="coo", M_shape=np.array(M.shape), M_data=M.data,
             M_row=M.row, M_col=M.col, q=q)
    p = load(tmp_path / "coo.npz")
    assert p.sparse
    np.testing.assert_allclose(p.M.toarray(), M.toarray())
    csr = M.tocsr()
    np.savez(tmp_path / "csr.npz", M_format="csr", M_shape=np.array(M.shape), M_data=csr.data,
             M_indices=csr.indices, M_indptr=csr.indptr, q=q)
    np.testing.assert_allclose(load(tmp_path / "csr.npz").M.toarray(), M.toarray())


def test_hdf5_sparse_group(tmp_path):
    M = (sp.random(15, 15, density=0.2, random_state=2) + sp.eye(15)).tocsr()
    with h5py.File(tmp_path / "s.h5", "w") as f:
        g = f.create_group("M")
        g.attrs["format"] = "csr"
        g.attrs["shape"] = [15, 15]
        g["data"], g["indices"], g["indptr"] = M.data, M.indices, M.indptr
        f["q"] = -np.ones(15)
    p = load(tmp_path / "s.h5")
    assert p.sparse and lcpcli.solve(p).solved


def test_hdf5_multi_problem_and_missing_name(tmp_path):
    probs = [Problem.create(np.eye(2) * (k + 1), [-1.0, -2.0], name=f"p{k}") for k in range(3)]
    write_many(probs, tmp_path / "many.h5")
    assert list_problems(tmp_path / "many.h5") == ["p0", "p1", "p2"]
    assert load(tmp_path / "many.h5", "p2").M[0, 0] == 3
    with pytest.raises(ProblemError, match="pick one with --problem") as exc:
        load(tmp_path / "many.h5")
    assert "p0, p1, p2" in str(exc.value)
    with pytest.raises(ProblemError, match="no problem named 'zz'.*p0, p1, p2"):
        load(tmp_path / "many.h5", "zz")


BAD_JSON = {
    "not json": "{M: ]",
    "not an object": "[1, 2]",
    "missing q": '{"M": [[1]]}',
    "unknown key": '{"M": [[1]], "q": [1], "Q": 3}',
    "ragged": '{"M": [[1, 2], [3]], "q": [1, 2]}',
    "not square": '{"M": [[1, 2]], "q": [1]}',
    "q length": '{"M": [[1, 0], [0, 1]], "q": [1]}',
    "nan": '{"M": [[NaN]], "q": [1]}',
    "inf": '{"M": [[1]], "q": [Infinity]}',
    "strings": '{"M": [["a"]], "q": [1]}',
    "bad n_eq": '{"M": [[1]], "q": [1], "n_eq": 5}',
    "bounds crossed": '{"M": [[1]], "q": [1], "lower": [2], "upper": [1]}',
    "both forms": '{"M": [[1, 0], [0, 1]], "q": [1, 1], "n_eq": 1, "lower": [0, 0]}',
}


@pytest.mark.parametrize("case", sorted(BAD_JSON))
def test_bad_json_is_one_clear_problem_error(tmp_path, case):
    f = tmp_path / "bad.json"
    f.write_text(BAD_JSON[case])
    with pytest.raises(ProblemError) as exc:
        load(f)
    msg = str(exc.value)
    assert msg.startswith(str(f)) and "\n" not in msg


def test_bad_files(tmp_path):
    (tmp_path / "x.txt").write_text("1")
    (tmp_path / "t.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 10)
    (tmp_path / "t.npz").write_bytes(b"PK\x03\x04garbage")
    np.savez(tmp_path / "obj.npz", M=np.array([[1.0]]), q=np.array([None, 1], dtype=object))
    (tmp_path / "short.dat").write_text("3\n0\n3\n3\n3 3\n1 2 3\n")
    cases = {"x.txt": "unknown file type", "missing.json": "no such file",
             "t.h5": "HDF5", "t.npz": "NPZ", "obj.npz": "pickled", "short.dat": "ends early"}
    for name, text in cases.items():
        with pytest.raises(ProblemError, match=text):
            load(tmp_path / name)


def test_huge_sizes_refused_before_allocation(tmp_path):
    n = int(MAX_DENSE_ENTRIES ** 0.5) + 10
    (tmp_path / "huge.dat").write_text(f"{n}\n0\n{n}\n{n}\n{n} {n}\n")
    with pytest.raises(ProblemError, match="GiB"):
        load(tmp_path / "huge.dat")
    with h5py.File(tmp_path / "huge.h5", "w") as f:  # a lazily allocated 10^6 x 10^6 dataset
        f.create_dataset("M", shape=(10**6, 10**6), dtype="f8")
        f.create_dataset("q", shape=(10**6,), dtype="f8")
    with pytest.raises(ProblemError, match="too large|GiB"):
        load(tmp_path / "huge.h5")


def test_save_is_atomic_and_keeps_existing_file_on_failure(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("precious")
    with pytest.raises(ProblemError):
        save(PROBLEMS["box"](), tmp_path / "out.dat")
    assert target.read_text() == "precious"
    save(PROBLEMS["dense"](), target)
    assert json.loads(target.read_text())["name"] == "dense"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_json_bounds_null_means_infinite(tmp_path):
    f = tmp_path / "b.json"
    f.write_text('{"M": [[1, 0], [0, 1]], "q": [1, 1], "lower": [null, 0], '
                 '"upper": [2, null]}')
    p = load(f)
    assert p.kind == "box" and p.lower[0] == -np.inf and p.upper[1] == np.inf


# ---------------------------------------------------------------------- issue 17
@pytest.mark.parametrize("ext", ["json", "npz", "h5", "dat"])
def test_empty_problem_every_format(tmp_path, ext):
    p0 = Problem.create(np.zeros((0, 0)), [], name="empty")
    save(p0, tmp_path / f"e.{ext}")
    p1 = load(tmp_path / f"e.{ext}")
    assert p1.n == 0 and p1.M.shape == (0, 0) and p1.q.shape == (0,)


def test_sparse_problem_to_dat_stays_sparse(tmp_path):
    """A 30000 x 30000 sparse M goes to .dat as 1 x 1 sparse blocks (dense: 6.7 GiB)."""
    n = 30_000
    M = sp.diags([np.full(n - 1, -1.0), np.full(n, 4.0), np.full(n - 1, -1.0)], [-1, 0, 1],
                 format="csr")
    p0 = Problem.create(M, -np.ones(n), name="chain")
    save(p0, tmp_path / "chain.dat")
    p1 = load(tmp_path / "chain.dat")
    assert p1.sparse and (p1.M != M).nnz == 0
    np.testing.assert_array_equal(p1.q, p0.q)
    small = Problem.create(sp.csr_matrix(np.array([[2.0, 0], [1, 3]])), [1.0, -1.0])
    save(small, tmp_path / "small.dat")  # small sparse-block files come back dense
    np.testing.assert_array_equal(load(tmp_path / "small.dat").M, [[2, 0], [1, 3]])


@pytest.mark.parametrize("M, q, words", [
    (np.eye(2) + 1j, [1, 1], "M holds complex numbers"),
    (np.eye(2) > 0, [1, 1], "M holds booleans"),
    ([["1", "0"], ["0", "1"]], [1, 1], "M holds strings"),
    (np.eye(2), [True, False], "q holds booleans"),
    (np.eye(2), ["1", "2"], "q holds strings"),
    (sp.csr_matrix(np.eye(2) * (1 + 1j)), [1, 1], "M holds complex numbers"),
    ([[1, 0], [0]], [1, 1], "M is not a rectangular array"),
])
def test_api_arrays_follow_the_data_rule(M, q, words):
    with pytest.raises(ProblemError, match=words):
        lcpcli.solve(M, q)


def test_api_accepts_arrays_and_the_old_signature():
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    r1 = lcpcli.solve(M, [-5, -6], method="lemke")
    r2 = lcpcli.solve(sp.csr_matrix(M), np.array([-5.0, -6.0]))
    r3 = lcpcli.solve(Problem.create(M, [-5, -6]), "lemke", tol=1e-10)
    r4 = lcpcli.solve(Problem.create(M, [-5, -6]), method="lemke")
    for r in (r1, r2, r3, r4):
        assert r.solved
        np.testing.assert_allclose(r.z, [4 / 3, 7 / 3])
    box = lcpcli.solve(np.eye(2), [1.0, -3.0], lower=[-1, -1], upper=[1, 1])
    assert box.solved and box.z.tolist() == [-1.0, 1.0]
    with pytest.raises(TypeError, match="needs q"):
        lcpcli.solve(M)
    with pytest.raises(TypeError, match="method name second"):
        lcpcli.solve(Problem.create(M, [-5, -6]), "lemke", method="pgs")


def test_result_repr_is_short_and_str_has_the_details():
    n = 300
    r = lcpcli.solve(np.eye(n) * 2, -np.ones(n))
    text = repr(r)
    assert len(text) < 120 and text.startswith("Result(status='solved'")
    for part in ("method=", "n=300", "error=", "iterations="):
        assert part in text
    details = str(r)
    assert "message:" in details and "z = [" in details and len(details) < 2000


def test_non_regular_inputs_refused_without_reading(tmp_path):
    import os

    os.mkfifo(tmp_path / "p.json")
    with pytest.raises(ProblemError, match="is a FIFO"):
        load(tmp_path / "p.json")  # returns at once: never opened for reading
    (tmp_path / "d.npz").mkdir()
    with pytest.raises(ProblemError, match="is a directory"):
        load(tmp_path / "d.npz")
    os.symlink("/dev/zero", tmp_path / "z.dat")
    with pytest.raises(ProblemError, match="is a character device"):
        load(tmp_path / "z.dat")


def test_header_checks_before_reading(tmp_path):
    """Every dataset is checked against M's size from the header, nothing is allocated."""
    with h5py.File(tmp_path / "lazy.h5", "w") as f:
        f["M"] = np.eye(2)
        f["q"] = np.ones(2)
        f.create_dataset("upper", shape=(10**9,), dtype="f8")  # 8 GB declared, none stored
    with pytest.raises(ProblemError, match=r"upper has shape \(1000000000,\) but M is 2 x 2"):
        load(tmp_path / "lazy.h5")
    np.savez(tmp_path / "c.npz", M=np.eye(2), q=np.ones(2), lower=np.zeros(2, dtype=np.complex64))
    with pytest.raises(ProblemError, match="lower holds complex numbers"):
        load(tmp_path / "c.npz")


def test_read_many_fast_path_refuses_data_outside_the_file(tmp_path):
    """The per-group fast reader takes only plain contiguous data of this file; chunked data
    is read too, and external or virtual storage is refused by name, as by ``read``."""
    from lcpcli.io.hdf5_format import read_many

    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    q = np.array([-1.0, -1.0])
    M.tofile(tmp_path / "raw.bin")
    path = tmp_path / "groups.h5"
    with h5py.File(path, "w") as f:
        f.create_group("plain").update({"M": M, "q": q})
        g = f.create_group("chunked")
        g.create_dataset("M", data=M, chunks=(1, 2))
        g["q"] = q
        g = f.create_group("external")
        g.create_dataset("M", shape=(2, 2), dtype="f8",
                         external=[(str(tmp_path / "raw.bin"), 0, 32)])
        g["q"] = q
        g = f.create_group("virtual")
        layout = h5py.VirtualLayout(shape=(2, 2), dtype="f8")
        layout[:] = h5py.VirtualSource(str(tmp_path / "other.h5"), "M", shape=(2, 2))
        g.create_virtual_dataset("M", layout)
        g["q"] = q
        g = f.create_group("text")
        g["M"] = np.array([[b"a", b"b"], [b"c", b"d"]])
        g["q"] = q
        f["soft"] = h5py.SoftLink("/plain")
    got = dict(read_many(path, ["plain", "chunked", "external", "virtual", "text", "soft",
                                "missing"]))
    for name in ("plain", "chunked", "soft"):
        np.testing.assert_array_equal(got[name].M, M)
        np.testing.assert_array_equal(got[name].q, q)
    for name in ("external", "virtual"):
        assert isinstance(got[name], ProblemError)
        assert "virtual or external" in str(got[name])
    assert isinstance(got["text"], ProblemError)
    assert isinstance(got["missing"], ProblemError) and "missing" in str(got["missing"])


@settings(max_examples=40, deadline=None)
@given(size=st.integers(0, 5000), limit=st.integers(0, 5000))
def test_read_input_bytes_is_the_file_up_to_the_limit(tmp_path_factory, size, limit):
    """The bare-descriptor read returns the file's bytes exactly when it fits the limit, and
    refuses it (never cuts it) when it does not."""
    from lcpcli.io import files

    path = tmp_path_factory.mktemp("rb") / "f.json"
    data = bytes(range(256)) * (size // 256) + bytes(range(size % 256))
    path.write_bytes(data)
    if size <= limit:
        assert files.read_input_bytes(path, limit=limit) == data
    else:
        with pytest.raises(ProblemError, match="over the limit"):
            files.read_input_bytes(path, limit=limit)


def test_read_input_bytes_a_file_that_grows_after_the_size_check(tmp_path, monkeypatch):
    """The size is read once (fstat); a file longer by the time it is read is read on to the
    limit, and refused beyond it, never cut."""
    import os as _os

    from lcpcli.io import files

    path = tmp_path / "grown.json"
    path.write_bytes(b"x" * 100)
    real_fstat = _os.fstat

    class Shrunk:
        def __init__(self, st):
            self.st_mode, self.st_size = st.st_mode, 10  # as if it had 10 bytes at the fstat

    monkeypatch.setattr(files.os, "fstat", lambda fd: Shrunk(real_fstat(fd)))
    assert files.read_input_bytes(path, limit=1000) == b"x" * 100
    with pytest.raises(ProblemError, match="too large|larger|exceeds|limit"):
        files.read_input_bytes(path, limit=50)


@settings(max_examples=300, deadline=None)
@given(path=st.text(alphabet="ab./-J", max_size=12))
def test_suffix_is_pathlibs(path):
    """The format detection's suffix and the default problem name's stem, computed without a
    Path, are pathlib's for any path."""
    from pathlib import Path

    from lcpcli.io import stem, suffix

    assert suffix(path) == Path(path).suffix
    assert stem(path) == Path(path).stem


@pytest.mark.parametrize("ext", ["json", "npz", "h5"])
def test_non_finite_meta_is_written_as_null(tmp_path, ext):
    """``meta`` holding NaN and a float beyond the double range (Inf): every format writes
    them as null (the output rule of lcpcli.core.numeric.json_text), never the NaN/Infinity
    tokens that are not JSON; converted back to JSON, the text is strict JSON."""
    src = tmp_path / "m.json"
    src.write_text('{"M": [[2, 1], [1, 2]], "q": [-5, -6], "meta": {"a": NaN, "b": 1e400}}')
    out = tmp_path / f"out.{ext}"
    save(load(src), out)
    back = tmp_path / "back.json"
    save(load(out), back)
    for path in (back, out) if ext == "json" else (back,):
        text = path.read_text()
        assert "NaN" not in text and "Infinity" not in text
        assert json.loads(text)["meta"] == {"a": None, "b": None}
