"""Final bases on results, block principal pivoting (``bpp``) and warm starts from a basis."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.core.certificate import AT_LOWER, AT_UPPER, BETWEEN
from lcpcli.core.errors import OptionError
from lcpcli.core.problem import Problem
from lcpcli.solvers.warm import warm_basis


def _pd(n: int, seed: int, skew: float = 0.0) -> np.ndarray:
    """A positive definite M (a P-matrix): A A^T / n + I, plus a skew part when ``skew``."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T / n + np.eye(n)
    if skew:
        S = rng.standard_normal((n, n))
        M = M + skew * (S - S.T)
    return M


def _p_matrix(n: int, seed: int) -> np.ndarray:
    """A non-symmetric P-matrix that is not positive definite: D (PD) with D diagonal > 0,
    column-scaled (a column scaling keeps the P property, not definiteness)."""
    rng = np.random.default_rng(seed)
    return _pd(n, seed, skew=1.0) @ np.diag(rng.uniform(0.01, 100.0, n))


# ----------------------------------------------------------------------------- the basis
@pytest.mark.parametrize("method", ["auto", "lemke", "murty", "pgs", "bpp", "newton"])
def test_every_solved_result_carries_its_basis(method: str) -> None:
    M, q = _pd(12, 1), np.random.default_rng(2).standard_normal(12)
    r = lcpcli.solve(M, q, method=method)
    assert r.solved
    assert r.basis is not None and r.basis.shape == (12,)
    # the basis says which of z_i / w_i is basic: w_i = 0 where F (z_i basic), z_i = 0 where L
    assert set(r.basis.tolist()) <= {AT_LOWER, BETWEEN} and r.z_basic.any()
    assert np.allclose(r.w[r.z_basic], 0, atol=1e-7)
    assert np.allclose(r.z[r.basis == AT_LOWER], 0, atol=1e-7)
    assert np.array_equal(r.z_basic[r.z > 1e-6], np.ones(int(np.sum(r.z > 1e-6)), bool))
    assert r.to_dict()["basis"] == "".join("LUF"[c] for c in r.basis)


def test_box_basis_names_the_active_bound() -> None:
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    r = lcpcli.solve(M, np.array([-5.0, 1.0]), lower=[0, 0], upper=[1, 1])
    assert r.solved and r.z.tolist() == [1.0, 0.0]
    assert r.basis.tolist() == [AT_UPPER, AT_LOWER] and r.to_dict()["basis"] == "UL"


def test_mlcp_free_variables_are_basic() -> None:
    M, q = _pd(6, 3), np.random.default_rng(3).standard_normal(6)
    r = lcpcli.solve(M, q, n_eq=2)
    assert r.solved and np.all(r.basis[:2] == BETWEEN)


# ------------------------------------------------------------------------ bpp, cold
@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 30), seed=st.integers(0, 2**32 - 1), kind=st.sampled_from(["pd", "p"]))
def test_bpp_cold_agrees_with_lemke_on_p_matrices(n: int, seed: int, kind: str) -> None:
    M = _pd(n, seed, skew=0.5) if kind == "pd" else _p_matrix(n, seed)
    q = np.random.default_rng(seed + 1).standard_normal(n)
    b, lem = lcpcli.solve(M, q, method="bpp"), lcpcli.solve(M, q, method="lemke")
    assert b.solved and lem.solved
    scale = 1.0 + np.max(np.abs(lem.z), initial=0.0)
    assert np.max(np.abs(b.z - lem.z), initial=0.0) <= 1e-7 * scale


#: A 4 x 4 P-matrix (all principal minors positive) on which pure block pivoting, started from
#: the basis {z1, z3}, cycles (found by a search over small integer P-matrices); the
#: single-pivot fallback of Júdice & Pires (Murty's least-index rule) ends it.
CYCLING_M = np.array([[3.0, 3, -1, -3], [-2, 3, -2, 1], [4, -1, 3, -4], [-2, -1, 4, 3]])
CYCLING_Q = np.array([0.0, -2, 1, -2])
CYCLING_BASIS = [True, False, True, False]


