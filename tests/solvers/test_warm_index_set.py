"""Murty's and Dantzig's methods started from a given index set (``basis=``, ``warm=``).

Independent checks: the certificate of :mod:`lcpcli.core.certificate` and numpy recomputations
of ``w = M z + q`` and of the principal pivot transform; never the code under test alone.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.core.certificate import AT_LOWER, AT_UPPER, BETWEEN, check
from lcpcli.core.errors import OptionError
from lcpcli.core.problem import Problem
from lcpcli.solvers.methods.dantzig import basic_solution, principal_pivot_transform

METHODS = ("murty", "dantzig")


def _pd(n: int, seed: int) -> np.ndarray:
    """M = A A^T + n I: symmetric positive definite (a P-matrix), as in the benchmark."""
    A = np.random.default_rng(seed).standard_normal((n, n))
    return A @ A.T + n * np.eye(n)


def _p_matrix(n: int, seed: int) -> np.ndarray:
    """A non-symmetric P-matrix that is not positive definite: (PD + skew) column-scaled (a
    positive column scaling keeps the P property, not definiteness)."""
    rng = np.random.default_rng(seed)
    S = rng.standard_normal((n, n))
    return (_pd(n, seed) + n * (S - S.T) / 3) @ np.diag(rng.uniform(0.01, 100.0, n))


def _matrix(kind: str, n: int, seed: int) -> np.ndarray:
    return _pd(n, seed) if kind == "pd" else _p_matrix(n, seed)


def _assert_solves(M: np.ndarray, q: np.ndarray, z: np.ndarray, tol: float = 1e-7) -> None:
    """z solves LCP(q, M), recomputed with numpy: z >= 0, w >= 0, z_i w_i = 0 (scaled)."""
    w = M @ z + q
    scale = 1.0 + np.max(np.abs(q)) + np.max(np.abs(M)) * np.max(np.abs(z), initial=0.0)
    assert np.min(z, initial=0.0) >= -tol * scale
    assert np.min(w, initial=0.0) >= -tol * scale
    assert np.max(np.minimum(np.abs(z), np.abs(w)), initial=0.0) <= tol * scale


def _close(a: np.ndarray, b: np.ndarray, rel: float = 1e-7) -> bool:
    return float(np.max(np.abs(a - b), initial=0.0)) <= rel * (1.0 + np.max(np.abs(b),
                                                                            initial=0.0))


# ----------------------------------------------------------- the principal pivot transform
@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["pd", "p"]))
@example(n=8, seed=7, kind="pd")  # |G| = 1 of n = 8: numpy 2.4's in-place negative on that
# column (a stride of 8 elements) negated the wrong entries
def test_principal_pivot_transform_exchanges_w_and_z_on_the_set(n: int, seed: int,
                                                                kind: str) -> None:
    """For any z': w' = M' z' + q' read as z_F = w'_F, w_F = z'_F, z_G = z'_G, w_G = w'_G
    satisfies the original w = M z + q (checked with numpy)."""
    M = _matrix(kind, n, seed)
    rng = np.random.default_rng(seed + 1)
    q = rng.standard_normal(n)
    F = rng.random(n) < 0.5
    start = basic_solution(M, q, F)
    assert start is not None  # a P-matrix's principal blocks are nonsingular
    kept, solve, z_basic = start
    assert np.array_equal(kept, F)
    Mp, qp = principal_pivot_transform(M, q, kept, solve)
    zp = rng.standard_normal(n)
    wp = Mp @ zp + qp
    z, w = zp.copy(), wp.copy()
    z[F], w[F] = wp[F], zp[F]
    assert np.allclose(M @ z + q, w, atol=1e-8 * (1 + np.abs(w).max()))
    # the basic solution is the transform at z' = 0: z_F = q'_F, w_G = q'_G
    assert np.allclose(z_basic[F], qp[F]) and np.all(z_basic[~F] == 0)


@pytest.mark.parametrize("seed", range(4))
def test_principal_pivot_transform_of_a_p_matrix_is_a_p_matrix(seed: int) -> None:
    """Cottle-Pang-Stone, section 4.1: every principal minor of the transform is positive
    (all 2^n - 1 of them, by numpy determinants)."""
    n = 6
    M = _p_matrix(n, seed)
    F = np.random.default_rng(seed).random(n) < 0.5
    kept, solve, _ = basic_solution(M, np.ones(n), F)
    Mp, _ = principal_pivot_transform(M, np.ones(n), kept, solve)
    for k in range(1, n + 1):
        for rows in itertools.combinations(range(n), k):
            assert np.linalg.det(Mp[np.ix_(rows, rows)]) > 0


# ------------------------------------------------------------------ from the right basis
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("kind", ["pd", "p"])
def test_from_the_solution_basis_takes_no_pivot(method: str, kind: str) -> None:
    n = 40
    M, q = _matrix(kind, n, 5), np.random.default_rng(5).standard_normal(n) * n
    cold = lcpcli.solve(M, q, method)
    assert cold.solved and cold.iterations > 0
    for basis in (cold, cold.basis, cold.z_basic, cold.to_dict()["basis"]):
        warm = lcpcli.solve(M, q, method, basis=basis)
        assert warm.solved and warm.iterations == 0 and "from the given basis" in warm.message
        assert _close(warm.z, cold.z)
        assert check(Problem.create(M, q), warm.z, 1e-8)[0].passed
    # through warm=: the method keeps its own name and pivots (not BPP's)
    warm = lcpcli.solve(M, q, method, warm=cold)
    assert warm.method == method and warm.iterations == 0 and warm.solved
    # basis= given beside warm= is the one the method starts from
    both = lcpcli.solve(M, q, method, basis=cold, warm=np.zeros(n, bool))
    assert both.solved and both.iterations == 0


@pytest.mark.parametrize("method", METHODS)
def test_n200_warm_takes_the_method_not_bpp(method: str) -> None:
    """From n = 200 on auto and Lemke try BPP from the basis first; murty and dantzig start
    from it themselves, in at most a few pivots on a 1 % perturbation (cold: about n)."""
    n = 200
    M, rng = _pd(n, 8), np.random.default_rng(8)
    q = rng.standard_normal(n) * n
    prev = lcpcli.solve(M, q, method)
    q2 = q + 0.01 * np.abs(q) * rng.standard_normal(n)
    warm, cold = lcpcli.solve(M, q2, method, warm=prev), lcpcli.solve(M, q2, method)
    assert warm.solved and cold.solved and warm.method == method
    assert "from the given basis" in warm.message and "solved cold" not in warm.message
    assert warm.iterations <= 10 < cold.iterations
    assert _close(warm.z, cold.z)
    _assert_solves(M, q2, warm.z)


def test_scaling_keeps_the_index_set() -> None:
    """A badly scaled problem is equilibrated (D1 M D2) before the method runs; the index set
    passes unchanged, so the solution's basis still takes no pivot."""
    n = 30
    rng = np.random.default_rng(3)
    D1, D2 = np.diag(10.0 ** rng.uniform(-3, 3, n)), np.diag(10.0 ** rng.uniform(-3, 3, n))
    M, q = D1 @ _pd(n, 3) @ D2, D1 @ rng.standard_normal(n)
    for method in METHODS:
        cold = lcpcli.solve(M, q, method)
        assert cold.solved and "equilibrated" in cold.message
        warm = lcpcli.solve(M, q, method, basis=cold)
        assert warm.solved and warm.iterations == 0 and "equilibrated" in warm.message
        assert np.array_equal(warm.z_basic, cold.z_basic)


