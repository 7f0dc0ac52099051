"""Stacked result files carry the basis, and `lcpcli solve STACK --z0 PREVIOUS` warm-starts
each problem of a stack from it (issue 26, items 1 and 3)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from lcpcli.batch.output import read_rows
from lcpcli.core.certificate import check
from lcpcli.core.problem import Problem
from lcpcli.core.result import STATUS_CODES, basis_text
from lcpcli.io.stack import write_stack


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


def perturbed(q: np.ndarray, seed: int = 1) -> np.ndarray:
    """q changed by up to 1 % of each entry: the next step of a time-stepping sequence."""
    rng = np.random.default_rng(seed)
    return q * (1 + 0.01 * rng.uniform(-1, 1, q.shape))


def two_steps(tmp_path, M: np.ndarray, q: np.ndarray):
    """Stacked files ``s1.h5`` (M, q) and ``s2.h5`` (M, q perturbed): two steps of a sequence."""
    first, second = tmp_path / "s1.h5", tmp_path / "s2.h5"
    write_stack(first, M, q)
    write_stack(second, M, perturbed(q))
    return first, second


def arrays(path, key: str) -> np.ndarray:
    if str(path).endswith(".npz"):
        with np.load(path) as d:
            return d[key].copy()
    with h5py.File(path, "r") as f:
        (g,) = f.values()
        return g[key][...]


def one_line_error(res, *words: str) -> None:
    assert res.returncode == 2, (res.stdout, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: "), res.stderr
    for word in words:
        assert word in lines[0], lines[0]


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_result_files_and_rows_carry_each_problems_basis(cli, tmp_path, ext):
    """The ``basis`` dataset holds Result.basis of every problem (the certificate's pair
    states of its z), -1 for an error problem; JSONL rows carry it as --json's letters."""
    M, q = pd_stack(40, 5)
    M[3, 0, 0] = np.nan  # an error problem: no basis
    M[7], q[7] = 0.0, -1.0  # no solution (Farkas): a basis of its z all the same
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    out = tmp_path / f"r.{ext}"
    assert cli("solve", str(path), "-o", str(out)).returncode == 2  # the error problem
    basis, z, status = arrays(out, "basis"), arrays(out, "z"), arrays(out, "status")
    assert basis.shape == (40, 5) and basis.dtype == np.int8
    assert status[3] == STATUS_CODES["error"] and (basis[3] == -1).all()
    for k in (0, 7, 11, 39):
        want = np.empty(5, np.int8)
        check(Problem.create(M[k], q[k]), z[k], state=want)
        np.testing.assert_array_equal(basis[k], want)
    rows = {r["index"]: r for r in (json.loads(line) for line in
                                     cli("solve", str(path), "--json").stdout.splitlines())
            if "index" in r}
    assert rows[3]["basis"] is None
    for k in (0, 7, 39):
        assert rows[k]["basis"] == basis_text(basis[k])
    out_rows = tmp_path / "r.jsonl"
    cli("solve", str(path), "-o", str(out_rows))
    got = {r["index"]: r["basis"] for r in read_rows(out_rows)}
    assert got[0] == basis_text(basis[0]) and got[3] is None


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_warm_stack_round_trip_equals_a_cold_run_in_fewer_pivots(cli, tmp_path, ext):
    """Cold run, q perturbed by 1 %, warm run from the first run's file: the verdicts and z
    of a cold run of the perturbed stack (to rounding), in fewer pivots; the warm file's
    digest is recorded in the run's solve options."""
    M, q = pd_stack(400, 8, seed=2)
    first, second = two_steps(tmp_path, M, q)
    prev, cold, warm = (tmp_path / f"{x}.{ext}" for x in ("prev", "cold", "warm"))
    assert cli("solve", str(first), "-o", str(prev)).returncode == 0
    assert cli("solve", str(second), "-o", str(cold)).returncode == 0
    res = cli("solve", str(second), "--z0", str(prev), "-o", str(warm))
    assert res.returncode == 0, res.stderr
    np.testing.assert_array_equal(arrays(warm, "status"), arrays(cold, "status"))
    np.testing.assert_allclose(arrays(warm, "z"), arrays(cold, "z"), rtol=0, atol=1e-10)
    np.testing.assert_array_equal(arrays(warm, "basis"), arrays(cold, "basis"))
    assert arrays(warm, "iterations").sum() < arrays(cold, "iterations").sum() / 2
    options = json.loads(str(arrays(warm, "solve_options")) if ext == "npz" else
                         h5py.File(warm, "r")["s2"].attrs["solve_options"])
    assert len(options["warm"]) == 64 and "warm" not in json.loads(
        str(arrays(cold, "solve_options")) if ext == "npz" else
        h5py.File(cold, "r")["s2"].attrs["solve_options"])