def test_cycling_example_is_a_p_matrix() -> None:
    from itertools import combinations

    minors = [np.linalg.det(CYCLING_M[np.ix_(s, s)]) for k in range(1, 5)
              for s in combinations(range(4), k)]
    assert min(minors) > 0


def test_pure_block_pivoting_cycles_and_the_fallback_ends_it() -> None:
    pure = lcpcli.solve(CYCLING_M, CYCLING_Q, method="bpp", basis=CYCLING_BASIS,
                        block_tries=10**6, max_iter=60)
    assert not pure.solved and pure.termination == "iteration_limit"
    r = lcpcli.solve(CYCLING_M, CYCLING_Q, method="bpp", basis=CYCLING_BASIS)
    assert r.solved and r.info["single_pivots"] >= 1
    lem = lcpcli.solve(CYCLING_M, CYCLING_Q, method="lemke")
    assert np.allclose(r.z, lem.z, atol=1e-12)
    # the same basis as a warm start: ends certified, same z
    w = lcpcli.solve(CYCLING_M, CYCLING_Q, "bpp", warm=np.array(CYCLING_BASIS))
    assert w.solved and np.allclose(w.z, lem.z, atol=1e-12)


# ------------------------------------------------------------------------ warm starts
def test_warm_from_the_solution_basis_takes_one_factorisation() -> None:
    M, q = _pd(40, 5), np.random.default_rng(5).standard_normal(40)
    cold = lcpcli.solve(M, q)
    warm = lcpcli.solve(M, q, "bpp", warm=cold)
    assert warm.solved and warm.method == "bpp" and warm.iterations == 1
    assert np.allclose(warm.z, cold.z, atol=1e-12)
    assert np.array_equal(warm.basis, cold.basis)


@settings(max_examples=25, deadline=None)
@given(n=st.integers(1, 40), seed=st.integers(0, 2**32 - 1), steps=st.integers(2, 6),
       kind=st.sampled_from(["pd", "p"]))
def test_perturbed_sequence_warm_equals_cold(n: int, seed: int, steps: int, kind: str) -> None:
    """q_{k+1} = q_k + 1% noise, each solve warm-started from the previous result: same verdict
    and (P-matrix: unique solution) the same z as a cold solve."""
    M = _pd(n, seed) if kind == "pd" else _p_matrix(n, seed)
    rng = np.random.default_rng(seed + 7)
    q = rng.standard_normal(n)
    prev = lcpcli.solve(M, q)
    for _ in range(steps):
        q = q + 0.01 * np.abs(q) * rng.standard_normal(n)
        warm, cold = lcpcli.solve(M, q, "bpp", warm=prev), lcpcli.solve(M, q)
        assert warm.status == cold.status == "solved"
        scale = 1.0 + np.max(np.abs(cold.z), initial=0.0)
        assert np.max(np.abs(warm.z - cold.z), initial=0.0) <= 1e-7 * scale
        prev = warm


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 25), seed=st.integers(0, 2**32 - 1),
       start=st.sampled_from(["random", "all_z", "all_w", "point"]))
def test_warm_from_a_wrong_basis_still_ends_correctly(n: int, seed: int, start: str) -> None:
    M = _p_matrix(n, seed)
    rng = np.random.default_rng(seed + 3)
    q = rng.standard_normal(n)
    warm = {"random": rng.random(n) < 0.5, "all_z": np.ones(n, bool),
            "all_w": np.zeros(n, bool), "point": rng.standard_normal(n) * 10}[start]
    r, cold = lcpcli.solve(M, q, "bpp", warm=warm), lcpcli.solve(M, q)
    assert r.status == cold.status == "solved"
    assert np.max(np.abs(r.z - cold.z)) <= 1e-7 * (1.0 + np.max(np.abs(cold.z)))