# ----------------------------------------------------------------- perturbed sequences
@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 30), seed=st.integers(0, 2**32 - 1), steps=st.integers(2, 5),
       kind=st.sampled_from(["pd", "p"]), method=st.sampled_from(METHODS))
def test_perturbed_sequence_warm_equals_cold(n: int, seed: int, steps: int, kind: str,
                                             method: str) -> None:
    """q_{k+1} = q_k + 1 % noise, each solve warm-started from the previous result: the same
    verdict as cold and (P-matrix: the unique solution) the same z to rounding."""
    M = _matrix(kind, n, seed)
    rng = np.random.default_rng(seed + 7)
    q = rng.standard_normal(n)
    prev = lcpcli.solve(M, q, method)
    for _ in range(steps):
        q = q + 0.01 * np.abs(q) * rng.standard_normal(n)
        warm, cold = lcpcli.solve(M, q, method, warm=prev), lcpcli.solve(M, q, method)
        assert warm.status == cold.status == "solved"
        assert warm.method == method
        assert _close(warm.z, cold.z)
        _assert_solves(M, q, warm.z)
        prev = warm


# ---------------------------------------------------- wrong, infeasible, singular bases
@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 25), seed=st.integers(0, 2**32 - 1), method=st.sampled_from(METHODS),
       start=st.sampled_from(["random", "all_z", "all_w", "letters", "codes"]))
