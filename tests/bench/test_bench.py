"""Tests of the benchmark suites, the runner's verdicts and the ``lcpcli bench`` command.

Suite facts are checked against independent references (small re-implementations of Murty's
least-index method and plain Newton-min, enumeration, Farkas inequalities), never timings.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from lcpcli.api import solve
from lcpcli.bench import runner as bench
from lcpcli.bench import suites
from lcpcli.core.certificate import certify
from lcpcli.core.result import Result


@pytest.fixture(scope="module")
def siconos_data():
    root = suites.siconos_root()
    if root is None:
        pytest.skip("Siconos data folder not found")
    return root


# ---------------------------------------------------------------------- references
def least_index_pivots(M: np.ndarray, q: np.ndarray, limit: int = 10**5) -> tuple[int, np.ndarray]:
    """Murty's least-index principal pivoting from z = 0: (pivots, solution)."""
    n = q.size
    in_z = np.zeros(n, dtype=bool)
    for pivots in range(limit):
        S = np.flatnonzero(in_z)
        z = np.zeros(n)
        if S.size:
            z[S] = np.linalg.solve(M[np.ix_(S, S)], -q[S])
        w = M @ z + q
        basic = np.where(in_z, z, w)
        neg = np.flatnonzero(basic < -1e-12)
        if neg.size == 0:
            return pivots, z
        in_z[neg[0]] = ~in_z[neg[0]]
    raise AssertionError("no convergence")


def plain_newton_min(M: np.ndarray, q: np.ndarray, iters: int = 50) -> tuple[str, int]:
    """Plain Newton-min from z = 0: ('solved', k) or ('cycle', k) when an index set repeats."""
    n = q.size
    z = np.zeros(n)
    seen = []
    for k in range(iters):
        w = M @ z + q
        if np.max(np.abs(np.minimum(z, w))) < 1e-12:
            return "solved", k
        assert not np.any(np.isclose(z, w) & (np.abs(z) > 0)), "a tie z_i = w_i"
        active = tuple(w < z)  # rows where w is the smaller: w_i = 0, z_i free
        if active in seen:
            return "cycle", k
        seen.append(active)
        S = np.flatnonzero(active)
        z = np.zeros(n)
        if S.size:
            z[S] = np.linalg.solve(M[np.ix_(S, S)], -q[S])
    return "limit", iters


def is_p_matrix(M: np.ndarray) -> bool:
    n = M.shape[0]
    return all(np.linalg.det(M[np.ix_(s, s)]) > 0 for k in range(1, n + 1)
               for s in itertools.combinations(range(n), k))


# ---------------------------------------------------------------------- suite facts
@pytest.mark.parametrize("n", range(2, 9))
def test_murty_lemke_takes_exactly_2_to_the_n_pivots(n: int) -> None:
    case = suites.murty_lemke(n)
    r = solve(case.problem, "lemke")
    assert r.status == "solved"
    assert r.iterations == 2 ** n == case.facts["lemke_pivots"]
    assert np.array_equal(r.z, case.solution)
    w = case.problem.w(case.solution)
    assert np.allclose(w[:-1], 2.0 ** np.arange(1, n)) and w[-1] == 0


@pytest.mark.parametrize("n", range(2, 9))
def test_least_index_family_takes_2_to_the_n_minus_1_pivots(n: int) -> None:
    case = suites.murty_least_index(n)
    pivots, z = least_index_pivots(case.problem.dense_M(), case.problem.q)
    assert pivots == 2 ** n - 1 == case.facts["murty_pivots"]
    assert np.allclose(z, case.solution)


def test_murty_family_matches_siconos_files(siconos_data) -> None:
    from lcpcli.io import load

    for fname, case in (("lcp_exp_murty2.dat", suites.murty_lemke(6)),
                        ("lcp_exp_murty.dat", suites.murty_least_index(6)),
                        ("lcp_CPS_3.dat", suites.bimatrix_cps())):
        p = load(siconos_data / "lcp" / fname)
        assert np.array_equal(p.dense_M(), case.problem.dense_M()), fname
        assert np.array_equal(p.q, case.problem.q), fname