def test_warm_outside_bpp_class_falls_back_to_cold() -> None:
    """A skew-symmetric M (PSD, zero diagonal; 100 blocks [[0, 1], [-1, 0]], n = 200 so that
    auto pivots from the warm basis): the basis {z1, z3, ...} has a singular block; the warm
    start falls back to the cold solve, with the cold verdict."""
    M = np.kron(np.eye(100), np.array([[0.0, 1.0], [-1.0, 0.0]]))
    q = np.tile([-1.0, 1.0], 100)
    cold = lcpcli.solve(M, q)
    r = lcpcli.solve(M, q, warm=np.tile([True, False], 100))
    assert r.status == cold.status == "solved" and r.method == "auto"
    assert "solved cold" in r.message
    assert np.allclose(r.z, cold.z)


def test_warm_never_worse_than_cold_without_solution() -> None:
    """An infeasible LCP: the cold verdict (with its proof) is kept; the warm start itself never
    claims no_solution."""
    n = 200  # auto pivots from the warm basis from n = 200 on
    M, q = -np.eye(n), -np.ones(n)
    cold = lcpcli.solve(M, q)
    assert cold.status == "no_solution"
    for warm in (np.ones(n, bool), np.zeros(n, bool)):
        r = lcpcli.solve(M, q, warm=warm)
        assert r.status == cold.status and r.method == cold.method
        assert "solved cold" in r.message


def test_warm_mlcp_and_box() -> None:
    M, q = _pd(10, 11), np.random.default_rng(11).standard_normal(10)
    prev = lcpcli.solve(M, q, n_eq=3)
    r = lcpcli.solve(M, q * 1.01, "bpp", n_eq=3, warm=prev)
    assert r.solved and r.method == "bpp"
    M, q = _pd(200, 12), np.random.default_rng(12).standard_normal(200)
    lo, up = -np.ones(200), np.ones(200)
    prev = lcpcli.solve(M, 5 * q, lower=lo, upper=up)
    assert set(prev.to_dict()["basis"]) == set("LUF")
    r = lcpcli.solve(M, 5 * q, lower=lo, upper=up, warm=prev)
    assert r.solved and r.method == "bpp" and r.iterations == 1
    assert np.allclose(r.z, prev.z, atol=1e-10)


def test_warm_basis_forms_and_errors() -> None:
    p = Problem.create(_pd(3, 1), np.array([-1.0, 2.0, -3.0]))
    assert warm_basis(p, "FLF").tolist() == [BETWEEN, AT_LOWER, BETWEEN]
    assert warm_basis(p, np.array([True, False, True])).tolist() == [BETWEEN, AT_LOWER, BETWEEN]
    assert warm_basis(p, np.array([1.0, 0.0, 2.0])).tolist() == [BETWEEN, AT_LOWER, BETWEEN]
    with pytest.raises(OptionError):
        warm_basis(p, "FX")
    with pytest.raises(OptionError):
        lcpcli.solve(p, warm=np.array([True, False]))
    with pytest.raises(OptionError):
        lcpcli.solve(p, warm=np.ones(5))


@pytest.mark.parametrize("method", ["auto", "bpp", "pgs", "newton", "murty", "lemke"])
@pytest.mark.parametrize("given", [
    {"warm": "FXF"},                               # a letter outside 'LUF'
    {"warm": np.array([1 + 1j, 0, 1])},            # complex
    {"warm": ["1", "0", "1"]},                     # text
    {"z0": np.array([1 + 1j, 0, 1])},
    {"z0": ["1", "0", "1"]},
    {"z0": np.array([True, False, True])},         # booleans are no point
    {"covering": [1 + 0j, 1, 1]},
])
def test_warm_starts_and_vectors_follow_the_data_rule_for_every_method(method, given) -> None:
    """README: the data rule of M and q applies to warm starts too, whatever the method does
    with them: auto below n = 200 ignored an unknown basis letter ('FXF' solved, bpp refused
    it), and z0= / covering= took complex numbers (imaginary part dropped), text and
    booleans."""
    M, q = 2 * np.eye(3), -np.ones(3)
    key = next(iter(given))
    if key in ("z0", "covering"):
        from lcpcli.solvers.registry import get_method

        if key not in get_method(method).options:
            pytest.skip(f"{method} takes no {key}")
    with pytest.raises(OptionError):
        lcpcli.solve(M, q, method, **given)


