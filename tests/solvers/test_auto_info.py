"""``auto``'s ``Result.info`` when its first attempt solved: built on first read
(:class:`lcpcli.core.result.LazyInfo`, :class:`~lcpcli.core.result.LazyResult`), it must be
the dict that computing everything afresh gives, and the same whenever it is read."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import lcpcli
from lcpcli.analysis.classify import Classifier
from lcpcli.core.result import CONVERGED, LazyInfo, LazyResult, Outcome, Result
from lcpcli.solvers import memo, policy

TIMES = ("seconds", "classify_seconds")


def _family(name: str, n: int, seed: int):
    """``benchmarks/bench_methods.py``'s families (bench_auto's): random PD, PSD of rank n/2
    with a solvable q, a non-symmetric P-matrix (H-matrix with positive diagonal) whose
    symmetric part is indefinite; and a PSD one with a zero diagonal entry (its plan reads more
    than the minima)."""
    rng = np.random.default_rng(seed)
    if name == "pd":
        A = rng.standard_normal((n, n))
        return lcpcli.Problem.create(A @ A.T / n + 0.5 * np.eye(n), rng.standard_normal(n))
    if name == "psd":
        B = rng.standard_normal((n, max(1, n // 2)))
        M = B @ B.T / max(1, n // 2)
        z = np.where(rng.random(n) < 0.5, rng.random(n), 0.0)
        w = np.where(z > 0, 0.0, rng.random(n))
        return lcpcli.Problem.create(M, w - M @ z)
    if name == "p":
        M = 0.02 / n * rng.standard_normal((n, n))
        k = np.arange(0, n - 1, 2)
        M[k, k + 1] = 3.0
        M[k + 1, k] = 0.0
        M[np.diag_indices(n)] = 1.0 + 0.2 * rng.random(n)
        return lcpcli.Problem.create(M, rng.standard_normal(n))
    B = rng.standard_normal((n, n))
    B[0] = 0.0
    A = rng.standard_normal((n, n))
    M = B @ B.T + A - A.T  # PSD (x^T M x = |B^T x|^2), m_00 = 0: copositive-plus
    z = np.where(rng.random(n) < 0.5, rng.random(n), 0.0)
    w = np.where(z > 0, 0.0, rng.random(n))
    return lcpcli.Problem.create(M, w - M @ z)  # solvable


def _fresh_info(p: lcpcli.Problem) -> dict:
    """auto's info for a first attempt that solves, every part computed afresh and eagerly:
    the class report after the diagonal test, the regime and first step of a fresh plan, and
    the chosen method's own solve (the attempt's status, termination, iterations, certified
    error and message)."""
    c = Classifier(p)
    c.minima()
    report = c.report
    regime, step = policy.first_step(p, c)
    alone = lcpcli.solve(p, step.method)
    assert alone.solved
    return {"chosen": step.method,
            "attempts": [{"method": step.method, "reason": step.reason, "status": "solved",
                          "termination": "converged", "iterations": alone.iterations,
                          "error": alone.error, "message": alone.message}],
            "classification": report, "regime": regime.name}


def _without_times(info: dict) -> dict:
    out = {k: v for k, v in info.items() if k not in TIMES}
    out["attempts"] = [{k: v for k, v in a.items() if k not in TIMES} for a in info["attempts"]]
    return out


@pytest.mark.parametrize("family, n", [(f, n) for f in ("pd", "psd", "p", "zero-diagonal")
                                       for n in (1, 4, 10, 30) if (f, n) != ("zero-diagonal", 1)])
def test_lazy_info_equals_a_fresh_eager_computation(family, n):
    p = next(p for seed in range(100, 200) if (p := _family(family, n, seed)).q.min() < 0)
    for _ in range(2):  # a first solve (memos filled) and a repeated one (memos hit)
        r = lcpcli.solve(p)
        assert r.solved and len(r.info["attempts"]) == 1
        info = r.info
        assert type(info) is dict and r.info is info  # built once, then the same dict
        assert _without_times(info) == _fresh_info(p)
        assert info["classify_seconds"] >= 0 and info["attempts"][0]["seconds"] >= 0
        step = info["attempts"][0]
        assert r.message == (f"auto ({info['classification'].describe()}): solved by "
                             f"{step['method']} ({step['reason']})")
        assert (r.iterations, r.termination, r.error) == (step["iterations"], "converged",
                                                          step["error"])


def test_the_info_keeps_the_values_of_the_solve():
    """The report's numbers are those at solve time, whatever happens to the problem's arrays
    before ``info`` is first read; changes to the dict are kept."""
    p = _family("pd", 8, 3)
    expected = _without_times(_fresh_info(p))
    r = lcpcli.solve(p)
    assert isinstance(r, LazyResult) and isinstance(r, Result)
    p.M[np.diag_indices(8)] = 7.0  # the user's arrays, changed in place after the solve
    assert _without_times(r.info) == expected
    r.info["note"] = 1
    assert r.info["note"] == 1
    r.info = {"replaced": True}
    assert r.info == {"replaced": True}


def test_a_pickled_result_carries_the_built_info():
    p = _family("psd", 6, 4)
    r = lcpcli.solve(p)
    back = pickle.loads(pickle.dumps(r))
    assert _without_times(back.info) == _without_times(_fresh_info(p))
    assert back.info["classify_seconds"] == r.info["classify_seconds"]
    np.testing.assert_array_equal(back.z, r.z)


def test_info_of_the_other_statuses_is_built_eagerly_with_the_same_layout():
    """Not solved at the first attempt (a failed first attempt, unsolved, no_solution): a plain
    Result whose info has the lazily built one's keys and attempt records."""
    p = _family("pd", 10, 5)
    lazy = lcpcli.solve(p).info
    second = lcpcli.solve(p, max_iter=1)  # Lemke stops at its pivot limit; the plan goes on
    unsolved = lcpcli.solve(p, order="lemke", max_iter=1)
    infeasible = lcpcli.solve(lcpcli.Problem.create(-np.eye(2), -np.ones(2)))
    assert (second.status, unsolved.status, infeasible.status) == (
        "solved", "unsolved", "no_solution")
    for r in (second, unsolved, infeasible):
        assert type(r) is Result and type(r.info) is dict
        assert set(lazy) <= set(r.info)
        assert set(r.info["attempts"][0]) == set(lazy["attempts"][0])
    assert second.info["attempts"][0]["status"] == "unsolved"
    first = second.info["attempts"][0]
    assert f"; {first['method']} failed first ({first['message']})" in second.message


