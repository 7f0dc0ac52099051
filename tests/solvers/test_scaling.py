"""Honest verdicts on badly scaled problems: equilibration, scaled copies, no false proofs.

The cases of issue 11, kept as tests: wrong answers that a normwise certificate called solved,
and solvable problems that absolute thresholds called unsolvable once scaled.
"""

from __future__ import annotations

import numpy as np
import pytest
from references import componentwise_error

import lcpcli
from lcpcli.bench import suites
from lcpcli.core.problem import Problem

PIVOTING = ("auto", "lemke", "lemke-tableau", "murty", "dantzig", "enum")
ALL_LCP = PIVOTING + ("newton", "newton-min", "ip", "pgs", "psor")
SCALES = [1e-300, 1e-200, 1e-100, 1e-12, 1.0, 1e12, 1e100, 1e300]


#: Forward accuracy expected at the default tolerance: pivoting methods end on an exact basis;
#: iterative ones stop once the certificate (1e-8) is met, for these well-conditioned problems
#: about 1e-8 in z too.
FORWARD = {"pgs": 1e-7, "psor": 1e-7, "newton": 1e-7, "newton-min": 1e-7, "ip": 1e-7}


def _solves(p: Problem, method: str, z_star: np.ndarray, **kw) -> None:
    r = lcpcli.solve(p, method, **kw)
    assert r.status == "solved", (method, r.message)
    assert np.allclose(r.z, z_star, rtol=FORWARD.get(method, 1e-9), atol=0), (method, r.z)
    assert componentwise_error(p.M, p.q, r.z) <= 1e-8


@pytest.mark.parametrize("s", SCALES)
@pytest.mark.parametrize("method", PIVOTING + ("newton", "pgs"))
def test_scaled_p_matrix_is_solved(method, s):
    # M = [[2, 1], [1, 2]] s, q = (-1, -1) s: a P-matrix with solution (1/3, 1/3) for every s;
    # absolute thresholds used to give "ray termination" / "not a P-matrix" below 1e-12
    p = Problem.create(np.array([[2.0, 1.0], [1.0, 2.0]]) * s, np.array([-1.0, -1.0]) * s)
    _solves(p, method, np.array([1 / 3, 1 / 3]))


@pytest.mark.parametrize("method", ["lemke", "lemke-tableau"])
@pytest.mark.parametrize("scale", [1e-300, 1.0, 1e300])
def test_covering_vector_of_any_size(method, scale):
    p = Problem.create([[2.0, 1.0], [1.0, 2.0]], [-5.0, -6.0])
    _solves(p, method, np.array([4 / 3, 7 / 3]), covering=[scale, 2 * scale])


def test_rows_of_very_different_scale():
    # M = diag(1e8, 1e-8), q = (-1e8, -1e-8): the solution is (1, 1); auto used to answer (1, 0)
    p = Problem.create(np.diag([1e8, 1e-8]), [-1e8, -1e-8])
    for method in ALL_LCP:
        r = lcpcli.solve(p, method)
        if r.status == "solved":
            assert np.allclose(r.z, [1.0, 1.0], rtol=1e-9), (method, r.z)