@pytest.mark.parametrize("method", ["pgs", "auto", "bpp", "lemke", "newton"])
def test_a_previous_result_that_is_not_finite_starts_cold(method) -> None:
    """A loop that hands on every previous Result: PGS diverging on a non-symmetric M leaves
    z with inf, which has no basis and is no point; the next solve runs cold (as solve_many's
    rows with NaN) instead of raising 'warm start z0 contains NaN or Inf'."""
    A = np.array([[1.73352959, 0.34781037, -0.94141329],
                  [0.90704896, 0.01765561, -0.61521853],
                  [-0.63350893, -0.99343179, 0.04811898]])
    q = np.array([1.06881669, -0.3250521, 0.42082413])
    prev = lcpcli.solve(A, q, "pgs")
    assert not np.all(np.isfinite(prev.z)) and prev.basis is None
    warm, cold = lcpcli.solve(A, q, method, warm=prev), lcpcli.solve(A, q, method)
    assert warm.status == cold.status
    assert np.array_equal(warm.z, cold.z, equal_nan=True)
    assert "not finite: solved cold" in warm.message
    with pytest.raises(OptionError, match="length 3"):
        lcpcli.solve(2 * np.eye(2), -np.ones(2), method, warm=prev)


@pytest.mark.parametrize("method", ["bpp", "lemke"])
def test_one_warm_result_gives_the_same_bits_in_any_order_and_thread(method) -> None:
    """A Result's kept factors (Result.factors) were updated in place by every warm solve
    that used them: several solves from one previous Result (a sweep of scenarios from one
    state) gave z bits that depended on which ran before (2 of 12 differed between two
    orders), and threads sharing it saw each other's q (9 of 32 warm starts failed and ran
    cold).  Each use now starts from the Result's own state."""
    from concurrent.futures import ThreadPoolExecutor

    n = 300
    rng = np.random.default_rng(2)
    M, q = _pd(n, 2), rng.standard_normal(n)
    prev = lcpcli.solve(M, q, method, warm=lcpcli.solve(M, q, method))
    assert prev.factors is not None
    qs = [q + 0.02 * rng.standard_normal(n) for _ in range(12)]
    forward = [lcpcli.solve(M, x, method, warm=prev) for x in qs]
    backward = [lcpcli.solve(M, x, method, warm=prev) for x in reversed(qs)][::-1]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda x: lcpcli.solve(M, x, method, warm=prev), qs))
    for a, b, c in zip(forward, backward, threaded, strict=True):
        assert a.solved and "did not end certified" not in c.message
        assert a.z.tobytes() == b.z.tobytes() == c.z.tobytes()


def test_iterative_methods_take_the_warm_point() -> None:
    M, q = _pd(20, 4), np.random.default_rng(4).standard_normal(20)
    prev = lcpcli.solve(M, q)
    r = lcpcli.solve(M, q, method="pgs", warm=prev)
    assert r.solved and r.method == "pgs"
    assert r.iterations <= lcpcli.solve(M, q, method="pgs").iterations


