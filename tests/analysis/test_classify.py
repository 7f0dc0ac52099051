"""The class report and its tests: the generated classes, exact references, scale invariance.

Independent checks: principal minors in exact rational arithmetic (``fractions.Fraction`` of
the float entries) for the P-matrix test, eigenvalues (numpy) for definiteness, the
definition (``x > 0`` with ``C x > 0``) for H-matrices.  Invariances (property-based):
P, Z, H and positive diagonal under ``D1 M D2``; symmetry and definiteness under ``D M D``;
everything under ``2^k M`` for k in [-1000, 1000].
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

import lcpcli.analysis.classify as classify_module
from lcpcli.analysis.classify import (
    INDEFINITE,
    PD,
    PSD,
    SYM_TOL,
    Classifier,
    ClassReport,
    classify,
    definiteness,
    h_matrix_positive_diagonal,
    is_p_matrix_exact,
    is_symmetric,
    p_matrix,
)
from lcpcli.core.problem import Problem


# ---------------------------------------------------------------------------- generators
def rand_pd(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return A @ A.T / n + 0.5 * np.eye(n)


def rand_psd(n: int, rank: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, rank))
    return B @ B.T / rank


def rand_p_nonsym(n: int, seed: int) -> np.ndarray:
    """A non-symmetric H-matrix with positive diagonal (so P) with indefinite symmetric part."""
    rng = np.random.default_rng(seed)
    M = 0.02 / n * rng.standard_normal((n, n))
    for k in range(0, n - 1, 2):
        M[k, k + 1] = 3.0
        M[k + 1, k] = 0.0
    M[np.diag_indices(n)] = 1.0 + 0.2 * rng.random(n)
    return M


def rand_indefinite_sym(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A + A.T
    M[np.diag_indices(n)] = np.abs(M.diagonal()) + 0.1  # positive diagonal, still indefinite
    return M


def m_matrix(n: int, seed: int) -> np.ndarray:
    """A nonsingular M-matrix (Z, H and P): s I - B, B >= 0, s > rho(B)."""
    rng = np.random.default_rng(seed)
    B = rng.random((n, n))
    return 1.2 * np.max(np.abs(np.linalg.eigvals(B))) * np.eye(n) - B


def rand_general(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    M[np.diag_indices(n)] = rng.random(n) + 0.05
    return M


FAMILIES = [rand_pd, lambda n, s: rand_psd(n, max(1, n // 2), s), rand_p_nonsym,
            rand_indefinite_sym, m_matrix, rand_general]


def problem(M) -> Problem:  # type: ignore[no-untyped-def]
    return Problem.create(M, -np.ones(M.shape[0]))


# ---------------------------------------------------------------------------- references
def exact_p_matrix(M: np.ndarray, margin: float = 0.0) -> bool | None:
    """All principal minors positive, in exact rational arithmetic (n <= 8).

    With ``margin > 0``: None (ambiguous) when no minor is <= 0 but one is positive by less
    than ``margin`` times the product of its diagonal entries (numerically singular)."""
    n = M.shape[0]
    F = [[Fraction(float(x)) for x in row] for row in M]

    def det(idx: tuple[int, ...]) -> Fraction:
        A = [[F[i][j] for j in idx] for i in idx]
        k, sign, out = len(idx), 1, Fraction(1)
        for c in range(k):
            piv = next((r for r in range(c, k) if A[r][c] != 0), None)
            if piv is None:
                return Fraction(0)
            if piv != c:
                A[c], A[piv] = A[piv], A[c]
                sign = -sign
            out *= A[c][c]
            for r in range(c + 1, k):
                f = A[r][c] / A[c][c]
                A[r] = [A[r][j] - f * A[c][j] for j in range(k)]
        return sign * out

    ambiguous = False
    for k in range(1, n + 1):
        for idx in itertools.combinations(range(n), k):
            d = det(idx)
            if d <= 0:
                return False
            scale = abs(np.prod([float(M[i, i]) for i in idx]))
            ambiguous |= float(d) <= margin * scale
    return None if ambiguous else True


def eig_definiteness(M: np.ndarray) -> str:
    ev = np.linalg.eigvalsh(0.5 * (M + M.T))
    big = np.max(np.abs(ev))
    if ev[0] > 1e-8 * big:
        return PD
    return PSD if ev[0] >= -1e-8 * big else INDEFINITE


def comparison_is_m_matrix(M: np.ndarray) -> bool | None:
    """H-matrix with positive diagonal by the spectral radius of the Jacobi matrix of |M|;
    None when that radius is 1 to within rounding (RHO_MARGIN: the classifier then answers
    "not known to be H", and an eigenvalue routine's answer is rounding too)."""
    d = np.diagonal(M)
    if np.any(d <= 0):
        return False
    B = np.abs(M) / d[:, None]
    np.fill_diagonal(B, 0.0)
    rho = float(np.max(np.abs(np.linalg.eigvals(B))))
    if abs(rho - 1.0) <= 1e-9:
        return None
    return rho < 1.0


# ---------------------------------------------------------------------------- the classes
def test_the_generated_classes_are_recognised():
    c = classify(problem(rand_pd(30, 5)))
    assert isinstance(c, ClassReport)
    assert c.symmetric and c.definiteness == PD and c.pd and c.p_matrix
    c = classify(problem(rand_psd(30, 5, 6)))
    assert c.definiteness == PSD and c.psd and not c.pd and c.p_matrix is not True
    c = classify(problem(rand_p_nonsym(30, 7)))
    assert not c.symmetric and c.definiteness == INDEFINITE
    assert c.h_matrix and c.p_matrix and "H-matrix" in c.p_matrix_reason
    c = classify(problem(m_matrix(12, 3)))
    assert c.z_matrix and c.h_matrix and c.p_matrix and not c.nonnegative
    c = classify(problem(np.array([[2.0, -1.0], [-1.0, 2.0]])))
    assert c.z_matrix and c.diagonally_dominant and c.p_matrix
    # exact P test for small n: [[1, 4], [0, 1]] is P (not PD); [[1, 2], [1, 1]] is not P
    c = classify(problem(np.array([[1.0, 4.0], [0.0, 1.0]])))
    assert c.p_matrix and c.definiteness == INDEFINITE
    c = classify(problem(np.array([[1.0, 2.0], [1.0, 1.0]])))
    assert c.p_matrix is False and "minor" in c.p_matrix_reason
    # singular 2 x 2 minor: exactly zero determinant is not P
    assert p_matrix(np.array([[1.0, 2.0], [0.5, 1.0]]))[0] is False


def test_sparse_report_has_the_fill_of_its_factorisation():
    rng = np.random.default_rng(8)
    J = sp.random(300, 200, density=0.02, random_state=8, format="csr")
    M = (J @ J.T + 1e-3 * sp.identity(300)).tocsr()
    c = classify(Problem.create(M, rng.standard_normal(300)))
    assert c.sparse and c.symmetric and c.pd and c.positive_diagonal
    assert c.factor_fill is not None and c.factor_fill >= 1.0
    d = c.as_dict()
    assert d["factor_fill"] == c.factor_fill and d["h_matrix_positive_diagonal"] == c.h_matrix
    assert not hasattr(classify_module, "_LAST_FILL")  # no value passed through a global


def test_zero_and_negative_diagonals():
    c = classify(problem(np.array([[0.0, 1.0], [1.0, 1.0]])))
    assert c.zero_diagonal == 1 and not c.positive_diagonal and c.p_matrix is False
    assert c.definiteness == INDEFINITE  # a zero diagonal entry with a nonzero in its row
    c = classify(problem(np.array([[0.0, 0.0], [0.0, 1.0]])))
    assert c.definiteness == PSD and c.p_matrix is False
    c = classify(problem(np.array([[-1.0, 0.0], [0.0, 1.0]])))
    assert c.definiteness == INDEFINITE and c.h_matrix is False


def test_classifier_runs_only_what_is_asked():
    c = Classifier(problem(rand_pd(40, 1)))
    assert c.known("pd") is None and c.known("p_matrix") is None  # only the O(n) test ran
    assert c.report.positive_diagonal and c.report.symmetric is None
    assert c.cheap("pd") is None  # O(n^3): not run by cheap()
    assert c.cheap("symmetric") is True and c.report.definiteness is None
    assert c.get("psd") is True and c.report.p_matrix is None and c.report.h_matrix is None
    assert c.get("p_matrix") is True and c.report.p_matrix_reason.startswith("positive definite")
    # a non-positive diagonal entry settles P, H (and PD) without any O(n^2) test
    c = Classifier(problem(np.array([[1.0, 2.0], [3.0, -1.0]])))
    assert c.known("p_matrix") is False and c.known("h_matrix") is False
    assert c.known("pd") is False and c.report.symmetric is None


# ---------------------------------------------------------------------------- references
@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 6), seed=st.integers(0, 10_000), family=st.integers(0, 5))
def test_exact_p_test_agrees_with_rational_minors(n, seed, family):
    M = FAMILIES[family](n, seed)
    ref = exact_p_matrix(M, margin=1e-9)
    assume(ref is not None)  # a minor positive only by rounding (rank-deficient PSD)
    assert is_p_matrix_exact(M) == ref


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 5), seed=st.integers(0, 10_000))
def test_exact_p_test_on_small_integer_matrices(n, seed):
    """Integer entries: singular minors are exactly zero, and must count as not positive."""
    M = np.random.default_rng(seed).integers(-2, 3, size=(n, n)).astype(float)
    M[np.diag_indices(n)] = np.abs(M.diagonal()) + 1
    assert is_p_matrix_exact(M) == exact_p_matrix(M)
    p, _ = p_matrix(M)
    assert p == exact_p_matrix(M)  # n <= 10: always decided, and rightly


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 30), seed=st.integers(0, 10_000), family=st.integers(0, 5))
@example(n=2, seed=259, family=1)  # a rank-1 PSD M: rho(B) = 1 - 2e-16
def test_definiteness_and_h_matrix_agree_with_spectral_references(n, seed, family):
    M = FAMILIES[family](n, seed)
    assert definiteness(M).kind == eig_definiteness(M)
    expected = comparison_is_m_matrix(M)
    got = h_matrix_positive_diagonal(M)
    assert got == expected or (expected is None and got is not True)


