"""The memos of the solve path (:mod:`lcpcli.solvers.memo`): each is hit on a repeated solve,
and a hit returns what a fresh computation returns."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import lcpcli
from lcpcli.analysis.classify import (
    DIAGONAL_FACTS,
    DIAGONAL_WORDS,
    PROPERTIES,
    Classifier,
    ClassReport,
)
from lcpcli.core.problem import Problem
from lcpcli.solvers import memo, policy
from lcpcli.solvers.methods import auto
from lcpcli.solvers.registry import get_method, methods


def _replace_memos(monkeypatch, limit: int | None = None) -> None:
    """Every memo replaced by an empty one with zero counts, of its own limit (or ``limit``:
    0 makes a memo that never stores, so every value is computed afresh)."""
    for name in ("REQUESTS", "OPTION_DEFAULTS", "ATTEMPTS", "ORDERS", "OPENINGS", "FIRSTS"):
        old = getattr(memo, name)
        new = memo.Memo(old.name, old.limit if limit is None else limit)
        monkeypatch.setattr(memo, name, new)
        for module in ("lcpcli.solvers.registry", "lcpcli.solvers.policy",
                       "lcpcli.solvers.methods.auto", "lcpcli.solvers.request"):
            mod = __import__(module, fromlist=[name])
            if hasattr(mod, name):
                monkeypatch.setattr(mod, name, new)


@pytest.fixture(autouse=True)
def fresh_memos(monkeypatch):
    """Every memo empty with zero counts for the test (module state restored after)."""
    _replace_memos(monkeypatch)


def _pd(n: int, seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + n * np.eye(n), rng.standard_normal(n))


def test_a_repeated_auto_solve_hits_every_memo_and_gives_the_same_result():
    p = _pd(10, 1)
    first = lcpcli.solve(p)
    misses = {m.name: m.misses for m in (memo.REQUESTS, memo.FIRSTS)}
    second = lcpcli.solve(p)
    for m in (memo.REQUESTS, memo.FIRSTS):
        assert len(m) >= 1 and m.misses == misses[m.name], m.name  # served, not recomputed
    assert first.status == second.status == "solved"
    np.testing.assert_array_equal(first.z, second.z)
    assert first.message == second.message and first.certificate == second.certificate
    assert first.info["attempts"][0]["method"] == second.info["attempts"][0]["method"]


@pytest.mark.parametrize("method, tol", [(None, None), ("lemke", None), ("pgs", 1e-6),
                                         ("LEMKE", 1e-9)])
def test_request_hit_equals_fresh(method, tol):
    from lcpcli.solvers.request import Request, method_of, resolve, resolve_tol

    p = _pd(5, 2)
    first = resolve(p, method, tol)
    misses = memo.REQUESTS.misses
    hit = resolve(_pd(6, 3), method, tol)
    assert memo.REQUESTS.misses == misses  # served from the memo
    spec = method_of(method)
    fresh = Request(p, spec, resolve_tol(spec, tol), spec.parse_options({}), {})
    assert (hit.spec, hit.tol, hit.options, hit.given) == (
        first.spec, first.tol, first.options, first.given) == (
        fresh.spec, fresh.tol, fresh.options, fresh.given)
    # the problem's own checks run on a hit too
    with pytest.raises(Exception, match="does not handle MLCP"):
        resolve(Problem.create(np.eye(3), -np.ones(3), n_eq=1), "lemke", tol)


def test_run_defaults_are_the_option_defaults():
    """The dispatcher passes ``Method.run`` only the options that differ from their defaults
    (``Request.given``): every method's keyword defaults must be its options' defaults."""
    import inspect

    for name, spec in methods().items():
        params = inspect.signature(spec.run).parameters
        for key, opt in spec.options.items():
            assert key in params, (name, key)
            assert params[key].default is opt.default or params[key].default == opt.default, \
                (name, key)
    r = lcpcli.solve(_pd(8, 4), "lemke", max_iter=1)
    assert r.status == "unsolved" and r.iterations == 1  # a given option reaches run


def test_option_defaults_hit_equals_fresh():
    spec = get_method("lemke")
    a = spec.parse_options({})
    misses = memo.OPTION_DEFAULTS.misses
    b = spec.parse_options({})
    assert memo.OPTION_DEFAULTS.misses == misses  # a hit
    assert a == b == spec.option_defaults()
    a["max_iter"] = 7  # the caller's copy: the memo is not changed through it
    assert spec.parse_options({}) == spec.option_defaults()
    # another record under a reused id is not served the old defaults
    other = dataclasses.replace(spec, options={})
    memo.OPTION_DEFAULTS[id(other)] = (spec, spec.option_defaults())
    assert other.parse_options({}) == {}


@pytest.mark.parametrize("max_iter", [None, 5])
def test_attempt_hit_equals_fresh(max_iter):
    for name in ("lemke-revised", "pgs", "newton"):
        spec, opts = auto._attempt(name, max_iter, None)
        misses = memo.ATTEMPTS.misses
        hit = auto._attempt(name, max_iter, None)
        assert memo.ATTEMPTS.misses == misses and hit == (spec, opts)
        fresh = get_method(name)
        cap = max_iter if max_iter is not None else fresh.auto_max_iter
        expected = fresh.parse_options({"max_iter": cap} if "max_iter" in fresh.options
                                       and cap is not None else {})
        # the attempt hands the dispatcher the options that differ from their defaults
        assert hit[1] == fresh.given_options(expected)
        assert {**fresh.option_defaults(), **hit[1]} == expected
    assert memo.ATTEMPTS.misses == 3 and len(memo.ATTEMPTS) == 3
    # a warm start is never memoised
    z0 = np.ones(3)
    spec, opts = auto._attempt("pgs", max_iter, z0)
    np.testing.assert_array_equal(opts["z0"], z0)
    assert len(memo.ATTEMPTS) == 3


def test_order_hit_equals_fresh():
    for regime in policy.REGIMES:
        for kind in ("lcp", "mlcp", "box"):
            table = policy._table(kind, regime, None)
            assert policy._table(kind, regime, None) is table
            assert table == policy.ordered(policy.rows(kind, methods()), regime)
    assert memo.ORDERS.misses == len(memo.ORDERS) == len(policy.REGIMES) * 3


def test_opening_hit_equals_fresh():
    for n in (2, 10, 40):
        p = _pd(n, n)
        first = policy.opening(p, Classifier(p))
        misses = memo.OPENINGS.misses
        q = _pd(n, n + 1)  # another problem with the same diagonal facts: served from the memo
        c = Classifier(q)
        assert policy.opening(q, c) == first
        assert memo.OPENINGS.misses == misses
        regime = policy.regime_of(c)
        fresh = policy.plan(q, c, optimistic=True, first=True, regime=regime)
        assert first == (regime, fresh[0] if fresh else None)


@pytest.mark.parametrize("diag", [[2.0, 1.0, 3.0], [0.0, 1.0, 3.0], [-1.0, 1.0, 3.0],
                                  [0.0, 0.0, 0.0]])
def test_the_opening_key_lists_every_fact_the_diagonal_test_sets(diag):
    """Structural: every report field the O(n) diagonal test sets is a fact of the opening key
    (DIAGONAL_FACTS) or one that no condition reads (DIAGONAL_WORDS)."""
    M = np.array([[diag[0], 1.0, 0.0], [1.0, diag[1], 0.5], [0.0, 0.5, diag[2]]])
    p = Problem.create(M, -np.ones(3))
    c = Classifier(p)
    before = dataclasses.asdict(c.report)
    c.minima()  # runs the diagonal test
    after = dataclasses.asdict(c.report)
    changed = {k for k in after if after[k] != before[k]}
    assert changed <= set(DIAGONAL_FACTS) | set(DIAGONAL_WORDS), changed
    assert not set(DIAGONAL_WORDS) & set(PROPERTIES)
    # the properties conditions read are fields of DIAGONAL_FACTS or derived from them
    derived = {name for name in PROPERTIES if isinstance(getattr(ClassReport, name, None),
                                                         property)}
    assert derived <= {"pd", "psd"}
    assert policy.opening_key(c)[-1] == tuple(getattr(c.report, f) for f in DIAGONAL_FACTS)


def _diagonal_problem(n: int, diag: float, seed: int) -> Problem:
    """Random off-diagonal entries, ``diag * n`` on the diagonal, q < 0."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return Problem.create(A - np.diag(np.diag(A)) + diag * n * np.eye(n), -rng.random(n))