def test_warm_file_without_a_basis_starts_from_z_and_unsolved_problems_cold(cli, tmp_path):
    """A result file without ``basis`` (written before it existed) warm-starts from z; a
    problem the previous run did not solve starts cold; the answers are a cold run's."""
    M, q = pd_stack(60, 6, seed=3)
    first, second = two_steps(tmp_path, M, q)
    prev, cold, warm = tmp_path / "prev.h5", tmp_path / "cold.h5", tmp_path / "warm.h5"
    cli("solve", str(first), "-o", str(prev))
    with h5py.File(prev, "r+") as f:
        del f["s1"]["basis"]
        f["s1"]["status"][5] = STATUS_CODES["unsolved"]
        f["s1"]["z"][6] = np.nan
    cli("solve", str(second), "-o", str(cold))
    assert cli("solve", str(second), "--z0", str(prev), "-o", str(warm)).returncode == 0
    np.testing.assert_array_equal(arrays(warm, "status"), arrays(cold, "status"))
    np.testing.assert_allclose(arrays(warm, "z"), arrays(cold, "z"), rtol=0, atol=1e-10)
    np.testing.assert_array_equal(arrays(warm, "iterations")[5:7],
                                  arrays(cold, "iterations")[5:7])


def test_resume_with_a_warm_file_needs_the_same_file(cli, tmp_path):
    """The warm file's digest is part of the solve options: --resume goes on with the same
    file, and refuses another file or none, with one line."""
    M, q = pd_stack(50, 4, seed=6)
    first, second = two_steps(tmp_path, M, q)
    prev, other, out = tmp_path / "prev.h5", tmp_path / "other.h5", tmp_path / "out.h5"
    cli("solve", str(first), "-o", str(prev))
    cli("solve", str(first), "-m", "lemke", "-o", str(other))
    assert cli("solve", str(second), "--z0", str(prev), "-o", str(out)).returncode == 0
    with h5py.File(out, "r+") as f:
        f["s2"]["status"][20:] = -1
    res = cli("solve", str(second), "--z0", str(prev), "-o", str(out), "--resume", "--json")
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout.splitlines()[-1])
    assert (summary["skipped"], summary["new"]) == (20, 30)
    with h5py.File(out, "r+") as f:
        f["s2"]["status"][20:] = -1
    one_line_error(cli("solve", str(second), "--z0", str(other), "-o", str(out), "--resume"),
                   "warm")
    one_line_error(cli("solve", str(second), "-o", str(out), "--resume"), "warm")


def _solved_stack(cli, tmp_path):
    """A stack of 30 problems of n = 4 (``s.h5``) and its result file (``good.h5``)."""
    M, q = pd_stack(30, 4, seed=7)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    good = tmp_path / "good.h5"
    cli("solve", str(path), "-o", str(good))
    return path, good