def test_symmetry_tolerance_is_relative_to_the_entries():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((40, 25))
    W = np.diag(rng.random(25) + 0.1)
    M = (A @ W) @ A.T  # rounding may make it asymmetric at 1e-16
    assert is_symmetric(M, SYM_TOL)
    E = M.copy()
    E[3, 7] *= 1 + 1e-13
    assert is_symmetric(E, SYM_TOL)
    E[3, 7] = M[3, 7] + 1e-6 * abs(M[3, 7]) + 1e-6
    assert not is_symmetric(E, SYM_TOL)
    # a tiny entry far from the diagonal's scale is compared with its own pair, not with max|M|
    T = np.diag([1e6, 1e6, 1.0])
    T[0, 2], T[2, 0] = 1e-3, 2e-3
    assert not is_symmetric(T, SYM_TOL)
    assert is_symmetric(sp.csr_matrix(M), SYM_TOL)
    assert not is_symmetric(sp.csr_matrix(T), SYM_TOL)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 6), seed=st.integers(0, 2**32 - 1),
       change=st.sampled_from(["none", "rounding", "large"]))
def test_exact_symmetry_is_the_tolerant_test_at_tol_zero(n, seed, change):
    """``is_symmetric(M, 0.0)`` (the exact test the scaling and BPP use) is "every pair
    equal", on dense and sparse M alike, and implies the tolerant test; a rounding-level
    asymmetry passes the tolerant test only."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A + A.T
    if change != "none" and n > 1:
        M[0, n - 1] *= 1 + (1e-14 if change == "rounding" else 1e-3)
    equal = bool(np.array_equal(M, M.T))
    for form in (M, sp.csr_matrix(M)):
        assert is_symmetric(form, 0.0) is equal
        if equal:
            assert is_symmetric(form, SYM_TOL)
        else:
            assert is_symmetric(form, SYM_TOL) is (change == "rounding")


# ---------------------------------------------------------------------------- invariances
def report_key(r: ClassReport, props: tuple[str, ...]) -> tuple:
    return tuple(getattr(r, p) for p in props)


ALL = ("symmetric", "positive_diagonal", "nonnegative", "z_matrix", "diagonally_dominant",
       "definiteness", "h_matrix", "p_matrix", "zero_diagonal")
D1MD2 = ("positive_diagonal", "z_matrix", "h_matrix", "p_matrix")
DMD = ("symmetric", "definiteness")


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), family=st.integers(0, 5),
       k=st.integers(-1000, 1000), sparse=st.booleans())
def test_global_power_of_two_scaling_changes_nothing(n, seed, family, k, sparse):
    M = FAMILIES[family](n, seed)
    S = np.ldexp(M, k)
    if sparse:
        M, S = sp.csr_matrix(M), sp.csr_matrix(S)
    with np.errstate(over="raise"):
        a, b = classify(problem(M)), classify(problem(S))
    assert report_key(a, ALL) == report_key(b, ALL)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), family=st.integers(0, 5),
       spread=st.integers(0, 30), pow2=st.booleans())
def test_row_and_column_scaling_keeps_p_z_h_and_the_diagonal_sign(n, seed, family, spread,
                                                                  pow2):
    M = FAMILIES[family](n, seed)
    rng = np.random.default_rng(seed + 1)
    if pow2:
        d1 = np.ldexp(1.0, rng.integers(-spread, spread + 1, n))
        d2 = np.ldexp(1.0, rng.integers(-spread, spread + 1, n))
    else:
        d1, d2 = np.exp(rng.uniform(-spread, spread, (2, n)) / 3)
    a, b = classify(problem(M)), classify(problem(d1[:, None] * M * d2[None, :]))
    # family 1 is rank-deficient: on the boundary of P and H, its exact minors are rounding
    # noise whose sign a scaling that is not a power of two (so rounded) may flip; scaling by
    # powers of two is exact and keeps every property
    keys = D1MD2 if pow2 or family != 1 else ("positive_diagonal", "z_matrix")
    assert report_key(a, keys) == report_key(b, keys)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 14), seed=st.integers(0, 10_000), family=st.integers(0, 5),
       spread=st.integers(0, 30), sparse=st.booleans())
def test_symmetric_scaling_keeps_symmetry_and_definiteness(n, seed, family, spread, sparse):
    M = FAMILIES[family](n, seed)
    d = np.exp(np.random.default_rng(seed + 2).uniform(-spread, spread, n) / 3)
    S = d[:, None] * M * d[None, :]
    if sparse:
        M, S = sp.csr_matrix(M), sp.csr_matrix(S)
    a, b = classify(problem(M)), classify(problem(S))
    assert report_key(a, DMD) == report_key(b, DMD)


@pytest.mark.parametrize("scale", [1e300, 1e-300, 2.0 ** 1000, 2.0 ** -1000])
def test_extreme_magnitudes_do_not_overflow(scale):
    for family in FAMILIES:
        M = family(8, 4) * scale
        with np.errstate(over="raise", invalid="raise"):
            a = classify(problem(M))
        b = classify(problem(family(8, 4)))
        assert report_key(a, ALL) == report_key(b, ALL)


@pytest.mark.parametrize("sparse", [False, True])
def test_diagonal_entries_2000_binades_apart_keep_the_h_and_p_tests(sparse):
    """diag(2^1000, 2^-1000) is an H-matrix and a P-matrix; with off-diagonal entries 1 it is
    singular (det 1 - 1 = 0: neither).  The unit-row and unit-diagonal scalings divide by each
    row's own diagonal (a normalisation by the largest entry flushed 2^-1000 to 0: numpy
    warned of a division by zero and the H test saw NaN); no warning escapes."""
    import warnings

    D = np.diag([2.0 ** 1000, 2.0 ** -1000])
    S = np.array([[2.0 ** 1000, 1.0], [1.0, 2.0 ** -1000]])
    wrap = sp.csr_matrix if sparse else np.asarray
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert h_matrix_positive_diagonal(wrap(D)) is True
        assert h_matrix_positive_diagonal(wrap(S)) is False
        assert p_matrix(D)[0] is True
        assert p_matrix(S)[0] is False
        for M in (D, S):
            Classifier(Problem.create(M, -np.ones(2))).complete()


@pytest.mark.parametrize("sparse", [False, True])
@pytest.mark.parametrize("M, kind", [
    (np.diag([2.0 ** 1000, 2.0 ** -1000]), PD),
    (np.array([[2.0 ** 1000, 0.5], [0.5, 2.0 ** -1000]]), PD),  # det 0.75
    (np.array([[2.0 ** 1000, 1.0], [1.0, 2.0 ** -1000]]), PSD),  # det 0, trace > 0
    (np.array([[2.0 ** 1000, 2.0], [2.0, 2.0 ** -1000]]), INDEFINITE),  # det -3
    (np.array([[2.0 ** -1000, 1e308], [-1e308, 2.0 ** -1000]]), PD),  # skew part only
    (np.array([[2.0 ** -1000, 1e308], [1e308, 2.0 ** -1000]]), INDEFINITE),
    (np.array([[5e-324, 0.0], [0.0, 1.0]]), PD),
    (np.full((2, 2), 1.7e308), PSD),
])
def test_definiteness_of_diagonals_far_apart(M, kind, sparse):
    """The inertia of (M + M^T)/2 does not depend on how far apart its diagonal entries lie:
    each case's kind is known exactly (2 x 2: the signs of the diagonal and determinant).
    A normalisation by the largest entry had flushed 2^-1000 to 0 and called the first
    three indefinite."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert definiteness(sp.csr_matrix(M) if sparse else M).kind == kind