def _first_attempt(problem: Problem, max_iter):
    """``auto._first`` as ``auto.run`` calls it (after the q >= 0 test, which runs the
    diagonal test)."""
    c = Classifier(problem)
    c.minima()
    return auto._first(problem, c, max_iter, None, None), c


@pytest.mark.parametrize("max_iter", [None, 7])
@pytest.mark.parametrize("diag", [1.0, 0.0, -1.0])
@pytest.mark.parametrize("n", [1, 3, 12])
def test_first_attempt_hit_equals_fresh(n, diag, max_iter, monkeypatch):
    """auto's first attempt (regime, step, method, options, message head) is stored exactly
    when the diagonal test alone planned it; a second problem with the same facts is then
    served from the memo, and what it is served is what planning afresh (no memo at all)
    gives."""
    first, c = _first_attempt(_diagonal_problem(n, diag, 1), max_iter)
    stored = c.tests_run == {"_diagonal"}
    assert stored == (diag > 0 or (diag == 0 and n == 1))
    assert len(memo.FIRSTS) == memo.FIRSTS.misses == int(stored)
    other = _diagonal_problem(n, diag, 2)  # other data, the same diagonal facts
    hit, _ = _first_attempt(other, max_iter)
    assert memo.FIRSTS.misses == len(memo.FIRSTS) == int(stored)  # stored: served
    _replace_memos(monkeypatch, limit=0)
    fresh, _ = _first_attempt(other, max_iter)
    assert len(memo.FIRSTS) == len(memo.ATTEMPTS) == len(memo.OPENINGS) == 0
    assert hit == fresh and (not stored or first == fresh)
    regime, step, spec, opts, head = fresh
    assert spec.name == step.method and head.endswith(f"solved by {step.method} ({step.reason})")
    r = lcpcli.solve(other, max_iter=max_iter)  # the message a solve shows
    if r.solved and len(r.info["attempts"]) == 1:
        assert r.message == head


