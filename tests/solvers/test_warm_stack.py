"""Warm-started stacks in the batched Lemke kernel (lcpcli.solvers.warm_stack)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.core.certificate import BETWEEN
from lcpcli.core.errors import OptionError
from lcpcli.solvers.warm_stack import stack_bases


def _stack(K: int, n: int, seed: int, kind: str = "pd") -> tuple[np.ndarray, np.ndarray]:
    """K positive definite M's (A A^T / n + I; ``kind="p"``: column-scaled with a skew part,
    a P-matrix that is not positive definite) and standard normal q's."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    M = np.einsum("kij,klj->kil", A, A) / n + np.eye(n)
    if kind == "p":
        S = rng.standard_normal((K, n, n))
        M = (M + (S - S.transpose(0, 2, 1))) * rng.uniform(0.01, 100.0, (K, 1, n))
    return np.ascontiguousarray(M), rng.standard_normal((K, n))


def _perturbed(q: np.ndarray, seed: int, noise: float = 0.01) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return q + noise * np.abs(q) * rng.standard_normal(q.shape)


@settings(max_examples=20, deadline=None)
@given(K=st.integers(1, 40), n=st.integers(1, 16), seed=st.integers(0, 2**32 - 1),
       steps=st.integers(1, 4), kind=st.sampled_from(["pd", "p"]),
       noise=st.sampled_from([0.01, 0.3]))
def test_perturbed_sequence_warm_stack_equals_cold(K: int, n: int, seed: int, steps: int,
                                                   kind: str, noise: float) -> None:
    """Each step warm-started from the previous step's stack result: the same verdicts and
    (P-matrices: unique solutions) the same z as a cold stack, and every solved problem's
    basis recorded (the state codes of its certificate)."""
    M, q = _stack(K, n, seed, kind)
    prev = lcpcli.solve_many(M, q, "lemke")
    for step in range(steps):
        q = _perturbed(q, seed + step, noise)
        warm, cold = lcpcli.solve_many(M, q, "lemke", warm=prev), lcpcli.solve_many(M, q, "lemke")
        assert np.array_equal(warm.status, cold.status) and warm.counts() == {"solved": K}
        scale = 1.0 + np.max(np.abs(cold.z), axis=1, initial=0.0)
        assert np.all(np.max(np.abs(warm.z - cold.z), axis=1, initial=0.0) <= 1e-7 * scale)
        assert warm.basis is not None and warm.basis.shape == (K, n)
        for k in range(K):  # the basis is the certificate's reading of the answer
            r = lcpcli.solve(M[k], q[k], warm=warm.z[k])
            assert np.array_equal(warm.basis[k] == BETWEEN, r.basis == BETWEEN) or \
                np.any((warm.z[k] == 0) & (np.abs(warm.w[k]) < 1e-12))  # degenerate pairs
        prev = warm


def test_the_unchanged_problem_takes_one_factorisation() -> None:
    """The same q again: every basis is still right, so each problem ends after one
    iteration (its basic solution certified), with the cold z."""
    M, q = _stack(50, 12, 1)
    prev = lcpcli.solve_many(M, q, "lemke")
    again = lcpcli.solve_many(M, q, "lemke", warm=prev)
    assert again.counts() == {"solved": 50} and np.all(again.iterations == 1)
    assert np.allclose(again.z, prev.z, atol=1e-12)


@pytest.mark.parametrize("start", ["random", "all_z", "all_w", "points"])
def test_wrong_bases_still_end_correctly(start: str) -> None:
    """Bases unrelated to the answer (and z0 points) on P-matrices: the kernel's BPP or its
    cold Lemke fallback ends every problem at the cold answer."""
    K, n = 60, 10
    M, q = _stack(K, n, 2, "p")
    rng = np.random.default_rng(3)
    warm = {"random": rng.random((K, n)) < 0.5, "all_z": np.ones((K, n), bool),
            "all_w": np.zeros((K, n), bool), "points": rng.standard_normal((K, n))}[start]
    cold = lcpcli.solve_many(M, q, "lemke")
    r = lcpcli.solve_many(M, q, "lemke", warm=warm)
    assert np.array_equal(r.status, cold.status)
    assert np.allclose(r.z, cold.z, atol=1e-7 * (1 + np.abs(cold.z).max()))