def _row_scaled_spd(n: int, seed: int) -> tuple[Problem, np.ndarray]:
    """An SPD problem with a planted solution, rows scaled by 10^k, k uniform in [-8, 8]."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    S = A @ A.T / n + np.eye(n)
    z = np.where(rng.random(n) < 0.5, rng.uniform(0.5, 2.0, n), 0.0)
    w = np.where(z > 0, 0.0, rng.uniform(0.5, 2.0, n))
    D = 10.0 ** rng.uniform(-8, 8, n)
    return Problem.create(D[:, None] * S, D * (w - S @ z)), z


@pytest.mark.parametrize("n", [20, 50, 100])
def test_row_scaled_family_auto_and_lemke(n):
    for seed in range(3):
        p, z_star = _row_scaled_spd(n, seed)
        for method in ("auto", "lemke", "lemke-tableau"):
            r = lcpcli.solve(p, method)
            assert r.status == "solved", (method, r.message)
            assert r.error <= 1e-12, (method, r.error)
            assert np.max(np.abs(r.z - z_star)) <= 1e-8 * np.max(np.abs(z_star)), method


#: Methods whose class is stated for symmetric matrices: a row or column scaling takes a
#: symmetric PSD matrix out of their class (only D M D keeps it), so they get D M D copies.
SYMMETRIC_CLASS = {"dantzig"}


def _scaled_copies(p: Problem, seed: int, method: str) -> list[tuple[str, Problem, np.ndarray]]:
    """Row-, column- and globally scaled copies (powers of two: exact) and how z maps."""
    rng = np.random.default_rng(seed)
    n = p.n
    M, q = p.dense_M(), p.q
    D = 2.0 ** rng.integers(-30, 31, n)
    E = 2.0 ** rng.integers(-30, 31, n)
    glob = [("global 2^-900", Problem.create(M * 2.0 ** -900, q * 2.0 ** -900), np.ones(n)),
            ("global 2^900", Problem.create(M * 2.0 ** 900, q * 2.0 ** 900), np.ones(n))]
    if method in SYMMETRIC_CLASS:
        return [("D M D", Problem.create(D[:, None] * M * D[None, :], D * q), D)] + glob
    return [("rows", Problem.create(D[:, None] * M, D * q), np.ones(n)),
            ("columns", Problem.create(M * E[None, :], q), E)] + glob


CASES = ["random-pd", "random-p", "random-psd", "random-contact", "infeasible-robust",
         "degenerate-p", "murty-lemke"]


def _cases() -> list[suites.Case]:
    out = []
    for c in suites.suite("random", n=12) + suites.suite("hard", n=8):
        if any(c.name.startswith(k) for k in CASES):
            out.append(c)
    return out


@pytest.mark.parametrize("method", PIVOTING + ("newton", "ip"))
def test_identical_verdicts_on_scaled_copies(method):
    """The verdict does not depend on units: no absolute threshold is left in pivot, ratio,
    rank, definiteness or ray tests (scalings that keep the method's matrix class)."""
    for case in _cases():
        if method == "enum" and case.n > 20:
            continue
        base = lcpcli.solve(case.problem, method)
        for label, copy, E in _scaled_copies(case.problem, 1, method):
            r = lcpcli.solve(copy, method)
            assert r.status == base.status, (method, case.name, label, base.message, r.message)
            if r.solved and case.unique:
                # the copy's z is E^-1 times the original's
                assert np.allclose(r.z * E, base.z, rtol=1e-7, atol=1e-12 * np.abs(base.z).max())


def test_zero_matrix_is_never_solved():
    p = Problem.create(np.zeros((4, 4)), [-1.0, 2.0, -3.0, 0.5])
    for method in ALL_LCP:
        r = lcpcli.solve(p, method)
        assert r.status != "solved", method
        if r.status == "no_solution":
            assert "Farkas" in r.message or "cones" in r.message


def test_diverging_psor_is_not_solved():
    rng = np.random.default_rng(3)
    n = 60
    K = rng.standard_normal((n, n))
    M = np.eye(n) + 10.0 * (K - K.T) / np.sqrt(n)   # PD (symmetric part I), strongly skew
    r = lcpcli.solve(Problem.create(M, rng.standard_normal(n)), "psor")
    assert r.status == "unsolved"


def test_infeasible_psd_family_is_not_solved_by_any_method():
    for n in (8, 16, 32):
        case = suites.infeasible_psd(n)
        for method in ALL_LCP:
            if method == "enum" and n > 20:
                continue
            r = lcpcli.solve(case.problem, method)
            assert r.status != "solved", (method, n, r.message)


@pytest.mark.parametrize("method", ["newton", "murty", "auto", "pgs"])
def test_a_wrong_warm_start_is_not_accepted(method):
    p = Problem.create([[2.0, 1.0], [1.0, 2.0]], [-5.0, -6.0])
    r = lcpcli.solve(p, method, z0=[1.0, 0.0], max_iter=1) if method != "auto" else \
        lcpcli.solve(p, method, z0=[1.0, 0.0])
    if r.status == "solved":
        assert np.allclose(r.z, [4 / 3, 7 / 3])


@pytest.mark.parametrize("s", [1e-300, 1e-12, 1.0, 1e6, 1e100, 1e300])
def test_enumeration_of_scaled_seed004(s):
    from lcpcli.analysis.enumeration import enumerate_cones

    p = Problem.create(np.array([[2.0, 1.0], [1.0, 2.0]]) * s, np.array([-5.0, -6.0]) * s)
    e = enumerate_cones(p, all_cones=True)
    assert e.verdict == "unique" and len(e.solutions) == 1
    assert np.allclose(e.solutions[0].z, [4 / 3, 7 / 3], rtol=1e-12)
    assert e.solutions[0].certificate.passed
    assert [c.rank for c in e.cones] == [2, 2, 2, 2]


@pytest.mark.parametrize("rows,cols", [((-3, -3), (-3, -3)), ((2, 2), (-2, -2)), ((-1, 4), (0, 3)),
                                       ((5, 5), (-1, 2)), ((0, 0), (0, 0))])
@pytest.mark.parametrize("sparse", [False, True])
def test_scaling_apply_and_ranges_are_the_exponent_formula(rows, cols, sparse):
    """:meth:`Scaling.apply` is ``D_r M D_c`` entry by entry, bit for bit, whether the factors
    are one power of two for all of M (applied as one factor) or not; ``ranges`` and the
    message and ``info`` built from it are the exponents' minima and maxima."""
    import scipy.sparse as sp

    from lcpcli.analysis.scaling import Scaling

    rng = np.random.default_rng(7)
    n = 9
    M = rng.standard_normal((n, n)) * 2.0 ** rng.integers(-20, 20, (n, n))
    M[rng.random((n, n)) < 0.3] = 0.0
    r = np.sort(rng.integers(rows[0], rows[1] + 1, n))
    c = rng.integers(cols[0], cols[1] + 1, n)
    r[0], r[-1], c[0], c[-1] = rows[0], rows[1], cols[0], cols[1]
    s = Scaling(row=r, col=c, kind="two-sided")
    p = Problem.create(sp.csr_matrix(M) if sparse else M, rng.standard_normal(n))
    got = s.apply(p)
    expected = np.ldexp(M, (r[:, None] + c[None, :]).astype(np.int32))
    np.testing.assert_array_equal(got.dense_M(), expected)
    np.testing.assert_array_equal(got.q, np.ldexp(p.q, r.astype(np.int32)))
    assert s.ranges == ((int(r.min()), int(r.max())), (int(c.min()), int(c.max())))
    assert f"rows x 2^{rows[0]}" in s.describe() and f"columns x 2^{cols[0]}" in s.describe()


def _balance_case(n: int, seed: int, spread: int, magnitude: int, q_magnitude: int,
                  zeros: float) -> Problem:
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n)) * 2.0 ** rng.integers(-spread, spread + 1, (n, n))
    M[rng.random((n, n)) < zeros] = 0.0
    q = rng.standard_normal(n) * 2.0 ** q_magnitude
    return Problem.create(M * 2.0 ** magnitude, q)