def test_the_first_attempt_key_lists_every_fact_the_message_reads():
    """Structural: the class phrase of auto's message (``ClassReport.describe``) read after the
    diagonal test alone changes only with the facts of :func:`auto.first_key` (the opening's
    facts and ``zero_diagonal``), not with the other fields that test sets."""
    words = set(DIAGONAL_WORDS) - {"zero_diagonal"}
    for diag in ([2.0, 1.0, 3.0], [0.0, 1.0, 3.0], [-1.0, 0.0, 3.0]):
        M = np.array([[diag[0], 1.0, 0.0], [1.0, diag[1], 0.5], [0.0, 0.5, diag[2]]])
        c = Classifier(Problem.create(M, -np.ones(3)))
        c.minima()
        phrase = c.report.describe()
        key = auto.first_key(c, None)
        for field in words:
            setattr(c.report, field, "changed" if isinstance(getattr(c.report, field), str)
                    else 12345.0)
        assert c.report.describe() == phrase and auto.first_key(c, None) == key
        c.report.zero_diagonal = 7
        assert auto.first_key(c, None) != key


@pytest.mark.parametrize("diag", [[2.0, 1.0, 3.0], [0.0, 1.0, 3.0], [-1.0, 1.0, 3.0]])
def test_a_classifier_seeded_with_the_minima_equals_one_that_computed_them(diag):
    """``Classifier(problem, minima)`` (auto, which computed the minima first) holds what
    ``Classifier(problem)`` holds after :meth:`Classifier.minima`; for a positive diagonal,
    :func:`positive_diagonal_report` builds that report from the facts alone."""
    from lcpcli.analysis._scaling import dense_minima
    from lcpcli.analysis.classify import (
        POSITIVE_DIAGONAL_FACTS,
        diagonal_facts,
        positive_diagonal_report,
    )

    M = np.array([[diag[0], 1.0, 0.0], [1.0, diag[1], 0.5], [0.0, 0.5, diag[2]]])
    p = Problem.create(M, -np.ones(3))
    plain = Classifier(p)
    minima = plain.minima()
    seeded = Classifier(p, dense_minima(p.M, p.q))
    assert seeded.minima() == minima and seeded.tests_run == plain.tests_run == {"_diagonal"}
    assert seeded.report == plain.report
    if min(diag) > 0:
        assert positive_diagonal_report("lcp", 3, 0, minima[0]) == plain.report
        assert diagonal_facts(plain.report) == POSITIVE_DIAGONAL_FACTS
    else:
        assert diagonal_facts(plain.report) != POSITIVE_DIAGONAL_FACTS


