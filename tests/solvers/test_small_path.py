"""The pipeline's small path (``Method.fast``): one compiled call gives the same result as the
full pipeline, and declines (None) whenever the full pipeline would do more."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.analysis.scaling import is_balanced
from lcpcli.core.problem import Problem
from lcpcli.solvers import registry
from lcpcli.solvers.methods import lemke_revised
from lcpcli.solvers.pipeline import run_method


def _spd(n: int, seed: int, row_scale: float = 1.0) -> Problem:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T / n + np.eye(n)
    q = rng.standard_normal(n)
    if row_scale != 1.0:
        d = row_scale ** rng.uniform(-1, 1, n)
        M, q = d[:, None] * M, d * q
    return Problem.create(M, q)


@pytest.fixture
def without_small_path(monkeypatch):
    """Solve with lemke-revised's small path switched off (the full pipeline only)."""
    spec = registry.get_method("lemke-revised")
    plain = dataclasses.replace(spec, fast=None)

    def solve(problem, method="lemke", **kw):
        monkeypatch.setitem(registry._load(), "lemke-revised", plain)
        try:
            return lcpcli.solve(problem, method, **kw)
        finally:
            monkeypatch.setitem(registry._load(), "lemke-revised", spec)
    return solve


def _same(a, b) -> None:
    assert a.status == b.status
    assert a.method == b.method
    np.testing.assert_array_equal(a.z, b.z)
    np.testing.assert_array_equal(a.w, b.w)
    assert a.iterations == b.iterations
    assert a.message == b.message
    assert a.termination == b.termination
    assert a.certificate == b.certificate
    assert a.info == b.info


@pytest.mark.parametrize("n", [1, 2, 10, 50])
def test_same_result_as_the_full_pipeline(n, without_small_path):
    for seed in range(5):
        p = _spd(n, seed)
        assert is_balanced(p)
        _same(lcpcli.solve(p, "lemke"), without_small_path(p))


def test_declines_what_the_full_pipeline_must_do():
    opts = registry.get_method("lemke").parse_options({})
    p = _spd(10, 1)
    assert lemke_revised.fast(p, 1e-8, opts) is not None
    # a problem the pipeline equilibrates first
    unbalanced = _spd(10, 1, row_scale=1e6)
    assert not is_balanced(unbalanced)
    assert lemke_revised.fast(unbalanced, 1e-8, opts) is None
    assert lcpcli.solve(unbalanced, "lemke").solved
    # a trace (recorded by the tableau replica)
    assert lemke_revised.fast(p, 1e-8, {**opts, "trace": True}) is None
    # q >= 0 (z = 0, certified the ordinary way) and an infeasible problem (a ray)
    easy = Problem.create(p.M, np.abs(p.q))
    assert lemke_revised.fast(easy, 1e-8, opts) is None
    assert lcpcli.solve(easy, "lemke").solved
    infeasible = Problem.create(-np.eye(3), -np.ones(3))
    assert lemke_revised.fast(infeasible, 1e-8, opts) is None
    assert lcpcli.solve(infeasible, "lemke").status == "no_solution"
    # a tolerance the answer does not meet
    assert lemke_revised.fast(p, 1e-17, opts) is None  # tol below the rounding of this z


def test_options_reach_the_compiled_call(without_small_path):
    p = _spd(12, 3)
    for opts in ({"max_iter": 2}, {"covering": np.arange(1.0, 13.0)}, {"refactor_every": 1}):
        _same(lcpcli.solve(p, "lemke", **opts), without_small_path(p, "lemke", **opts))
    assert lcpcli.solve(p, "lemke", max_iter=2).status == "unsolved"


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1),
       psd=st.booleans(), scale=st.sampled_from([1.0, 1e-3, 1e5]))
def test_small_path_never_changes_a_result(n, seed, psd, scale):
    """Random P and PSD problems, some not balanced: with or without the small path, the
    Result is the same."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T if psd else A @ A.T + np.eye(n)
    q = rng.standard_normal(n) * scale
    p = Problem.create(M, q)
    spec = registry.get_method("lemke-revised")
    plain = dataclasses.replace(spec, fast=None)
    opts = spec.parse_options({})
    a = run_method(spec, p, 1e-8, opts)
    b = run_method(plain, p, 1e-8, opts)
    np.testing.assert_array_equal(a.z, b.z)
    assert (a.termination, a.iterations, a.message) == (b.termination, b.iterations, b.message)
    assert a.info == b.info
