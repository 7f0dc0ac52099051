"""Iterative methods stop when they stagnate (issue 22): termination ``stalled``."""

from __future__ import annotations

import numpy as np
import pytest

import lcpcli
from lcpcli.core.result import Termination
from lcpcli.solvers.methods.newton import STALL_WINDOW


@pytest.mark.parametrize("method", ["newton", "newton-min"])
def test_newton_stops_when_stuck_on_an_infeasible_problem(siconos, method: str) -> None:
    # row 2 of M is (-1, 0, 0) with q_2 = -1: no z >= 0 has w_2 >= 0, the merit cannot reach 0
    p = lcpcli.load(siconos / "lcp" / "lcp_Pang_isolated_sol_perturbed.dat")
    r = lcpcli.solve(p, method, max_iter=20000)
    assert r.status != "solved"
    assert r.iterations < 20000
    assert r.termination in (Termination.STALLED, Termination.NUMERICAL)
    if r.termination == Termination.STALLED:
        assert r.iterations >= STALL_WINDOW and "no progress" in r.message


def test_stalled_is_one_term() -> None:
    assert Termination("stalled") is Termination.STALLED


@pytest.mark.parametrize("seed", range(10))
def test_stagnation_never_stops_a_converging_run(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 30
    A = rng.standard_normal((n, n))
    M = A @ A.T / n + 1e-3 * np.eye(n) + (A - A.T) / n  # P (PD symmetric part), ill conditioned
    r = lcpcli.solve(M, rng.standard_normal(n), "newton", max_iter=500)
    assert r.solved, r.message
