"""Lemke's method: seed examples, every Siconos LCP file, random problems vs references."""

from __future__ import annotations

import numpy as np
import pytest
from references import brute_force_solutions, exact_lemke_sequence

import lcpcli
from lcpcli.core.problem import Problem
from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL


def lemke(M, q, **kw):
    return lcpcli.solve(Problem.create(M, q), method="lemke", **kw)


def kernel_sequence(M: np.ndarray, q: np.ndarray, limit: int = 5000):
    from lcpcli.solvers.kernels.lemke import lemke_kernel

    rec = np.zeros((limit, 3), dtype=np.int64)
    status, z, pivots, *_ = lemke_kernel(np.asarray(M, float), np.asarray(q, float),
                                         np.ones(len(q)), limit, PIVOT_TOL, TIE_TOL, rec)
    return status, [tuple(int(x) for x in row) for row in rec[:pivots]]


def test_seed004_example():
    r = lemke([[2, 1], [1, 2]], [-5, -6])
    assert r.status == "solved"
    np.testing.assert_allclose(r.z, [4 / 3, 7 / 3], rtol=1e-14)
    np.testing.assert_allclose(r.w, [0, 0], atol=1e-14)
    assert r.residual <= 1e-14 and r.error <= 1e-15


def test_seed000_problem_cps_447():
    r = lemke([[0, -1, 2], [2, 0, -2], [-1, 1, 0]], [-3, 6, -1])
    assert r.status == "solved"
    np.testing.assert_allclose(r.z, [0, 1, 3], atol=1e-14)


def test_trivial_q_nonnegative_needs_no_pivot():
    r = lemke([[1, 5], [-3, 1]], [0.0, 2.0])
    assert r.status == "solved" and r.iterations == 0 and np.all(r.z == 0)


# file -> expected status of Lemke (the Siconos README: Lemke fails on CPS_3 with a ray, and
# Pang_isolated_sol_perturbed has no solution at all)
SICONOS_LCP = {
    "lcp_CPS_1.dat": "solved", "lcp_CPS_2.dat": "solved", "lcp_CPS_3.dat": "unsolved",
    "lcp_CPS_4.dat": "solved", "lcp_CPS_4bis.dat": "solved", "lcp_CPS_5.dat": "solved",
    "lcp_Pang_isolated_sol.dat": "solved", "lcp_Pang_isolated_sol_perturbed.dat": "no_solution",
    "lcp_deudeu.dat": "solved", "lcp_deudeu_block.dat": "solved",
    "lcp_enum_fails.dat": "solved", "lcp_exp_murty.dat": "solved",
    "lcp_exp_murty2.dat": "solved", "lcp_inf_sol_perturbed.dat": "solved",
    "lcp_mmc.dat": "solved", "lcp_ortiz.dat": "solved", "lcp_ortiz_block.dat": "solved",
    "lcp_tobenna.dat": "solved", "lcp_trivial.dat": "solved", "lcp_trivial_block.dat": "solved",
}


@pytest.mark.parametrize("name", sorted(SICONOS_LCP))
def test_siconos_lcp_files(siconos, name):
    p = lcpcli.load(siconos / "lcp" / name)
    r = lcpcli.solve(p, method="lemke")
    assert r.status == SICONOS_LCP[name], r.message
    if r.status == "solved":
        # the certificate is recomputed independently here
        w = p.M @ r.z + p.q
        assert np.abs(np.minimum(r.z, w)).max() <= 1e-9 * (1 + np.abs(p.q).max())
        assert r.error <= 1e-8


def test_every_siconos_lcp_file_is_listed(siconos):
    assert {f.name for f in (siconos / "lcp").glob("*.dat")} == set(SICONOS_LCP)


def test_known_solutions(siconos):
    expect = {"lcp_ortiz.dat": [2 / 3, 0, 1 / 3, 0], "lcp_exp_murty2.dat": [0, 0, 0, 0, 0, 64],
              "lcp_trivial.dat": 1 / np.arange(1, 10), "lcp_CPS_4.dat": [2, 2, 2, 92],
              "lcp_inf_sol_perturbed.dat": [1, 0, 1e-4]}
    for name, z in expect.items():
        r = lcpcli.solve(lcpcli.load(siconos / "lcp" / name))
        np.testing.assert_allclose(r.z, z, atol=1e-10, err_msg=name)


def test_murty_family_takes_exponential_pivots(siconos):
    # lcp_exp_murty2: Lemke needs 2^6 - 1 complementary pivots after the initial one
    r = lcpcli.solve(lcpcli.load(siconos / "lcp" / "lcp_exp_murty2.dat"))
    assert r.iterations == 64


def test_tobenna_needs_and_gets_the_lexicographic_rule(siconos):
    p = lcpcli.load(siconos / "lcp" / "lcp_tobenna.dat")
    status, seq = kernel_sequence(p.M, p.q)
    ref_status, ref_seq, _ = exact_lemke_sequence(p.M, p.q)
    assert ref_status == "ok" and status == 0
    assert seq == ref_seq  # identical pivot sequence to exact rational arithmetic


def test_ray_with_farkas_certificate_is_no_solution():
    # row 1 of M is <= 0 and q1 < 0: no z >= 0 makes w1 >= 0
    r = lemke([[-1, 0], [1, 1]], [-1, 1])
    assert r.status == "no_solution"
    assert "Farkas" in r.message


def test_ray_on_psd_matrix_is_proven_infeasible():
    # M PSD (copositive-plus); w1 = z1 - z2 - 1, w2 = -z1 + z2 - 1 cannot both be >= 0
    r = lemke([[1, -1], [-1, 1]], [-1, -1])
    assert r.status == "no_solution"


