"""The certificate: one definition of residual and scaled error for every problem form."""

from __future__ import annotations

import numpy as np
import pytest

from lcpcli.core.certificate import certify
from lcpcli.core.problem import Problem


def test_exact_solution_scores_zero():
    p = Problem.create([[2, 1], [1, 2]], [-5, -6])
    c = certify(p, np.array([4 / 3, 7 / 3]))
    assert c.passed and c.residual < 1e-15 and c.error < 1e-15


def test_residual_is_inf_norm_of_min_z_w():
    p = Problem.create(np.eye(3), [1.0, -2.0, 0.5])
    z = np.array([0.5, 1.0, -0.25])
    w = z + p.q
    c = certify(p, z)
    assert c.residual == pytest.approx(np.abs(np.minimum(z, w)).max())
    assert not c.passed


def test_error_is_scale_invariant():
    rng = np.random.default_rng(0)
    M = rng.standard_normal((5, 5))
    q = rng.standard_normal(5)
    z = np.abs(rng.standard_normal(5))
    base = certify(Problem.create(M, q), z).error
    assert certify(Problem.create(1e8 * M, 1e8 * q), z).error == pytest.approx(base)
    assert certify(Problem.create(M, 1e-12 * q), 1e-12 * z).error == pytest.approx(base)


def test_error_stays_meaningful_when_q_is_near_zero():
    # the q-relative measure ||min(z, w)|| / ||q|| explodes as q -> 0; ours does not
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    q = np.array([-5.0, -6.0]) * 1e-15
    z = np.array([4 / 3, 7 / 3]) * 1e-15
    c = certify(Problem.create(M, q), z)
    assert c.passed and c.error < 1e-14
    # ... and a wrong answer is still wrong at that scale
    assert not certify(Problem.create(M, q), np.zeros(2)).passed
    # q = 0 exactly: z = 0 is exact
    assert certify(Problem.create(M, [0.0, 0.0]), np.zeros(2)).error == 0.0


def test_non_finite_answers_fail():
    p = Problem.create(np.eye(2), [-1.0, -1.0])
    assert not certify(p, np.array([np.nan, 1.0])).passed
    assert not certify(p, np.array([np.inf, 1.0])).passed


def test_mlcp_equality_rows_and_box_bounds():
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    mlcp = Problem.create(M, [-1.0, 1.0], n_eq=1)
    c = certify(mlcp, np.array([0.5, 0.0]))  # free row: 2*0.5 - 1 = 0; w2 = 1.5 >= 0, z2 = 0
    assert c.passed and c.equality_residual == 0.0
    c = certify(mlcp, np.array([0.0, 0.0]))
    assert not c.passed and c.equality_residual == pytest.approx(1.0)

    box = Problem.create(np.eye(2), [-3.0, 2.0], lower=[-1, -1], upper=[1, 1])
    # z1 at upper bound with w1 = 1 - 3 = -2 <= 0; z2 at lower bound with w2 = -1 + 2 = 1 >= 0
    assert certify(box, np.array([1.0, -1.0])).passed
    c = certify(box, np.array([1.5, -1.0]))
    assert not c.passed and c.bound_violation == pytest.approx(0.5)


def test_huge_solution_gets_a_warning():
    # a z of 1e14 passes the backward-error test on a nearly infeasible PSD problem, but the
    # verdict says how large it is compared with the data
    from lcpcli.api import certify_outcome
    from lcpcli.core.result import Outcome

    p = Problem.create([[1, -1], [-1, 1]], [-1, -1])
    r = certify_outcome(p, Outcome(np.array([1.5e14, 1.5e14 + 0.5]), 1, "converged", "x"),
                        "m", 0.0, 1e-8)
    assert "huge compared with the data" in r.message
    ok = certify_outcome(Problem.create([[2, 1], [1, 2]], [-5, -6]),
                         Outcome(np.array([4 / 3, 7 / 3]), 3, "converged", "x"), "m", 0.0, 1e-8)
    assert ok.solved and "warning" not in ok.message