def test_from_a_wrong_basis_still_ends_correctly(n: int, seed: int, method: str,
                                                 start: str) -> None:
    M = _p_matrix(n, seed)
    rng = np.random.default_rng(seed + 3)
    q = rng.standard_normal(n)
    F = {"random": rng.random(n) < 0.5, "all_z": np.ones(n, bool), "all_w": np.zeros(n, bool),
         "letters": rng.random(n) < 0.5, "codes": rng.random(n) < 0.5}[start]
    basis = {"letters": "".join("F" if f else "L" for f in F),
             "codes": np.where(F, BETWEEN, AT_LOWER).astype(np.int8)}.get(start, F)
    r, cold = lcpcli.solve(M, q, method, basis=basis), lcpcli.solve(M, q, method)
    assert r.status == cold.status == "solved"
    assert _close(r.z, cold.z)
    _assert_solves(M, q, r.z)


@pytest.mark.parametrize("method", METHODS)
def test_singular_block_is_repaired(method: str) -> None:
    """M_FF singular (pairs 1 and 2 dependent): one pair leaves the set, the rest starts."""
    M = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    q = np.array([-1.0, -1.0, -1.0])
    r = lcpcli.solve(M, q, method, basis=[True, True, True])
    assert r.solved and "1 dependent pair dropped" in r.message
    _assert_solves(M, q, r.z)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("case", ["skew", "infeasible"])
def test_warm_never_gives_a_worse_verdict_than_cold(method: str, case: str) -> None:
    """Outside the methods' class the warm run ends unsolved and the cold run decides: the
    verdict is the cold one (never no_solution from the warm start)."""
    if case == "skew":  # PSD with a zero diagonal: the basis {z1, z3, ...} is singular
        M = np.kron(np.eye(3), np.array([[0.0, 1.0], [-1.0, 0.0]]))
        q, warm = np.tile([-1.0, 1.0], 3), np.tile([True, False], 3)
    else:  # -I, q < 0: no solution
        M, q, warm = -np.eye(4), -np.ones(4), np.ones(4, bool)
    cold = lcpcli.solve(M, q, method)
    r = lcpcli.solve(M, q, method, warm=warm)
    assert r.status == cold.status and r.method == method
    if not cold.solved:
        assert "did not end certified" in r.message


# ------------------------------------------------------------------------ options
def test_basis_option_forms_and_errors() -> None:
    M, q = _pd(4, 1), np.array([-1.0, 2.0, -3.0, 1.0])
    cold = lcpcli.solve(M, q, "murty")
    assert cold.to_dict()["basis"] == "FLFL"
    for form in ("FLFL", "FLFU", "1,0,1,0", [1, 0, 1, 0], [True, False, True, False],
                 np.array([BETWEEN, AT_LOWER, BETWEEN, AT_UPPER], dtype=np.int8), cold):
        for method in METHODS:
            r = lcpcli.solve(M, q, method, basis=form)
            assert r.solved and r.iterations == 0, (form, method)
    for bad in ("FX", "1,2", np.array([0, 3, 0, 0], dtype=np.int8), [0.5, 1, 0, 0]):
        with pytest.raises(OptionError):
            lcpcli.solve(M, q, "murty", basis=bad)
    for method in METHODS:
        with pytest.raises(OptionError, match="length"):
            lcpcli.solve(M, q, method, basis=[True, False])


def test_dantzig_basis_is_for_lcps_and_cold_traces() -> None:
    M, q = _pd(4, 2), np.array([-1.0, 2.0, -3.0, 1.0])
    with pytest.raises(OptionError, match="box LCP"):
        lcpcli.solve(M, q, "dantzig", basis="FLFL", lower=np.zeros(4), upper=np.ones(4))
    with pytest.raises(OptionError, match="trace"):
        lcpcli.solve(M, q, "dantzig", basis="FLFL", trace=True)
    # a box LCP warm-started through warm= keeps the rule of the other methods (no error)
    prev = lcpcli.solve(M, q, "dantzig", lower=np.zeros(4), upper=np.ones(4))
    r = lcpcli.solve(M, q, "dantzig", lower=np.zeros(4), upper=np.ones(4), warm=prev)
    assert r.solved and r.status == prev.status


