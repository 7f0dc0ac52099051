"""The small path: ``lemke-revised``'s kernel certifies its own answer in the same compiled
call (``Outcome.checked``), and the dispatcher (:func:`lcpcli.solvers.pipeline.run_method`)
reuses that certificate instead of checking again.  The Result must be the one a fresh check
gives: with the kernel's certificate dropped, every field is the same."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.analysis.scaling import is_balanced
from lcpcli.core.certificate import check
from lcpcli.core.problem import Problem
from lcpcli.solvers import registry
from lcpcli.solvers.pipeline import run_method


def _without_kernel_certificate(spec):
    """``spec`` whose runs hand back no certificate (the dispatcher then checks z itself)."""
    def run(problem, **kw):
        out = spec.run(problem, **kw)
        if out is not None:  # None: the balance test in the call refused (Method.balance_test)
            out.checked = None
        return out
    return dataclasses.replace(spec, run=run)


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
    """Solve with lemke-revised's own certificate dropped (the dispatcher checks z)."""
    spec = registry.get_method("lemke-revised")
    plain = _without_kernel_certificate(spec)

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


@pytest.mark.parametrize("case", ["balanced", "unbalanced", "trace", "easy", "infeasible",
                                  "tight tol"])
def test_the_reused_certificate_is_a_fresh_check(case):
    """Whatever path the answer took (the kernel's certificate on a balanced problem, a
    scaled run whose certificate is of the scaled problem and so dropped, the tableau replica
    of a trace, z = 0, a ray, a tolerance the answer does not meet), the Result's certificate
    is check()'s of its z on the user's problem."""
    p = _spd(10, 1)
    tol, opts = 1e-8, {}
    if case == "unbalanced":
        p = _spd(10, 1, row_scale=1e6)
        assert not is_balanced(p)
    elif case == "trace":
        opts = {"trace": True}
    elif case == "easy":
        p = Problem.create(p.M, np.abs(p.q))
    elif case == "infeasible":
        p = Problem.create(-np.eye(3), -np.ones(3))
    elif case == "tight tol":
        tol = 1e-16  # rounding level: the kernel's answer may or may not meet it
    res = lcpcli.solve(p, "lemke", tol=tol, **opts)
    cert, w = check(p, res.z, tol)
    assert res.certificate == cert
    np.testing.assert_array_equal(res.w, w)
    assert res.solved == cert.passed or res.status == "no_solution"
    if case != "tight tol":
        assert res.status == ("no_solution" if case == "infeasible" else "solved")


def test_options_reach_the_compiled_call(without_small_path):
    p = _spd(12, 3)
    for opts in ({"max_iter": 2}, {"covering": np.arange(1.0, 13.0)}, {"refactor_every": 1}):
        _same(lcpcli.solve(p, "lemke", **opts), without_small_path(p, "lemke", **opts))
    assert lcpcli.solve(p, "lemke", max_iter=2).status == "unsolved"


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1),
       psd=st.booleans(), scale=st.sampled_from([1.0, 1e-3, 1e5]))
def test_small_path_never_changes_a_result(n, seed, psd, scale):
    """Random P and PSD problems, some not balanced: with or without the kernel's own
    certificate, the dispatcher's Outcome is the same."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T if psd else A @ A.T + np.eye(n)
    q = rng.standard_normal(n) * scale
    p = Problem.create(M, q)
    spec = registry.get_method("lemke-revised")
    plain = _without_kernel_certificate(spec)
    opts = spec.parse_options({})
    a = run_method(spec, p, 1e-8, opts)
    b = run_method(plain, p, 1e-8, opts)
    np.testing.assert_array_equal(a.z, b.z)
    assert (a.termination, a.iterations, a.message) == (b.termination, b.iterations, b.message)
    assert a.info == b.info
    assert a.checked[0] == b.checked[0]


@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 70), seed=st.integers(0, 2**32 - 1),
       row_scale=st.sampled_from([1.0, 4.0, 64.0, 1e6]), q_scale=st.sampled_from([1.0, 1e-4, 1e4]),
       m_scale=st.sampled_from([1.0, 40.0, 1e-3]))
def test_the_balance_test_in_the_compiled_call_is_is_balanced(n, seed, row_scale, q_scale,
                                                              m_scale):
    """``lemke-revised`` makes the equilibration's balance test inside its compiled call
    (``Method.balance_test``): it solves exactly when :func:`is_balanced` says the problem is
    balanced, and then gives what the call without the test gives."""
    from lcpcli.analysis.scaling import BALANCE

    p = _spd(n, seed, row_scale)
    p = Problem.create(p.M * m_scale, p.q * q_scale)
    spec = registry.get_method("lemke")
    assert spec.balance_test
    got = spec.run(p, tol=1e-8, balance=BALANCE)
    assert (got is not None) == is_balanced(p)
    if got is not None:
        plain = spec.run(p, tol=1e-8)
        np.testing.assert_array_equal(got.z, plain.z)
        assert got.message == plain.message
        assert (got.checked is None) == (plain.checked is None)  # None: z = 0 (q >= 0)
        if got.checked is not None:
            assert got.checked[0] == plain.checked[0]
