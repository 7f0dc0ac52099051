"""Scaled copies get the same verdict: power-of-two row and column scalings (issue 22).

``M = diag(2^a) K diag(2^b)``, ``q = -2^a`` with the P-matrix ``K = [[1,2,0],[0,1,2],[2,0,1]]``
has the unique solution ``z* = 2^-b / 3`` for every ``a``, ``b`` (``K (1,1,1)/3 = (1,1,1)``).
Ruiz's equilibration balances only the row and column maxima of such an ``M`` and may leave
the diagonal at ``2^-72``; the methods then rerun on Curtis and Reid's geometric scaling
(:func:`lcpcli.analysis.scaling.geometric`), which undoes the scaling exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

import lcpcli
from lcpcli.analysis.enumeration import enumerate_cones
from lcpcli.analysis.scaling import Scaling, geometric
from lcpcli.core.problem import Problem

K = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 2.0], [2.0, 0.0, 1.0]])
#: Exponents drawn once, uniformly in [-150, 150] per row and per column.
DRAWS = np.random.default_rng(22).integers(-150, 151, size=(300, 2, 3))


def scaled(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M, q, z*)`` of the scaled copy (every entry exact: powers of two times 1 or 2)."""
    a, b = np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)
    M = np.ldexp(K, (a[:, None] + b[None, :]).astype(np.int32))
    q = -np.ldexp(1.0, a.astype(np.int32))
    return M, q, np.ldexp(np.full(3, 1.0 / 3.0), (-b).astype(np.int32))


def _solves(method: str, a: np.ndarray, b: np.ndarray) -> bool:
    M, q, z_star = scaled(a, b)
    r = lcpcli.solve(M, q, method=method)
    return bool(r.solved and np.allclose(r.z / z_star, 1.0, rtol=1e-9, atol=0.0))


@pytest.mark.parametrize("method", ["auto", "lemke", "lemke-tableau", "enum", "murty"])
def test_the_issue_example(method: str) -> None:
    assert _solves(method, [-6, -100, -31], [-32, -53, 54])


def test_auto_solves_all_300_scaled_copies() -> None:
    failed = [(a.tolist(), b.tolist()) for a, b in DRAWS if not _solves("auto", a, b)]
    assert failed == []


@pytest.mark.parametrize("method", ["lemke", "enum", "dantzig"])
def test_pivoting_methods_solve_the_scaled_copies(method: str) -> None:
    failed = [(a.tolist(), b.tolist()) for a, b in DRAWS[:100] if not _solves(method, a, b)]
    assert failed == []


def test_enumerate_finds_the_one_solution_and_no_singular_cone() -> None:
    # a P-matrix has no singular principal block, at any scaling
    for a, b in [([-6, -100, -31], [-32, -53, 54])] + [tuple(d) for d in DRAWS[:60]]:
        M, q, z_star = scaled(a, b)
        res = enumerate_cones(Problem.create(M, q))
        assert res.verdict == "unique" and res.counts["singular"] == 0, (a, b)
        np.testing.assert_allclose(res.solutions[0].z / z_star, 1.0, rtol=1e-9)


@pytest.mark.parametrize("k", range(20))
def test_geometric_scaling_undoes_any_power_of_two_scaling(k: int) -> None:
    a, b = DRAWS[k]
    M, q, _ = scaled(a, b)
    s = geometric(Problem.create(M, q), False)
    assert isinstance(s, Scaling)
    Ms = np.ldexp(M, (s.row[:, None] + s.col[None, :]).astype(np.int32))
    e = np.frexp(Ms[K != 0])[1]
    assert e.max() - e.min() <= 3  # K's entries 1 and 2, up to the rounding of the exponents


def test_an_answer_past_the_float64_range_is_unsolved_quietly_and_says_why():
    """M = 2^-1000, q = -2^1000: the one solution z = 2^2000 is not representable.  The run
    on the equilibrated problem finds it in scaled units; unscaled, z overflows.  The verdict
    is unsolved (never solved, exit 1), no numpy warning escapes (the CLI would print each
    one), and the message says that z overflows; a stack gets the same verdicts."""
    import warnings

    M, q = np.array([[2.0 ** -1000]]), np.array([-(2.0 ** 1000)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = lcpcli.solve(M, q)
        stack = lcpcli.solve_many(np.repeat(M[None], 3, 0), np.repeat(q[None], 3, 0))
        alone = lcpcli.solve(M, q, method="lemke")
    assert r.status == alone.status == "unsolved"
    assert "its z overflows float64 in the problem's units" in alone.message
    assert stack.counts() == {"unsolved": 3}