def test_cli_json_basis_and_z0_result_file(cli, tmp_path) -> None:
    n = 200  # auto and lemke pivot from the warm basis from n = 200 on
    M, q = _pd(n, 8), np.random.default_rng(8).standard_normal(n)
    (tmp_path / "p1.json").write_text(json.dumps({"M": M.tolist(), "q": q.tolist()}))
    q2 = q + 0.01 * np.abs(q) * np.random.default_rng(9).standard_normal(n)
    (tmp_path / "p2.json").write_text(json.dumps({"M": M.tolist(), "q": q2.tolist()}))
    r1 = cli("solve", str(tmp_path / "p1.json"), "--json", "-o", str(tmp_path / "r1.json"))
    assert r1.returncode == 0, r1.stderr
    first = json.loads(r1.stdout)
    assert len(first["basis"]) == n and set(first["basis"]) == set("LF")
    for method in ("auto", "lemke"):
        r2 = cli("solve", str(tmp_path / "p2.json"), "--z0", str(tmp_path / "r1.json"),
                 "--json", "-m", method)
        assert r2.returncode == 0, r2.stderr
        second = json.loads(r2.stdout)
        # auto pivots from the basis by BPP, Lemke by Lemke from that basis (lemke_warm)
        assert second["status"] == "solved"
        assert second["method"] == ("bpp" if method == "auto" else "lemke-revised")
        assert "warm start" in second["message"]
        cold = lcpcli.solve(M, q2)
        assert np.allclose(second["z"], cold.z, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 40), seed=st.integers(0, 2**32 - 1), k=st.integers(1, 8),
       symmetric=st.booleans())
def test_bordered_solve_equals_a_fresh_factorisation(n: int, seed: int, k: int,
                                                     symmetric: bool) -> None:
    """A basis k pairs away from the factored one, solved through the Schur complement of the
    bordered system, has the basic solution of its own factorisation (and costs none)."""
    from lcpcli.solvers.methods.bpp import Blocks

    M = _pd(n, seed) if symmetric else _p_matrix(n, seed)
    rng = np.random.default_rng(seed + 5)
    q = rng.standard_normal(n)
    F0 = rng.random(n) < 0.5
    F = F0.copy()
    F[rng.choice(n, size=min(k, n), replace=False)] ^= True
    blocks = Blocks(M, q, symmetric)
    blocks.solve(F0)
    z = blocks.solve(F)
    assert blocks.factorisations == 1
    ref = np.zeros(n)
    idx = np.flatnonzero(F)
    if idx.size:
        ref[idx] = np.linalg.solve(M[np.ix_(idx, idx)], -q[idx])
    assert z is not None and np.all(z[~F] == 0)
    assert np.max(np.abs(z - ref)) <= 1e-8 * (1.0 + np.max(np.abs(ref)))
    # a new q on the same M keeps the factors; another M does not
    assert blocks.reuse(M.copy(), -q) and not blocks.reuse(M + 1.0, q)


def test_solve_many_warm_from_the_previous_stack() -> None:
    """Each problem of a stack warm-started from the previous stack's answer (n = 200: auto
    pivots from the basis): same verdicts and z as a cold stack; a NaN row is solved cold."""
    K, n = 3, 200
    M = np.stack([_pd(n, s) for s in range(K)])
    rng = np.random.default_rng(21)
    q = rng.standard_normal((K, n))
    prev = lcpcli.solve_many(M, q)
    q2 = q + 0.01 * np.abs(q) * rng.standard_normal((K, n))
    cold = lcpcli.solve_many(M, q2)
    warm = lcpcli.solve_many(M, q2, warm=prev)
    assert warm.counts() == cold.counts() == {"solved": K}
    assert np.allclose(warm.z, cold.z, atol=1e-9)
    assert [warm.method_of(k) for k in range(K)] == ["bpp"] * K
    rows = prev.z.copy()
    rows[1] = np.nan
    again = lcpcli.solve_many(M, q2, warm=rows)
    assert again.counts() == {"solved": K} and again.method_of(1) == "auto"
    with pytest.raises(OptionError):
        lcpcli.solve_many(M, q2, warm=prev.z[:2])


def test_sparse_warm_start_solves_the_basis_without_densifying() -> None:
    import scipy.sparse as sp

    n = 300
    M = sp.diags([-1.0, 4.0, -1.0], [-1, 0, 1], shape=(n, n), format="csr")
    q = np.random.default_rng(30).standard_normal(n)
    prev = lcpcli.solve(M, q)
    r = lcpcli.solve(M, q, warm=prev)
    assert r.solved and r.method == "bpp" and r.iterations == 1
    assert "basic solution of the given basis" in r.message
    assert np.allclose(r.z, prev.z, atol=1e-10)


