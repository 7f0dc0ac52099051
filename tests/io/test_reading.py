"""The reading rules of every input and the work budgets (issue 23, docs/files.md "Reading").

Warm starts (``solve --z0``, ``contact-matrix --z0``) go through the problem readers' rules:
bounded JSON (duplicate keys, integer length, nesting), the data rule (real numbers only), NPZ
headers and declared sizes checked before anything is decompressed.  Work budgets
(:mod:`lcpcli.core.limits`) refuse or announce an expensive step before it starts.  Hostile
runs use the helpers of tests/cli/test_bad_inputs.py: exit 2, one ``lcpcli: error:`` line
naming the file, no traceback.
"""

from __future__ import annotations

import io
import json
import re
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lcpcli.core import limits
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.io.files import MAX_JSON_INT_DIGITS, parse_json
from lcpcli.io.stack import open_stack
from lcpcli.io.warmstart import read_warm_start
from tests.cli.test_bad_inputs import (
    BAD,
    Case,
    _npy_header,
    _zip_bomb,
    problems,
    run_in_process,
    run_subprocess,
)

PROBLEM = {"M": [[2, 1], [1, 2]], "q": [-5, -6]}
SCENE = {"bodies": [{"name": "ground", "static": True},
                    {"name": "ball", "mass": 1.0, "inertia": [0.4, 0.4, 0.4],
                     "position": [0, 0, 1], "velocity": [0, 0, -1]}],
         "contacts": [{"a": "ball", "b": "ground", "point": [0, 0, 0], "normal": [0, 0, 1]}]}

#: Warm-start files (JSON text) and the start of the reason each must be refused with.
Z0_JSON = {
    "numeric_text": ('["1", 2]', "z0 holds strings"),
    "bool": ("[true, 2]", "z0 holds booleans"),
    "int_401_digits": ("[" + "9" * 401 + ", 1]", "z0 holds an integer too large for a float"),
    "int_700_digits": ("[" + "9" * 700 + ", 1]",
                       f"invalid JSON: Exceeds the limit of {MAX_JSON_INT_DIGITS} digits"),
    "deep": ("[" * 100_000 + "]" * 100_000, "invalid JSON: arrays or objects nested too deeply"),
    "duplicate": ('{"z": [1, 2], "z": [3, 4]}', "invalid JSON: key 'z' appears twice"),
    "named_text": (json.dumps({"unknowns": ["n[c1]"], "z": ["0.5"]}), "z0 holds strings"),
    "named_bool": (json.dumps({"unknowns": ["n[c1]"], "impulses": [True]}),
                   "z0 holds booleans"),
    "named_length": (json.dumps({"unknowns": ["n[c1]", "n[c2]"], "z": [0.5]}),
                     "'unknowns' must be a list of 1 names"),
    "nan": ("[NaN]", "contains NaN or Inf"),
}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("reading")
    (d / "a.json").write_text(json.dumps(PROBLEM))
    (d / "scene.json").write_text(json.dumps(SCENE))
    for name, (text, _words) in Z0_JSON.items():
        (d / f"z_{name}.json").write_text(text)
    np.savez(d / "z_complex.npz", z=np.array([0.5 + 1j]), unknowns=np.array(["n[c1]"]))
    np.savez(d / "z_ok.npz", z=np.array([0.5]), unknowns=np.array(["n[c1]"]))
    # zip bombs: a few MB on disk, hundreds of MB to gigabytes declared
    _zip_bomb(d / "bomb_z.npz", {"z.npy": (_npy_header((60_000_000,)), 480_000_000)})
    _zip_bomb(d / "bomb_unknowns.npz", {
        "z.npy": (_npy_header((3_000_000,)), 24_000_000),
        "unknowns.npy": (_text_header((3_000_000,), 99), 3_000_000 * 99 * 4)})
    return d


