"""Mixed and box LCPs: Schur reduction, block pivoting, mlcp-schur, mlcp-lemke, dantzig.

Answers are checked by substitution into the ORIGINAL problem (independently of the
project's certificate), box LCPs against an enumeration of the 3^n active sets.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from lcpcli.analysis.mlcp import choose_pivot_set, factor, recover, reduce, schur, split
from lcpcli.api import solve
from lcpcli.core.problem import Problem
from lcpcli.io import load

_ROOT = Path(__file__).resolve().parents[2]
MLCP_DIR = next((d / "shared" / "data" / "siconos" / "mlcp" for d in (_ROOT.parent,
                 _ROOT.parent.parent) if (d / "shared" / "data" / "siconos" / "mlcp").is_dir()),
                _ROOT.parent / "shared" / "data" / "siconos" / "mlcp")
MLCP_FILES = sorted(p.name for p in MLCP_DIR.glob("*_mlcp.dat")
                    if p.name != "Rectangular_mlcp.dat") if MLCP_DIR.is_dir() else []
#: Siconos' README: "Lemke on the Schur complement" is expected to fail on these.
SICONOS_SCHUR_LEMKE_FAILS = ["PD_mlcp.dat", "diodeBridge_mlcp.dat", "diodeBridge20_mlcp.dat",
                             "diodeBridge40_mlcp.dat", "Buck2_mlcp.dat", "deltasigma2_mlcp.dat"]
A_SINGULAR = ["PD_mlcp.dat", "diodeBridge_mlcp.dat", "diodeBridge20_mlcp.dat",
              "diodeBridge40_mlcp.dat"]

needs_data = pytest.mark.skipif(not MLCP_FILES, reason="shared Siconos MLCP data not present")


# ----------------------------------------------------------------------------- references
def check_box_solution(M, q, lo, up, z, tol=1e-7) -> None:
    """Independent substitution check of lo <= z <= up, sign conditions and w = 0 between."""
    M = np.asarray(M, dtype=float)
    w = M @ z + q
    scale = np.max(np.abs(M)) * max(1.0, np.max(np.abs(z))) + np.max(np.abs(q)) + 1.0
    t = tol * scale
    assert np.all(z >= lo - t) and np.all(z <= up + t), "bound violated"
    for i in range(len(z)):
        at_lo = np.isfinite(lo[i]) and abs(z[i] - lo[i]) <= t
        at_up = np.isfinite(up[i]) and abs(z[i] - up[i]) <= t
        if at_lo and at_up:
            continue
        if at_lo:
            assert w[i] >= -t, f"w{i + 1} = {w[i]} < 0 at the lower bound"
        elif at_up:
            assert w[i] <= t, f"w{i + 1} = {w[i]} > 0 at the upper bound"
        else:
            assert abs(w[i]) <= t, f"w{i + 1} = {w[i]} != 0 strictly inside the box"


def check_mlcp_solution(problem: Problem, z: np.ndarray, tol: float = 1e-7) -> None:
    lo, up = problem.bounds()
    check_box_solution(problem.dense_M(), problem.q, lo, up, z, tol)


def enumerate_box(M, q, lo, up) -> list[np.ndarray]:
    """All solutions of the box LCP found among the 3^n active sets (L, U, F per index)."""
    n = len(q)
    sols = []
    for pattern in itertools.product("LUF", repeat=n):
        if any((s == "L" and not np.isfinite(lo[i])) or (s == "U" and not np.isfinite(up[i]))
               for i, s in enumerate(pattern)):
            continue
        z = np.zeros(n)
        F = [i for i, s in enumerate(pattern) if s == "F"]
        N = [i for i, s in enumerate(pattern) if s != "F"]
        for i in N:
            z[i] = lo[i] if pattern[i] == "L" else up[i]
        if F:
            K = M[np.ix_(F, F)]
            if abs(np.linalg.det(K)) < 1e-12:
                continue
            z[F] = np.linalg.solve(K, -(q[F] + M[np.ix_(F, N)] @ z[N]))
        w = M @ z + q
        ok = all(lo[i] - 1e-9 <= z[i] <= up[i] + 1e-9 for i in F)
        ok = ok and all(w[i] >= -1e-9 for i in N if pattern[i] == "L")
        ok = ok and all(w[i] <= 1e-9 for i in N if pattern[i] == "U")
        if ok and not any(np.allclose(z, s, atol=1e-8) for s in sols):
            sols.append(z)
    return sols


def random_bounds(rng, n, free=0):
    lo = -rng.uniform(0.0, 2.0, n)
    up = rng.uniform(0.0, 2.0, n)
    kinds = rng.integers(0, 4, n)
    lo[kinds == 1] = -np.inf            # upper bound only
    up[kinds == 2] = np.inf             # lower bound only
    lo[:free] = -np.inf                 # free variables
    up[:free] = np.inf
    return lo, up


def spd(rng, n):
    A = rng.standard_normal((n, n))
    return A @ A.T / n + 0.2 * np.eye(n)


def p_matrix(rng, n):
    """Nonsymmetric P-matrix, not PD: permuted upper triangular, unit diagonal, big entries."""
    U = np.triu(rng.uniform(-3.0, 3.0, (n, n)), 1) + np.diag(rng.uniform(0.5, 2.0, n))
    perm = rng.permutation(n)
    return U[np.ix_(perm, perm)]


# ----------------------------------------------------------------------------- mlcp.py
def test_split_and_schur_formula():
    rng = np.random.default_rng(1)
    M = spd(rng, 7) + 0.3 * rng.standard_normal((7, 7))
    q = rng.standard_normal(7)
    p = Problem.create(M, q, n_eq=3)
    b = split(p)
    assert np.array_equal(np.block([[b.A, b.C], [b.D, b.B]]), M)
    red = schur(p)
    Ainv = np.linalg.inv(b.A)
    np.testing.assert_allclose(red.lcp_M, b.B - b.D @ Ainv @ b.C, atol=1e-12)
    np.testing.assert_allclose(red.lcp_q, b.b - b.D @ Ainv @ b.a, atol=1e-12)
    v = np.abs(rng.standard_normal(4))
    z = recover(M, q, red, v)
    np.testing.assert_allclose(z[3:], v)
    np.testing.assert_allclose((M @ z + q)[:3], 0.0, atol=1e-12)   # u recovered exactly


def test_block_pivot_is_equivalent_to_the_mlcp():
    """After pivoting on eq + J, a solution of the reduced LCP recovers one of the MLCP."""
    rng = np.random.default_rng(2)
    for _ in range(5):
        n_eq, m = 2, 4
        N = n_eq + m
        M = spd(rng, N) + 0.2 * (lambda K: K - K.T)(rng.standard_normal((N, N)))
        M[:n_eq, :n_eq] = np.outer(M[:n_eq, 0], M[0, :n_eq]) / M[0, 0]  # A of rank 1
        q = rng.standard_normal(N)
        J, cond = choose_pivot_set(M, n_eq)
        assert J.size >= 1 and np.isfinite(cond)
        red = reduce(M, q, n_eq, J)
        sub = Problem.create(red.lcp_M, red.lcp_q)
        r = solve(sub, "lemke")
        if not r.solved:
            continue
        z = recover(M, q, red, r.z)
        check_mlcp_solution(Problem.create(M, q, n_eq=n_eq), z)


def test_mlcp_lemke_on_monotone_mlcps_with_singular_a():
    """Random monotone MLCPs (M + M^T PSD) with A of rank 1 and a planted solution."""
    rng = np.random.default_rng(3)
    solved = 0
    for _trial in range(8):
        n_eq, m = 3, 5
        a = rng.standard_normal(n_eq)
        A = np.outer(a, a)                               # rank 1, PSD
        C = rng.standard_normal((n_eq, m))
        Bh = rng.standard_normal((m, m))
        B = Bh @ Bh.T / m + 0.1 * np.eye(m)
        M = np.block([[A, C], [-C.T, B]])                # monotone
        u = rng.standard_normal(n_eq)
        v = np.where(rng.random(m) < 0.5, rng.uniform(0.5, 2.0, m), 0.0)
        w = np.r_[np.zeros(n_eq), np.where(v > 0, 0.0, rng.uniform(0.5, 2.0, m))]
        q = w - M @ np.r_[u, v]
        p = Problem.create(M, q, n_eq=n_eq)
        r = solve(p, "mlcp-lemke")
        assert r.status == "solved", r.message          # a solution exists; M is monotone
        check_mlcp_solution(p, r.z)
        solved += 1
        rs = solve(p, "mlcp-schur")
        assert rs.status == "unsolved" and "mlcp-lemke" in rs.message
    assert solved == 8


def test_infeasible_mlcp_is_proven():
    """u + 2 = 0 and 0 <= v _|_ 0 u + 0 v - 1 >= 0: no v gives w >= 0 (Farkas: y = e_1)."""
    p = Problem.create([[1.0, 0.0], [0.0, 0.0]], [2.0, -1.0], n_eq=1)
    for method in ("mlcp-schur", "mlcp-lemke"):
        r = solve(p, method)
        assert r.status == "no_solution", r.message
        assert "Farkas" in r.message


def test_equilibrated_condition_estimate_on_buck():
    """Buck converter: cond(A) 2.6e12 from bad row scaling only; equilibrated it is modest."""
    if not (MLCP_DIR / "Buck2_mlcp.dat").exists():
        pytest.skip("no Buck2 data")
    p = load(MLCP_DIR / "Buck2_mlcp.dat")
    A = split(p).A
    assert np.linalg.cond(A) > 1e12
    assert factor(A).cond < 1e8
    assert not np.isfinite(factor(np.array([[1.0, 2.0], [2.0, 4.0]])).cond)


# ----------------------------------------------------------------------------- Siconos MLCP files
@needs_data
@pytest.mark.parametrize("name", MLCP_FILES)
def test_every_siconos_mlcp_file_is_solved(name):
    p = load(MLCP_DIR / name)
    r = solve(p, "mlcp-lemke")
    assert r.status == "solved", r.message
    assert r.error <= 1e-8
    check_mlcp_solution(p, r.z)
    assert r.certificate.equality_residual <= 1e-8 * (1 + np.max(np.abs(p.q)))


@needs_data
@pytest.mark.parametrize("name", MLCP_FILES)
def test_no_false_solved_on_siconos_files(name):
    p = load(MLCP_DIR / name)
    for method in ("mlcp-schur", "mlcp-lemke"):
        r = solve(p, method)
        assert r.status in ("solved", "unsolved")
        if r.status == "solved":
            check_mlcp_solution(p, r.z)
        else:
            assert not r.certificate.passed


@needs_data
@pytest.mark.parametrize("name", SICONOS_SCHUR_LEMKE_FAILS)
def test_siconos_schur_lemke_failures_are_honest(name):
    """Siconos' 'Lemke on the Schur complement' fails on these: ours is unsolved where A is
    singular (and says so), and is solved elsewhere only with a passing substitution check."""
    p = load(MLCP_DIR / name)
    r = solve(p, "mlcp-schur")
    if name in A_SINGULAR:
        assert r.status == "unsolved"
        assert "singular" in r.message and "mlcp-lemke" in r.message
    elif r.status == "solved":
        check_mlcp_solution(p, r.z)
    # the direct method solves all of them
    assert solve(p, "mlcp-lemke").solved


@needs_data
def test_deltasigma_is_fast_and_accurate():
    p = load(MLCP_DIR / "deltasigma_mlcp.dat")
    assert p.n == 221 and p.n_eq == 65
    for method in ("mlcp-schur", "mlcp-lemke"):
        r = solve(p, method)
        assert r.solved


@needs_data
def test_rectangular_file_is_bad_input(cli):
    res = cli("solve", str(MLCP_DIR / "Rectangular_mlcp.dat"), "--method", "mlcp-lemke")
    assert res.returncode == 2
    assert "Traceback" not in res.stderr + res.stdout
    assert res.stderr.count("\n") == 1


# ----------------------------------------------------------------------------- box LCPs
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
@pytest.mark.parametrize("cls", ["spd", "p"])
def test_dantzig_box_matches_enumeration(n, cls):
    rng = np.random.default_rng(100 * n + (cls == "p"))
    for trial in range(3):
        M = spd(rng, n) if cls == "spd" else p_matrix(rng, n)
        q = 2.0 * rng.standard_normal(n)
        lo, up = random_bounds(rng, n, free=trial % 2)
        sols = enumerate_box(M, q, lo, up)
        assert len(sols) == 1  # P-matrix: unique solution for every box
        r = solve(Problem.create(M, q, lower=lo, upper=up), "dantzig")
        assert r.status == "solved", r.message
        np.testing.assert_allclose(r.z, sols[0], atol=1e-8, rtol=1e-8)
        check_box_solution(M, q, lo, up, r.z)


def test_dantzig_lcp_psd_matches_lemke():
    """Rank-deficient symmetric PSD: solutions may differ, but w = M z + q is unique."""
    rng = np.random.default_rng(7)
    for n in (5, 20, 60):
        B = rng.standard_normal((n, n // 2))
        M = B @ B.T
        q = rng.standard_normal(n)
        q -= 1.5 * M @ np.abs(rng.standard_normal(n))   # a feasible, hence solvable, LCP
        p = Problem.create(M, q)
        rd, rl = solve(p, "dantzig"), solve(p, "lemke")
        assert rd.solved and rl.solved, (rd.message, rl.message)
        np.testing.assert_allclose(rd.w, rl.w, atol=1e-7 * (1 + np.max(np.abs(q))))
        assert np.all(rd.z >= 0) and abs(rd.z @ rd.w) <= 1e-7 * (1 + np.max(np.abs(q))) ** 2


def test_dantzig_p_matrix_lcp_matches_lemke():
    rng = np.random.default_rng(8)
    for n in (6, 30):
        M = spd(rng, n) + 0.5 * (lambda K: K - K.T)(rng.standard_normal((n, n)))
        q = rng.standard_normal(n)
        p = Problem.create(M, q)
        rd, rl = solve(p, "dantzig"), solve(p, "lemke")
        assert rd.solved and rl.solved
        np.testing.assert_allclose(rd.z, rl.z, atol=1e-8)


def test_free_variables_and_infinite_bounds():
    """Free indices end with w_i = 0; one-sided bounds are honoured."""
    rng = np.random.default_rng(9)
    n = 6
    M = spd(rng, n)
    q = 3.0 * rng.standard_normal(n)
    lo = np.array([-np.inf, -np.inf, 0.0, -np.inf, -1.0, -0.5])
    up = np.array([np.inf, np.inf, np.inf, 0.25, 1.0, 0.5])
    r = solve(Problem.create(M, q, lower=lo, upper=up), "dantzig")
    assert r.solved
    assert abs(r.w[0]) <= 1e-10 and abs(r.w[1]) <= 1e-10
    check_box_solution(M, q, lo, up, r.z)
    (ref,) = enumerate_box(M, q, lo, up)
    np.testing.assert_allclose(r.z, ref, atol=1e-9)
    # all free: the linear system M z = -q
    r = solve(Problem.create(M, q, lower=[None] * n, upper=[None] * n), "dantzig")
    np.testing.assert_allclose(r.z, np.linalg.solve(M, -q), atol=1e-9)


def test_box_equals_mlcp_when_bounds_say_so():
    """A box LCP with free first block is the MLCP: dantzig and mlcp-schur agree."""
    rng = np.random.default_rng(11)
    n_eq, n = 3, 8
    M = spd(rng, n)
    q = rng.standard_normal(n)
    lo = np.r_[np.full(n_eq, -np.inf), np.zeros(n - n_eq)]
    up = np.full(n, np.inf)
    rb = solve(Problem.create(M, q, lower=lo, upper=up), "dantzig")
    rm = solve(Problem.create(M, q, n_eq=n_eq), "mlcp-schur")
    assert rb.solved and rm.solved
    np.testing.assert_allclose(rb.z, rm.z, atol=1e-9)


def test_dantzig_outside_its_class_is_never_falsely_solved():
    rng = np.random.default_rng(12)
    bad = 0
    for _ in range(30):
        n = 5
        M = rng.standard_normal((n, n))          # arbitrary: often not P, not PSD
        q = rng.standard_normal(n)
        lo, up = random_bounds(rng, n)
        p = Problem.create(M, q, lower=lo, upper=up)
        r = solve(p, "dantzig")
        if r.solved:
            check_box_solution(M, q, lo, up, r.z)
        else:
            bad += 1
            assert r.status == "unsolved" and not r.certificate.passed
    assert bad < 30


def test_fixed_variables():
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    q = np.array([-1.0, -4.0])
    r = solve(Problem.create(M, q, lower=[0.5, -1.0], upper=[0.5, 10.0]), "dantzig")
    assert r.solved
    np.testing.assert_allclose(r.z, [0.5, 1.75])


# ----------------------------------------------------------------------------- CLI
def test_cli_box_sample(cli, samples):
    res = cli("solve", str(samples / "box_small.json"), "--method", "dantzig", "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    p = load(samples / "box_small.json")
    assert out["status"] == "solved"
    check_box_solution(p.M, p.q, *p.bounds(), np.array(out["z"]))
    (ref,) = enumerate_box(p.M, p.q, *p.bounds())
    np.testing.assert_allclose(out["z"], ref, atol=1e-12)
    assert out["certificate"]["bound_violation"] == 0.0


def test_cli_mlcp_sample_all_routes(cli, samples):
    for f, extra in (("mlcp_small.dat", []), ("mlcp_small.json", ["-m", "mlcp-lemke"]),
                     ("mlcp_small.json", ["-m", "mlcp-schur", "-O", "inner=dantzig"])):
        res = cli("solve", str(samples / f), "--json", *extra)
        assert res.returncode == 0, res.stderr
        out = json.loads(res.stdout)
        np.testing.assert_allclose(out["z"], [1, -1, 2, 0], atol=1e-12)
        np.testing.assert_allclose(out["w"], [0, 0, 0, 3], atol=1e-12)


def test_cli_human_output_mentions_equalities(cli, samples):
    res = cli("solve", str(samples / "mlcp_small.json"))
    assert res.returncode == 0
    assert "equality residual" in res.stdout and "mid(" in res.stdout


def test_cli_wrong_kind_and_bad_input(cli, samples, tmp_path):
    bad = tmp_path / "bad_box.json"
    bad.write_text(json.dumps({"M": [[1]], "q": [1], "lower": [2], "upper": [1]}))
    for args in (("solve", str(samples / "box_small.json"), "-m", "mlcp-schur"),
                 ("solve", str(bad), "-m", "dantzig")):
        res = cli(*args)
        assert res.returncode == 2, args
        assert "Traceback" not in res.stderr + res.stdout
        assert res.stdout == ""


def test_wrong_kind_and_bad_options_raise_option_error(samples):
    from lcpcli.core.errors import OptionError

    mlcp = load(samples / "mlcp_small.json")
    box = load(samples / "box_small.json")
    for problem, method, opts in ((mlcp, "dantzig", {}), (box, "mlcp-lemke", {}),
                                  (mlcp, "mlcp-schur", {"inner": "nope"}),
                                  (mlcp, "mlcp-schur", {"inner": "mlcp-lemke"}),
                                  (mlcp, "mlcp-lemke", {"cond_max": "-1"}),
                                  (box, "dantzig", {"max_iter": "0"})):
        with pytest.raises(OptionError):
            solve(problem, method, **opts)


def test_methods_are_registered_with_kinds():
    from lcpcli.solvers.registry import get_method

    assert get_method("mlcp-schur").kinds == ("mlcp",)
    assert get_method("mlcp-lemke").kinds == ("mlcp",)
    assert set(get_method("dantzig").kinds) == {"lcp", "box"}
    for name in ("mlcp-schur", "mlcp-lemke", "dantzig"):
        assert get_method(name).matrix_classes
