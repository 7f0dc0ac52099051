"""No false verdicts: every method, every bench family, every Siconos file.

A ``solved`` answer must pass an independent componentwise check
(``tests/references.py: componentwise_error``, written apart from the compiled certificate) and,
where the solution is known and unique, be close to it; a ``no_solution`` must be a problem that
truly has none (a suite case known infeasible, checked independently by its Farkas vector).
``unsolved`` is always allowed: a method may give up, it may not lie.
"""

from __future__ import annotations

import numpy as np
import pytest
from references import componentwise_error

import lcpcli
from lcpcli.bench import suites
from lcpcli.core.errors import OptionError

#: Sizes that keep the whole table (every method x every case) to a few seconds per method.
HARD_N, RANDOM_N = 5, 16
#: Iteration caps for the iterative methods (they may give up; they may not lie).
CAPS = {"pgs": 3000, "psor": 3000, "newton": 100, "newton-min": 100, "ip": 100}


def _cases(siconos: bool) -> list[suites.Case]:
    cases = suites.suite("hard", n=HARD_N) + suites.suite("random", n=RANDOM_N)
    if siconos:
        cases += suites.suite("siconos")
    return cases


def _independently_infeasible(case: suites.Case) -> bool:
    """The case is known infeasible and its Farkas vector proves it (checked here)."""
    if case.expected != suites.INFEASIBLE:
        return False
    y = case.farkas
    if y is None:  # Siconos' Pang_perturbed: row 1 of M <= 0 with q_1 < 0
        M, q = case.problem.dense_M(), case.problem.q
        rows = np.flatnonzero((q < 0) & np.all(M <= 0, axis=1))
        return rows.size > 0
    M, q = case.problem.dense_M(), case.problem.q
    return bool(np.all(y >= 0) and np.all(M.T @ y <= 1e-9 * np.abs(M).max() * y.sum())
                and q @ y < 0)


def _check(method: str, case: suites.Case) -> None:
    p = case.problem
    opts = {"max_iter": CAPS[method]} if method in CAPS else {}
    try:
        r = lcpcli.solve(p, method, **opts)
    except OptionError:
        return  # a clean refusal (wrong problem kind, too large for enumeration, ...)
    if r.status == "solved":
        lo, up = (p.lower, p.upper) if p.lower is not None else (None, None)
        err = componentwise_error(p.M, p.q, r.z, lo, up, p.n_eq)
        assert err <= r.certificate.tol * (1 + 1e-6), (method, case.name, err)
        if case.solution is not None and case.unique:
            scale = max(1.0, float(np.max(np.abs(case.solution))))
            assert np.max(np.abs(r.z - case.solution)) <= 1e-4 * scale, (method, case.name)
    elif r.status == "no_solution":
        assert _independently_infeasible(case), (method, case.name, r.message)


LCP_METHODS = ["auto", "lemke-revised", "lemke-tableau", "murty", "dantzig", "newton",
               "newton-min", "ip", "pgs", "psor", "enum"]


@pytest.mark.parametrize("method", LCP_METHODS)
def test_no_false_verdicts_on_the_bench_families(method):
    for case in _cases(siconos=False):
        _check(method, case)


@pytest.mark.parametrize("method", LCP_METHODS + ["mlcp-schur", "mlcp-lemke"])
def test_no_false_verdicts_on_the_siconos_files(method, siconos):
    for case in suites.suite("siconos"):
        _check(method, case)


@pytest.mark.parametrize("method", ["bpp", "newton", "newton-min", "ip", "pgs", "auto"])
def test_every_answer_lies_inside_its_bounds(method: str) -> None:
    """A method's rounding (z_i = -1e-15 from a factorisation, -6.8e-9 from Newton-min on a
    degenerate problem) never reaches the user: the dispatcher moves z onto its bounds before
    certifying it (the certificate judges that move anyway)."""
    M = np.array([[-1, -1, 0, 0, 1, 1], [-1, 1, 1, 1, 1, -1], [1, 0, 0, -1, 0, -1],
                  [0, -1, 1, 0, -1, 1], [1, 0, -1, 0, 0, 0], [0, 1, 0, 1, -1, 0]], float)
    cases = [(M, np.array([-1, 0, 0, 0, 0, 1.0]), {})]
    rng = np.random.default_rng(0)
    for n in (50, 200):
        A = rng.standard_normal((n, n))
        cases.append((A @ A.T + np.eye(n), rng.standard_normal(n), {}))
    cases.append((np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, 6.0]),
                  {"lower": np.array([-1.0, -1.0]), "upper": np.array([1.0, 1.0])}))
    for M_, q_, box in cases:
        if box and method in ("ip", "bpp"):  # LCP and MLCP methods
            continue
        r = lcpcli.solve(M_, q_, method=method, **box)
        lo = box.get("lower", np.zeros(len(q_)))
        up = box.get("upper", np.full(len(q_), np.inf))
        assert np.all(r.z >= lo) and np.all(r.z <= up), (method, r.z.min())