def test_planted_and_known_solutions_certify() -> None:
    cases = suites.hard_suite(4) + suites.random_suite(50)
    with_solution = [c for c in cases if c.solution is not None]
    assert len(with_solution) >= 20
    for c in with_solution:
        cert = certify(c.problem, c.solution, 1e-12)
        assert cert.passed, (c.name, cert.error)
    for c in cases:  # unique solutions: Lemke must find the same point on the well-posed ones
        if c.unique and c.solution is not None and "illcond" not in c.name:
            r = solve(c.problem, "lemke")
            assert r.status == "solved", c.name
            assert np.allclose(r.z, c.solution, atol=1e-8 * max(1, c.solution.max())), c.name


def exact_support_solution(M: np.ndarray, q: np.ndarray, support: np.ndarray) -> np.ndarray:
    """The exact solution of ``M_SS z_S = -q_S`` for the stored doubles (Gaussian elimination
    in rationals), rounded once to doubles; 0 off the support."""
    from fractions import Fraction

    S = support.tolist()
    k = len(S)
    A = [[Fraction(float(M[i, j])) for j in S] + [-Fraction(float(q[i]))] for i in S]
    for c in range(k):
        p = next(r for r in range(c, k) if A[r][c] != 0)
        A[c], A[p] = A[p], A[c]
        for r in range(k):
            if r != c and A[r][c] != 0:
                f = A[r][c] / A[c][c]
                A[r] = [a - f * b for a, b in zip(A[r], A[c], strict=True)]
    z = np.zeros(q.size)
    z[support] = [float(A[i][k] / A[i][i]) for i in range(k)]
    return z


@pytest.mark.parametrize("case", [suites.illcond_pd(12, 1e12, 2), suites.illcond_pd(8, 1e8, 7),
                                  suites.random_pd(10, 0), suites.random_p(10, 2)],
                         ids=lambda c: c.name)
def test_a_planted_unique_solution_is_the_solution_of_the_stored_data(case) -> None:
    """The forward error is measured against z*: z* must be the exact solution of the (M, q)
    as stored, not the planted vector whose q = w - M z* was rounded (at cond 1e12, n = 12,
    that one lies 8.7e-12 from the exact solution; 2e-10 at n = 32), to within an ulp."""
    M, q, z = case.problem.dense_M(), case.problem.q, case.solution
    exact = exact_support_solution(M, q, np.flatnonzero(z > 0))
    assert np.all(np.abs(z - exact) <= np.spacing(np.abs(exact))), case.name
    w = M @ z + q
    assert z.min() >= 0 and w[z == 0].min() >= 0.5, case.name  # still strictly complementary


def test_unique_solutions_are_the_only_ones_small_cases() -> None:
    for c in (suites.kostreva(), suites.newton_min_cycle(3), suites.murty_lemke(4)):
        sols = suites.enumerate_solutions(c.problem.dense_M(), c.problem.q)
        assert len(sols) == 1 and np.allclose(sols[0], c.solution), c.name


def test_infeasible_cases_carry_a_farkas_certificate() -> None:
    for c in (suites.infeasible_psd(12), suites.infeasible_robust(12)):
        assert c.expected == suites.INFEASIBLE
        M, q, y = c.problem.dense_M(), c.problem.q, c.farkas
        assert np.all(y > 0)
        assert np.max(M.T @ y) <= 1e-12 * np.abs(M).max() * y.sum()
        assert q @ y < -0.5
    robust = suites.infeasible_robust(12)
    assert np.max(robust.problem.dense_M().T @ robust.farkas) < -0.1  # strictly: well posed
    assert np.linalg.eigvalsh(suites.infeasible_psd(12).problem.dense_M()).min() > -1e-10
    r = solve(suites.infeasible_psd(12).problem, "lemke")
    assert r.status == "no_solution"


def test_newton_min_case_is_p_and_plain_newton_min_cycles() -> None:
    assert is_p_matrix(suites.NEWTON_MIN_M)
    for n in (3, 9):
        c = suites.newton_min_cycle(n)
        status, _ = plain_newton_min(c.problem.dense_M(), c.problem.q)
        assert status == "cycle", n
        assert certify(c.problem, c.solution, 1e-12).passed