def test_bad_warm_files_are_one_line_errors(cli, tmp_path):
    """Wrong K, wrong n, a file that is no stacked result, an external link, bad codes, a
    per-file input, the output itself: one line, exit 2, no output written."""
    path, good = _solved_stack(cli, tmp_path)
    out = tmp_path / "out.h5"

    def refused(z0, *words: str) -> None:
        one_line_error(cli("solve", str(path), "--z0", str(z0), "-o", str(out)), *words)
        assert not out.exists()

    for name, (K, n) in {"k.h5": (29, 4), "n.h5": (30, 5)}.items():
        stack = tmp_path / f"in_{name}"
        write_stack(stack, *pd_stack(K, n))
        cli("solve", str(stack), "-o", str(tmp_path / name))
        refused(tmp_path / name, "K = ", "n = ")
        cli("solve", str(stack), "-o", str(tmp_path / f"{name}.npz"))
        refused(tmp_path / f"{name}.npz", "shape")
    refused(path, "not a stacked result file")  # a problem stack, not results
    vector = tmp_path / "v.npz"
    np.savez(vector, z=np.zeros(4), status=np.zeros(4, np.int8))
    refused(vector, "shape")
    linked = tmp_path / "linked.h5"
    with h5py.File(linked, "w") as f:
        f.attrs["lcpcli_stacked_results"] = 1
        f["s"] = h5py.ExternalLink(str(good), "/s")
    refused(linked, "external link")
    bad = tmp_path / "bad.h5"
    bad.write_bytes(good.read_bytes())
    with h5py.File(bad, "r+") as f:
        f["s"]["basis"][3, 1] = 9
    refused(bad, "no basis code")
    single = tmp_path / "p.json"
    single.write_text(json.dumps({"M": [[1.0]], "q": [-1.0]}))
    one_line_error(cli("solve", str(single), str(single), "--z0", str(good), "-o",
                       str(tmp_path / "r.jsonl")), "stacked")
    one_line_error(cli("solve", str(path), "--z0", str(good), "-o", str(good)))


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_resume_of_a_result_file_without_basis_is_refused(cli, tmp_path, ext):
    """A stacked result file of an older lcpcli (no ``basis``) is not resumed: one line."""
    M, q = pd_stack(20, 3, seed=8)
    path, out = tmp_path / "s.h5", tmp_path / f"r.{ext}"
    write_stack(path, M, q)
    cli("solve", str(path), "-o", str(out))
    if ext == "npz":
        with np.load(out) as d:
            kept = {k: d[k] for k in d.files if k != "basis"}
        np.savez(out, **kept)
    else:
        with h5py.File(out, "r+") as f:
            del f["s"]["basis"]
    one_line_error(cli("solve", str(path), "-o", str(out), "--resume"), "without their basis")


def test_warm_file_refusals_inside_hdf5_keep_their_own_whole_message(cli, tmp_path):
    """A refusal raised while a stacked .h5 result file is opened (chunks far larger than the
    data, two stacks) is its own message, whole; never 'damaged HDF5 data (...)'."""
    path, good = _solved_stack(cli, tmp_path)
    chunky = tmp_path / "chunky.h5"
    chunky.write_bytes(good.read_bytes())
    with h5py.File(chunky, "r+") as f:
        z = f["s"]["z"][...]
        del f["s"]["z"]
        f["s"].create_dataset("z", data=z, maxshape=(None, None), chunks=(2**22, 4))
    res = cli("solve", str(path), "--z0", str(chunky), "-o", str(tmp_path / "out.h5"))
    one_line_error(res, "'z' is stored in HDF5 chunks of", "refused before reading")
    assert "damaged HDF5 data" not in res.stderr
    two = tmp_path / "two.h5"
    two.write_bytes(good.read_bytes())
    with h5py.File(two, "r+") as f:
        f.copy(f["s"], "t")
    res = cli("solve", str(path), "--z0", str(two), "-o", str(tmp_path / "out.h5"))
    one_line_error(res, "holds the results of 2 stacks; --z0 takes the result file of one stack")