def _text_header(shape: tuple[int, ...], chars: int) -> bytes:
    """A ``.npy`` header declaring strings of ``chars`` characters (``<U``)."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": f"<U{chars}", "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue()


def _refused(d: Path, args: list[str], words: str, *, sub: bool = False) -> None:
    case = Case("x", "lenient", args, BAD, words, sub=sub, memory=sub)
    out = run_subprocess(case, d) if sub else run_in_process(case, d)
    assert problems(case, out, d, {}) == []


@pytest.mark.parametrize("name", sorted(Z0_JSON))
@pytest.mark.parametrize("command", ["solve", "contact"])
def test_json_warm_start_refused(files: Path, name: str, command: str) -> None:
    args = ["solve", "{d}/a.json"] if command == "solve" else \
        ["contact-matrix", "{d}/scene.json", "--solve"]
    _refused(files, [*args, "--z0", f"{{d}}/z_{name}.json"],
             f"--z0 {{d}}/z_{name}.json: {Z0_JSON[name][1]}")


@pytest.mark.parametrize("command", ["solve", "contact"])
def test_npz_warm_start_data_rule(files: Path, command: str) -> None:
    args = ["solve", "{d}/a.json"] if command == "solve" else \
        ["contact-matrix", "{d}/scene.json", "--solve"]
    _refused(files, [*args, "--z0", "{d}/z_complex.npz"],
             "--z0 {d}/z_complex.npz: z0 holds complex numbers")


def test_named_warm_start_is_matched_by_name(files: Path) -> None:
    values, names = read_warm_start(files / "z_ok.npz")
    assert names == ["n[c1]"] and values.tolist() == [0.5]


@pytest.mark.parametrize(("bomb", "words", "cli_words"), [
    ("bomb_z.npz", "vector of 60,000,000 entries is too long", None),
    ("bomb_unknowns.npz", "array 'unknowns' of 1,133 MiB is over the limit of 256 MiB",
     # the scene's LCP has 1 unknown: the values are refused first, from their header
     "declares 3,000,000 values but the problem has n = 1 (at most 1,028 (by name) expected): "
     "refused before reading them"),
])
def test_zip_bomb_refused_from_declared_sizes(files: Path, bomb: str, words: str,
                                              cli_words: str | None) -> None:
    """Refused from the zip directory and the .npy headers: nothing is decompressed (the
    allocation peak stays far below the declared size), and the CLI runs under 1 GiB."""
    tracemalloc.start()
    try:
        with pytest.raises(ProblemError, match=re.escape(words)):
            read_warm_start(files / bomb)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20
    _refused(files, ["contact-matrix", "{d}/scene.json", "--solve", "--z0", f"{{d}}/{bomb}"],
             f"--z0 {{d}}/{bomb}: {cli_words or words}", sub=True)


def test_warm_start_bounded_by_the_problems_n(files: Path, tmp_path: Path) -> None:
    """The issue's zip bomb in --z0 within the vector limit (50,000,000 values, 400 MB, in a
    1.7 MB file) for a problem of n = 2: refused from the .npy header with n known, nothing
    decompressed (it was decompressed whole: 426 MB); by position exactly n values, by name a
    few more (limits.warm_start_entries)."""
    _zip_bomb(tmp_path / "bomb.npz", {"z.npy": (_npy_header((50_000_000,)), 400_000_000)})
    words = ("declares 50,000,000 values but the problem has n = 2 (2 expected): refused "
             "before reading them")
    tracemalloc.start()
    try:
        with pytest.raises(ProblemError, match=re.escape(words)):
            read_warm_start(tmp_path / "bomb.npz", n=2)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 * 2**20
    (tmp_path / "a.json").write_text(json.dumps(PROBLEM))
    _refused(tmp_path, ["solve", "{d}/a.json", "--z0", "{d}/bomb.npz"],
             f"--z0 {{d}}/bomb.npz: {words}", sub=True)
    most = limits.warm_start_entries(3, named=True)
    assert most == limits.WARM_START_NAMED_FACTOR * 3 + limits.WARM_START_SLACK
    for size, named, ok in ((3, False, True), (4, False, False), (most, True, True),
                            (most + 1, True, False)):
        path = tmp_path / f"z{size}{named}.npy"
        np.save(path, np.zeros(size))
        if named:
            path = path.with_suffix(".npz")
            np.savez(path, z=np.zeros(size), unknowns=np.array([f"u{k}" for k in range(size)]))
        if ok:
            assert read_warm_start(path, n=3, by_name=True)[0].shape == (size,)
        else:
            with pytest.raises(ProblemError, match="refused before reading them"):
                read_warm_start(path, n=3, by_name=True)
    _refused(tmp_path, ["solve", "{d}/a.json", "--z0", "{d}/z4False.npy"],
             "--z0 {d}/z4False.npy: declares 4 values but the problem has n = 2")


# ------------------------------------------------------------------------------ JSON bounds
@pytest.mark.parametrize("text", ['{"a": 1, "a": 1}', '[{"x": {"k": 1, "k": 2}}]',
                                  '{"M": [[1]], "q": [1], "q": [2]}'])
def test_duplicate_keys_refused_at_any_depth(text: str) -> None:
    with pytest.raises(ProblemError, match="appears twice in one object"):
        parse_json(text)


def test_integer_length_limit_is_restored_after_parsing() -> None:
    """The integer-length bound holds during a parse only (Python's own guard)."""
    import sys

    before = sys.get_int_max_str_digits()
    assert parse_json("[" + "9" * MAX_JSON_INT_DIGITS + "]")[0] == int("9" * MAX_JSON_INT_DIGITS)
    with pytest.raises(ProblemError, match="Exceeds the limit"):
        parse_json("[" + "9" * (MAX_JSON_INT_DIGITS + 1) + "]")
    assert sys.get_int_max_str_digits() == before


def test_problem_json_with_duplicate_keys_refused(tmp_path: Path) -> None:
    (tmp_path / "p.json").write_text('{"M": [[2]], "q": [-1], "q": [1]}')
    _refused(tmp_path, ["solve", "{d}/p.json"], "{d}/p.json: invalid JSON: key 'q' appears twice")


# ------------------------------------------------------------------------------ work budgets
def test_dense_budget_default_and_override(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(limits.DENSE_N_ENV, raising=False)
    assert limits.dense_n_budget() == limits.DENSE_N_BUDGET
    limits.check_dense_work(limits.DENSE_N_BUDGET, "work")
    # dense15k.h5 of the issue: n = 15,000 is refused before any dense work, naming the override
    with pytest.raises(ProblemError, match=f"set {limits.DENSE_N_ENV}=15000 to run it anyway"):
        limits.check_dense_work(15_000, "work")
    monkeypatch.setenv(limits.DENSE_N_ENV, "20000")
    limits.check_dense_work(15_000, "work")
    for bad in ("abc", "-5", str(limits.DENSE_N_FLOOR - 1)):
        monkeypatch.setenv(limits.DENSE_N_ENV, bad)
        with pytest.raises(OptionError, match=limits.DENSE_N_ENV):
            limits.dense_n_budget()


@pytest.mark.parametrize(("method", "refused"), [("auto", True), ("lemke", True),
                                                 ("newton", True), ("pgs", False)])
def test_api_checks_the_method_before_dense_work(method: str, refused: bool) -> None:
    """Pivoting, factoring and auto are checked; sweeping methods (O(n^2) a sweep) are not.
    The check takes only n: the issue's dense15k.h5 (n = 15,000) costs nothing to test."""
    from lcpcli.api import check_dense_work
    from lcpcli.solvers.registry import get_method

    if refused:
        with pytest.raises(ProblemError, match="over the dense-work budget"):
            check_dense_work(15_000, get_method(method))
    else:
        check_dense_work(15_000, get_method(method))
    check_dense_work(limits.DENSE_N_FLOOR, get_method(method))


def test_solve_many_checks_the_budget_of_one_problem(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stack of K dense problems: the budget applies to each (checked before any work)."""
    import lcpcli

    monkeypatch.setenv(limits.DENSE_N_ENV, str(limits.DENSE_N_FLOOR))
    n = limits.DENSE_N_FLOOR + 1
    M, q = np.tile(np.eye(n), (2, 1, 1)), -np.ones((2, n))
    with pytest.raises(ProblemError, match=f"n = {n}: method 'lemke"):
        lcpcli.solve_many(M, q, "lemke")
    assert lcpcli.solve_many(M, q, "pgs").status.shape == (2,)


@pytest.mark.parametrize(("command", "words"), [
    ("solve", "method 'auto' factorises or pivots on the dense M"),
    ("info", "the classification works on dense copies of M"),
])
def test_cli_refuses_dense_work_over_the_budget(tmp_path: Path, command: str,
                                                words: str) -> None:
    n = 120
    M = np.eye(n) * 2 + np.full((n, n), 0.01)
    (tmp_path / "p.json").write_text(json.dumps({"M": M.tolist(), "q": [-1.0] * n}))
    env = {limits.DENSE_N_ENV: str(limits.DENSE_N_FLOOR)}
    case = Case("budget", "lenient", [command, "{d}/p.json"], BAD,
                f"{{d}}/p.json: n = {n}: {words}", env=env)
    out = run_in_process(case, tmp_path)
    assert problems(case, out, tmp_path, {}) == []
    assert f"set {limits.DENSE_N_ENV}={n} to run it anyway" in out.stderr
    # the override runs it; a sweeping method (O(n^2) a sweep) is not limited
    runs = [([command, "{d}/p.json"], {limits.DENSE_N_ENV: str(n)})]
    if command == "solve":
        runs.append((["solve", "{d}/p.json", "-m", "pgs"], env))
    for args, run_env in runs:
        ok = Case("ok", "lenient", args, 0, None, env=run_env)
        out = run_in_process(ok, tmp_path)
        assert problems(ok, out, tmp_path, {}) == []


@pytest.mark.parametrize("command", ["info", "solve"])
def test_large_sparse_with_zero_diagonal_is_never_densified(tmp_path: Path,
                                                            command: str) -> None:
    """n = 200,000, three entries, zero diagonal (the issue's sparse30k/sparse5e7): a dense copy
    would need 298 GiB; under the 1 GiB limit the run finishes with a verdict, not exit 3."""
    _sparse_file(tmp_path / "s.npz", 200_000)
    case = Case("sparse", "memory", [command, "{d}/s.npz"], 0, None, sub=True, memory=True)
    out = run_subprocess(case, tmp_path)
    assert problems(case, out, tmp_path, {}) == []


def _lcp_file(d: Path, n: int) -> None:
    M = np.eye(n) + np.full((n, n), 0.01)
    (d / f"n{n}.json").write_text(json.dumps({"M": M.tolist(), "q": [-1.0] * n}))


@pytest.mark.parametrize("n", [limits.ENUM_ANNOUNCE_N - 1, limits.ENUM_ANNOUNCE_N])
def test_enumeration_cost_is_announced_once(tmp_path: Path, n: int) -> None:
    _lcp_file(tmp_path, n)
    case = Case("enum", "lenient", ["solve", f"{{d}}/n{n}.json", "-m", "enum"], 0, None)
    out = run_in_process(case, tmp_path)
    assert problems(case, out, tmp_path, {}) == []
    notes = [line for line in out.stderr.splitlines() if line.startswith("lcpcli: note:")]
    if n >= limits.ENUM_ANNOUNCE_N:
        assert notes == [f"lcpcli: note: enumerating up to 2^{n} = {2 ** n:,} complementary "
                         f"cones (each extra variable doubles the time; --max-n / -O max-n=24 "
                         f"allows it)"]
    else:
        assert notes == []


def _sparse_file(path: Path, n: int) -> None:
    """A sparse n x n M with three entries and a zero diagonal, q = 1."""
    indptr = np.r_[0, 1, 2, 3, np.full(n - 3, 3)]
    np.savez_compressed(path, M_format=np.array("csr"), M_shape=np.array([n, n]),
                        M_data=np.ones(3), M_indices=np.array([1, 2, 0]), M_indptr=indptr,
                        q=np.ones(n))


def test_sparse_factorisation_budget_default_and_override(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    """The issue's sparse5e7.npz (n = 5e7, few nonzeros): SuperLU failed with "gstrf was called
    with invalid arguments" (exit 3) after 69 s and 8 GB; the budget refuses it from n alone,
    naming the override and the workspace, and lets the sweeping methods run."""
    from lcpcli.api import check_sparse_work
    from lcpcli.solvers.registry import get_method

    monkeypatch.delenv(limits.SPARSE_N_ENV, raising=False)
    assert limits.sparse_n_budget() == limits.SPARSE_N_BUDGET
    for method in ("auto", "ip", "newton", "newton-min"):
        with pytest.raises(ProblemError, match=re.escape(
                f"n = 50,000,000: method '{method}' factorises the sparse M (SuperLU needs about "
                f"18.63 GiB of workspace before any fill-in): over the sparse-factorisation "
                f"budget n <= 2,000,000; set {limits.SPARSE_N_ENV}=50000000 to run it anyway")):
            check_sparse_work(50_000_000, get_method(method))
        check_sparse_work(limits.SPARSE_N_BUDGET, get_method(method))
    for method in ("pgs", "psor"):
        check_sparse_work(50_000_000, get_method(method))
    monkeypatch.setenv(limits.SPARSE_N_ENV, "60_000_000")
    check_sparse_work(50_000_000, get_method("auto"))
    for bad in ("abc", "-5", str(limits.SPARSE_N_FLOOR - 1)):
        monkeypatch.setenv(limits.SPARSE_N_ENV, bad)
        with pytest.raises(OptionError, match=limits.SPARSE_N_ENV):
            limits.sparse_n_budget()


def test_cli_refuses_a_sparse_factorisation_over_the_budget(tmp_path: Path) -> None:
    """solve of a sparse M over the budget (set low here): one line, exit 2, before SuperLU
    starts; -m pgs runs; the override runs auto."""
    n = limits.SPARSE_N_FLOOR + 1
    np.savez_compressed(tmp_path / "s.npz", M_format=np.array("csr"),
                        M_shape=np.array([n, n]), M_data=np.full(n, 2.0),
                        M_indices=np.arange(n), M_indptr=np.arange(n + 1), q=-np.ones(n))
    env = {limits.SPARSE_N_ENV: str(limits.SPARSE_N_FLOOR)}
    case = Case("sparse-budget", "internal", ["solve", "{d}/s.npz"], BAD,
                f"{{d}}/s.npz: n = {n:,}: method 'auto' factorises the sparse M", env=env)
    assert problems(case, run_in_process(case, tmp_path), tmp_path, {}) == []
    for args, run_env in ((["solve", "{d}/s.npz", "-m", "pgs", "--json"], env),
                          (["solve", "{d}/s.npz", "--json"], {limits.SPARSE_N_ENV: str(n)})):
        ok = Case("ok", "lenient", args, 0, None, env=run_env)
        assert problems(ok, run_in_process(ok, tmp_path), tmp_path, {}) == []


def test_pivot_checks_the_dense_budget(tmp_path: Path) -> None:
    _sparse_file(tmp_path / "s.npz", 150)
    case = Case("pivot", "lenient", ["pivot", "{d}/s.npz", "-d", "z1"], BAD,
                "{d}/s.npz: n = 150: pivot works on a dense tableau of M",
                env={limits.DENSE_N_ENV: str(limits.DENSE_N_FLOOR)})
    assert problems(case, run_in_process(case, tmp_path), tmp_path, {}) == []


def test_enumeration_refusal_of_a_huge_n_is_one_line(tmp_path: Path) -> None:
    """2^20000 has more digits than Python turns into text: the message gives the exponent."""
    _sparse_file(tmp_path / "s.npz", 20_000)
    case = Case("enum", "lenient", ["enumerate", "{d}/s.npz"], BAD,
                "n = 20000 means 2^20,000 complementary cones, above the limit max-n = 24")
    assert problems(case, run_in_process(case, tmp_path), tmp_path, {}) == []
    assert limits.power_of_two(20) == "2^20 = 1,048,576"


def test_stack_names_declared_huge_are_refused_unread(tmp_path: Path) -> None:
    """A 500 KB HDF5 stack whose never-written names repeat a 500 KB fill value (95 GB
    declared), and an NPZ stack whose names member is a zip bomb (1.1 GB declared): refused
    from the headers, under the 1 GiB limit (MemoryError, exit 3, before)."""
    import h5py

    K = 200_000
    with h5py.File(tmp_path / "fill.h5", "w") as f:
        f.create_dataset("M", shape=(K, 2, 2), dtype="f8", chunks=(10_000, 2, 2), fillvalue=1.0)
        f.create_dataset("q", shape=(K, 2), dtype="f8", chunks=(10_000, 2), fillvalue=-1.0)
        f.create_dataset("names", shape=(K,), dtype=h5py.string_dtype(), chunks=(10_000,),
                         fillvalue="x" * 500_000)
    K = 3_000_000
    _zip_bomb(tmp_path / "bomb.npz", {
        "M.npy": (_npy_header((K, 2, 2)), K * 32), "q.npy": (_npy_header((K, 2)), K * 16),
        "names.npy": (_text_header((K,), 99), K * 99 * 4)})
    for name, size in (("fill.h5", "95,367 MiB"), ("bomb.npz", "1,133 MiB")):
        _refused(tmp_path, ["solve", f"{{d}}/{name}"],
                 f"{{d}}/{name}: the declared 'names'", sub=True)
        with pytest.raises(ProblemError, match=f"of {size} is over the limit of 1,024 MiB"), \
                open_stack(tmp_path / name):
            pass


@pytest.mark.parametrize("command", ["solve", "info"])
@pytest.mark.parametrize("fmt", ["h5", "npz"])
def test_dense15k_refused_from_the_header(tmp_path: Path, command: str, fmt: str) -> None:
    """The issue's dense15k.h5: a 122 KB file whose 15,000 x 15,000 M is never written (HDF5
    fill value; NPZ: a zip bomb of 1.7 GiB of zeros).  solve (auto) and info are refused by the
    dense-work budget from the header, before M is read: no dense copy is allocated."""
    import h5py

    n = 15_000
    path = tmp_path / f"dense15k.{fmt}"
    if fmt == "h5":
        with h5py.File(path, "w") as f:
            f.create_dataset("M", shape=(n, n), dtype="f8", chunks=(1000, 1000), fillvalue=1.0)
            f["q"] = -np.ones(n)
    else:
        _zip_bomb(path, {"M.npy": (_npy_header((n, n)), n * n * 8),
                         "q.npy": (_npy_header((n,)), n * 8)})
    case = Case("dense15k", "memory", [command, f"{{d}}/{path.name}"], BAD,
                f"{{d}}/{path.name}: n = 15,000: ")
    tracemalloc.start()
    try:
        out = run_in_process(case, tmp_path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert problems(case, out, tmp_path, {}) == []
    assert f"{limits.DENSE_N_ENV}=15000" in out.stderr
    assert peak < 64 * 2**20  # one dense copy would be 1,716 MiB


# ------------------------------------------------------------------------------ HDF5 chunks
def _chunked(f: Any, name: str, data: np.ndarray | None = None, width: int = 10_000) -> None:
    """Dataset ``name`` of ``f`` (re)made with ``data`` (default: its own) stored gzip'ed in
    chunks ``width`` wide along the last axis: chunks far larger than the data."""
    data = f[name][...] if data is None else data
    if name in f:
        del f[name]
    f.create_dataset(name, data=data, maxshape=(*data.shape[:-1], None),
                     chunks=(*data.shape[:-1], width), compression="gzip")


def test_hdf5_chunk_bombs_refused_from_the_header(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """A dataset stored in chunks larger than both its data and MAX_H5_CHUNK_BYTES is refused
    before HDF5 decompresses a chunk (the audit's 2 x 2 M in chunks of 2 x 260,000,000: 21 s
    and 4.1 GB for ``info``): problems (root, groups: the batch's fast path), stacks, scenes,
    stacked results read by --z0 and resumed, per-problem HDF5 results resumed.  The limit is
    lowered to 64 KiB here so the files stay small (chunks of 160 KB)."""
    import h5py

    from lcpcli.contact.scene import load_scene, write_scene_hdf5
    from lcpcli.io import files as io_files
    from lcpcli.io.hdf5_format import read_many

    words = "is stored in HDF5 chunks of"
    d = tmp_path
    (d / "a.json").write_text(json.dumps(PROBLEM))
    (d / "b.json").write_text(json.dumps(PROBLEM))
    M, q = np.array(PROBLEM["M"], float), np.array(PROBLEM["q"], float)
    with h5py.File(d / "p.h5", "w") as f:
        _chunked(f, "M", M)
        f["q"] = q
    with h5py.File(d / "groups.h5", "w") as f:
        for name in ("p0", "p1"):
            _chunked(f.create_group(name), "M", M)
            f[name]["q"] = q
    with h5py.File(d / "stack.h5", "w") as f:
        f["M"], f["q"] = np.stack([M] * 4), np.stack([q] * 4)
    with h5py.File(d / "stackbomb.h5", "w") as f:
        _chunked(f, "M", np.stack([M] * 4))
        f["q"] = np.stack([q] * 4)
    write_scene_hdf5(load_scene(Path(__file__).parents[2] / "samples" / "scene_two_balls.json"),
                     d / "scene.h5")
    with h5py.File(d / "scene.h5", "r+") as f:
        _chunked(f["contacts"], "point")
    ok_cases = [["solve", "{d}/stack.h5", "-o", "{d}/sres.h5"],
                ["solve", "{d}/stack.h5", "-o", "{d}/sres2.h5"],
                ["solve", "{d}/a.json", "{d}/b.json", "-o", "{d}/rows.h5"]]
    for args in ok_cases:
        assert run_in_process(Case("x", "lenient", args, 0, None), d).code == 0
    for name in ("sres.h5", "sres2.h5"):
        with h5py.File(d / name, "r+") as f:
            _chunked(f[next(iter(f))], "z")
    with h5py.File(d / "rows.h5", "r+") as f:
        _chunked(f[next(iter(f))], "z")
    monkeypatch.setattr(io_files, "MAX_H5_CHUNK_BYTES", 2**16)
    _refused(d, ["info", "{d}/p.h5"], f"'M' {words} 160,000 bytes for 32 bytes of data")
    _refused(d, ["solve", "{d}/p.h5"], f"'M' {words}")
    _refused(d, ["solve", "{d}/stackbomb.h5", "-o", "{d}/out.jsonl"], f"'M' {words}")
    _refused(d, ["contact-matrix", "{d}/scene.h5"], f"'contacts/point' {words}")
    _refused(d, ["solve", "{d}/stack.h5", "--z0", "{d}/sres.h5", "-o", "{d}/o2.jsonl"],
             words)
    _refused(d, ["solve", "{d}/stack.h5", "-o", "{d}/sres2.h5", "--resume"], words)
    _refused(d, ["solve", "{d}/a.json", "{d}/b.json", "-o", "{d}/rows.h5", "--resume"],
             words)
    got = dict(read_many(d / "groups.h5", ["p0", "p1"]))
    assert all(isinstance(e, ProblemError) and words in str(e) for e in got.values())
