"""Invariants at the boundary, through the Python API (issue 22, What to build 7).

For every valid problem of every kind, class and scale (tests/invariants.py), every method
that handles its kind answers (no exception), ``solved`` passes an independent componentwise
check, ``no_solution`` is true (and its Farkas vector, when it carries one, checks exactly),
and ``lcpcli.solve_many`` answers every problem of a stack the same way.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from invariants import (
    Case,
    cases,
    check_solved,
    check_verdict,
    farkas_ok,
    farkas_vector,
)

import lcpcli
from lcpcli.core.result import STATUS_OF_CODE, Status

#: Methods for each kind of problem (from the registry: new methods are included).
METHODS = {kind: [name for name, m in lcpcli.methods().items() if kind in m.kinds]
           for kind in ("lcp", "box", "mlcp")}
SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def solve_checked(case: Case, method: str, sparse: bool = False) -> None:
    """Solve with ``method`` (``sparse``: M as scipy CSR); assert the invariants, and that no
    numpy warning escapes (the CLI prints each as a ``lcpcli: warning`` line)."""
    M = case.M
    if sparse:
        import scipy.sparse as sp

        M = sp.csr_matrix(M)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = lcpcli.solve(M, case.q, method=method, **case.kwargs())
    assert res.z.shape == (case.n,) and res.w.shape == (case.n,)
    if res.status == Status.SOLVED:
        check_solved(case, res.z, res.certificate.tol)
    check_verdict(case, res.status, res.message, method, res.info)


def _row_scaled_lcp(base: list[list[int]], q: list[int], exps: list[int]) -> Case:
    """The LCP ``diag(2^exps) (base, q)`` (row scaling by powers of two: exact), infeasible."""
    e = np.array(exps)
    return Case("infeasible", "lcp", np.ldexp(np.array(base, float), e[:, None]),
                np.ldexp(np.array(q, float), e), row_exp=e, col_exp=np.zeros(len(q), np.int64),
                solvable=False)


#: A weighted graph's Laplacian with sum(q) < 0, rows scaled up to 2^+-956: the interior
#: point's centring cubed a ratio near 1e103 (OverflowError, exit 3 through `lcpcli solve`).
IP_CUBE_OVERFLOW = _row_scaled_lcp(
    [[14, -3, -1, -3, -2, -2, -3], [-3, 11, -3, -3, -1, -1, 0], [-1, -3, 8, -1, 0, 0, -3],
     [-3, -3, -1, 7, 0, 0, 0], [-2, -1, 0, 0, 5, 0, -2], [-2, -1, 0, 0, 0, 5, -2],
     [-3, 0, -3, 0, -2, -2, 10]], [-2, -4, 0, -2, -1, -1, 3],
    [33, 580, -486, -956, -356, -432, 522])


@SETTINGS
@given(case=cases(max_n=8), sparse=st.booleans())
# the interior point's step on w = -z - 3 is not finite (a numpy warning before)
@example(case=_row_scaled_lcp([[-1]], [-3], [0]), sparse=False)
@example(case=IP_CUBE_OVERFLOW, sparse=False)  # the interior point's centring cubed 1e103
def test_every_method_answers_every_valid_problem(case: Case, sparse: bool) -> None:
    for method in METHODS[case.kind]:
        solve_checked(case, method, sparse)


@settings(max_examples=8, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(case=cases(max_n=60, kinds=("lcp",), classes=("pd", "p", "qpos", "infeasible")))
def test_auto_answers_larger_problems(case: Case) -> None:
    solve_checked(case, "auto")


@SETTINGS
@given(case=cases(max_n=8, kinds=("lcp", "box", "mlcp")),
       method=st.sampled_from(["auto", "lemke", "lemke-tableau", "pgs", "psor"]),
       copies=st.integers(1, 4))
def test_solve_many_answers_every_problem_of_a_stack(case: Case, method: str,
                                                     copies: int) -> None:
    """A stack of copies of one problem, one of them with ``q`` replaced by ``|q|`` (z = 0
    solves it): every row gets a verdict, none raises for the whole stack."""
    if case.kind == "mlcp" or (case.kind == "box" and method.startswith("lemke")):
        method = "auto"
    K = copies + 1
    M = np.broadcast_to(case.M, (K, case.n, case.n)).copy()
    q = np.broadcast_to(case.q, (K, case.n)).copy()
    q[-1] = np.abs(q[-1])
    kw = case.kwargs()
    res = lcpcli.solve_many(M, q, method=method, **kw)
    assert res.status.shape == (K,)
    positive = Case(case.cls if case.cls != "infeasible" else "qpos", case.kind, case.M,
                    np.abs(case.q), case.lower, case.upper, case.n_eq, case.row_exp,
                    case.col_exp, True)
    for k in range(K):
        status = STATUS_OF_CODE[int(res.status[k])]
        assert status != Status.ERROR, res.message(k)
        this = positive if k == K - 1 else case
        if status == Status.SOLVED:
            check_solved(this, res.z[k], res.tol)
        one = res.results.get(k)
        check_verdict(this, status, res.message(k), res.method_of(k),
                      one.info if one is not None else None)


# ------------------------------------------------------------------ the examples
@pytest.mark.parametrize("method", METHODS["lcp"])
def test_zero_solution_every_method(method: str) -> None:
    """q >= 0: z = 0, solved, for every method (issue 22 problem 1's data)."""
    for M, q in (([[1.0]], [1.0]), ([[2.0, 1.0], [1.0, 2.0]], [0.0, 3.0])):
        res = lcpcli.solve(np.array(M), np.array(q), method=method)
        assert res.status == Status.SOLVED, res.message
        np.testing.assert_array_equal(res.z, np.zeros(len(q)))


@pytest.mark.parametrize("method", ["pgs", "psor", "auto", "lemke"])
def test_diag_1e308(method: str) -> None:
    """M = diag(1e308, 1), q = (-1e308, -1): OverflowError in the power-of-two rescaling of
    ||M||_inf (exit 3) before; z = (1, 1) solves it."""
    M, q = np.diag([1e308, 1.0]), np.array([-1e308, -1.0])
    res = lcpcli.solve(M, q, method=method)
    assert res.status == Status.SOLVED, res.message
    np.testing.assert_allclose(res.z, [1.0, 1.0], rtol=1e-6)
    stack = lcpcli.solve_many(np.stack([M, M]), np.stack([q, -q]), method=method)
    assert stack.statuses()[0] == Status.SOLVED and stack.statuses()[1] == Status.SOLVED


def test_norm_of_an_overflowing_matrix() -> None:
    """||M|| beyond the largest double: the norm saturates, never Inf, never raises."""
    from lcpcli.core.certificate import matrix_norm_inf

    M = np.full((3, 3), 1e308)
    assert matrix_norm_inf(M) == np.finfo(np.float64).max
    import scipy.sparse as sp

    assert matrix_norm_inf(sp.csr_matrix(M)) == np.finfo(np.float64).max
    assert matrix_norm_inf(np.diag([5e-324, 0.0])) == 5e-324


def test_forward_bound_of_extreme_data_never_raises() -> None:
    """The forward error bound scales data beyond 2^+-400 first (eigvalsh of M + M^T on
    entries of 1e308 raised LinAlgError: exit 3 after a 'solved')."""
    from lcpcli.analysis.bounds import forward_error_bound

    K = np.array([[1.0, 1.0, 1.0], [1.0, 1.0, -1.0], [1.0, -1.0, 1.0]])
    for s in (1e308, 1e-308, 2.0**-1070):
        prob = lcpcli.Problem.create(s * K, np.array([-1.0, -1.0, -1.0]) * min(s, 1.0))
        res = lcpcli.solve(prob, method="murty")
        forward_error_bound(prob, res.z)  # no exception, whatever it finds
    M, q = 2.0**1000 * np.diag([2.0, 3.0]), -(2.0**1000) * np.array([2.0, 3.0])
    bound = forward_error_bound(lcpcli.Problem.create(M, q), np.array([1.0, 1.0]))
    assert bound is not None and bound.bound < 1e-12


def test_certificate_sees_a_row_whose_terms_all_underflow() -> None:
    """Row 3 of this box LCP holds one term, M_32 z_2 = -2.8e-250 x -1.1e-137: it underflows
    to 0, so w_3 and the row's scale s_3 read 0 and the pair looked complementary (every
    method returned 'solved'; the data scaled back by powers of two gives error 1).  Such a
    row now sends the check to the exactly rescaled path."""
    M = np.array([[5.2886553980414929e-279, -2.5296161067071823e-321, 0.0],
                  [0.0, 6.6461399789245794e+035, 0.0],
                  [0.0, -2.7934029957198183e-250, 8.5528470722950261e-050]])
    q = np.array([2.2013136429275836e-134, 7.1436711955142186e-102, 0.0])
    lo = np.array([-9.3652456509479767e+144, -3.2245805316322026e-137, -4.263256414560601e-14])
    up = np.array([1.248699420126397e+145, np.inf, 4.263256414560601e-14])
    z = np.array([-4.16233140e+144, -1.07486018e-137, 0.0])
    prob = lcpcli.Problem.create(M, q, lower=lo, upper=up)
    assert lcpcli.certify(prob, z).error == 1.0
    import scipy.sparse as sp

    sparse = lcpcli.Problem.create(sp.csr_matrix(M), q, lower=lo, upper=up)
    assert lcpcli.certify(sparse, z).error == 1.0
    for method in METHODS["box"]:
        res = lcpcli.solve(prob, method)
        if res.solved:
            check_solved(Case("subnormal", "box", M, q, lo, up, 0, np.array([-446, -338, -210]),
                              np.array([-480, 455, 46])), res.z, res.certificate.tol)


@pytest.mark.parametrize("e", [-22, 30])
def test_farkas_vector_of_a_scaled_problem_checks(e: int) -> None:
    """The Laplacian of a weighted path (PSD, M 1 = 0) with sum(q) < 0 has no solution; y = 1
    proves it.  Scaled by 2^e, Lemke equilibrates it; the y it reports must still check."""
    W = np.array([[0, 3, 0, 0, 0], [3, 0, 1, 0, 0], [0, 1, 0, 2, 0], [0, 0, 2, 0, 1],
                  [0, 0, 0, 1, 0]], dtype=float)
    M, q = np.ldexp(np.diag(W.sum(axis=1)) - W, e), np.ldexp(np.array([-1.0, 0, 0, 0, 0]), e)
    res = lcpcli.solve(M, q, method="lemke")
    assert res.status == Status.NO_SOLUTION
    case = Case("infeasible", "lcp", M, q, row_exp=np.full(5, e),
                col_exp=np.zeros(5, dtype=np.int64), solvable=False)
    assert farkas_ok(case, farkas_vector(res.info))


@pytest.mark.parametrize("method", ["auto", "lemke", "lemke-tableau"])
def test_no_false_farkas_proof_on_a_copositive_matrix(method: str) -> None:
    """M >= 0 (copositive) with q = (0, -d): z = (0, d / M_22) solves it."""
    M = np.array([[0.0, 2.2911123134779969e+251], [5.6110319334615118e-191,
                                                  1.6069380442589903e+060]])
    q = np.array([0.0, -1.448908652612274e-70])
    res = lcpcli.solve(M, q, method=method)
    assert res.status != Status.NO_SOLUTION, res.message


def test_enumeration_finds_the_solution_of_a_scaled_p_matrix() -> None:
    """A diagonally dominant (P) matrix with rows scaled 2^-980 .. 2^978: its solution has
    z_2 = 1.7e-311, which the equilibrated copy holds as a subnormal with 4 digits (every cone
    containing q failed the certificate: 'uncertified'); the cone solved again in the
    problem's own units passes it."""
    d = np.array([1.9010915662951598e-211, 2.0773386235504175e+275, 1.9196119217864076e-239,
                  1.4196068833898572e+133, 7.8886090522101181e-031, 7.6640267886133241e+294,
                  3.3810849992682576e+271, 1.0305838031355413e-229])
    M = np.diag(d)
    M[1, [2, 3, 4, 5, 6, 7]] = [1.0263416486754031e-48, -3.4211388289180104e-49,
                                -6.9244620785013704e-36, 3.4211388289180104e-49,
                                -6.9244620785013704e-36, 3.4211388289180104e-49]
    M[3, [1, 2, 4, 5, 6, 7]] = [1.4027579833653779e-191, -1.4027579833653779e-191,
                                -1.4027579833653779e-191, 4.2082739500961338e-191,
                                -1.4027579833653779e-191, 4.2082739500961338e-191]
    M[5, [0, 2, 3, 4, 6, 7]] = [-2.5546755962044336e-16, -1.2621774483536189e-29,
                                1.2621774483536189e-29, -1.2621774483536189e-29,
                                -2.5546755962044336e-16, -1.2621774483536189e-29]
    M[6, [0, 1, 2, 3, 5, 7]] = [8.4527124981706181e-40, 1.2528584578557167e-52,
                                -4.1761948595190557e-53, -4.1761948595190557e-53,
                                1.2528584578557167e-52, 4.1761948595190557e-53]
    q = np.array([2.3763644578689498e-211, 0.0, 1.9196119217864076e-239,
                  5.6784275335594288e+132, 3.9443045261050590e-031, 1.0218702384817765e+295,
                  -1.6905424996341288e+271, -1.0305838031355413e-229])
    assert lcpcli.solve(M, q, method="lemke").solved
    assert lcpcli.solve(M, q, method="enum").solved
    from lcpcli.analysis.enumeration import UNIQUE, enumerate_cones

    every = enumerate_cones(lcpcli.Problem.create(M, q), all_cones=True)
    assert every.verdict == UNIQUE and len(every.cones) == 2**8
    assert sorted(c.code for c in every.cones) == list(range(2**8))  # the rescued cone once
    assert [c.code for c in every.cones if c.feasible] == every.solutions[0].cones


def test_enumeration_with_subnormal_entries() -> None:
    """diag(5,5,3,2,5,5,4,2,5,4) plus subnormal off-diagonal entries: a P-matrix, one
    solution, z* = (0,0,1,z_4,0,0,1/4,0,1/5,1/4) with w_4 = 0 and z_4 about t/40 = 1.2e-325
    (t = 5e-324; in rationals), below the smallest subnormal: no double vector passes the
    certificate (z_4 = 0 leaves w_4 = -t/20, error 0.026; z_4 = t gives error 0.49).  Every
    method, enumeration included, says so honestly: unsolved, never solved, never
    no_solution."""
    from fractions import Fraction

    t, m = 5e-324, 1e-310
    noise = [[0, 0, -t, m, -t, -m, 0, -t, 3 * t, -m], [t, 0, 0, -t, m, 3 * t, -m, m, -m, m],
             [0, -m, 0, 0, -m, m, t, 0, -t, -m], [m, t, -t, 0, 3 * t, t, 0, -m, t, 3 * t],
             [m, t, 3 * t, t, 0, 3 * t, t, -t, m, m], [t, 0, 0, t, m, 0, -t, 3 * t, -t, t],
             [3 * t, 0, -t, 0, t, t, 0, -t, m, 3 * t], [m, -m, 0, m, 0, -t, 0, 0, -t, -t],
             [-t, -t, -t, 3 * t, 3 * t, -t, m, 3 * t, 0, 0], [m, t, t, m, -m, -m, m, m, m, 0]]
    M = np.diag([5.0, 5, 3, 2, 5, 5, 4, 2, 5, 4]) + np.array(noise)
    q = np.array([1.0, 3, -3, 0, 3, 3, -1, 1, -1, -1])
    z = np.array([0, 0, 1, 0, 0, 0, 0.25, 0, 0.2, 0.25])
    w4 = sum(Fraction(float(M[3, j])) * Fraction(float(z[j])) for j in range(10))
    z4 = -w4 / Fraction(float(M[3, 3]))  # w_4 = 0 needs this z_4 > 0, which rounds to 0
    assert 0 < z4 < Fraction(t) / 2
    for z4 in (0.0, t):
        assert not lcpcli.certify(lcpcli.Problem.create(M, q), np.where(
            np.arange(10) == 3, z4, z)).passed
    for method in METHODS["lcp"]:
        res = lcpcli.solve(M, q, method=method)
        assert res.status == Status.UNSOLVED, (method, res.message)
    from lcpcli.analysis.enumeration import UNCERTIFIED, enumerate_cones

    assert enumerate_cones(lcpcli.Problem.create(M, q)).verdict == UNCERTIFIED


def test_enumeration_lists_certified_solutions_only() -> None:
    from lcpcli.analysis.enumeration import enumerate_cones

    t, m = 5e-324, 1e-310
    M = np.array([[2, 0, 0, 0, 0, 0], [0, 4, 0, 0, 0, 0], [0, -t, 3, -m, m, -t],
                  [m, 0, 0, 2, -t, -t], [0, 0, 0, 0, 2, 0], [t, m, -m, -t, t, 4.0]])
    r = np.array([-89, -198, 802, 959, -135, 333])
    prob = lcpcli.Problem.create(np.ldexp(M, r[:, None]),
                                 np.ldexp(np.array([5.0, 4, 3, 0, 4, -1]), r))
    found = enumerate_cones(prob)
    assert all(s.certificate.passed for s in found.solutions), \
        [s.certificate.error for s in found.solutions]


def test_sparse_certificate_keeps_q_when_the_terms_cancel() -> None:
    """The Laplacian [[1,-1],[-1,1]] with q = (1,-2) (no solution: y = (1,1)), rows scaled
    2^(-287, 119) and columns 2^(207, 435): at this z the terms of each row cancel exactly and
    w = q.  The CSR certificate added q first (w_1 = q_1 + t_1 + t_2 = 0: q_1 absorbed) and
    passed the point with error 0, so ip on the sparse copy said 'solved'; the dense
    certificate (terms first) gives error 0.5."""
    import scipy.sparse as sp

    r, c = np.array([-287, 119]), np.array([207, 435])
    M = np.ldexp(np.array([[1.0, -1.0], [-1.0, 1.0]]), r[:, None] + c[None, :])
    q = np.ldexp(np.array([1.0, -2.0]), r)
    z = np.array([float.fromhex("0x1.f1813411fdfafp-85"), float.fromhex("0x1.f1813411fdfafp-313")])
    dense = lcpcli.certify(lcpcli.Problem.create(M, q), z)
    sparse = lcpcli.certify(lcpcli.Problem.create(sp.csr_matrix(M), q), z)
    assert not dense.passed and not sparse.passed
    assert sparse.error == dense.error
    case = Case("infeasible", "lcp", M, q, row_exp=r, col_exp=c, solvable=False)
    for method in METHODS["lcp"]:
        solve_checked(case, method, sparse=True)


@pytest.mark.parametrize("sparse", [False, True])
def test_newton_on_an_extreme_infeasible_laplacian(sparse: bool) -> None:
    """2 [[1,-1],[-1,1]] with q = (0, -1), rows scaled 2^(-463, 327) and columns 2^(241, -259):
    Newton's descent test ||d||^2.1 raised OverflowError (exit 3 through auto) on a direction
    of size ~1e300; every method now answers (never 'solved': y = (1, 1) proves infeasibility)."""
    r, c = np.array([-463, 327]), np.array([241, -259])
    M = np.ldexp(np.array([[2.0, -2.0], [-2.0, 2.0]]), r[:, None] + c[None, :])
    q = np.ldexp(np.array([0.0, -1.0]), r)
    case = Case("infeasible", "lcp", M, q, row_exp=r, col_exp=c, solvable=False)
    for method in METHODS["lcp"]:
        solve_checked(case, method, sparse=sparse)



def _far_scaled(n: int, family: int, seed: int, kind: str) -> tuple[np.ndarray, np.ndarray,
                                                                      dict]:
    """A problem whose rows and columns are scaled by powers of two drawn in [-1000, 1000]
    (symmetrically or not): PD, general, PSD, nonnegative with a dominant diagonal, or skew
    plus a positive diagonal; q of either sign; an LCP, an MLCP or a box LCP with bounds of
    2^+-500."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    K = [A @ A.T + np.eye(n), A, A @ A.T, np.abs(A) + n * np.eye(n),
         A - A.T + np.diag(rng.random(n))][family]
    a = rng.integers(-1000, 1000, n)
    b = rng.integers(-1000, 1000, n) if seed % 2 else a
    with np.errstate(all="ignore"):
        M = np.ldexp(K, (a[:, None] + b[None, :]).clip(-1074, 1023).astype(np.int32))
        M = np.where(np.isfinite(M), M, np.sign(M) * 1e308)
        q = -np.ldexp(np.abs(rng.standard_normal(n)) + 0.1, a.astype(np.int32))
    q *= np.where(rng.random(n) < 0.3, -1.0, 1.0)
    kw: dict = {}
    if kind == "mlcp" and n > 1:
        kw = {"n_eq": 1}
    elif kind == "box":
        kw = {"lower": -np.ldexp(1.0, rng.integers(-500, 500, n).astype(np.int32)),
              "upper": np.ldexp(1.0, rng.integers(-500, 500, n).astype(np.int32))}
    return M, q, kw


@SETTINGS
@given(n=st.integers(1, 6), family=st.integers(0, 4), seed=st.integers(0, 2**32 - 1),
       kind=st.sampled_from(["lcp", "mlcp", "box"]))
@example(n=6, family=0, seed=3734, kind="lcp")  # the proof's refinement overflowed (|M| 1e308)
def test_no_numpy_warning_escapes_a_solve_or_a_classification(n: int, family: int, seed: int,
                                                               kind: str) -> None:
    """Floating-point exceptions inside lcpcli (an intermediate past the float64 range on data
    scaled by 2^+-1000) are never numpy RuntimeWarnings: the CLI prints each warning as a
    line, and the verdict already says what failed.  ``auto`` (its fallbacks, equilibrated
    runs, polish and the classification it reads) and the full classification of
    ``lcpcli info``; the verdict is one of the three, and a solved z passes an independent
    componentwise check."""
    import warnings

    from lcpcli.analysis.classify import Classifier
    from lcpcli.core.problem import Problem

    M, q, kw = _far_scaled(n, family, seed, kind)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = lcpcli.solve(M, q, **kw)
        Classifier(Problem.create(M, q, **kw)).complete()
    assert res.status in (Status.SOLVED, Status.UNSOLVED, Status.NO_SOLUTION)
    if res.status == Status.SOLVED:
        from invariants import exact_w
        from references import componentwise_error

        lo, up = kw.get("lower"), kw.get("upper")
        n_eq = kw.get("n_eq", 0)
        tol = res.certificate.tol * (1 + 1e-6)
        assert np.all(np.isfinite(res.z))
        with np.errstate(all="ignore"):  # the reference's own intermediates
            assert min(componentwise_error(M, q, res.z, lo, up, n_eq=n_eq),
                       componentwise_error(M, q, res.z, lo, up, n_eq=n_eq,
                                           w=exact_w(M, q, res.z))) <= tol


def test_no_basis_when_z_is_not_finite() -> None:
    """PGS and PSOR diverge on this P-matrix with a 1e16 entry (z ends with inf and NaN): no
    pair has a state, so there is no basis (the certificate left its state array as it was:
    uninitialised codes such as -54, an IndexError in ``to_dict``, exit 3 through ``solve
    --json``).  Through ``lcpcli.solve`` and through the stacked path (``solve_each``)."""
    from lcpcli.stacks import solve_each

    M = np.array([[2.0, 2.0, 0.0, 0.0], [5e-324, 2.0, -1e16, 1.0], [-1.0, -1.0, 2.0, 1.0],
                  [0.0, 1.0, 0.0, 2.0]])
    q = np.array([1.0, -2.0, -2.0, -2.0])
    for method in ("pgs", "psor"):
        res = lcpcli.solve(M, q, method)
        assert res.status == Status.UNSOLVED and not np.all(np.isfinite(res.z))
        assert res.basis is None and res.to_dict()["basis"] is None
        stacked = solve_each([lcpcli.Problem.create(M, q)] * 9, method)
        assert all(r.basis is None and r.to_dict()["basis"] is None for r in stacked)


def test_mlcp_with_a_subnormal_pivot_every_method() -> None:
    """An MLCP whose equality block has a subnormal pivot (5e-324): the block's power-of-two
    equilibration overflowed (2^1074), mlcp-lemke's SVD of the NaN block raised LinAlgError
    (exit 3) and the others printed numpy warnings.  Every MLCP method answers without a
    warning; a solved z passes the independent check."""
    import warnings

    from references import componentwise_error

    M = np.array([[5e-324, 1, 1, 0], [0, 3, 0, -1], [-1, 0, 1e-16, 0], [0, 1, 0, 1]], float)
    q = np.array([-3.0, 2.0, -1.0, 4.0])
    for method in METHODS["mlcp"]:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            res = lcpcli.solve(M, q, method=method, n_eq=2)
        assert res.status in (Status.SOLVED, Status.UNSOLVED), (method, res.message)
        if res.status == Status.SOLVED:
            assert componentwise_error(M, q, res.z, n_eq=2) <= res.certificate.tol * (1 + 1e-6)