def test_pivot_limit_is_reported_unsolved(siconos):
    p = lcpcli.load(siconos / "lcp" / "lcp_exp_murty2.dat")
    r = lcpcli.solve(p, "lemke", max_iter=10)
    assert r.status == "unsolved" and r.termination == "iteration_limit"
    assert "pivot limit" in r.message


def test_covering_vector_option():
    r = lemke([[2, 1], [1, 2]], [-5, -6], covering=[1.0, 3.0])
    assert r.status == "solved"
    np.testing.assert_allclose(r.z, [4 / 3, 7 / 3])
    with pytest.raises(lcpcli.core.errors.OptionError):
        lemke([[2, 1], [1, 2]], [-5, -6], covering=[1.0, -1.0])


def random_p_matrix(rng, n):
    A = rng.standard_normal((n, n))
    S = rng.standard_normal((n, n))
    return A @ A.T + 0.1 * np.eye(n) + (S - S.T)  # PD symmetric part => P-matrix


@pytest.mark.parametrize("seed", range(25))
def test_random_p_matrices_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 9))
    M = random_p_matrix(rng, n)
    q = rng.standard_normal(n) * 10 ** rng.uniform(-3, 3)
    sols = brute_force_solutions(M, q)
    assert len(sols) == 1  # P-matrix: unique solution
    r = lemke(M, q)
    assert r.status == "solved"
    np.testing.assert_allclose(r.z, sols[0], atol=1e-8 * (1 + np.abs(sols[0]).max()))


@pytest.mark.parametrize("seed", range(15))
def test_random_psd_rank_deficient(seed):
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(2, 9))
    # integer B: M = B B^T exact in floating point, so exactly PSD and singular (a rounded
    # product of a real B may be definite: tests/solvers/test_proofs.py has those)
    B = rng.integers(-3, 4, size=(n, max(1, n // 2))).astype(float)
    M = B @ B.T
    q = rng.integers(-4, 5, size=n).astype(float)
    sols = brute_force_solutions(M, q)
    r = lemke(M, q)
    if sols:
        assert r.status == "solved"
    else:
        assert r.status == "no_solution"  # PSD: a ray proves infeasibility


@pytest.mark.parametrize("seed", range(20))
def test_degenerate_integer_problems_follow_exact_lexicographic_path(seed):
    rng = np.random.default_rng(200 + seed)
    n = int(rng.integers(3, 9))
    M = rng.integers(-3, 4, size=(n, n)).astype(float)
    M += np.diag(rng.integers(0, 3, size=n))
    q = rng.integers(-2, 2, size=n).astype(float)
    q[rng.random(n) < 0.5] = 0.0  # many zeros in q: degenerate ties
    status, seq = kernel_sequence(M, q)
    ref_status, ref_seq, _ = exact_lemke_sequence(M, q)
    if ref_status == "trivial":
        return
    assert seq == ref_seq
    r = lemke(M, q)
    if ref_status == "ok":
        assert r.status == "solved"
    else:
        assert r.status in ("no_solution", "unsolved")
        if r.status == "no_solution":  # only with a proof: check there is no solution
            assert not brute_force_solutions(M, q)


def test_scaling_invariance_of_the_answer():
    rng = np.random.default_rng(7)
    M = random_p_matrix(rng, 6)
    q = rng.standard_normal(6)
    r1 = lemke(M, q)
    r2 = lemke(M * 1e-9, q * 1e-9)
    r3 = lemke(M, q * 1e-12)
    assert r1.solved and r2.solved and r3.solved
    np.testing.assert_allclose(r2.z, r1.z, rtol=1e-9)
    np.testing.assert_allclose(r3.z, r1.z * 1e-12, rtol=1e-9, atol=1e-25)


def test_large_random_pd_problem_is_certified():
    rng = np.random.default_rng(3)
    n = 300
    A = rng.standard_normal((n, n))
    r = lemke(A @ A.T + n * np.eye(n), rng.standard_normal(n))
    assert r.solved and r.error < 1e-13 and r.iterations >= 50


def test_sparse_matrix_is_accepted(samples):
    p = lcpcli.load(samples / "sparse_chain.npz")
    assert p.sparse
    r = lcpcli.solve(p)
    assert r.solved


def test_solver_never_claims_solved_without_the_certificate():
    # a method that lies about convergence: the shared certification must catch it
    from lcpcli.api import certify_outcome
    from lcpcli.core.result import CONVERGED, Outcome

    p = Problem.create([[2, 1], [1, 2]], [-5, -6])
    lie = Outcome(np.ones(p.n), 1, CONVERGED, "trust me")
    res = certify_outcome(p, lie, "liar", 0.0, 1e-8)
    assert res.status == "unsolved" and "certificate failed" in res.message
    lie_proof = Outcome(np.ones(p.n), 1, "ray_termination", "no", proven_infeasible=True)
    # a claimed proof of infeasibility needs a Farkas vector that passes its check (this
    # problem is solvable: none exists), and a good point wins anyway
    good = Outcome(np.array([4 / 3, 7 / 3]), 1, "ray_termination", "x", proven_infeasible=True)
    assert certify_outcome(p, good, "m", 0.0, 1e-8).status == "solved"
    res = certify_outcome(p, lie_proof, "m", 0.0, 1e-8)
    assert res.status == "unsolved" and "no Farkas vector" in res.message
    fake_y = Outcome(np.ones(p.n), 1, "ray_termination", "no", proven_infeasible=True,
                     info={"farkas_y": [1.0, 1.0]})
    assert certify_outcome(p, fake_y, "m", 0.0, 1e-8).status == "unsolved"
