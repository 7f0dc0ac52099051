"""Lemke with the covering ray started from a given basis (lcpcli.solvers.methods.lemke_warm)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.solvers.methods import lemke_warm
from lcpcli.solvers.methods.bpp import Blocks
from tests.solvers.test_warm import CYCLING_BASIS, CYCLING_M, CYCLING_Q, _p_matrix, _pd


def _matrix(kind: str, n: int, seed: int) -> np.ndarray:
    M = _pd(n, seed) if kind == "pd" else _pd(n, seed, skew=0.5) if kind == "skew" \
        else _p_matrix(n, seed)
    return np.ascontiguousarray(M)


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.max(np.abs(a - b), initial=0.0) <= 1e-7 * (1.0 + np.max(np.abs(b),
                                                                              initial=0.0)))


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 30), seed=st.integers(0, 2**32 - 1),
       kind=st.sampled_from(["pd", "skew", "p"]),
       start=st.sampled_from(["random", "all_z", "all_w", "solution"]))
def test_from_any_basis_on_p_matrices_the_unique_solution(n: int, seed: int, kind: str,
                                                          start: str) -> None:
    """On a P-matrix, Lemke from any complementary basis (covering vector B e) ends at the
    unique solution, the cold Lemke's, which the certificate passes."""
    M = _matrix(kind, n, seed)
    rng = np.random.default_rng(seed + 1)
    q = rng.standard_normal(n)
    cold = lcpcli.solve(M, q, "lemke")
    F = {"random": rng.random(n) < 0.5, "all_z": np.ones(n, bool), "all_w": np.zeros(n, bool),
         "solution": cold.z_basic}[start]
    out = lemke_warm.run(M, q, F)
    assert out.termination == "converged", out.message
    assert _close(out.z, cold.z)
    assert lcpcli.core.certificate.certify(lcpcli.Problem.create(M, q), out.z).passed
    if start == "solution":  # the given basis is feasible: no pivot, one factorisation
        assert "the given basis is feasible" in out.message and out.info["factorisations"] == 1


def test_from_the_all_w_basis_it_is_cold_lemke() -> None:
    """F = {}: B = I, the covering vector B e = e, so the pivots are cold Lemke's (d = e)."""
    M, q = _matrix("pd", 40, 4), np.random.default_rng(4).standard_normal(40)
    out = lemke_warm.run(M, q, np.zeros(40, bool), max_pivots=10**4)
    cold = lcpcli.solve(M, q, "lemke-tableau")
    assert out.termination == "converged" and out.iterations == cold.iterations
    assert sorted(out.info["basis"]) == sorted(np.flatnonzero(cold.z_basic).tolist())


def test_the_bpp_cycling_basis_ends() -> None:
    """The 4 x 4 P-matrix and basis on which pure block pivoting cycles: Lemke from that basis
    ends at the solution."""
    out = lemke_warm.run(np.ascontiguousarray(CYCLING_M), CYCLING_Q, np.array(CYCLING_BASIS))
    lem = lcpcli.solve(CYCLING_M, CYCLING_Q, "lemke")
    assert out.termination == "converged" and np.allclose(out.z, lem.z, atol=1e-12)