def test_kostreva_is_fully_degenerate_and_p() -> None:
    c = suites.kostreva()
    M, q = c.problem.dense_M(), c.problem.q
    assert is_p_matrix(M)
    assert np.all(q == q[0])  # every ratio of the first Lemke step ties
    assert np.allclose(c.problem.w(c.solution), 0.0)


def test_bimatrix_lemke_ray_though_solvable() -> None:
    for c in (suites.bimatrix_cps(), suites.bimatrix_ray(10)):
        M = c.problem.dense_M()
        assert np.all(M >= 0)  # copositive
        e1 = np.eye(M.shape[0])[0]
        assert e1 @ M @ e1 == 0 and np.any((M + M.T) @ e1 != 0)  # not copositive-plus
        r = solve(c.problem, "lemke")
        assert r.status == "unsolved" and r.termination == "ray_termination"
        assert certify(c.problem, c.solution, 1e-12).passed


def test_cube_contacts_are_singular_psd() -> None:
    for k in (4, 8):
        c = suites.cube_contact(k)
        M = c.problem.dense_M()
        ev = np.linalg.eigvalsh(M)
        assert ev.min() > -1e-12 and np.linalg.matrix_rank(M) == 3 < k
        assert np.allclose(M, M.T)
        assert certify(c.problem, c.solution, 1e-14).passed


def test_illcond_family_hits_its_condition_numbers() -> None:
    for cond in (1e2, 1e8, 1e12):
        c = suites.illcond_pd(16, cond)
        assert np.linalg.cond(c.problem.dense_M()) == pytest.approx(cond, rel=0.05)


def test_suites_are_deterministic_and_sized() -> None:
    a, b = suites.suite("hard", 5), suites.suite("hard", 5)
    assert [c.name for c in a] == [c.name for c in b]
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.problem.dense_M(), y.problem.dense_M())
        assert np.array_equal(x.problem.q, y.problem.q)
    rnd = suites.suite("random", 50)
    assert sorted({c.n for c in rnd}) == [10, 50]
    assert any(c.problem.sparse for c in rnd)
    with pytest.raises(Exception, match="unknown suite"):
        suites.suite("nope")


def test_siconos_suite_expectations(siconos_data) -> None:
    cases = suites.siconos_suite()
    names = {c.name for c in cases}
    assert "Rectangular_mlcp" not in names and "lcp_deudeu" in names
    infeasible = [c.name for c in cases if c.expected == suites.INFEASIBLE]
    assert infeasible == ["lcp_Pang_isolated_sol_perturbed"]
    for c in cases:
        if c.solution is not None:
            assert certify(c.problem, c.solution, 1e-9).passed, c.name


def test_siconos_known_solutions_of_p_matrices_give_a_forward_error(siconos_data) -> None:
    """The README's solutions of the P-matrix files (deudeu, trivial, ortiz, exp_murty*) are
    the only ones, so the forward error is measured against them; the singular files' are not
    claimed unique."""
    from references import brute_force_solutions

    cases = {c.name: c for c in suites.siconos_suite(10)}
    unique = sorted(name for name, c in cases.items() if c.unique)
    assert set(unique) == {"lcp_deudeu", "lcp_deudeu_block", "lcp_exp_murty", "lcp_exp_murty2",
                           "lcp_ortiz", "lcp_ortiz_block", "lcp_trivial", "lcp_trivial_block"}
    for name in unique:
        c = cases[name]
        (only,) = brute_force_solutions(c.problem.dense_M(), c.problem.q)
        assert np.allclose(only, c.solution, rtol=1e-15, atol=0), name
        rec = bench.run_one(c, "lemke-tableau", 1e-8, repeat=0)
        assert rec.success and rec.z_error is not None and rec.z_error < 1e-14, name
    assert not cases["lcp_inf_sol_perturbed"].unique  # singular M


# ---------------------------------------------------------------------- runner verdicts
def _fake_solve(behaviour: str):
    """A solve function that lies (or not) in a chosen way."""

    def fake(problem, method, tol=1e-8):
        n = problem.n
        z = np.zeros(n)
        status = {"lie_solved": "solved", "lie_infeasible": "no_solution",
                  "honest": "unsolved"}[behaviour]
        cert = certify(problem, z, tol)
        return Result(status=status, method=method, z=z, w=problem.w(z), iterations=1,
                      seconds=1e-4, certificate=cert, message="fake", termination="converged")

    return fake