def test_infeasible_and_nan_rows_keep_the_cold_verdicts() -> None:
    """An infeasible problem (M = -I, q = -1: no_solution, proven by the pipeline), a NaN row
    of the warm start and a problem with NaN data (on_error='mark'): the verdicts of a cold
    stack; the warm start never claims no_solution itself."""
    K, n = 6, 5
    M, q = _stack(K, n, 4)
    M[2], q[2] = -np.eye(n), -np.ones(n)
    q[4, 0] = np.nan
    prev = lcpcli.solve_many(M, q, "lemke", on_error="mark")
    rows = prev.z.copy()
    rows[1] = np.nan
    cold = lcpcli.solve_many(M, q, "lemke", on_error="mark")
    for warm in (prev, rows, np.ones((K, n), bool)):
        r = lcpcli.solve_many(M, q, "lemke", warm=warm, on_error="mark")
        assert np.array_equal(r.status, cold.status)
        assert r.counts() == {"solved": 4, "no_solution": 1, "error": 1}


def test_stack_bases_forms_and_errors() -> None:
    M, q = _stack(3, 4, 5)
    cold = lcpcli.solve_many(M, q, "lemke")  # a cold stack records no basis: z > 0 is used
    assert cold.basis is None and np.array_equal(stack_bases(cold, 3, 4) == 1, cold.z > 0)
    prev = lcpcli.solve_many(M, q, "lemke", warm=cold)
    b = stack_bases(prev, 3, 4)
    assert b.dtype == np.int8 and np.array_equal(b == 1, prev.basis == BETWEEN)
    pts = prev.z.copy()
    pts[0, 0] = np.nan
    assert np.all(stack_bases(pts, 3, 4)[0] == -1)
    with pytest.raises(OptionError):
        lcpcli.solve_many(M, q, "lemke", warm=prev.z[:2])


@settings(max_examples=15, deadline=None)
@given(K=st.integers(1, 30), n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1),
       method=st.sampled_from(["lemke", "pgs", "auto"]), box=st.booleans())
def test_record_basis_changes_no_answer_and_gives_each_results_basis(
        K: int, n: int, seed: int, method: str, box: bool) -> None:
    """``record_basis=True`` (stacked result files): every array equals a plain solve_many's,
    and ``basis`` is each problem's Result.basis (the certificate's pair states of its z),
    whether the Lemke kernel filled it or a certificate pass afterwards."""
    from lcpcli.core.certificate import check
    from lcpcli.core.problem import Problem

    M, q = _stack(K, n, seed)
    q[0] = -1.0
    M[0] = 0.0  # no solution (Farkas): a basis of its z all the same
    box = box and method != "lemke"  # Lemke takes LCPs only
    bounds = {"lower": -np.ones(n), "upper": np.ones(n)} if box else {}
    plain = lcpcli.solve_many(M, q, method, **bounds)
    got = lcpcli.solve_many(M, q, method, record_basis=True, **bounds)
    for key in ("z", "w", "status", "iterations", "error", "residual"):
        np.testing.assert_array_equal(getattr(got, key), getattr(plain, key))
    assert got.basis.shape == (K, n) and got.basis.dtype == np.int8 and got.warmed is None
    for k in range(K):
        want = np.empty(n, np.int8)
        check(Problem.create(M[k], q[k], **bounds), got.z[k], got.tol, state=want)
        np.testing.assert_array_equal(got.basis[k], want)


@settings(max_examples=25, deadline=None)
@given(K=st.integers(2, 11), n=st.integers(1, 20), seed=st.integers(0, 2**32 - 1),
       kind=st.sampled_from(["pd", "p"]))
def test_problems_started_in_pairs_get_the_numbers_each_gets_alone(K: int, n: int, seed: int,
                                                                   kind: str) -> None:
    """The warm kernel starts small problems (n <= 16) two at a time, the eliminations and
    solves of the two interleaved; every number of every problem equals that of the same
    problem warm-started alone (a stack of one), bit for bit, with rows without a basis (cold)
    and wrong bases mixed in, and at sizes above the paired range."""
    M, q = _stack(K, n, seed, kind)
    prev = lcpcli.solve_many(M, q, "lemke")
    q = _perturbed(q, seed)
    rng = np.random.default_rng(seed)
    z0 = (stack_bases(prev, K, n) == 1).astype(np.float64)  # points whose bases are prev's
    wrong = rng.random(K) < 0.25
    z0[wrong] = rng.random((int(wrong.sum()), n)) < 0.5
    z0[rng.random(K) < 0.25] = np.nan  # no basis: cold
    got = lcpcli.solve_many(M, q, "lemke", warm=z0)
    for k in range(K):
        alone = lcpcli.solve_many(M[k:k + 1], q[k:k + 1], "lemke", warm=z0[k:k + 1])
        for key in ("z", "w", "status", "iterations", "error", "residual", "basis", "warmed"):
            np.testing.assert_array_equal(getattr(got, key)[k], getattr(alone, key)[0],
                                          err_msg=f"{key} of problem {k}")