def test_order_and_memo_less_first_attempts_give_the_same_info(monkeypatch):
    """The first attempt planned with a classifier (``order=``; every memo empty: the general
    path) gives the info the memoised path gives."""
    p = _family("p", 12, 6)
    hit = lcpcli.solve(p)
    assert lcpcli.solve(p).info["chosen"] == hit.info["chosen"]
    for name in ("FIRSTS", "OPENINGS", "ATTEMPTS"):
        monkeypatch.setattr(getattr(memo, name), "limit", 0)
    for m in (memo.FIRSTS, memo.OPENINGS, memo.ATTEMPTS):
        m.clear()
    fresh = lcpcli.solve(p)
    assert len(memo.FIRSTS) == 0
    ordered = lcpcli.solve(p, order=hit.info["chosen"])
    assert _without_times(fresh.info) == _without_times(hit.info)
    assert fresh.message == hit.message
    want = _without_times(hit.info)
    want["attempts"][0]["reason"] = "given by order="
    assert _without_times(ordered.info) == want


def test_outcome_details_builds_a_lazy_info_once():
    calls = []

    def build(x):
        calls.append(x)
        return {"x": x}

    out = Outcome(np.zeros(2), 0, CONVERGED, info=LazyInfo(build, 3))
    assert out.details() == {"x": 3} and out.details() is out.info and calls == [3]
