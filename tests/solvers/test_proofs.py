"""A ``no_solution`` is a checked proof (issue 22): a Farkas vector that passes its own check.

Every ``no_solution`` carries ``info["farkas_y"]``, verified here by
``tests/references.py: farkas_certifies`` (exact rational arithmetic, written apart from
:mod:`lcpcli.analysis.proof`).  A secondary ray without such a vector is ``unsolved`` and
``auto`` goes on to the next method.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from references import brute_force_solutions, componentwise_error, farkas_certifies

import lcpcli
from lcpcli.analysis.proof import check_farkas, prove_infeasible
from lcpcli.core.errors import OptionError
from lcpcli.core.problem import Problem

#: The LCP methods whose verdicts are checked (iterative ones with small caps: they may give
#: up, they may not lie).
METHODS = {"auto": {}, "lemke": {}, "lemke-tableau": {}, "enum": {}, "murty": {},
           "dantzig": {}, "newton": {"max_iter": 50}, "pgs": {"max_iter": 500}}


def hilbert_example() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The issue's ``M = 232792560 H_10`` (integer, exactly PD), ``q = (1 - z*) - M z*``."""
    n = 10
    M = np.array([[232792560 // (i + j + 1) for j in range(n)] for i in range(n)], dtype=float)
    z = np.array([1, 1, 1, 1, 0, 1, 0, 1, 1, 0], dtype=float)
    q = (1 - z) - M @ z
    assert q.tolist()[:3] == [-578748170, -381151628, -294694218]  # as in the issue
    return M, q, z


def tiny_eigenvalue_example() -> tuple[np.ndarray, np.ndarray]:
    """Positive definite, eigenvalues 1 and 1e-12 (eigenvector (1, 1)); q = -(1, 1): the
    solution is z ~ 1e12 (1, 1), an infeasible problem lies within 1e-12 of it."""
    e = 1e-12
    M = np.array([[0.5 + 0.5 * e, -0.5 + 0.5 * e], [-0.5 + 0.5 * e, 0.5 + 0.5 * e]])
    return M, np.array([-1.0, -1.0])


def test_hilbert_example_is_solved_not_proven_infeasible() -> None:
    M, q, z_star = hilbert_example()
    r = lcpcli.solve(M, q)
    assert r.status == "solved"
    np.testing.assert_allclose(r.z, z_star, atol=1e-6)
    for method in ("lemke", "lemke-tableau", "enum"):
        assert lcpcli.solve(M, q, method=method).status != "no_solution", method


def test_tiny_eigenvalue_example_is_never_no_solution() -> None:
    M, q = tiny_eigenvalue_example()
    for method in METHODS:
        r = lcpcli.solve(M, q, method=method, **METHODS[method])
        assert r.status != "no_solution", (method, r.message)
    r = lcpcli.solve(M, q)
    assert r.status == "solved" and r.z.min() > 1e11
    # w = M z + q in exact arithmetic (a float M @ z cancels terms of size 5e11): both rows
    # are equations, z > 0, so |w_i| must be tiny relative to |M| |z| + |q|
    for i in range(2):
        w = sum(Fraction(M[i, j]) * Fraction(r.z[j]) for j in range(2)) + Fraction(q[i])
        size = sum(abs(Fraction(M[i, j]) * Fraction(r.z[j])) for j in range(2)) + 1
        assert abs(w) <= Fraction(1, 10**8) * size


def test_a_psd_ray_without_a_farkas_vector_is_unsolved() -> None:
    M, q = tiny_eigenvalue_example()
    r = lcpcli.solve(M, q, method="lemke-tableau")
    assert r.status == "unsolved" and "proves nothing" in r.message


@pytest.mark.parametrize("M, q", [([[0.0]], [-1.0]), ([[1.0, -1.0], [-1.0, 1.0]], [-1.0, -1.0]),
                                  ([[-1.0, 0.0], [1.0, 1.0]], [-1.0, 1.0]),
                                  ([[0.0, 1e300], [-1e300, 0.0]], [-1e-300, -1.0])])
@pytest.mark.parametrize("method", ["auto", "lemke", "lemke-tableau", "enum"])
def test_infeasible_problems_stay_no_solution_with_a_passing_proof(M, q, method) -> None:
    r = lcpcli.solve(np.array(M), np.array(q), method=method)
    assert r.status == "no_solution", r.message
    assert farkas_certifies(np.array(M), np.array(q), r.info["farkas_y"])


def test_the_check_rejects_a_vector_off_by_more_than_rounding() -> None:
    M = np.array([[1.0, -1.0], [-1.0, 1.0 + 2.0 ** -40]])   # PD: solvable for every q
    q = np.array([-1.0, -1.0])
    lo, up = np.zeros(2), np.full(2, np.inf)
    got = check_farkas(M, q, lo, up, np.array([1.0, 1.0]))  # M^T y = (0, 2^-40)
    assert not got.passed and got.worst == 1
    exact = np.array([[1.0, -1.0], [-1.0, 1.0]])
    assert check_farkas(exact, q, lo, up, np.array([1.0, 1.0])).passed


def test_mlcp_and_box_forms() -> None:
    # MLCP: u free with 0 = u + 1 (A = 1), and w_v = -u*0 + 0 v - 1 >= 0 impossible
    p = Problem.create([[1.0, 0.0], [0.0, 0.0]], [1.0, -1.0], n_eq=1)
    proof = prove_infeasible(p, search=True)
    assert proof is not None and farkas_certifies(p.M, p.q, proof.y, n_eq=1)
    r = lcpcli.solve(p)
    assert r.status == "no_solution" and farkas_certifies(p.M, p.q, r.info["farkas_y"], n_eq=1)
    # a box LCP with finite bounds always has a solution: never a proof
    b = Problem.create([[0.0, 0.0], [0.0, 0.0]], [-1.0, 1.0], lower=[0, 0], upper=[1, 1])
    assert prove_infeasible(b, search=True) is None
    # one-sided bounds: z >= -2 with w = -1 < 0 everywhere: infeasible
    c = Problem.create([[0.0]], [-1.0], lower=[-2.0], upper=[np.inf])
    proof = prove_infeasible(c, search=True)
    assert proof is not None and farkas_certifies(c.M, c.q, proof.y, c.lower, c.upper)


def _small_lcps() -> st.SearchStrategy:
    """Small LCPs of every sort: integer (degenerate, often infeasible), PSD of low rank, P,
    and power-of-two scaled copies of them."""
    n = st.integers(1, 4)

    @st.composite
    def build(draw):
        k = draw(n)
        kind = draw(st.sampled_from(["int", "psd", "p"]))
        ints = st.integers(-3, 3)
        if kind == "int":
            M = np.array(draw(st.lists(ints, min_size=k * k, max_size=k * k)), float)
            M = M.reshape(k, k)
        elif kind == "psd":
            B = np.array(draw(st.lists(ints, min_size=k, max_size=k)), float).reshape(k, 1)
            S = np.array(draw(st.lists(ints, min_size=k * k, max_size=k * k)), float)
            S = S.reshape(k, k)
            M = B @ B.T + (S - S.T)
        else:
            M = np.array(draw(st.lists(ints, min_size=k * k, max_size=k * k)), float)
            M = M.reshape(k, k)
            M = M @ M.T + np.eye(k)
        q = np.array(draw(st.lists(ints, min_size=k, max_size=k)), float)
        a = np.array(draw(st.lists(st.integers(-60, 60), min_size=k, max_size=k)))
        b = np.array(draw(st.lists(st.integers(-60, 60), min_size=k, max_size=k)))
        if draw(st.booleans()):
            M = np.ldexp(M, (a[:, None] + b[None, :]).astype(np.int32))
            q = np.ldexp(q, a.astype(np.int32))
        return M, q

    return build()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_small_lcps())
def test_every_no_solution_carries_an_independently_checked_farkas_vector(data) -> None:
    M, q = data
    for method, opts in METHODS.items():
        try:
            r = lcpcli.solve(M, q, method=method, **opts)
        except OptionError:
            continue
        if r.status == "no_solution":
            assert farkas_certifies(M, q, r.info["farkas_y"]), (method, r.message)
        elif r.status == "solved":
            assert componentwise_error(M, q, r.z) <= r.certificate.tol * (1 + 1e-6), method


@pytest.mark.parametrize("seed", range(12))
def test_rank_one_psd_problems_are_solved_or_proven(seed: int) -> None:
    """On a PSD (copositive-plus) M, Lemke's method either solves or, when no solution exists,
    proves it: the proof check does not lose the true proofs.  ``B`` has small integer entries,
    so ``M = B B^T`` is exact in floating point: exactly PSD and singular, as its proofs need
    (the rounded product of a real ``B`` is another matrix, see the next test)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 7))
    B = rng.integers(-3, 4, size=(n, max(1, n // 2))).astype(float)
    M, q = B @ B.T, rng.integers(-4, 5, size=n).astype(float)
    r = lcpcli.solve(M, q, method="lemke")
    if brute_force_solutions(M, q):
        assert r.status == "solved"
    else:
        assert r.status == "no_solution" and farkas_certifies(M, q, r.info["farkas_y"])


def test_a_solvable_problem_within_rounding_of_an_infeasible_one_is_never_proven() -> None:
    """The data as given decide: ``M`` is positive definite (its smallest eigenvalue ~5e-16)
    although ``y = (1/2, 1/2)`` is a Farkas vector to within rounding (``M^T y`` ~ +2e-16):
    every method ends ``solved`` or ``unsolved``, never ``no_solution``; so does the same
    block inside ``I_200``, where the old rounding margin (``2 (n + 2) u`` of ``|M|^T |y|``) was
    wide enough for a smallest eigenvalue of 3e-14."""
    M = np.array([[1.0, -1.0], [-1.0, 1.0 + 1e-15]])
    q = np.array([-1.0, 0.5])
    big_M, big_q = np.eye(200), np.ones(200)
    big_M[:2, :2] = [[1.0, -1.0], [-1.0, 1.0 + 6e-14]]
    big_q[:2] = q
    for data in ((M, q), (big_M, big_q)):
        for method in ("auto", "lemke", "lemke-tableau", "newton"):
            r = lcpcli.solve(*data, method=method)
            assert r.status != "no_solution", (method, r.message)
    assert lcpcli.solve(M, q, method="enum").status != "no_solution"
    assert not farkas_certifies(M, q, [0.5, 0.5])


@pytest.mark.parametrize("seed", range(12))
def test_rounded_rank_deficient_psd_problems_are_proven_only_when_exactly_infeasible(
        seed: int) -> None:
    """``M = B B^T`` of a real ``B``, rounded: singular in real arithmetic, but the rounded
    matrix may be positive definite, with an exact solution of size ~1e15.  A no_solution
    verdict then needs a Farkas vector of the rounded data (the exact reference); a solved one
    passes the exact certificate."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 7))
    B = rng.standard_normal((n, max(1, n // 2)))
    M, q = B @ B.T, rng.standard_normal(n)
    for method in ("auto", "lemke"):
        r = lcpcli.solve(M, q, method=method)
        if r.status == "no_solution":
            assert farkas_certifies(M, q, r.info["farkas_y"]), (seed, method)
        elif r.status == "solved":
            assert componentwise_error(M, q, r.z) <= r.certificate.tol * (1 + 1e-6)


# ------------------------------------------------------------------ messages say what was shown
def _det(A: list[list[Fraction]]) -> Fraction:
    """Laplace expansion in rationals (independent of the project's elimination)."""
    if not A:
        return Fraction(1)
    return sum(((-1) ** j * A[0][j] * _det([row[:j] + row[j + 1:] for row in A[1:]])
                for j in range(len(A))), Fraction(0))


def _is_p_exactly(M: np.ndarray) -> bool:
    n = M.shape[0]
    for mask in range(1, 1 << n):
        idx = [i for i in range(n) if mask >> i & 1]
        if _det([[Fraction(float(M[i, j])) for j in idx] for i in idx]) <= 0:
            return False
    return True


def test_murty_says_not_p_only_with_a_witness() -> None:
    p_close = np.array([[1.0, 2.0], [0.5, 1.0 + 2.0 ** -40]])   # minors 1, 1 + 2^-40, 2^-40
    r = lcpcli.solve(p_close, np.array([-1.0, -1.0]), method="murty")
    assert "not a P-matrix" not in r.message
    assert r.status == "solved" or "is a P-matrix" in r.message
    not_p = np.array([[1.0, 2.0], [0.6, 1.0]])                    # det = -0.2
    r = lcpcli.solve(not_p, np.array([-1.0, -1.0]), method="murty")
    assert r.status != "solved" and "not a P-matrix" in r.message and "{1, 2}" in r.message


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 4).flatmap(lambda n: st.lists(
    st.sampled_from([-2.0, -1.0, 0.0, 0.5, 1.0, 2.0, 1.0 + 2.0 ** -40, 2.0 ** -40]),
    min_size=n * n, max_size=n * n).map(lambda v: np.array(v).reshape(n, n))))
def test_p_matrix_never_says_not_p_without_an_exact_witness(M: np.ndarray) -> None:
    from lcpcli.analysis.classify import p_matrix

    verdict, reason = p_matrix(M)
    if verdict is False:
        assert not _is_p_exactly(M), reason
    elif verdict is True:
        assert _is_p_exactly(M), reason


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(2, 4).flatmap(lambda n: st.tuples(
    st.just(n), st.integers(1, n - 1),
    st.lists(st.integers(-2, 2), min_size=n * n, max_size=n * n),
    st.lists(st.integers(-2, 2), min_size=n, max_size=n))))
def test_mlcp_no_solution_carries_a_checked_farkas_vector(data) -> None:
    n, n_eq, flat, qv = data
    M, q = np.array(flat, float).reshape(n, n), np.array(qv, float)
    try:
        p = Problem.create(M, q, n_eq=n_eq)
    except lcpcli.core.errors.ProblemError:
        return
    for method in ("auto", "mlcp-schur", "mlcp-lemke", "newton"):
        r = lcpcli.solve(p, method)
        if r.status == "no_solution":
            assert farkas_certifies(M, q, r.info["farkas_y"], n_eq=n_eq), (method, r.message)
        elif r.status == "solved":
            assert componentwise_error(M, q, r.z, n_eq=n_eq) <= r.certificate.tol * (1 + 1e-6)


def test_a_large_sparse_problem_is_proven_without_densifying() -> None:
    import scipy.sparse as sp

    n = 100_000  # dense, M would need 80 GB
    M = sp.identity(n, format="lil")
    M[7, 7] = -1.0  # w_8 = -z_8 - 1 < 0 for every z >= 0
    q = np.ones(n)
    q[7] = -1.0
    p = Problem.create(M.tocsr(), q)
    proof = prove_infeasible(p, search=True)
    assert proof is not None and np.flatnonzero(proof.y).tolist() == [7]
    assert prove_infeasible(Problem.create(sp.identity(n, format="csr"), -q), search=True) is None


@pytest.mark.parametrize("M,q,n_eq,want", [
    ([[2.0, -2.0], [-1.0, 1.0]], [-2.0, -1.0], 0, "no_solution"),   # a row scaling of the next
    ([[1.0, -1.0], [-1.0, 1.0]], [-1.0, -1.0], 0, "no_solution"),
    ([[1.0, -3.0], [-3.0, 3.0]], [-2.0, 3.0], 0, "no_solution"),    # y = (1/2, 1/6)
    ([[0.0, -1.0], [2.0, -2.0]], [3.0, -2.0], 0, "solved"),         # z = (4, 3), enumeration
    ([[0.0]], [1.0], 1, "no_solution"),                             # 0 u + 1 = 0
    ([[1.0, 1.0], [1.0, 1.0]], [1.0, 2.0], 2, "no_solution"),       # inconsistent equalities
])
def test_auto_finds_what_a_small_problem_allows(M, q, n_eq, want) -> None:
    """Where no method's class argument applies, auto still ends with the truth on a small
    problem: the enumeration (last, n <= 12) finds a solution, the proof search a Farkas
    vector of the data as given; every proof passes the exact reference."""
    M, q = np.array(M), np.array(q)
    r = lcpcli.solve(M, q, n_eq=n_eq) if n_eq else lcpcli.solve(M, q)
    assert r.status == want, r.message
    if want == "no_solution":
        lo = np.zeros(len(q))
        lo[:n_eq] = -np.inf
        assert farkas_certifies(M, q, r.info["farkas_y"], lo, np.full(len(q), np.inf))
    else:
        assert componentwise_error(M, q, r.z) <= r.certificate.tol


def test_auto_tries_principal_pivoting_on_a_box_problem_outside_every_class() -> None:
    """Two box LCPs (indefinite, non-symmetric M, one-sided bounds) with exact solutions that
    Newton's methods miss: Dantzig's principal pivoting is among auto's fallbacks."""
    cases = [
        ([[2.0, -2, 2], [0, 1, -3], [3, 0, -2]], [3.0, -1, -2], [-1.0, -2, -1],
         [np.inf] * 3, [1.25, 3.625, 0.875]),
        ([[1.0, 0, 0, -1], [2, 0, -2, 3], [-1, 1, 1, -3], [-2, -2, 1, -2]], [-4.0, -4, -2, 1],
         [-np.inf, -2, -np.inf, -np.inf], [np.inf, np.inf, 2, 1], [5.0, -2, 2, 1]),
    ]
    for M, q, lo, up, z in cases:
        r = lcpcli.solve(np.array(M), np.array(q), lower=np.array(lo), upper=np.array(up))
        assert r.status == "solved", r.message
        np.testing.assert_allclose(r.z, z, rtol=1e-12, atol=1e-12)