@pytest.mark.parametrize("n", [1, 2, 7, 50, 130])
@pytest.mark.parametrize("spread", [0, 2, 3, 6])
@pytest.mark.parametrize("magnitude", [-8, -4, 0, 3, 5, 9])
def test_the_balance_test_is_the_first_ruiz_round(n, spread, magnitude):
    """The one balance test (``_scaling._balanced``, behind :func:`is_balanced` and inside
    compiled calls) says balanced exactly when one round of Ruiz's iteration
    (``ruiz_exponents(..., max_rounds=1)``) finds nothing to scale, dense and sparse alike."""
    import scipy.sparse as sp

    from lcpcli.analysis._scaling import ruiz_exponents
    from lcpcli.analysis.scaling import BALANCED, Q_BALANCED, is_balanced

    seen = set()
    for seed in range(6):
        for q_mag in (-10, 0, 10):
            for zeros in (0.0, 0.6):
                p = _balance_case(n, seed, spread, magnitude, q_mag, zeros)
                one_round = ruiz_exponents(p.M, p.q, False, BALANCED, Q_BALANCED, 1) is None
                assert is_balanced(p) == one_round
                sparse = Problem.create(sp.csr_matrix(p.M), p.q)
                assert is_balanced(sparse) == one_round
                if zeros == 0.0:  # (a zero matrix is balanced at any magnitude)
                    seen.add(one_round)
    if magnitude == 0 and spread == 0:
        assert True in seen  # the family reaches both answers across the grid
    if magnitude == 9 and n >= 7:  # an entry of 2^6 or more: never balanced
        assert seen == {False}