def test_results_pickle_with_their_basis_and_without_factors() -> None:
    import pickle

    n = 200
    M, q = _pd(n, 40), np.random.default_rng(40).standard_normal(n)
    r = lcpcli.solve(M, q, "bpp", warm=lcpcli.solve(M, q))
    assert r.factors is not None
    back = pickle.loads(pickle.dumps(r))
    assert back.factors is None and back.basis_source is None
    assert np.array_equal(back.basis, r.basis) and np.array_equal(back.z, r.z)


def test_bpp_basis_option_forms() -> None:
    from lcpcli.solvers.registry import get_method

    spec = get_method("bpp")
    for form in ("FLF", "1,0,1", [True, False, True], [1, 0, 1]):
        assert spec.parse_options({"basis": form})["basis"].tolist() == [True, False, True]
    for bad in ("FX", "1,2", "", [0.5, 1]):
        with pytest.raises(OptionError):
            spec.parse_options({"basis": bad})


def test_batch_jsonl_rows_carry_the_basis(cli, tmp_path) -> None:
    """A batch row is the --json object: its basis included, usable as the next --z0."""
    M, q = _pd(6, 50), np.random.default_rng(50).standard_normal(6)
    for name in ("a", "b"):
        (tmp_path / f"{name}.json").write_text(json.dumps({"M": M.tolist(), "q": q.tolist()}))
    r = cli("solve", str(tmp_path / "a.json"), str(tmp_path / "b.json"), "-o",
            str(tmp_path / "rows.jsonl"), "-q")
    assert r.returncode == 0, r.stderr
    rows = [json.loads(line) for line in (tmp_path / "rows.jsonl").read_text().splitlines()]
    expected = lcpcli.solve(M, q).to_dict()["basis"]
    assert [row["basis"] for row in rows] == [expected, expected]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_warm_on_psd_matrices_keeps_the_cold_verdict(seed: int) -> None:
    """Rank-deficient PSD M (n = 200, rank 100; outside BPP's class: singular blocks), q making
    the LCP solvable: a warm start from a random basis ends with the cold verdict (solved), by
    BPP or by the cold fallback, and its answer passes the certificate."""
    n = 200
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n // 2))
    M = B @ B.T / n
    x = np.maximum(rng.standard_normal(n), 0)
    q = -M @ x + np.where(x > 0, 0.0, rng.uniform(0, 1, n))  # x solves it
    cold = lcpcli.solve(M, q)
    r = lcpcli.solve(M, q, warm=rng.random(n) < 0.5)
    assert r.status == cold.status == "solved"
    assert r.method in ("bpp", "auto")


@pytest.mark.parametrize("method", ["bpp", "auto", "lemke"])
def test_a_warm_result_of_an_m_changed_in_place_starts_from_its_basis(method: str) -> None:
    """A simulation loop that updates one M array in place and hands on the previous Result:
    the Result's kept factors were made from the old contents of that same array, so they are
    not reused (their answer failed the certificate and the step ran cold, 143-147 pivots);
    the step starts from the Result's basis, factored afresh."""
    rng = np.random.default_rng(21)
    n = 300  # auto warm-starts from n = 200 on
    A = rng.normal(size=(n, n)) / np.sqrt(n)
    M0 = A @ A.T + np.eye(n)
    q = rng.normal(size=n)
    M = M0.copy()
    prev = lcpcli.solve(M, q, "bpp")
    prev = lcpcli.solve(M, q, "bpp", warm=prev)  # a warm result: it keeps its factors
    assert prev.factors is not None
    B = rng.normal(size=(n, n)) / np.sqrt(n) * 0.3
    M[...] = M0 + B @ B.T  # the next step, in the same buffer
    res = lcpcli.solve(M, q, method, warm=prev)
    cold = lcpcli.solve(M.copy(), q, method)
    assert res.status == "solved" and "cold" not in res.message
    assert "warm start" in res.message and res.iterations <= 8
    np.testing.assert_allclose(res.z, cold.z, atol=1e-9)