def test_murty_trace_from_a_basis_starts_there() -> None:
    """The replica pivots the set in like the kernel: the trace's start is the given set and
    it takes the kernel's number of pivots."""
    n = 6
    M, q = _pd(n, 4), np.random.default_rng(4).standard_normal(n) * n
    F = np.array([True, False, True, False, False, True])
    plain = lcpcli.solve(M, q, "murty", basis=F)
    traced = lcpcli.solve(M, q, "murty", basis=F, trace=True)
    assert traced.solved and traced.iterations == plain.iterations
    assert traced.trace[0]["alpha"] == [i + 1 for i in np.flatnonzero(F)]


# ---------------------------------------------------------------------------- CLI
@pytest.mark.parametrize("method", METHODS)
def test_cli_z0_previous_result_starts_the_method(cli, tmp_path, method: str) -> None:
    n = 30
    M, rng = _pd(n, 6), np.random.default_rng(6)
    q = rng.standard_normal(n) * n
    q2 = q + 0.01 * np.abs(q) * rng.standard_normal(n)
    (tmp_path / "p1.json").write_text(json.dumps({"M": M.tolist(), "q": q.tolist()}))
    (tmp_path / "p2.json").write_text(json.dumps({"M": M.tolist(), "q": q2.tolist()}))
    first = cli("solve", str(tmp_path / "p1.json"), "-m", method, "--json", "-o",
                str(tmp_path / "prev.json"))
    assert first.returncode == 0, first.stderr
    cold = cli("solve", str(tmp_path / "p2.json"), "-m", method, "--json")
    warm = cli("solve", str(tmp_path / "p2.json"), "-m", method, "--z0",
               str(tmp_path / "prev.json"), "--json")
    assert cold.returncode == warm.returncode == 0, warm.stderr
    c, w = json.loads(cold.stdout), json.loads(warm.stdout)
    assert w["status"] == c["status"] == "solved" and w["method"] == method
    assert "from the given basis" in w["message"]
    assert w["iterations"] < c["iterations"]
    assert _close(np.array(w["z"]), np.array(c["z"]))
    _assert_solves(M, q2, np.array(w["z"]))


@pytest.mark.parametrize("kind", ["pd", "p"])
def test_murty_transform_and_pivoting_in_take_the_same_pivots(monkeypatch, kind: str) -> None:
    """Murty from F on the principal pivot transform (n >= TRANSFORM_MIN_N) and with F pivoted
    in on the tableau (below it) are one method: the same least-index pivots, the same z."""
    from lcpcli.solvers.methods import murty

    runs = {}
    for path, threshold in (("transform", 0), ("pivot-in", 10**9)):
        monkeypatch.setattr(murty, "TRANSFORM_MIN_N", threshold)
        out = []
        for seed in range(12):
            n = 20
            M = _matrix(kind, n, seed)
            rng = np.random.default_rng(seed)
            q = rng.standard_normal(n) * n
            F = rng.random(n) < 0.5
            out.append(lcpcli.solve(M, q, "murty", basis=F))
        runs[path] = out
    for a, b in zip(runs["transform"], runs["pivot-in"], strict=True):
        assert a.solved and b.solved and a.iterations == b.iterations
        assert _close(a.z, b.z)


def test_murty_transform_repairs_a_singular_block(monkeypatch) -> None:
    from lcpcli.solvers.methods import murty

    monkeypatch.setattr(murty, "TRANSFORM_MIN_N", 0)
    M = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    q = np.array([-1.0, -1.0, -1.0])
    r = lcpcli.solve(M, q, "murty", basis=[True, True, True])
    assert r.solved and "1 dependent pair dropped" in r.message
    _assert_solves(M, q, r.z)
    # -I from the all-z basis: the first pivot is not positive; restarted from z = 0
    r = lcpcli.solve(-np.eye(3), -np.ones(3), "murty", basis=[True, True, True])
    assert not r.solved and "restarted from z = 0" in r.message
