"""The compiled Ruiz exponents (``analysis._scaling.ruiz_exponents``) against an independent
numpy reference of the same definition, on dense and sparse data with zero rows and columns,
subnormal, huge and tiny entries, and negative zeros (the balance test's fast pass reads the
exponent bits directly for dense M up to 1024)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.analysis._scaling import ruiz_exponents
from lcpcli.analysis.scaling import BALANCED, MAX_ROUNDS, Q_BALANCED

FLOOR = -(1 << 40)


def _exp(x: np.ndarray) -> np.ndarray:
    return np.frexp(x)[1].astype(np.int64)


def _maxima(M: np.ndarray, r: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    E = np.where(M != 0, _exp(M) + r[:, None] + c[None, :], FLOOR)
    return E.max(axis=1, initial=FLOOR), E.max(axis=0, initial=FLOOR)


def _floordiv2(x):
    return x // 2


def reference(M: np.ndarray, q: np.ndarray, symmetric: bool, balanced: int, q_balanced: int,
              max_rounds: int):
    """Ruiz's iteration on binary exponents, as lcpcli.analysis.scaling documents it."""
    n = q.shape[0]
    if n == 0:
        return None
    r = np.zeros(n, np.int64)
    c = np.zeros(n, np.int64)
    for _ in range(max_rounds):
        rmax, cmax = _maxima(M, r, c)
        rmax = np.where(rmax == FLOOR, 1, rmax)
        cmax = np.where(cmax == FLOOR, 1, cmax)
        lo, hi, clo, chi = rmax.min(), rmax.max(), cmax.min(), cmax.max()
        if hi - lo <= balanced and chi - clo <= balanced and -balanced <= hi - 1 <= balanced:
            break
        if symmetric:
            d = _floordiv2(1 - np.maximum(rmax, cmax))
            r += d
            c += d
        else:
            r -= _floordiv2(rmax - 1)
            _, cmax = _maxima(M, r, c)
            cmax = np.where(cmax == FLOOR, 1, cmax)
            c -= _floordiv2(cmax - 1)
    nz = q != 0
    qexp = (_exp(q[nz]) + r[nz]).max() if nz.any() else FLOOR
    k = 0 if qexp == FLOOR else -qexp + 1
    if not (r.any() or c.any()) and -q_balanced <= k <= q_balanced:
        return None
    return r + k, c - k


def _check(M: np.ndarray, q: np.ndarray, symmetric: bool, rounds: int) -> None:
    want = reference(M, q, symmetric, BALANCED, Q_BALANCED, rounds)
    for arg in (np.ascontiguousarray(M), _csr(M)):
        got = ruiz_exponents(arg, q, symmetric, BALANCED, Q_BALANCED, rounds)
        if want is None:
            assert got is None
        else:
            assert got is not None
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])


def _csr(M: np.ndarray):
    A = sp.csr_matrix(M)
    return A.data, A.indices.astype(np.intp), A.indptr.astype(np.intp)


ENTRIES = st.sampled_from([0.0, -0.0, 1.0, -3.5, 1e-300, 5e-324, -2.2e-310, 1e300, 7.0, 0.01,
                           1e8, -1e-8, 2.0**-1022, 2.0**1023])


@settings(max_examples=200, deadline=None)
@given(n=st.integers(1, 9), data=st.data(), symmetric=st.booleans(),
       rounds=st.sampled_from([1, 2, MAX_ROUNDS]))
def test_matches_the_reference(n, data, symmetric, rounds):
    M = np.array(data.draw(st.lists(ENTRIES, min_size=n * n, max_size=n * n))).reshape(n, n)
    q = np.array(data.draw(st.lists(ENTRIES, min_size=n, max_size=n)))
    _check(M, q, symmetric, rounds)


@pytest.mark.parametrize("n", [1, 7, 64, 1024, 1025])
@pytest.mark.parametrize("case", ["balanced", "rows", "zero row", "subnormal column"])
def test_large_and_special_matrices(n, case):
    rng = np.random.default_rng(n)
    M = rng.uniform(0.5, 1.5, (n, n)) * rng.choice([-1.0, 1.0], (n, n))
    q = rng.standard_normal(n)
    if case == "rows":
        M *= 2.0 ** rng.integers(-40, 40, n)[:, None]
    elif case == "zero row":
        M[n // 2, :] = 0.0
    elif case == "subnormal column":
        M[:, n // 3] = 1e-310
    for rounds in (1, MAX_ROUNDS):
        _check(M, q, False, rounds)