@pytest.mark.parametrize("max_iter", [None, 50])
@pytest.mark.parametrize("n", [1, 3, 12])
def test_the_first_key_from_the_minima_is_first_key_and_is_hit(n, max_iter):
    """``auto.run`` looks a dense problem with a positive diagonal up by
    ``first_key_of(kind, n, POSITIVE_DIAGONAL_FACTS, 0, max_iter)``, without a classifier: that
    is the key the general path stores under, so a second problem with the same facts is
    served from the memo (no miss, no classifier built) and gets what planning afresh gives."""
    from lcpcli.analysis.classify import POSITIVE_DIAGONAL_FACTS

    p = _diagonal_problem(n, 1.0, 1)
    c = Classifier(p)
    c.minima()
    assert auto.first_key_of("lcp", n, POSITIVE_DIAGONAL_FACTS, 0, max_iter) == \
        auto.first_key(c, max_iter)
    first = lcpcli.solve(p, max_iter=max_iter)
    assert len(memo.FIRSTS) == memo.FIRSTS.misses == 1
    built = []
    real = auto.Classifier

    class Counting(real):  # type: ignore[misc, valid-type]
        __slots__ = ()

        def __init__(self, *args, **kwargs):
            built.append(args)
            super().__init__(*args, **kwargs)

    other = _diagonal_problem(n, 1.0, 2)  # other data, the same facts
    try:
        auto.Classifier = Counting
        hit = lcpcli.solve(other, max_iter=max_iter)
    finally:
        auto.Classifier = real
    assert memo.FIRSTS.misses == 1 and built == []  # served from the memo, no classifier
    assert hit.solved and first.solved and hit.message == first.message
    assert hit.info["attempts"][0]["reason"] == first.info["attempts"][0]["reason"]
    c = Classifier(other)
    c.minima()
    assert hit.info["classification"] == c.report


def _kind_problem(kind: str, n: int, seed: int) -> Problem:
    """A dense problem of ``kind`` with a positive diagonal (the memoised first attempt's)."""
    p = _pd(n, seed)
    if kind == "mlcp":
        return Problem.create(p.M, p.q, n_eq=n // 3)
    if kind == "box":
        return Problem.create(p.M, p.q, lower=np.zeros(n), upper=np.full(n, 0.05))
    return p


def _without_times(info: dict) -> dict:
    out = {k: v for k, v in info.items() if k not in ("classify_seconds", "import_seconds")}
    out["attempts"] = [{k: v for k, v in a.items() if k != "seconds"} for a in info["attempts"]]
    return out


@pytest.mark.parametrize("max_iter", [None, 1])
@pytest.mark.parametrize("kind", ["lcp", "mlcp", "box"])
def test_a_first_attempt_served_from_the_memo_solves_or_searches_as_a_fresh_solve(
        kind, max_iter, monkeypatch):
    """On a dense M with a positive diagonal, ``auto.run`` looks its first attempt up from the
    minima alone and runs it (``_first_from_memo``).  Whether that attempt solves or fails (a
    pivot limit of 1: the search then goes on from it), the Result equals a solve with every
    memo off: verdict, z, iterations, message and info (times aside)."""
    stored = kind != "box"  # a box LCP's plan reads symmetry: planned afresh each time
    first = lcpcli.solve(_kind_problem(kind, 12, 1), max_iter=max_iter)
    assert memo.FIRSTS.misses == len(memo.FIRSTS) == int(stored), first.message
    other = _kind_problem(kind, 12, 2)  # other data, the same facts
    runs: list[str] = []
    real = auto.run_method

    def counted(spec, *args):
        runs.append(spec.name)
        return real(spec, *args)

    monkeypatch.setattr(auto, "run_method", counted)
    hit = lcpcli.solve(other, max_iter=max_iter)
    assert memo.FIRSTS.misses == int(stored)  # served from the memo when stored
    hit_runs, runs[:] = runs[:], []
    _replace_memos(monkeypatch, limit=0)
    fresh = lcpcli.solve(other, max_iter=max_iter)
    assert len(memo.FIRSTS) == 0
    assert hit_runs == runs == [a["method"] for a in fresh.info["attempts"]]  # each run once
    assert (hit.status, hit.method, hit.iterations, hit.message) == \
        (fresh.status, fresh.method, fresh.iterations, fresh.message)
    assert np.array_equal(hit.z, fresh.z)
    assert _without_times(hit.info) == _without_times(fresh.info)
    failed_first = hit.info["attempts"][0]["status"] != "solved"
    assert failed_first == (max_iter == 1 and stored), hit.info["attempts"]  # the box LCP:
    # Dantzig's index loop is not capped by one pivot