def test_defect_detection_with_lying_methods() -> None:
    case = suites.murty_lemke(4)  # z = 0 is not a solution (q < 0)
    for behaviour, defect in (("lie_solved", True), ("lie_infeasible", True), ("honest", False)):
        rep = bench.run_bench([case], [behaviour], repeat=1, solve_fn=_fake_solve(behaviour))
        (rec,) = rep.records
        assert rec.defect is defect, behaviour
        assert rec.success is False
        assert bool(rep.defects) is defect
    rep = bench.run_bench([case], ["lemke-tableau"], repeat=1)
    assert not rep.defects and rep.records[0].success


def _claims_no_solution(farkas):
    """A solve function that claims ``no_solution`` with ``farkas`` as its proof (None: none)."""

    def fake(problem, method, tol=1e-8):
        z = np.zeros(problem.n)
        info = {} if farkas is None else {"farkas_y": list(farkas)}
        return Result(status="no_solution", method=method, z=z, w=problem.w(z), iterations=1,
                      seconds=1e-4, certificate=certify(problem, z, tol), message="fake",
                      termination="ray_termination", info=info)

    return fake


@pytest.mark.parametrize("expected", ["unknown", "infeasible"])
def test_a_no_solution_claim_is_rechecked_whatever_the_expectation(expected) -> None:
    """The bench re-checks a no_solution's Farkas vector as it re-certifies a solved z: a claim
    with no vector, or a wrong one, is a DEFECT also on a user file (expected unknown) or an
    infeasible case; a true proof on a file of unknown outcome is the right outcome."""
    case = suites.infeasible_psd(6)
    case.expected = expected
    wrong = -case.farkas  # y <= 0: fails the sign rule
    for farkas, defect in ((None, True), (wrong, True), (case.farkas, False)):
        rec = bench.run_one(case, "liar", 1e-8, repeat=0, solve_fn=_claims_no_solution(farkas))
        assert rec.status == "no_solution" and rec.defect is defect, (farkas, rec)
        assert rec.success is not defect
        assert ("Farkas" in rec.defect_reason) is defect


def _sleepy(problem, method, tol=1e-8):
    """A solve function that hangs (module level: isolated runs pickle it to a child)."""
    import time

    time.sleep(30)


def _crashing(problem, method, tol=1e-8):
    """A solve function that dies as abruptly as a segfault."""
    import os

    os._exit(7)


def test_isolated_runs_time_out_and_survive_crashes() -> None:
    import time

    sleepy, crashing = _sleepy, _crashing
    case = suites.kostreva()
    t0 = time.perf_counter()
    rep = bench.run_bench([case], ["sleepy"], repeat=0, solve_fn=sleepy, timeout=0.5)
    assert time.perf_counter() - t0 < 10
    (rec,) = rep.records
    assert rec.status == "timeout" and not rec.success and not rec.defect
    (rec,) = bench.run_bench([case], ["crash"], repeat=0, solve_fn=crashing, timeout=5).records
    assert rec.status == "error" and "exit code 7" in rec.message
    rec = bench.run_isolated(case, "lemke-tableau", 1e-8, timeout=30, repeat=2)
    assert rec.status == "solved" and rec.success and rec.repeats == 2


def test_no_solution_on_infeasible_is_success_not_defect() -> None:
    case = suites.infeasible_psd(8)
    rec = bench.run_one(case, "lemke-tableau", 1e-8, repeat=1)
    assert rec.status == "no_solution" and rec.success and not rec.defect


