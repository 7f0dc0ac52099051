"""Forward error bounds: they bound, they are exact where the theory says, None outside P."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lcpcli.analysis.bounds import forward_error_bound
from lcpcli.core.problem import Problem


def _planted(M: np.ndarray, rng: np.random.Generator) -> tuple[Problem, np.ndarray]:
    n = M.shape[0]
    z = np.where(rng.random(n) < 0.5, rng.uniform(0.1, 2.0, n), 0.0)
    q = np.where(z > 0, 0.0, rng.uniform(0.1, 2.0, n)) - M @ z
    return Problem.create(M, q), z


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 25), kind=st.sampled_from(["dd", "pd"]),
       size=st.floats(-12, -1))
def test_the_bound_bounds(seed, n, kind, size):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    if kind == "dd":  # strictly diagonally dominant: an H-matrix with positive diagonal
        M = A.copy()
        np.fill_diagonal(M, np.abs(A).sum(axis=1) + rng.uniform(0.01, 2.0, n))
    else:             # positive definite, not symmetric
        M = A @ A.T / n + 0.1 * np.eye(n) + 0.5 * (A - A.T)
    p, z_star = _planted(M, rng)
    z = z_star + rng.standard_normal(n) * 10.0 ** size
    fb = forward_error_bound(p, z)
    assert fb is not None
    assert np.max(np.abs(z - z_star)) <= fb.bound * (1 + 1e-12)


def test_exact_for_a_diagonal_matrix():
    # M = diag(4, 1/4): max_d ||(I - D + DM)^-1|| = max(1, 1/m_i) = 4, reached for z off in z2
    p = Problem.create(np.diag([4.0, 0.25]), [-4.0, -0.25])
    z = np.array([1.0, 1.0 + 1e-6])          # z* = (1, 1); r = (0, 0.25e-6)
    fb = forward_error_bound(p, z)
    assert fb.how.startswith("H-matrix")
    assert fb.bound == pytest.approx(4 * 0.25e-6, rel=1e-6)
    assert np.max(np.abs(z - 1.0)) == pytest.approx(fb.bound, rel=1e-6)


def test_none_outside_the_proven_classes():
    p = Problem.create([[0.0, 1.0], [1.0, 0.0]], [-1.0, -1.0])      # zero diagonal: not P
    assert forward_error_bound(p, np.array([1.0, 1.0])) is None
    p = Problem.create([[1.0, 2.0], [2.0, 1.0]], [-1.0, -1.0])      # indefinite, not H
    assert forward_error_bound(p, np.array([1 / 3, 1 / 3])) is None
    mlcp = Problem.create(np.eye(2), [-1.0, -1.0], n_eq=1)           # not an LCP
    assert forward_error_bound(mlcp, np.ones(2)) is None