def test_singular_start_is_repaired_and_failures_prove_nothing() -> None:
    """A singular block (skew blocks [[0, 1], [-1, 0]], F = {z1, z3, ...}: zero diagonal, so
    the repair drops every pair) and an infeasible problem: warm Lemke never claims
    infeasibility; through lcpcli.solve the cold verdict comes back."""
    n = 200
    M = np.kron(np.eye(n // 2), np.array([[0.0, 1.0], [-1.0, 0.0]]))
    q = np.tile([-1.0, 1.0], n // 2)
    F = np.tile([True, False], n // 2)
    assert not lemke_warm.repair(M, F).any()
    out = lemke_warm.run(M, q, F)
    assert not out.proven_infeasible
    cold = lcpcli.solve(M, q, "lemke")
    r = lcpcli.solve(M, q, "lemke", warm=F)
    assert r.status == cold.status == "solved" and "warm start" in r.message
    Mi, qi = -np.eye(n), -np.ones(n)
    out = lemke_warm.run(Mi, qi, np.zeros(n, bool))
    assert out.termination != "converged" and not out.proven_infeasible
    cold = lcpcli.solve(Mi, qi, "lemke")
    r = lcpcli.solve(Mi, qi, "lemke", warm=np.zeros(n, bool))
    assert cold.status == r.status == "no_solution" and "solved cold" in r.message


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 30), rank=st.integers(1, 30), seed=st.integers(0, 2**32 - 1),
       skew=st.booleans())
def test_repair_leaves_a_nonsingular_block_of_full_rank(n: int, rank: int, seed: int,
                                                        skew: bool) -> None:
    """M = J J^T (+ a skew part) of rank r < n, as redundant contacts make it: the repaired
    basis's block is nonsingular and, from F = all, as large as M's rank allows; a
    nonsingular block is kept whole."""
    rng = np.random.default_rng(seed)
    r = min(rank, n - 1)
    J = rng.standard_normal((n, r))
    M = J @ J.T
    if skew:
        S = J @ rng.standard_normal((r, r)) @ J.T
        M = M + (S - S.T)
    F = lemke_warm.repair(M, np.ones(n, bool))
    block = M[np.ix_(F, F)]
    assert F.sum() == np.linalg.matrix_rank(M) == r
    assert np.linalg.cond(block) < 1e12
    P = _pd(n, seed)
    sub = rng.random(n) < 0.5
    assert np.array_equal(lemke_warm.repair(P, sub), sub)


def test_contact_islands_warm_lemke_from_the_previous_basis() -> None:
    """Box stacks (friction pyramid, redundant contacts), every velocity changed by 1 %: Lemke
    from each island's previous basis {z0 > 0} (singular blocks repaired) certifies every
    island, in fewer pivots than cold Lemke."""
    import dataclasses

    from lcpcli.contact import build, solve
    from lcpcli.contact.examples import box_stacks
    from lcpcli.contact.islands import island_problems

    scene = box_stacks(6, 3, seed=1)
    first = solve(build(scene, friction=4))
    rng = np.random.default_rng(0)
    nxt = build(dataclasses.replace(
        scene, velocity=scene.velocity * (1 + 0.01 * rng.normal(size=scene.velocity.shape)),
        omega=scene.omega * (1 + 0.01 * rng.normal(size=scene.omega.shape))), friction=4)
    lay = nxt.layout
    for k, p in enumerate(island_problems(nxt.problem, lay, nxt.storage, "x")):
        z0 = first.result.z[lay.unknowns(k)]
        M = np.ascontiguousarray(p.dense_M())
        out = lemke_warm.run(M, p.q, z0 > 0, problem=p)
        assert out.termination == "converged"
        assert lcpcli.core.certificate.certify(p, out.z).passed
        assert out.iterations < lcpcli.solve(p, "lemke").iterations


@pytest.mark.parametrize("seed", range(3))
def test_psd_problems_keep_the_cold_verdict(seed: int) -> None:
    """Positive semidefinite, singular M (outside the P class, where a covering vector that is
    not positive carries no guarantee), n = 200 so that Lemke pivots from the warm basis:
    the verdict is the cold one from every start."""
    n, rng = 200, np.random.default_rng(seed)
    A = rng.standard_normal((n, n // 3))
    M = A @ A.T
    q = rng.standard_normal(n)
    cold = lcpcli.solve(M, q, "lemke")
    for F in (rng.random(n) < 0.5, np.ones(n, bool), np.zeros(n, bool)):
        assert lcpcli.solve(M, q, "lemke", warm=F).status == cold.status


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), steps=st.integers(2, 5),
       kind=st.sampled_from(["pd", "skew", "p"]), noise=st.sampled_from([0.01, 0.1, 1.0]))
def test_perturbed_sequence_warm_lemke_equals_cold(seed: int, steps: int, kind: str,
                                                   noise: float) -> None:
    """q_{k+1} = q_k + noise |q_k| N(0, 1), n = 200 (Lemke pivots from the basis), each step
    warm-started from the previous warm result (which keeps its block's factors): the same
    verdict and z as a cold Lemke solve; a nearby q (1 %) is solved by the warm Lemke itself
    (a q changed by 100 % may need more than its pivot budget: then it is solved cold)."""
    n = 200
    M = _matrix(kind, n, seed)
    rng = np.random.default_rng(seed + 9)
    q = rng.standard_normal(n)
    prev = lcpcli.solve(M, q, "lemke")
    for _ in range(steps):
        q = q + noise * np.abs(q) * rng.standard_normal(n)
        warm, cold = lcpcli.solve(M, q, "lemke", warm=prev), lcpcli.solve(M, q, "lemke")
        assert warm.status == cold.status == "solved"
        assert _close(warm.z, cold.z)
        if noise <= 0.01:
            assert "warm Lemke" in warm.message and isinstance(warm.factors, Blocks)
        prev = warm