def test_statistics_shifted_geomean_and_profile() -> None:
    assert bench.shifted_geomean([0.0, 0.0]) == pytest.approx(0.0, abs=1e-15)
    assert bench.shifted_geomean([0.01, 0.03], shift=0.01) == pytest.approx(
        np.sqrt(0.02 * 0.04) - 0.01)
    R = bench.Record
    recs = [R("p1", 2, "a", "solved", 1.0, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p1", 2, "b", "solved", 2.0, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p2", 2, "a", "unsolved", 1.0, 1, 1.0, "solvable", False, 1e-8),
            R("p2", 2, "b", "solved", 4.0, 1, 0.0, "solvable", False, 1e-8, success=True)]
    rep = bench.BenchReport(recs, ["a", "b"], [1e-8],
                            [("p1", 2, "lcp", "solvable"), ("p2", 2, "lcp", "solvable")])
    prof = bench.performance_profile(rep)
    assert prof["ratios"] == {"a": [1.0, None], "b": [2.0, 1.0]}
    assert prof["tau"] == [1.0, 2.0]
    assert prof["rho"] == {"a": [0.5, 0.5], "b": [0.5, 1.0]}
    summ = {s.method: s for s in bench.summarize(rep)}
    # the failure of a on p2 is charged 10 x the slowest time on p2 (4 s)
    assert summ["a"].sgm_seconds == pytest.approx(np.sqrt(1.01 * 40.01) - 0.01)
    assert summ["a"].successes == 1 and summ["b"].successes == 2



def test_the_profile_keeps_every_problem_and_leaves_out_methods_that_ran_on_none() -> None:
    """``lcpcli bench --suite hard`` runs every registered method: the MLCP methods run on no
    LCP and enum skips n > 24, and the profile (then over the problems *every* method ran on)
    had 0 problems.  Now a method run on no problem is left out, and a problem a method was
    not run on counts as one it did not solve."""
    R = bench.Record
    recs = [R("p1", 2, "a", "solved", 1.0, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p1", 2, "c", "solved", 2.0, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p2", 40, "a", "solved", 3.0, 1, 0.0, "solvable", False, 1e-8, success=True)]
    rep = bench.BenchReport(recs, ["a", "c", "mlcp-only"], [1e-8],
                            [("p1", 2, "lcp", "solvable"), ("p2", 40, "lcp", "solvable")])
    prof = bench.performance_profile(rep)
    assert prof["problems"] == ["p1", "p2"]
    assert prof["ratios"] == {"a": [1.0, 1.0], "c": [2.0, None]}  # c was not run on p2
    assert prof["rho"]["a"][0] == 1.0 and prof["rho"]["c"] == [0.0, 0.5]


def test_the_default_bench_of_a_suite_draws_a_profile() -> None:
    """Every registered method on LCPs (the MLCP methods run on none of them): the profile is
    over the suite's problems, not empty."""
    cases = [suites.kostreva(), suites.cube_contact(4)]
    rep = bench.run_bench(cases, bench.resolve_methods(None), repeat=0)
    prof = bench.performance_profile(rep)
    assert prof["problems"] == [c.problem.name for c in cases]
    assert "mlcp-lemke" not in prof["ratios"] and prof["rho"]["auto"][-1] == 1.0

# ---------------------------------------------------------------------- CLI
REQUIRED = {"problem": str, "n": int, "method": str, "status": str, "seconds": float,
            "iterations": int, "error": float, "expected": str, "defect": bool}


def test_cli_json_schema(cli) -> None:
    proc = cli("bench", "--suite", "hard", "--n", "3", "--methods", "lemke-tableau", "--no-peers",
               "--repeat", "1", "--json")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == len(suites.hard_suite(3))
    names = set()
    for line in lines:
        d = json.loads(line)
        for key, typ in REQUIRED.items():
            assert key in d, key
            assert d[key] is None or isinstance(d[key], typ) or (typ is float and
                                                                  isinstance(d[key], int)), key
        assert d["method"] == "lemke-tableau" and d["expected"] in ("solvable", "infeasible")
        assert d["defect"] is False
        names.add(d["problem"])
    assert "murty-lemke-3" in names and "infeasible-psd-6" in names


