"""auto's policy table: derived from the methods' declared data, optimistic, certified.

A fake method registered here (never in the package) must be planned by ``auto`` from its
declared classes alone; docs/methods.md must match the generated tables; no module of the
policy names a method.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import lcpcli
import lcpcli.solvers.registry as registry
from lcpcli.analysis.classify import Classifier
from lcpcli.api import solve
from lcpcli.core.certificate import certify
from lcpcli.core.problem import Problem
from lcpcli.core.result import CONVERGED, NUMERICAL, Outcome, Status
from lcpcli.solvers import memo, policy
from lcpcli.solvers.registry import (
    Cost,
    Guarantee,
    Method,
    Requirement,
    get_method,
    methods,
    when,
)

ROOT = Path(__file__).resolve().parents[2]


def rand_pd(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return A @ A.T / n + 0.5 * np.eye(n), rng.standard_normal(n)


def m_matrix(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    B = rng.random((n, n))
    return 1.2 * np.max(np.abs(np.linalg.eigvals(B))) * np.eye(n) - B, rng.standard_normal(n)


# ---------------------------------------------------------------------------- a fake method
CALLS: list[str] = []


def _fake_run(problem, *, tol, max_iter=None):  # type: ignore[no-untyped-def]
    """Solves by enumerating supports (n <= 10): an independent method for the test."""
    CALLS.append(problem.name)
    M, q, n = problem.dense_M(), problem.q, problem.n
    for mask in range(2 ** n):
        S = [i for i in range(n) if mask >> i & 1]
        z = np.zeros(n)
        if S:
            try:
                z[S] = np.linalg.solve(M[np.ix_(S, S)], -q[S])
            except np.linalg.LinAlgError:
                continue
        if z.min() >= 0 and (M @ z + q).min() >= -1e-12:
            return Outcome(z, mask, CONVERGED, "fake: support found")
    return Outcome(np.zeros(n), 2 ** n, NUMERICAL, "fake: nothing found")


FAKE = Method(
    name="fake-zmatrix",
    run=_fake_run,
    summary="a test method for Z-matrices",
    guarantees=(Guarantee(when("z_matrix", "p_matrix"), "finds the unique solution"),),
    needs=(Requirement(when("positive_diagonal"), "it divides by M_ii"),),
    max_n=10,
    cost=Cost.PIVOTING,
    preference=0,  # before every pivoting method
    options={"max_iter": registry.Option(int, None, "unused")},
)


@pytest.fixture()
def fake_registered(monkeypatch):
    """The registry with FAKE added (restored after the test)."""
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._load()))
    monkeypatch.setattr(registry, "_ALIASES", dict(registry._ALIASES))
    registry.register(FAKE)
    CALLS.clear()
    return FAKE


def test_a_new_method_is_planned_from_its_declared_classes(fake_registered):
    M, q = m_matrix(6, 1)
    p = Problem.create(M, q, name="zp")
    r = solve(p)  # auto
    assert r.solved and r.info["chosen"] == "fake-zmatrix" and CALLS == ["zp"]
    assert "fake-zmatrix" in r.message
    steps = policy.plan(p, Classifier(p))
    assert steps[0].method == "fake-zmatrix" and steps[0].established is True
    rows = {row["method"]: row for row in policy.info_report(p)["methods"]}
    assert rows["fake-zmatrix"]["applies"] == "yes" and rows["fake-zmatrix"]["auto_rank"] == 1
    # not its class (not a Z-matrix): never planned, 'maybe' in info
    M2, q2 = rand_pd(6, 2)
    p2 = Problem.create(M2, q2)
    assert "fake-zmatrix" not in [s.method for s in policy.plan(p2, Classifier(p2))]
    rows = {row["method"]: row for row in policy.info_report(p2)["methods"]}
    assert rows["fake-zmatrix"]["applies"] == "maybe"
    # its own size limit: not planned above max_n, 'no' in info
    M3, q3 = m_matrix(12, 3)
    p3 = Problem.create(M3, q3)
    assert "fake-zmatrix" not in [s.method for s in policy.plan(p3, Classifier(p3))]
    rows = {row["method"]: row for row in policy.info_report(p3)["methods"]}
    assert rows["fake-zmatrix"]["applies"] == "no" and "max_n = 10" in rows["fake-zmatrix"]["why"]
    # and the docs table lists it
    assert "`fake-zmatrix`" in policy.markdown()


def test_policy_modules_name_no_method():
    """auto.py and policy.py decide from declared data only: no other method's name (or
    alias) appears in their code as a string constant (docstrings aside)."""
    names = set()
    for m in methods().values():
        if not m.planner:
            names |= {m.name, *m.aliases}
    for path in ("lcpcli/solvers/methods/auto.py", "lcpcli/solvers/policy.py"):
        tree = ast.parse((ROOT / path).read_text())
        docs = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Expr)}
        consts = {node.value for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and isinstance(node.value, str)
                  and id(node) not in docs}
        words = {w.strip("`'\",.:;()") for c in consts for w in c.split()}
        assert not (names & (consts | words)), (path, names & (consts | words))


def test_docs_method_table_is_generated_from_the_policy():
    text = (ROOT / "docs" / "methods.md").read_text()
    start, stop = text.index(policy.BEGIN), text.index(policy.END) + len(policy.END)
    assert text[start:stop] == policy.markdown(), (
        "docs/methods.md is out of date: run `python -m lcpcli.solvers.policy docs/methods.md`")


def test_enum_size_limit_comes_from_its_record():
    enum = get_method("enum")
    assert enum.max_n == enum.options["max_n"].default == 24
    for n, applies in ((24, "yes"), (25, "no")):
        M, q = rand_pd(n, 4)
        rep = policy.info_report(Problem.create(M, q))
        row = next(r for r in rep["methods"] if r["method"] == "enum")
        assert row["applies"] == applies and row["auto_rank"] is None  # above auto's 12
    assert "n > 24" in policy.markdown() and "auto: n > 12" in policy.markdown()


def test_first_attempt_is_optimistic_and_cheap():
    """A dense PD problem is solved by the first method before any O(n^3) test runs."""
    M, q = rand_pd(60, 5)
    r = solve(Problem.create(M, q))
    assert r.solved and len(r.info["attempts"]) == 1
    c = r.info["classification"]
    assert c.definiteness is None and c.p_matrix is None and c.h_matrix is None
    assert c.positive_diagonal and "not tested before this first attempt" in r.message
    first = policy.info_report(Problem.create(M, q))["auto_first"]
    assert first[0] == r.info["chosen"]


def test_after_a_failed_first_attempt_the_rest_is_planned_on_the_full_report(siconos):
    p = lcpcli.load(siconos / "lcp" / "lcp_CPS_3.dat")
    r = solve(p)
    assert r.solved and len(r.info["attempts"]) >= 2
    first, last = r.info["attempts"][0], r.info["attempts"][-1]
    assert first["status"] == Status.UNSOLVED and last["status"] == Status.SOLVED
    c = r.info["classification"]
    assert c.definiteness is not None and c.symmetric is not None  # the O(n^2+) tests ran
    # every method of the plan after the first attempt comes from the full plan, in order
    full = [s.method for s in policy.plan(p, Classifier(p)) if s.method != first["method"]]
    tried = [a["method"] for a in r.info["attempts"][1:]]
    assert tried == full[:len(tried)]


def test_every_auto_answer_is_certified():
    rng = np.random.default_rng(7)
    for _ in range(5):
        n = 8
        M = rng.standard_normal((n, n))
        q = rng.standard_normal(n)
        r = solve(Problem.create(M, q))
        cert = certify(Problem.create(M, q), r.z, 1e-8)
        assert (r.status == Status.SOLVED) == cert.passed or r.status == Status.NO_SOLUTION
        for a in r.info["attempts"]:
            assert a["status"] in (Status.SOLVED, Status.UNSOLVED, Status.NO_SOLUTION,
                                   Status.ERROR)


def test_methods_that_cannot_start_are_not_planned(monkeypatch):
    # zero diagonal: the sweeping methods need a positive one
    M = np.array([[0.0, 1.0], [1.0, 2.0]])
    p = Problem.create(M, [-1.0, -1.0])
    planned = {s.method for s in policy.plan(p, Classifier(p))}
    needs_diag = {name for name, m in methods().items()
                  if any("positive_diagonal" in r.when.props for r in m.needs)}
    assert needs_diag and not planned & needs_diag
    # a sparse M too large to densify: the dense methods are dropped
    monkeypatch.setattr(registry, "MAX_DENSIFY_ENTRIES", 100)
    S = sp.random(20, 20, density=0.2, random_state=1, format="csr") + 3 * sp.identity(20)
    p = Problem.create(S.tocsr(), -np.ones(20))
    for s in policy.plan(p, Classifier(p)):
        assert methods()[s.method].sparse, s.method


def test_regimes_order_the_cost_classes():
    def first_cost(p):  # type: ignore[no-untyped-def]
        step = policy.plan(p, Classifier(p))[0]
        return methods()[step.method].cost

    M, q = rand_pd(30, 1)
    assert policy.regime_of(Classifier(Problem.create(M, q))).name == "small"
    assert first_cost(Problem.create(M, q)) == Cost.PIVOTING
    # sparse, PSD, little fill: factoring first
    n = 600
    T = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    p = Problem.create(T, -np.ones(n))
    c = Classifier(p)
    assert policy.regime_of(c).name == "sparse, cheap to factor" and c.report.factor_fill < 30
    assert first_cost(p) == Cost.FACTORING
    r = solve(p)
    assert r.solved and methods()[r.info["chosen"]].cost == Cost.FACTORING


def test_guarantee_rows_come_before_fallbacks_and_slow_ones():
    """Tiers in order, except the exhaustive rows (the enumeration), which come last
    whatever their tier, and only in the regime that tries them (small problems)."""
    for regime in policy.REGIMES:
        table = policy.ordered(policy.rows("lcp", methods()), regime)
        polynomial = [row for row in table if row.cost is not Cost.EXHAUSTIVE]
        tiers = [row.tier for row in polynomial]
        assert tiers == sorted(tiers)
        assert table[:len(polynomial)] == polynomial
        assert all(row.cost in regime.order for row in table)
        assert (len(polynomial) < len(table)) == (regime.name == "small")


def test_info_json_has_first_attempt_and_plan(cli, samples):
    r = cli("info", str(samples / "seed004.json"), "--json")
    rep = json.loads(r.stdout)
    assert r.returncode == 0 and rep["regime"] == "small"
    assert rep["auto_first"][0] == rep["auto_plan"][0][0]
    assert rep["classification"]["definiteness"] == "pd"
    assert "min_eig_sym" not in rep["classification"]


def test_condition_names_are_checked():
    with pytest.raises(ValueError, match="unknown matrix properties"):
        when("positive_definite")


def test_large_problems_are_tested_before_the_first_attempt_but_only_as_needed():
    """Outside the optimistic regimes a wrong first attempt could cost 1000 sweeps: the first
    row is chosen on established classes, and only the tests its rows needed have run."""
    rng = np.random.default_rng(3)
    n = 400
    A = sp.random(n, n, density=0.02, random_state=3, format="csr")
    # diagonal plus a strictly upper triangle: an H-matrix (its comparison matrix is
    # triangular) whose symmetric part is indefinite (large off-diagonal entries)
    M = (sp.diags(1.0 + rng.random(n)) + 20 * sp.triu(A, 1)).tocsr()
    p = Problem.create(M, rng.standard_normal(n))
    c = Classifier(p)
    regime = policy.regime_of(c)
    assert not regime.optimistic and regime.name == "large"
    r = solve(p)
    assert r.solved and "not tested" not in r.message
    first = r.info["attempts"][0]
    assert methods()[first["method"]].cost == Cost.SWEEPING
    report = r.info["classification"]
    assert report.symmetric is False and report.h_matrix is True
    assert report.definiteness == "indefinite" and report.p_matrix is None  # P not needed
    # a dense symmetric PD problem of the large regime: PD established, P never tested
    Md, qd = rand_pd(1600, 9)
    r = solve(Problem.create(Md, qd))
    assert r.solved and r.info["regime"] == "large" and len(r.info["attempts"]) == 1
    assert r.info["classification"].pd is True and r.info["classification"].h_matrix is None


def _fresh_opening(problem: Problem) -> tuple:
    """What policy.opening plans without its memo."""
    c = Classifier(problem)
    regime = policy.regime_of(c)
    if not regime.optimistic:
        return regime, None
    steps = policy.plan(problem, c, optimistic=True, first=True, regime=regime)
    return regime, steps[0] if steps else None


@pytest.mark.parametrize("diag", [1.0, 0.0, -1.0])
@pytest.mark.parametrize("n", [1, 3, 12, 30])
def test_opening_memo_gives_what_planning_afresh_gives(n, diag, monkeypatch):
    """The opening (auto's regime and first step) equals a fresh plan, for positive, zero and
    negative diagonals and for sizes below and above enum's limit, hit or miss: it is stored
    exactly when the O(n) diagonal test alone decided it (a positive diagonal, or n = 1), and
    then the second call is a hit; otherwise (the symmetry test ran too) nothing is stored."""
    rng = np.random.default_rng(n)
    A = rng.standard_normal((n, n))
    M = A - np.diag(np.diag(A)) + diag * np.eye(n) * n
    q = -rng.random(n)
    monkeypatch.setattr(memo, "OPENINGS", memo.Memo("openings (test)", 16))
    monkeypatch.setattr(policy, "OPENINGS", memo.OPENINGS)
    p = Problem.create(M, q)
    c = Classifier(p)
    first = policy.opening(p, c)
    stored = c.tests_run == {"_diagonal"}
    assert stored == (diag > 0 or (diag == 0 and n == 1))  # 1 x 1: m_11 = 0 decides all
    assert len(memo.OPENINGS) == int(stored)
    p = Problem.create(M, q)
    second = policy.opening(p, Classifier(p))
    assert memo.OPENINGS.misses == int(stored)  # stored: the second call was served
    assert first == second == _fresh_opening(Problem.create(M, q))


def test_opening_memo_follows_the_registry(monkeypatch):
    """A method registered after a problem was planned is planned from then on (the registry
    version is part of the memo key)."""
    M, q = rand_pd(6, 3)
    p = Problem.create(M, q)
    before = policy.opening(p, Classifier(p))
    assert policy.opening(p, Classifier(p)) == before  # from the memo
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._load()))
    monkeypatch.setattr(registry, "_ALIASES", dict(registry._ALIASES))
    registry.register(Method(name="first-fake", run=_fake_run, summary="tried first",
                             guarantees=(Guarantee(when(), "always tried first"),),
                             cost=Cost.PIVOTING, preference=-1))
    regime, step = policy.opening(p, Classifier(p))
    assert step.method == "first-fake" and before[1].method != "first-fake"
    assert (regime, step) == _fresh_opening(p)
