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


#: The 3 x 3 P-matrix of issue 22 problem 5: PGS and PSOR cycle on it (its solution exists).
CYCLIC = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 2.0], [2.0, 0.0, 1.0]])


@pytest.mark.parametrize("method", ["pgs", "psor"])
@pytest.mark.parametrize("sparse", [False, True])
def test_sor_stops_when_it_cycles(method: str, sparse: bool) -> None:
    """PGS/PSOR on a non-symmetric P-matrix: the sweeps cycle; with --max-iter 100000 they end
    'stalled' after a window of sweeps without progress, not at the limit."""
    import scipy.sparse as sp

    from lcpcli.solvers.methods.pgs import STALL_BLOCK, STALL_WINDOW

    M = sp.csr_matrix(CYCLIC) if sparse else CYCLIC
    r = lcpcli.solve(M, -np.ones(3), method, max_iter=100_000)
    assert r.status == "unsolved"
    assert r.termination == Termination.STALLED, r.message
    assert STALL_WINDOW * STALL_BLOCK <= r.iterations <= (STALL_WINDOW + 3) * STALL_BLOCK
    assert "no progress" in r.message


def test_interior_point_stops_when_stuck() -> None:
    """A non-monotone 3 x 3 where the interior point makes no progress: 'stalled' after its
    window, not 100,000 iterations."""
    from lcpcli.solvers.methods.ip import STALL_WINDOW

    M = np.array([[0.0, 2.0, 3.0], [-3.0, -2.0, 2.0], [3.0, -2.0, -1.0]])
    r = lcpcli.solve(M, np.array([3.0, -1.0, -2.0]), "ip", max_iter=100_000)
    assert r.status != "solved"
    assert r.termination == Termination.STALLED, r.message
    assert STALL_WINDOW <= r.iterations <= 10 * STALL_WINDOW


@pytest.mark.parametrize("method", ["pgs", "psor", "ip"])
def test_stagnation_never_stops_a_slow_converging_run(method: str) -> None:
    """The 1-D Laplacian (symmetric positive definite, n = 100): PGS needs about 17,600 sweeps
    and PSOR about 9,800 (linear rate 1 - O(1/n^2)), many stagnation windows: solved, never
    'stalled'."""
    from lcpcli.solvers.methods.pgs import STALL_BLOCK, STALL_WINDOW

    n = 100
    M = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    r = lcpcli.solve(M, -np.ones(n) / n**2, method, max_iter=200_000)
    assert r.solved, r.message
    if method != "ip":
        assert r.iterations > 5 * STALL_WINDOW * STALL_BLOCK