def test_cli_table_files_folder_hdf5(cli, tmp_path) -> None:
    import h5py

    from lcpcli.io import save

    save(suites.kostreva().problem, tmp_path / "k.json")
    save(suites.murty_lemke(3).problem, tmp_path / "sub_m.npz")
    with h5py.File(tmp_path / "many.h5", "w") as f:
        for c in (suites.cube_contact(4), suites.murty_lemke(4)):
            g = f.create_group(c.name)
            g["M"] = c.problem.dense_M()
            g["q"] = c.problem.q
    cases = bench.cases_from_paths([str(tmp_path)])
    assert sorted(c.name for c in cases) == ["k", "many/cube-4", "many/murty-lemke-4", "sub_m"]
    assert {c.expected for c in cases} == {"unknown"}
    proc = cli("bench", str(tmp_path / "many.h5"), str(tmp_path / "k.json"), "-m", "lemke",
               "--no-peers", "--repeat", "1", "--tol", "1e-6,1e-10")
    assert proc.returncode == 0, proc.stderr
    assert "per method" in proc.stdout and "many/murty-lemke-4" in proc.stdout
    assert "time to reach each tolerance" in proc.stdout


@pytest.mark.parametrize("args, needle", [
    (["--suite", "hard", "-m", "nosuch"], "unknown method"),
    ([], "give problem files"),
    (["--suite", "nosuch"], "unknown suite"),
    (["--suite", "hard", "--tol", "abc"], "--tol"),
    (["--suite", "hard", "--tol", "-1"], "tolerance must lie in"),
    (["/nonexistent/file.json"], "no such file"),
])
def test_cli_bad_input(cli, args, needle) -> None:
    proc = cli("bench", "--no-peers", *args)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr + proc.stdout
    assert needle in proc.stderr


def test_cli_plot_and_markdown(cli, tmp_path) -> None:
    pytest.importorskip("matplotlib")
    png, md = tmp_path / "p.png", tmp_path / "r.md"
    proc = cli("bench", "--suite", "hard", "--n", "3", "-m", "lemke-tableau", "--no-peers",
               "--repeat", "0", "--plot", str(png), "--markdown", str(md))
    assert proc.returncode == 0, proc.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "| lemke-tableau | 1e-08 |" in md.read_text()


def test_siconos_peer_is_certified_like_our_methods() -> None:
    from lcpcli.bench import peers

    found, missing = peers.discover(["siconos"])
    if not found:
        pytest.skip(f"Siconos peer not available: {missing}")
    case = suites.murty_lemke(5)
    recs = bench.run_peer(case, found[0], 1e-8, repeat=1)
    lemke = next(r for r in recs if r.method == "siconos-lemke")
    assert lemke.success and lemke.peer == "siconos" and lemke.error is not None
    assert lemke.iterations == 2 ** 5 - 1  # Siconos counts the complementary pivots only


def test_cli_exits_1_when_a_method_claims_a_false_proof(capsys, monkeypatch) -> None:
    """A made-up proof of infeasibility never becomes ``no_solution`` (no Farkas vector passes
    :func:`lcpcli.analysis.proof.check_farkas`); and should the proof check ever accept one,
    `lcpcli bench` exits non-zero with a defect."""
    from lcpcli.cli import main
    from lcpcli.core.errors import EXIT_NOT_SOLVED
    from lcpcli.core.result import RAY, Outcome
    from lcpcli.solvers.registry import Method, register, unregister

    def false_proof(problem, *, tol):
        return Outcome(np.zeros(problem.n), 1, RAY, "a made-up proof", proven_infeasible=True)

    def bench_rows() -> tuple[int, list[dict]]:
        register(Method(name="false-proof-test", run=false_proof, summary="lies (test)"))
        try:
            with pytest.raises(SystemExit) as exc:
                main(["bench", "--suite", "hard", "--n", "3", "-m", "false-proof-test",
                      "--no-peers", "--repeat", "1", "--timeout", "0", "--json"])
        finally:
            unregister("false-proof-test")
        out = capsys.readouterr().out.splitlines()
        return exc.value.code, [json.loads(line) for line in out]

    _, rows = bench_rows()
    # no_solution only where the proof search found a true Farkas vector (infeasible cases)
    assert rows and not any(r["defect"] for r in rows)
    assert all(r["expected"] == "infeasible" for r in rows if r["status"] == "no_solution")

    class Accepted:  # a proof check that accepts anything: the bench must catch the lie
        y = np.zeros(0)

        def as_dict(self) -> dict:
            return {}

    monkeypatch.setattr("lcpcli.api.confirm", lambda problem, outcome: Accepted())
    code, rows = bench_rows()
    assert code == EXIT_NOT_SOLVED and any(r["defect"] for r in rows)


