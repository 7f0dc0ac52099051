"""The compiled kernels themselves: dense linear algebra, threads, OpenMP and worker pools."""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from lcpcli.core.problem import Problem
from lcpcli.solvers.kernels import dense
from lcpcli.solvers.kernels.lemke import lemke_kernel, polish_kernel
from lcpcli.solvers.kernels.lemke_revised import lemke_revised_kernel
from lcpcli.solvers.methods.lemke import NO_RECORD, PIVOT_TOL, TIE_TOL

ROOT = Path(__file__).resolve().parents[2]


def spd(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    A = rng.standard_normal((n, n))
    return A @ A.T + n * np.eye(n), rng.standard_normal(n)


@pytest.mark.parametrize("m", [1, 2, 5, 31, 63, 64, 65, 130])
def test_dense_solve_and_inverse_match_numpy(m):
    """Own loops below the LAPACK crossover, LAPACK (bound on first need) from it up."""
    rng = np.random.default_rng(m)
    A = rng.standard_normal((m, m)) + m * np.eye(m)
    b = rng.standard_normal(m)
    x = dense.solve(A, b)
    np.testing.assert_allclose(A @ x, b, atol=1e-12 * m)
    np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(dense.inv(A), np.linalg.inv(A), rtol=1e-10, atol=1e-13)
    if m >= dense.LAPACK_MIN:
        assert dense.lapack_bound()
        if dense._numpy_blas_files():  # a numpy wheel: its OpenBLAS, not scipy's
            assert dense.lapack_source() in dense._numpy_blas_files()


def test_dense_singular_is_an_error_both_ways():
    for m in (3, 70):
        A = np.ones((m, m))
        with pytest.raises(np.linalg.LinAlgError):
            dense.solve(A, np.ones(m))
        with pytest.raises(np.linalg.LinAlgError):
            dense.inv(A)


def test_small_solves_import_no_scipy():
    """A 2 x 2 (or 63 x 63) problem never imports scipy; the kernels import no heavy module."""
    code = (
        "import sys, numpy as np\n"
        "import lcpcli\n"
        "from lcpcli.core.problem import Problem\n"
        "for m in ('lemke-tableau', 'lemke-revised', 'murty', 'dantzig', 'pgs', 'enum'):\n"
        "    assert lcpcli.solve(Problem.create([[2.,1],[1,2]], [-5.,-6]), m).solved, m\n"
        "rng = np.random.default_rng(1); A = rng.standard_normal((63, 63))\n"
        "p = Problem.create(A @ A.T + 63 * np.eye(63), -np.ones(63))\n"
        "assert lcpcli.solve(p, 'lemke').solved\n"
        "heavy = [k for k in sys.modules if k.split('.')[0] in ('scipy', 'numba', 'h5py')]\n"
        "print(heavy)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_polish_keeps_the_kernel_answer_on_a_singular_block():
    M = np.array([[1.0, 1.0], [1.0, 1.0]])
    q = np.array([-1.0, -1.0])
    z = np.array([0.5, 0.5])
    basic = np.array([2, 3], dtype=np.int64)  # both z basic: M[b, b] singular
    np.testing.assert_array_equal(polish_kernel(M, q, z, basic), z)


def test_kernels_run_in_threads_with_the_same_results():
    """The kernels release the GIL (nogil C functions): threads give the serial answers."""
    rng = np.random.default_rng(5)
    probs = [spd(rng, n) for n in (5, 30, 80, 120) for _ in range(3)]

    def run(p):
        M, q = p
        a = lemke_kernel(M, q, np.ones(len(q)), 10_000, PIVOT_TOL, TIE_TOL, NO_RECORD)
        b = lemke_revised_kernel(M, q, np.ones(len(q)), 10_000, PIVOT_TOL, TIE_TOL,
                                 NO_RECORD, 50)
        return a[1], b[1], a[2], b[2]

    serial = [run(p) for p in probs]
    with ThreadPoolExecutor(4) as ex:
        threaded = list(ex.map(run, probs))
    for s, t in zip(serial, threaded, strict=True):
        for u, v in zip(s, t, strict=True):
            np.testing.assert_array_equal(u, v)


@pytest.mark.parametrize("refactor_every", [1, 3, 50])
def test_revised_kernel_pivots_as_the_tableau_on_both_sides_of_its_stack_work_space(
        refactor_every):
    """Up to n = 16 the revised kernel's work space, its refactorisation's included, is on the
    stack, above it on the heap: on both sides, refactorising at every pivot or rarely, it
    takes the tableau kernel's pivots (the same rule) and ends at the same z."""
    rng = np.random.default_rng(11)
    for n in range(12, 22):
        for _ in range(3):
            M, q = spd(rng, n)
            ones = np.ones(n)
            rec_t, rec_r = (np.zeros((4 * n, 3), dtype=np.int64) for _ in range(2))
            t = lemke_kernel(M, q, ones, 10_000, PIVOT_TOL, TIE_TOL, rec_t)
            r = lemke_revised_kernel(M, q, ones, 10_000, PIVOT_TOL, TIE_TOL, rec_r,
                                     refactor_every)
            assert r[0] == t[0] and r[2] == t[2] > 0
            assert refactor_every > 1 or r[7] >= r[2] - 2  # it did refactorise
            np.testing.assert_array_equal(rec_r[:r[2]], rec_t[:t[2]])
            np.testing.assert_allclose(r[1], t[1], rtol=1e-9, atol=1e-12)


def test_enum_fast_and_direct_paths_agree_in_parallel():
    """The OpenMP fast path (depth-first pivoting) and the direct LU path classify alike."""
    from lcpcli.analysis.enumeration import enumerate_cones

    rng = np.random.default_rng(3)
    for n in (7, 14, 14):
        A = rng.standard_normal((n, n))
        M = A @ A.T * 0.1 + rng.standard_normal((n, n))
        p = Problem.create(M, rng.standard_normal(n) - 0.5)
        fast = enumerate_cones(p, fast=True, max_n=20)
        slow = enumerate_cones(p, fast=False, max_n=20)
        assert fast.verdict == slow.verdict  # (the fast path prunes differently)
        assert fast.counts["feasible"] == slow.counts["feasible"]
        assert sorted(c.code for c in fast.cones) == sorted(c.code for c in slow.cones)


def _enum_problem(n: int, seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    C = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + 0.1 * np.eye(n) + (C - C.T), 3 * rng.standard_normal(n),
                          name=f"enum{seed}")


def test_enum_in_a_worker_pool_after_openmp_in_the_parent(tmp_path):
    """The crash of issue 13: a pool forked from a process that ran an OpenMP region."""
    from lcpcli.analysis.enumeration import enumerate_cones
    from lcpcli.batch.inputs import expand_inputs
    from lcpcli.batch.pool import iter_local
    from lcpcli.batch.records import SolveOptions
    from lcpcli.io import save

    enumerate_cones(_enum_problem(16, 0), max_n=20)  # a parallel region in this process
    for seed in (1, 2, 3):
        save(_enum_problem(15, seed), tmp_path / f"e{seed}.json")
    tasks, bad = expand_inputs([str(tmp_path)])
    rows = list(iter_local(tasks, SolveOptions(method="enum"), jobs=2, timeout=120))
    assert not bad and len(rows) == 3
    assert all(r["status"] == "solved" for r in rows), [r["message"] for r in rows]


def test_cli_enum_batch_and_bench(cli, tmp_path):
    from lcpcli.io import save

    for seed in (1, 2):
        save(_enum_problem(15, seed), tmp_path / f"e{seed}.json")
    r = cli("solve", str(tmp_path / "e1.json"), str(tmp_path / "e2.json"), "-m", "enum",
            "-j", "2", "--json")
    assert r.returncode == 0, r.stderr
    assert [json.loads(line)["status"] for line in r.stdout.splitlines()] == ["solved"] * 2
    r = cli("bench", str(tmp_path), "-m", "enum,lemke", "--repeat", "1", "--timeout", "120",
            "--no-peers", "--json")
    assert r.returncode == 0, r.stderr
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(rows) == 4 and all(row["status"] == "solved" for row in rows)


def _raising(problem, method, tol=1e-8):
    raise RuntimeError("kernel bug")


def test_bench_reports_methods_that_error():
    """A method that raises (or whose child dies) is an error of the run: exit code 3."""
    from lcpcli.bench import runner, suites

    rep = runner.run_bench([suites.kostreva()], ["broken"], repeat=0, solve_fn=_raising)
    assert [r.status for r in rep.errors] == ["error"] and not rep.defects
    rep = runner.run_bench([suites.kostreva()], ["broken"], repeat=0, solve_fn=_raising,
                           timeout=60)
    assert len(rep.errors) == 1
    rep = runner.run_bench([suites.kostreva()], ["lemke"], repeat=0)
    assert not rep.errors


def test_fused_call_certifies_like_the_certificate_module():
    """Kernel + polish + certificate in one C call: the same pivots and z as the kernel followed
    by its polish, the same certificate as lcpcli.core.certificate.check (the one
    definition)."""
    from lcpcli.core.certificate import check, from_kernel
    from lcpcli.solvers.kernels.lemke import polish_kernel
    from lcpcli.solvers.kernels.lemke_revised import OK, lemke_solve_certified

    rng = np.random.default_rng(8)
    for trial in range(40):
        n = int(rng.integers(1, 30))
        A = rng.standard_normal((n, n))
        scale = 10.0 ** rng.integers(-3, 4)
        M = [A @ A.T + 0.1 * np.eye(n), A - A.T + np.eye(n)][trial % 2] * scale
        q = rng.standard_normal(n)
        got = lemke_solve_certified(M, q, None, 5000, PIVOT_TOL, TIE_TOL, 50)
        ref = lemke_revised_kernel(M, q, np.ones(n), 5000, PIVOT_TOL, TIE_TOL,
                                   np.zeros((0, 3), dtype=np.int64), 50)
        assert got.status == ref[0] and got.pivots == ref[2]
        if got.status == OK:
            np.testing.assert_array_equal(got.z, polish_kernel(M, q, ref[1], ref[3]))
        cert = got.cert
        if cert is None:  # trivial: z = 0
            assert got.certificate(1e-8) is None
            continue
        c, w_ref = check(Problem.create(M, q), got.z, 1e-8)
        np.testing.assert_array_equal(got.w, w_ref)
        assert cert[0] == 0
        assert cert[1:] == (c.error, c.backward_error, c.growth, c.residual, c.bound_violation,
                            c.w_violation, c.complementarity, c.equality_residual, c.worst)
        # the record's Certificate (no tuple in between) is the tuple's, by the one rule
        for tol in (1e-8, 1e-14, c.error):
            assert got.certificate(tol) == from_kernel(cert, tol) == check(
                Problem.create(M, q), got.z, tol)[0]
