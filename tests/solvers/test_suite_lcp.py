"""The LCP solver suite: murty, pgs, psor, newton, newton-min, ip, auto; info; --z0.

Every "solved" verdict is re-checked here independently of the package's certificate (w is
recomputed with numpy and complementarity checked directly); unique solutions are compared with
Lemke's answer or an enumeration reference.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import lcpcli
from lcpcli.api import solve
from lcpcli.core.problem import Problem

LCP_METHODS = ["murty", "pgs", "psor", "newton", "newton-min", "ip", "auto"]


@pytest.fixture(scope="module")
def sico(siconos) -> Path:
    """The Siconos data (conftest's ``siconos`` fixture: one lookup for every test file)."""
    return siconos


# ---------------------------------------------------------------------------- generators
def rand_pd(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return A @ A.T / n + 0.5 * np.eye(n), rng.standard_normal(n)


def rand_psd_rank_deficient(n: int, rank: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric PSD of the given rank with a solvable q (built from a known solution)."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, rank))
    M = B @ B.T / rank
    z = np.where(rng.random(n) < 0.5, rng.random(n), 0.0)
    w = np.where(z > 0, 0.0, rng.random(n))
    return M, w - M @ z


def rand_p_nonsym(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A non-symmetric H-matrix with positive diagonal (hence P) whose symmetric part is
    indefinite (so it is not PD): 2 x 2 blocks [[d1, 3], [0, d2]] plus a weak random coupling."""
    rng = np.random.default_rng(seed)
    M = 0.02 / n * rng.standard_normal((n, n))
    for k in range(0, n - 1, 2):
        M[k, k + 1] = 3.0
        M[k + 1, k] = 0.0
    M[np.diag_indices(n)] = 1.0 + 0.2 * rng.random(n)
    return M, rng.standard_normal(n)


def contact_like(n_contacts: int, seed: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """M = J W J^T + eps I (sparse, symmetric PSD, positive diagonal), q = J v + b."""
    rng = np.random.default_rng(seed)
    n_bodies = max(2, n_contacts // 2)
    dof = 3 * n_bodies
    rows, cols, vals = [], [], []
    for i in range(n_contacts):
        a, b = rng.choice(n_bodies, 2, replace=False)
        for body, sign in ((a, 1.0), (b, -1.0)):
            for k in range(3):
                rows.append(i)
                cols.append(3 * body + k)
                vals.append(sign * rng.standard_normal())
    J = sp.csr_matrix((vals, (rows, cols)), shape=(n_contacts, dof))
    W = sp.diags(1.0 / (0.5 + rng.random(dof)))
    M = (J @ W @ J.T + 1e-6 * sp.identity(n_contacts)).tocsr()
    return M, J @ rng.standard_normal(dof) - 0.1


def check_solution(M, q, z, lo=None, up=None, rtol=2e-8) -> None:
    """Independent check: bounds, the signs of w = M z + q, complementarity.

    Tolerances in the units of w relative to the data, ``tol = rtol (||M|| ||z|| + ||q||)``
    (infinity norms); a deviation of z from a bound counts ``||M||`` times.
    """
    Md = M.toarray() if sp.issparse(M) else np.asarray(M, dtype=float)
    z = np.asarray(z, dtype=float)
    w = Md @ z + q
    lo = np.zeros_like(q) if lo is None else lo
    up = np.full_like(q, np.inf) if up is None else up
    norm_m = max(np.max(np.sum(np.abs(Md), axis=1)), 1e-300)
    tol = rtol * (norm_m * np.max(np.abs(z)) + np.max(np.abs(q)))
    ztol = tol / norm_m
    assert np.all(np.isfinite(z))
    assert np.all(z >= lo - ztol) and np.all(z <= up + ztol)
    at_lo = np.abs(z - lo) <= ztol
    at_up = np.abs(up - z) <= ztol
    between = ~at_lo & ~at_up
    assert np.all(w[at_lo & ~at_up] >= -tol)
    assert np.all(w[at_up & ~at_lo] <= tol)
    assert np.all(np.abs(w[between]) <= tol)


# ------------------------------------------------------------------------ methods on their classes
CLASS_CASES = {
    "pd": (lambda: rand_pd(60, 1), ["murty", "pgs", "psor", "newton", "newton-min", "ip",
                                    "auto"]),
    "psd_rank_deficient": (lambda: rand_psd_rank_deficient(50, 10, 2),
                           ["pgs", "psor", "newton", "ip", "auto"]),
    "p_nonsymmetric": (lambda: rand_p_nonsym(40, 3), ["murty", "pgs", "newton", "auto"]),
    "sparse_contact": (lambda: contact_like(400, 4), ["pgs", "psor", "newton", "ip", "auto"]),
}


@pytest.mark.parametrize("case,method", [(c, m) for c, (_, ms) in CLASS_CASES.items()
                                         for m in ms])
def test_method_on_its_class(case, method):
    M, q = CLASS_CASES[case][0]()
    p = Problem.create(M, q)
    r = solve(p, method, max_iter=50_000 if method in ("pgs", "psor") else None)
    assert r.status == "solved", r.message
    assert r.certificate.passed and r.error <= 1e-8
    check_solution(M, q, r.z)
    if case in ("pd", "p_nonsymmetric"):  # unique solution: compare with Lemke
        ref = solve(Problem.create(M, q), "lemke")
        assert ref.solved
        np.testing.assert_allclose(r.z, ref.z, atol=1e-5 * max(1.0, np.max(np.abs(ref.z))))


def test_sparse_and_dense_pgs_agree():
    M, q = contact_like(200, 9)
    rs = solve(Problem.create(M, q), "pgs", max_iter=50_000)
    rd = solve(Problem.create(M.toarray(), q), "pgs", max_iter=50_000)
    assert rs.solved and rd.solved and rs.iterations == rd.iterations
    np.testing.assert_allclose(rs.z, rd.z, rtol=1e-12, atol=1e-14)


def test_murty_exponential_family_and_pivot_limit(sico):
    p = lcpcli.load(sico / "lcp" / "lcp_exp_murty2.dat")
    r = solve(p, "murty")
    assert r.solved and r.iterations == 63
    np.testing.assert_allclose(r.z, [0, 0, 0, 0, 0, 64], atol=1e-12)
    r = solve(p, "murty", max_iter=10)
    assert r.status == "unsolved" and r.termination == "iteration_limit"


# ---------------------------------------------------------------------------- box and MLCP
def box_reference(M, q, lo, up):
    """All solutions of the box LCP by enumerating the 3^n active sets (n <= 6)."""
    n = len(q)
    sols = []
    for pattern in itertools.product((0, 1, 2), repeat=n):  # 0 at lo, 1 between, 2 at up
        if any(k == 2 and not np.isfinite(up[i]) for i, k in enumerate(pattern)):
            continue
        z = np.where(np.array(pattern) == 0, lo, up).astype(float)
        B = [i for i in range(n) if pattern[i] == 1]
        if B:
            N = [i for i in range(n) if pattern[i] != 1]
            try:
                z[B] = np.linalg.solve(M[np.ix_(B, B)], -(q[B] + M[np.ix_(B, N)] @ z[N]))
            except np.linalg.LinAlgError:
                continue
        w = M @ z + q
        pat = np.array(pattern)
        ok = (np.all(z >= lo - 1e-9) and np.all(z <= up + 1e-9)
              and np.all(w[pat == 0] >= -1e-9) and np.all(w[pat == 2] <= 1e-9))
        if ok:
            sols.append(z)
    return sols


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("method", ["pgs", "psor", "newton", "newton-min", "auto"])
def test_box_lcp_against_enumeration(method, seed):
    rng = np.random.default_rng(seed)
    n = 5
    M, q = rand_pd(n, 100 + seed)
    q = 3 * q
    lo = -rng.random(n)
    up = rng.random(n)
    up[0] = np.inf  # mixed: one variable with a lower bound only
    p = Problem.create(M, q, lower=lo, upper=up)
    r = solve(p, method, max_iter=20_000 if method in ("pgs", "psor") else None)
    refs = box_reference(M, q, lo, up)
    assert len(refs) == 1  # symmetric PD: unique solution
    assert r.solved, r.message
    np.testing.assert_allclose(r.z, refs[0], atol=1e-6)
    check_solution(M, q, r.z, lo, up)


def test_newton_on_an_mlcp_with_free_rows():
    rng = np.random.default_rng(11)
    M, q = rand_pd(12, 12)
    M = M + 0.3 * rng.standard_normal((12, 12))  # non-symmetric
    p = Problem.create(M, q, n_eq=4)
    for method in ("newton", "newton-min", "auto"):
        r = solve(p, method)
        assert r.solved, (method, r.message)
        w = M @ r.z + q
        assert np.max(np.abs(w[:4])) < 1e-8 * (1 + np.max(np.abs(q)))
        assert np.all(r.z[4:] >= 0) and np.all(w[4:] >= -1e-9)
        assert np.max(np.abs(r.z[4:] * w[4:])) < 1e-8


# ---------------------------------------------------------------------------- Siconos files
SOLVABLE = ["lcp_CPS_1", "lcp_CPS_2", "lcp_CPS_3", "lcp_CPS_4", "lcp_CPS_4bis", "lcp_CPS_5",
            "lcp_Pang_isolated_sol", "lcp_deudeu", "lcp_deudeu_block", "lcp_enum_fails",
            "lcp_exp_murty", "lcp_exp_murty2", "lcp_inf_sol_perturbed", "lcp_mmc", "lcp_ortiz",
            "lcp_ortiz_block", "lcp_tobenna", "lcp_trivial", "lcp_trivial_block"]

#: Siconos' expected failures (README table) for the methods of this suite.
EXPECTED_FAILURES = {
    "pgs": ["lcp_enum_fails", "lcp_CPS_2", "lcp_CPS_4", "lcp_CPS_4bis"],
    "psor": ["lcp_enum_fails", "lcp_CPS_2", "lcp_CPS_4", "lcp_CPS_4bis"],
    "newton-min": ["lcp_enum_fails", "lcp_CPS_1", "lcp_CPS_2", "lcp_CPS_4", "lcp_CPS_4bis",
                   "lcp_CPS_5"],
    "newton": ["lcp_CPS_1"],
    "murty": ["lcp_CPS_2", "lcp_CPS_3", "lcp_CPS_4", "lcp_CPS_4bis"],
}


@pytest.mark.parametrize("method", LCP_METHODS)
def test_no_false_verdict_on_any_siconos_lcp(sico, method):
    """Every method on every file: 'solved' only with an independently verified solution,
    never 'no_solution' on a solvable file."""
    for name in SOLVABLE:
        p = lcpcli.load(sico / "lcp" / f"{name}.dat")
        r = solve(p, method)
        assert r.status in ("solved", "unsolved"), (name, r.status, r.message)
        if r.status == "solved":
            check_solution(p.dense_M(), p.q, r.z)
        elif name in EXPECTED_FAILURES.get(method, []):
            assert r.message  # an honest reason


@pytest.mark.parametrize("method,name", [
    ("pgs", "lcp_CPS_2"), ("pgs", "lcp_enum_fails"), ("psor", "lcp_CPS_4"),
    ("murty", "lcp_CPS_2"), ("murty", "lcp_CPS_4bis"),
])
def test_siconos_expected_failures_are_honest_unsolved(sico, method, name):
    r = solve(lcpcli.load(sico / "lcp" / f"{name}.dat"), method)
    assert r.status == "unsolved"
    assert ("diagonal" in r.message) if method in ("pgs", "psor") else ("P-matrix" in r.message)


def test_newton_min_on_cps_1_and_5_is_never_falsely_solved(sico):
    for name in ("lcp_CPS_1", "lcp_CPS_5"):
        p = lcpcli.load(sico / "lcp" / f"{name}.dat")
        r = solve(p, "newton-min")
        if r.solved:  # allowed only with a genuine solution (these have continua of them)
            check_solution(p.dense_M(), p.q, r.z)
        else:
            assert r.status == "unsolved"


def test_auto_solves_every_solvable_siconos_lcp(sico):
    for name in SOLVABLE:
        p = lcpcli.load(sico / "lcp" / f"{name}.dat")
        r = solve(p)  # the default method is auto
        assert r.method == "auto" and r.solved, (name, r.message)
        check_solution(p.dense_M(), p.q, r.z)


def test_auto_falls_back_on_cps_3_where_lemke_ends_on_a_ray(sico):
    p = lcpcli.load(sico / "lcp" / "lcp_CPS_3.dat")
    assert solve(p, "lemke").status == "unsolved"
    r = solve(p, "auto")
    assert r.solved
    attempts = r.info["attempts"]
    assert attempts[0]["method"].startswith("lemke") and attempts[0]["status"] == "unsolved"
    assert attempts[-1]["status"] == "solved" and "failed first" in r.message


def test_auto_reports_the_perturbed_pang_problem_as_not_solved(sico):
    r = solve(lcpcli.load(sico / "lcp" / "lcp_Pang_isolated_sol_perturbed.dat"))
    assert r.status == "no_solution" and "Farkas" in r.message


def test_auto_solves_the_fc2d_contact_lcps(sico):
    files = sorted((sico / "fc2d_as_lcp").glob("*.npz"))
    assert len(files) == 4
    for f in files:
        p = lcpcli.load(f)
        r = solve(p)
        assert r.solved, (f.name, r.message)
        check_solution(p.dense_M(), p.q, r.z)


def test_auto_order_option_and_fallback_message():
    M, q = rand_pd(20, 21)
    p = Problem.create(M, q)
    r = solve(p, "auto", order="ip,newton")
    assert r.solved and r.info["chosen"] == "ip"
    with pytest.raises(lcpcli.core.errors.OptionError):
        solve(p, "auto", order="nope")


# ---------------------------------------------------------------------------- warm start, omega
def test_warm_start_from_the_solution_converges_at_once():
    M, q = rand_pd(80, 31)
    p = Problem.create(M, q)
    cold = solve(p, "pgs")
    warm = solve(p, "pgs", z0=cold.z)
    assert cold.solved and warm.solved and warm.iterations <= 2 < cold.iterations
    assert solve(p, "newton", z0=cold.z).iterations <= 1
    assert solve(p, "murty", z0=cold.z).iterations == 0
    with pytest.raises(lcpcli.core.errors.OptionError, match="length"):
        solve(p, "pgs", z0=np.zeros(3))


def test_omega_validation_and_effect():
    M, q = rand_pd(40, 41)
    p = Problem.create(M, q)
    r1 = solve(p, "psor", omega=1.0)
    r0 = solve(p, "pgs")
    assert r1.iterations == r0.iterations  # omega = 1 is Gauss-Seidel
    for bad in (0.0, 2.0, -1.0, float("nan")):
        with pytest.raises(lcpcli.core.errors.OptionError, match="omega"):
            solve(p, "psor", omega=bad)
    with pytest.raises(lcpcli.core.errors.OptionError, match="no option 'omega'"):
        solve(p, "pgs", omega=1.2)


def test_cli_z0_and_omega(cli, tmp_path, samples):
    src = str(samples / "seed004.json")
    r = cli("solve", src, "--method", "pgs", "--json")
    first = json.loads(r.stdout)
    assert r.returncode == 0 and first["iterations"] > 1
    res = tmp_path / "res.json"
    res.write_text(r.stdout)
    r = cli("solve", src, "--method", "pgs", "--z0", str(res), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["iterations"] == 1
    lst = tmp_path / "z.json"
    lst.write_text("[1.3333333333333333, 2.3333333333333335]")
    r = cli("solve", src, "--method", "psor", "--omega", "1.1", "--z0", str(lst), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["status"] == "solved"
    npz = tmp_path / "z.npz"
    np.savez(npz, z=np.array([1.0, 2.0]))
    assert cli("solve", src, "-m", "newton", "--z0", str(npz)).returncode == 0
    # Lemke has no z0 option: --z0 is a warm start (pivoting from z0's basis from n = 200 on;
    # below that the compiled cold kernel is faster, lcpcli.solvers.warm.WARM_MIN_N)
    r = cli("solve", src, "--method", "lemke-tableau", "--z0", str(lst), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["method"] == "lemke-tableau"
    r = cli("solve", src, "--method", "bpp", "--z0", str(lst), "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["iterations"] == 1
    for args, text in (
        (["--method", "psor", "--omega", "2.5"], "omega"),
        (["--method", "pgs", "--omega", "1.2"], "no option 'omega'"),
        (["--method", "pgs", "--z0", str(tmp_path / "missing.json")], "no such file"),
        (["--method", "pgs", "--z0", str(samples / "seed004.json")], "no 'z'"),
    ):
        r = cli("solve", src, *args)
        assert r.returncode == 2 and "Traceback" not in r.stderr + r.stdout, args
        assert r.stdout == "" and len(r.stderr.strip().splitlines()) == 1
        assert text in r.stderr, (args, r.stderr)
    bad = tmp_path / "short.json"
    bad.write_text("[1.0, 2.0, 3.0]")
    r = cli("solve", src, "--z0", str(bad))
    assert r.returncode == 2 and "has 3 values, the problem has n = 2" in r.stderr


def test_cli_default_method_is_auto(cli, samples):
    r = cli("solve", str(samples / "seed004.json"), "--json")
    out = json.loads(r.stdout)
    assert r.returncode == 0 and out["method"] == "auto" and "solved by" in out["message"]
    r = cli("solve", str(samples / "seed004.json"), env={"NO_COLOR": "1", "COLUMNS": "200"})
    assert r.returncode == 0 and "auto (dense, n=2): solved by" in r.stdout  # no markup


# ---------------------------------------------------------------------------- info
def test_info_json_and_table(cli, sico):
    r = cli("info", str(sico / "lcp" / "lcp_CPS_3.dat"), "--json")
    assert r.returncode == 0
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1
    rep = json.loads(lines[0])
    assert set(rep) >= {"classification", "methods", "auto_plan", "summary"}
    c = rep["classification"]
    assert c["zero_diagonal"] == 4 and c["p_matrix"] is False and not c["symmetric"]
    by = {m["method"]: m for m in rep["methods"]}
    assert by["pgs"]["applies"] == "no" and "diagonal" in by["pgs"]["why"]
    assert by["auto"]["applies"] == "yes"
    assert rep["auto_plan"][0][0].startswith("lemke")
    r = cli("info", str(sico / "lcp" / "lcp_mmc.dat"), env={"NO_COLOR": "1"})
    assert r.returncode == 0
    for text in ("P-matrix", "positive definite", "auto would try"):
        assert text in r.stdout
    r = cli("info", "nope.json")
    assert r.returncode == 2 and "Traceback" not in r.stderr and "no such file" in r.stderr


def test_info_report_library_on_mlcp_and_box():
    from lcpcli.solvers.policy import info_report

    M, q = rand_pd(6, 51)
    rep = info_report(Problem.create(M, q, n_eq=2))
    by = {m["method"]: m for m in rep["methods"]}
    assert by["pgs"]["applies"] == "no" and "MLCP" in by["pgs"]["why"]
    assert any(name == "newton" for name, _ in rep["auto_plan"])
    rep = info_report(Problem.create(M, q, lower=-np.ones(6), upper=np.ones(6)))
    assert all(name not in ("murty", "ip", "lemke-tableau") for name, _ in rep["auto_plan"])
    json.dumps(rep, allow_nan=False)


def test_pgs_zero_diagonal_message_names_the_entry():
    r = solve(Problem.create([[0, 1], [1, 1]], [-1, -1]), "pgs")
    assert r.status == "unsolved" and r.termination == "not_applicable"
    assert "M[1,1] = 0" in r.message


def test_auto_solves_every_siconos_mlcp_file(sico):
    files = sorted(f for f in (sico / "mlcp").glob("*.dat") if not f.name.startswith("Rect"))
    assert len(files) == 17
    for f in files:
        p = lcpcli.load(f)
        r = solve(p)
        assert r.solved and r.method == "auto", (f.name, r.message)
        w = p.w(r.z)
        ne = p.n_eq
        scale = 1e-7 * (np.max(np.abs(p.q)) + np.max(np.abs(p.dense_M())) * np.max(np.abs(r.z)))
        assert np.max(np.abs(w[:ne]), initial=0) <= scale  # equality rows
        assert np.all(r.z[ne:] >= -scale) and np.all(w[ne:] >= -scale)
        assert np.max(np.abs(np.minimum(r.z[ne:], w[ne:]))) <= scale