def test_methods_above_their_size_limit_are_skipped_not_errors() -> None:
    """enum refuses n > max_n: the bench lists the pair as skipped (no error row, no child
    traceback), in process and isolated."""
    rng = np.random.default_rng(0)
    n = 30
    A = rng.standard_normal((n, n))
    from lcpcli.core.problem import Problem

    case = suites.Case(Problem.create(A @ A.T + n * np.eye(n), rng.standard_normal(n),
                                      name="big-pd"))
    for timeout in (None, 20.0):
        rep = bench.run_bench([case], ["enum", "lemke-tableau"], repeat=1, timeout=timeout)
        assert [r.method for r in rep.records] == ["lemke-tableau"]
        assert rep.skipped and "max_n" in rep.skipped[0][2]


@pytest.mark.parametrize("tols", [[0.5], [0.0], [float("nan")], [1e-20], []])
def test_bench_tolerances_follow_the_solve_rule(tols):
    """A tolerance a solve would refuse (core.certificate.validate_tol) is refused up front,
    not once per (problem, method) inside the runs."""
    from lcpcli.core.errors import OptionError

    case = suites.murty_lemke(3)
    with pytest.raises(OptionError, match="tolerance"):
        bench.run_bench([case], ["lemke-tableau"], tols, repeat=0)


def test_bench_cli_refuses_a_tolerance_a_solve_refuses(tmp_path, cli):
    problem = tmp_path / "p.json"
    problem.write_text(json.dumps({"M": [[2.0]], "q": [-1.0]}))
    got = cli("bench", str(problem), "--tol", "0.5")
    assert got.returncode == 2 and got.stdout == ""
    assert got.stderr.count("\n") == 1 and "tolerance must lie in" in got.stderr


def test_problems_with_one_name_keep_their_own_rows() -> None:
    """Two problems called ``p`` (two files ``a/p.json`` and ``b/p.dat``) are two rows: the
    per-problem figures are keyed by name, so the second is renamed ``p (2)``; neither row
    shows the other's result, and the profile counts both problems."""
    from lcpcli.core.problem import Problem

    solvable, ray = suites.kostreva(), suites.bimatrix_cps()  # lemke: ok, then Lemke's ray
    cases = [suites.Case(Problem.create(c.problem.dense_M(), c.problem.q, name="p"))
             for c in (solvable, ray)]
    rep = bench.run_bench(cases, ["lemke-tableau"], repeat=0)
    assert [p for p, *_ in rep.problems] == ["p", "p (2)"]
    by = {r.problem: r for r in rep.records}
    assert by["p"].success and not by["p (2)"].success
    assert bench.performance_profile(rep)["ratios"]["lemke-tableau"] == [1.0, None]


def test_a_timeout_is_charged_at_least_the_time_it_ran() -> None:
    """docs/bench.md: a failure is charged 10x the slowest time on its problem, never less than
    its own; a run killed after the timeout ran at least that long (its ``seconds`` is null)."""
    R = bench.Record
    recs = [R("p", 2, "a", "solved", 1e-3, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p", 2, "b", "timeout", None, None, None, "solvable", False, 1e-8,
              killed_after=60.0)]
    rep = bench.BenchReport(recs, ["a", "b"], [1e-8], [("p", 2, "lcp", "solvable")])
    summ = {s.method: s for s in bench.summarize(rep)}
    assert summ["b"].sgm_seconds == pytest.approx(60.0)
    rec = bench.run_bench([suites.kostreva()], ["sleepy"], repeat=0, solve_fn=_sleepy,
                          timeout=0.5).records[0]
    assert rec.status == "timeout" and rec.killed_after == 0.5
    assert rec.to_json()["killed_after"] == 0.5


def test_a_peer_killed_by_the_timeout_is_a_timeout(tmp_path, monkeypatch) -> None:
    """A Siconos worker that outlives its limit gives status ``timeout`` (as our own methods
    get), not ``error``; an interpreter that hangs stands in for a hanging solver."""
    from lcpcli.bench import peers

    hang = tmp_path / "hang.sh"
    hang.write_text("#!/bin/sh\nexec sleep 30\n")
    hang.chmod(0o755)
    monkeypatch.setenv("LCPCLI_SICONOS_PYTHON", str(hang))
    peer = peers.Peer("siconos", ["siconos-lemke"], peers.run_siconos)
    case = suites.kostreva()
    recs = bench.run_peer(case, peer, 1e-8, repeat=0, timeout=0.5)
    assert [r.method for r in recs] == list(peers.SICONOS_SOLVERS)
    for rec in recs:  # the batch is killed, then each solver alone after 0.5 s
        assert rec.status == "timeout" and rec.killed_after == 0.5 and not rec.success


def test_the_timing_line_says_what_is_timed(monkeypatch) -> None:
    """Our methods' time includes the dispatcher's certificate of the answer (a peer's solver
    call certifies nothing): the report's header must say so, not "no certification"."""
    import time

    from lcpcli.cli.render.bench import header
    from lcpcli.solvers import pipeline

    certified = pipeline.certified

    def slow_certified(*args, **kwargs):
        time.sleep(0.05)
        return certified(*args, **kwargs)

    monkeypatch.setattr(pipeline, "certified", slow_certified)
    rec = bench.run_one(suites.murty_lemke(4), "pgs", 1e-8, repeat=0)
    assert rec.seconds >= 0.05  # the certificate's time is in `seconds`
    rep = bench.BenchReport([rec], ["pgs"], [1e-8], [("murty-lemke-4", 4, "lcp", "solvable")])
    grid = header(rep, "t")
    timing = next(str(c) for c in grid.columns[1].cells if "warm-up" in str(c))
    assert "no certification" not in timing and "includes the certificate" in timing


def test_a_zero_time_does_not_make_every_method_best() -> None:
    """Dolan-More ratios need positive times: a 0.0 (below the clock's resolution) is floored
    there, so a method 1 ms slower on that problem gets a ratio far above 1 (it was 1.0), and
    the problem is not dropped from the peer ratios."""
    R = bench.Record
    recs = [R("p", 2, "a", "solved", 0.0, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p", 2, "b", "solved", 1e-3, 1, 0.0, "solvable", False, 1e-8, success=True),
            R("p", 2, "c", "solved", 1e-3, 1, 0.0, "solvable", False, 1e-8, success=True,
              peer="x")]
    rep = bench.BenchReport(recs, ["a", "b"], [1e-8], [("p", 2, "lcp", "solvable")])
    prof = bench.performance_profile(rep)
    assert prof["ratios"]["a"] == [1.0] and prof["ratios"]["b"][0] > 1e3
    assert prof["rho"]["b"][0] == 0.0  # not within tau = 1 of the best
    (a_vs_c,) = [d for d in bench.peer_ratios(rep) if d["method"] == "a"]
    assert a_vs_c["problems"] == 1 and a_vs_c["geomean_ratio"] < 1e-3


def test_the_announced_run_count_is_the_runs_made() -> None:
    """"lcpcli: bench: N runs" (and "interrupted after k of N") counts what run_bench runs: a
    method above its max_n is skipped there, so it is not counted (enum: max_n 24)."""
    from lcpcli.cli.bench_cmd import _Tracker

    cases = [suites.kostreva(), suites.illcond_pd(28, 1e2)]
    rep = bench.run_bench(cases, ["enum"], repeat=0)
    tracker = _Tracker(cases, ["enum"], [1e-8], [], None)
    assert tracker.total == len(rep.records) == 1 and len(rep.skipped) == 1


def test_a_run_announces_no_cost_note() -> None:
    """The bench announces its own work (runs and time); the enumeration's note before 2^20
    cones is not printed once per run and repeat (six lines on the hard suite, in Python's
    'lcpcli:0: CostNote:' form from the child processes)."""
    import warnings

    from lcpcli.core.limits import ENUM_ANNOUNCE_N
    from lcpcli.core.problem import Problem

    n = ENUM_ANNOUNCE_N
    case = suites.Case(Problem.create(2.0 * np.eye(n), -np.ones(n), name="diag"))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        rec = bench.run_one(case, "enum", 1e-8, repeat=1)
    assert rec.success
    assert not [w for w in seen if "cones" in str(w.message)]
