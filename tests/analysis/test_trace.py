"""The step-by-step replicas (lcpcli.solvers.trace): same pivots as the compiled methods, and
the teaching data they record (initial tableau, pivot elements, ratio tests, tie-breaks,
tableau layouts), checked against tableaux computed by hand.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from lcpcli.analysis.pivoting import augment, parse_tuple, parse_var, principal_pivot
from lcpcli.api import solve
from lcpcli.core.problem import Problem
from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL
from lcpcli.solvers.trace.lemke import lemke_traced, path_points
from lcpcli.solvers.trace.path import driving_step, follow
from lcpcli.solvers.trace.tableau import LAYOUTS, canonical_key, tableau_view

CPS_M = np.array([[0.0, -1, 2], [2, 0, -2], [-1, 1, 0]])  # seed 000 = CPS Example 4.4.7
CPS_Q = np.array([-3.0, 6, -1])
DEG_M = np.array([[2.0, 2, 0, 0], [0, 2, 0, 1], [-1, -1, 2, 1], [0, 1, 0, 2]])
DEG_Q = np.array([1.0, -2, -2, -2])  # samples/degenerate_lex.json


def F(text: str) -> float:
    return float(Fraction(text))


def rows(*lines: str) -> np.ndarray:
    return np.array([[F(x) for x in line.split()] for line in lines])


# Murty's tableau of w - M z - e z0 = q, columns w1..wn, z1..zn, z0, q; computed by hand
# (Gauss-Jordan on the pivot element of each step, as in Murty's and Cottle-Pang-Stone's books).
CPS_STEPS = [
    (["w1", "w2", "w3"], rows("1 0 0  0 1 -2  -1 -3",
                              "0 1 0  -2 0 2  -1 6",
                              "0 0 1  1 -1 0  -1 -1"), (0, "z0", -1)),
    (["z0", "w2", "w3"], rows("-1 0 0  0 -1 2  1 3",
                              "-1 1 0  -2 -1 4  0 9",
                              "-1 0 1  1 -2 2  0 2"), (2, "z1", 1)),
    (["z0", "w2", "z1"], rows("-1 0 0  0 -1 2  1 3",
                              "-3 1 2  0 -5 8  0 13",
                              "-1 0 1  1 -2 2  0 2"), (2, "z3", 2)),
    (["z0", "w2", "z3"], rows("0 0 -1  -1 1 0  1 1",
                              "1 1 -2  -4 3 0  0 5",
                              "-1/2 0 1/2  1/2 -1 1  0 1"), (1, "w1", 1)),
    (["z0", "w1", "z3"], rows("0 0 -1  -1 1 0  1 1",
                              "1 1 -2  -4 3 0  0 5",
                              "0 1/2 -1/2  -3/2 1/2 1  0 7/2"), (0, "z2", 1)),
    (["z2", "w1", "z3"], rows("0 0 -1  -1 1 0  1 1",
                              "1 1 1  -1 0 0  -3 2",
                              "0 1/2 0  -1 0 1  -1/2 3"), None),
]

DEG_STEPS = [
    (["w1", "w2", "w3", "w4"], rows("1 0 0 0  -2 -2 0 0  -1 1",
                                    "0 1 0 0  0 -2 0 -1  -1 -2",
                                    "0 0 1 0  1 1 -2 -1  -1 -2",
                                    "0 0 0 1  0 -1 0 -2  -1 -2"), (3, "z0", -1)),
    (["w1", "w2", "w3", "z0"], rows("1 0 0 -1  -2 -1 0 2  0 3",
                                    "0 1 0 -1  0 -1 0 1  0 0",
                                    "0 0 1 -1  1 2 -2 1  0 0",
                                    "0 0 0 -1  0 1 0 2  1 2"), (2, "z4", 1)),
    (["w1", "w2", "z4", "z0"], rows("1 0 -2 1  -4 -5 4 0  0 3",
                                    "0 1 -1 0  -1 -3 2 0  0 0",
                                    "0 0 1 -1  1 2 -2 1  0 0",
                                    "0 0 -2 1  -2 -3 4 0  1 2"), (1, "z3", 2)),
    (["w1", "z3", "z4", "z0"], rows("1 -2 0 1  -2 1 0 0  0 3",
                                    "0 1/2 -1/2 0  -1/2 -3/2 1 0  0 0",
                                    "0 1 0 -1  0 -1 0 1  0 0",
                                    "0 -2 0 1  0 3 0 0  1 2"), (3, "z2", 3)),
    (["w1", "z3", "z4", "z2"], rows("1 -4/3 0 2/3  -2 0 0 0  -1/3 7/3",
                                    "0 -1/2 -1/2 1/2  -1/2 0 1 0  1/2 1",
                                    "0 1/3 0 -2/3  0 0 0 1  1/3 2/3",
                                    "0 -2/3 0 1/3  0 1 0 0  1/3 2/3"), None),
]


def trace_of(M: np.ndarray, q: np.ndarray) -> list[dict]:
    out = lemke_traced(M, q, np.ones(len(q)), 100, PIVOT_TOL, TIE_TOL)
    return out[-1]


@pytest.mark.parametrize("M, q, steps", [(CPS_M, CPS_Q, CPS_STEPS), (DEG_M, DEG_Q, DEG_STEPS)],
                         ids=["cps-4.4.7", "degenerate-4x4"])
def test_murty_layout_matches_hand_computed_tableaux(M, q, steps):
    trace = trace_of(M, q)
    assert len(trace) == len(steps)
    n = len(q)
    names = [f"w{i + 1}" for i in range(n)] + [f"z{i + 1}" for i in range(n)] + ["z0", "q"]
    for k, (basis, table, pivot) in enumerate(steps):
        nxt = trace[k + 1]["pivot_element"] if k + 1 < len(trace) else None
        view = tableau_view(trace[k], "murty", nxt)
        assert view.rows == basis, k
        assert view.columns == names  # the original order, at every step
        np.testing.assert_allclose(view.values, table, atol=1e-12, err_msg=f"step {k}")
        if pivot is None:
            assert nxt is None and view.pivot is None
        else:
            r, var, value = pivot
            assert view.pivot == (r, names.index(var)), k
            assert view.values[view.pivot] == pytest.approx(value)  # boxed = Murty's pivot
            assert -nxt["value"] == pytest.approx(value)  # JSON: the dictionary's sign


def test_seed000_state_is_the_seed_basis_in_both_layouts():
    trace = trace_of(CPS_M, CPS_Q)
    st = trace[3]
    assert st["basis"] == ["z0", "w2", "z3"] and st["q_prime"] == [1, 5, 1]
    assert st["next_entering"] == "w1"
    d = tableau_view(st, "dictionary", trace[4]["pivot_element"])
    assert d.columns == ["q'", "w1", "w3", "z1", "z2"]  # nonbasic, original order
    np.testing.assert_allclose(d.values[:, d.columns.index("z2")], [-1, -3, 1])  # seed's column
    m = tableau_view(st, "murty")
    np.testing.assert_allclose(m.values[:, m.columns.index("z2")], [1, 3, -1])  # opposite sign


def test_degenerate_lexicographic_step_records_the_compared_rows():
    trace = trace_of(DEG_M, DEG_Q)
    assert [s["rule"] for s in trace] == ["start", "initial", "lexicographic", "min_ratio",
                                          "min_ratio"]
    lex = trace[2]["lexicographic"]
    assert [r["row"] for r in lex["rows"]] == [2, 3]
    # the rows of B^-1 are the w columns of the hand-computed Murty tableau of step 1
    w_cols = DEG_STEPS[1][1][:, :4]
    for r in lex["rows"]:
        np.testing.assert_allclose(r["binv_row"], w_cols[r["row"] - 1])
    assert [c["variable"] for c in lex["compared"]] == ["w1", "w2"]
    assert lex["compared"][0]["kept"] == [2, 3] and lex["compared"][1]["kept"] == [3]
    assert lex["decided_by"] == "w2" and trace[2]["leaving"] == "w3"
    # the initial 3-way tie: the last row wins
    assert trace[1]["ratio_test"]["tied_rows"] == [1, 2, 3] and trace[1]["row"] == 4


def test_every_step_has_its_pivot_element_in_the_previous_tableau():
    rng = np.random.default_rng(8)
    for _ in range(40):
        n = int(rng.integers(2, 7))
        A = rng.integers(-2, 3, (n, n)).astype(float)
        M = A @ A.T + np.eye(n) if rng.random() < 0.5 else A
        q = rng.integers(-3, 3, n).astype(float)
        trace = trace_of(M, q)
        assert trace[0]["pivot"] == 0 and trace[0]["basis"] == [f"w{i + 1}" for i in range(n)]
        assert trace[0]["pivot_element"] is None
        for prev, st in zip(trace, trace[1:], strict=False):
            if st["rule"] == "ray":
                assert st["pivot_element"] is None and st["leaving"] is None
                assert not any(r["eligible"] for r in st["ratio_test"]["rows"])
                continue
            pe = st["pivot_element"]
            assert pe["row"] == st["row"] and pe["column"] == st["entering"]
            T = np.array(prev["tableau"])
            assert T[pe["row"] - 1, prev["nonbasic"].index(pe["column"])] == pe["value"]
            # a blocking entry of the dictionary column; the first pivot is on d_i > 0
            assert pe["value"] > 0 if st["rule"] == "initial" else pe["value"] < 0
            # every row of the ratio test is listed, with a ratio or a reason
            rows_ = st["ratio_test"]["rows"]
            assert [r["row"] for r in rows_] == list(range(1, n + 1))
            assert all(r["ratio"] is not None or r["why"] for r in rows_)
            # columns stay in the original variable order
            keys = [canonical_key(v) for v in st["nonbasic"]]
            assert keys == sorted(keys)
            # the complementary rule
            if st["pivot"] >= 2:
                left = prev["leaving"]
                assert st["entering"] == ("z" if left[0] == "w" else "w") + left[1:]
                assert f"because {left} left" in st["entering_reason"]


def test_trivial_problem_has_only_the_initial_tableau():
    trace = trace_of(np.eye(2), np.array([1.0, 0.0]))
    assert len(trace) == 1 and trace[0]["next_entering"] is None and "q >= 0" in \
        trace[0]["reason"]


def test_layouts_are_the_same_system():
    """Both layouts of a state describe the solutions of w - M z - d z0 = q."""
    trace = trace_of(CPS_M, CPS_Q)
    Maug = augment(CPS_M)
    for st in trace:
        for layout in LAYOUTS:
            assert tableau_view(st, layout) is not None
        m = tableau_view(st, "murty")
        # Murty's tableau is B^-1 [I, -Maug | q]: check with the basis matrix
        cols = {f"w{i + 1}": np.eye(3)[:, i] for i in range(3)}
        cols |= {f"z{j + 1}": -Maug[:, j] for j in range(3)} | {"z0": -Maug[:, 3]}
        B = np.column_stack([cols[b] for b in st["basis"]])
        full = np.column_stack([cols[v] for v in m.columns[:-1]] + [CPS_Q])
        np.testing.assert_allclose(m.values, np.linalg.solve(B, full), atol=1e-12)


# ------------------------------------------------------------------------ pivot --driving
def test_driving_ratio_test_on_the_seed_basis():
    Maug = augment(CPS_M)
    t = principal_pivot(Maug, CPS_Q, parse_tuple("z4,w2,z3", 3), parse_tuple("w1,w3,z2,z1", 3),
                        driving=parse_var("z2", 3))
    step = driving_step(t, Maug)
    assert step["blocking"] == "z0" and step["row"] == 1 and step["min_ratio"] == 1
    assert [r["ratio"] for r in step["rows"]] == [1, pytest.approx(5 / 3), None]
    assert "grows" in step["rows"][2]["why"] and step["next_entering"] is None
    t = principal_pivot(Maug, CPS_Q, parse_tuple("z0,w2,z3", 3), driving=parse_var("w1", 3))
    step = driving_step(t, Maug)
    assert step["blocking"] == "w2" and step["next_entering"] == "z2"
    assert step["next_dependent"] == ["z0", "w1", "z3"]


@pytest.mark.parametrize("M, q", [(CPS_M, CPS_Q), (DEG_M, DEG_Q)])
def test_follow_walks_lemkes_path(M, q):
    n = len(q)
    items = follow(augment(M), q, parse_tuple(",".join(f"w{i + 1}" for i in range(n)), n), None,
                   parse_var("z0", n))
    trace = trace_of(M, q)
    assert [t.names(t.dependent) for t, _ in items] == [s["basis"] for s in trace]
    assert [s["blocking"] for _, s in items[:-1]] == [s["leaving"] for s in trace[1:]]
    assert items[-1][1] is None and items[-1][0].driving is None  # the solution's basis
    for (t, _), st in zip(items, trace, strict=True):
        np.testing.assert_allclose(t.q_prime, st["q_prime"], atol=1e-12)


def test_random_follow_agrees_with_the_trace():
    rng = np.random.default_rng(12)
    for _ in range(30):
        n = int(rng.integers(2, 7))
        A = rng.standard_normal((n, n))
        M, q = A @ A.T + 0.1 * np.eye(n), rng.standard_normal(n)
        if q.min() >= 0:
            continue
        items = follow(augment(M), q, tuple(("w", i) for i in range(n)), None, ("z", n))
        trace = trace_of(M, q)
        assert [s["blocking"] for _, s in items if s] == [s["leaving"] for s in trace[1:]]
        assert [t.names(t.dependent) for t, _ in items] == [s["basis"] for s in trace]


def test_sample_file_is_the_degenerate_example(samples):
    from lcpcli.io import load

    prob = load(samples / "degenerate_lex.json")
    np.testing.assert_array_equal(prob.dense_M(), DEG_M)
    np.testing.assert_array_equal(prob.q, DEG_Q)


def test_path_points_seed004():
    M, q = np.array([[2.0, 1], [1, 2]]), np.array([-5.0, -6])
    pts = path_points(trace_of(M, q), q)
    assert [p["step"] for p in pts] == [0, 1, 2, 3]
    assert [p["z0"] for p in pts] == [0, 6, 4, 0]
    np.testing.assert_allclose(pts[1]["point"], [1, 0])  # on the boundary of Pos(I)
    np.testing.assert_allclose(pts[-1]["point"], q)


# ------------------------------------------------------------------------ the replicas
def test_status_codes_agree_with_the_kernels():
    from lcpcli.solvers.kernels import dantzig as kd
    from lcpcli.solvers.kernels import lemke as kl
    from lcpcli.solvers.kernels import murty as km
    from lcpcli.solvers.kernels import pgs as kp
    from lcpcli.solvers.trace import dantzig as td
    from lcpcli.solvers.trace import lemke as tl
    from lcpcli.solvers.trace import murty as tm
    from lcpcli.solvers.trace import pgs as tp

    for a, b, names in [(kl, tl, "OK RAY MAX_ITER TRIVIAL"), (km, tm, "OK LIMIT BAD_PIVOT"),
                        (kd, td, "OK UNBOUNDED MAX_ITER SINGULAR FREE CLAMPED AT_LOWER "
                                 "AT_UPPER FIXED"), (kp, tp, "CONVERGED LIMIT DIVERGED")]:
        for name in names.split():
            assert getattr(a, name) == getattr(b, name), name


def test_replicas_import_no_kernel():
    import subprocess
    import sys

    code = ("import sys, lcpcli.solvers.trace.lemke, lcpcli.solvers.trace.murty, "
            "lcpcli.solvers.trace.dantzig, lcpcli.solvers.trace.pgs, lcpcli.solvers.trace.path;"
            "print(sorted(m for m in sys.modules if 'kernels' in m or m == 'numba'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def random_problems(seed: int, count: int, box: bool = False):
    rng = np.random.default_rng(seed)
    for trial in range(count):
        n = int(rng.integers(1, 16))
        A = rng.standard_normal((n, n))
        kind = trial % 4
        if kind == 0:
            M = A @ A.T + 0.1 * np.eye(n)
        elif kind == 1:
            M = A - A.T + 0.5 * np.eye(n)
        elif kind == 2:
            B = rng.integers(-2, 3, (n, n)).astype(float)
            M = B @ B.T + np.eye(n)
        else:
            M = A @ A.T
        q = rng.standard_normal(n) if kind < 2 else rng.integers(-2, 2, n).astype(float)
        lo, up = np.zeros(n), np.full(n, np.inf)
        if box and trial % 2:
            lo, up = -rng.uniform(0, 1, n), rng.uniform(0, 1, n)
            lo[rng.random(n) < 0.2] = -np.inf
            up[rng.random(n) < 0.2] = np.inf
        yield M, q, lo, up


def test_murty_replica_makes_the_kernels_pivots():
    from lcpcli.solvers.kernels.murty import murty_kernel
    from lcpcli.solvers.methods.murty import NEG_TOL
    from lcpcli.solvers.methods.murty import PIVOT_TOL as MT
    from lcpcli.solvers.trace.murty import murty_traced

    for M, q, _, _ in random_problems(1, 120):
        n = len(q)
        b1, b2 = np.arange(n), np.arange(n)
        a = murty_kernel(M, q, 5000, MT, NEG_TOL, b1)
        b = murty_traced(M, q, 5000, MT, NEG_TOL, b2)
        assert a[0] == b[0] and a[2] == b[2] and a[3] == b[3]
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(b1, b2)  # same final basis
        assert len(b[4]) == b[2] + 1 + (b[0] == 2)  # start + one per pivot (+ the refusal)
        for prev, st in zip(b[4], b[4][1:], strict=False):
            if st["rule"] == "least_index":
                T = np.array(prev["tableau"]) if n <= 8 else None
                pe = st["pivot_element"]
                if T is not None:
                    assert T[pe["row"] - 1, prev["nonbasic"].index(pe["column"])] == pe["value"]
                assert min(r for r, v in enumerate(prev["q_prime"], 1) if v < 0) == st["row"]


def test_murty_replica_on_murtys_exponential_family():
    from lcpcli.solvers.kernels.murty import murty_kernel
    from lcpcli.solvers.methods.murty import NEG_TOL
    from lcpcli.solvers.methods.murty import PIVOT_TOL as MT
    from lcpcli.solvers.trace.murty import murty_traced

    n = 6
    M = np.eye(n) + 2 * np.tril(np.ones((n, n)), -1)
    q = -np.ones(n)
    a = murty_kernel(M, q, 5000, MT, NEG_TOL, np.arange(n))
    b = murty_traced(M, q, 5000, MT, NEG_TOL, np.arange(n))
    assert a[2] == b[2] and a[0] == b[0] == 0
    np.testing.assert_array_equal(a[1], b[1])


def test_dantzig_replica_makes_the_kernels_pivots():
    from lcpcli.solvers.kernels.dantzig import dantzig_kernel
    from lcpcli.solvers.methods.dantzig import processing_order
    from lcpcli.solvers.trace.dantzig import dantzig_traced

    for M, q, lo, up in random_problems(2, 120, box=True):
        order = processing_order(lo, up)
        a = dantzig_kernel(M, q, lo, up, order, 5000)
        b = dantzig_traced(M, q, lo, up, order, 5000)
        assert a[0] == b[0] and a[2] == b[2]
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(a[3], b[3])
        assert sum(1 for s in b[4] if s["step"] is not None) == b[2]  # one entry per pivot


def test_dantzig_replica_through_refactorisations():
    """More than 64 + |C| block updates: the replica refactorises like the kernel."""
    from lcpcli.solvers.kernels.dantzig import dantzig_kernel
    from lcpcli.solvers.methods.dantzig import processing_order
    from lcpcli.solvers.trace.dantzig import dantzig_traced

    rng = np.random.default_rng(5)
    n = 90
    A = rng.standard_normal((n, n))
    M, q = A @ A.T / n + np.eye(n), rng.standard_normal(n)
    lo, up = np.zeros(n), np.full(n, np.inf)
    a = dantzig_kernel(M, q, lo, up, processing_order(lo, up), 5000)
    b = dantzig_traced(M, q, lo, up, processing_order(lo, up), 5000)
    assert a[0] == b[0] == 0 and a[2] == b[2] > 64
    np.testing.assert_array_equal(a[1], b[1])


@pytest.mark.parametrize("omega", [1.0, 1.3])
def test_pgs_replica_makes_the_kernels_sweeps(omega):
    import scipy.sparse as sp

    from lcpcli.solvers.kernels import pgs as K
    from lcpcli.solvers.trace.pgs import FIRST_SWEEPS, pgs_traced

    for M, q, lo, up in random_problems(3, 60, box=True):
        n = len(q)
        M = M + np.diag(np.abs(M).sum(axis=1))  # diagonally dominant: PGS converges
        diag = np.diag(M).copy()
        mu, qn = float(np.max(np.abs(M).sum(axis=1))), float(np.max(np.abs(q)))
        for sparse in (False, True):
            z1, z2 = np.zeros(n), np.zeros(n)
            if sparse:
                A = sp.csr_matrix(M)
                a = K.pgs_csr(A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data, q,
                              diag, lo, up, z1, omega, 500, 1e-10, mu, qn)
                b = pgs_traced(A, q, diag, lo, up, z2, omega, 500, 1e-10, mu, qn)
            else:
                a = K.pgs_dense(M, q, diag, lo, up, z1, omega, 500, 1e-10, mu, qn)
                b = pgs_traced(M, q, diag, lo, up, z2, omega, 500, 1e-10, mu, qn)
            assert a[0] == b[0] and a[1] == b[1]
            np.testing.assert_array_equal(z1, z2)
            sweeps = [s["sweep"] for s in b[3]]
            assert sweeps[0] == 0 and sweeps[-1] == a[1]
            assert sweeps[1:-1] == list(range(1, min(FIRST_SWEEPS, a[1] - 1) + 1))


def test_methods_with_trace_return_the_kernels_answer():
    rng = np.random.default_rng(9)
    n = 6
    A = rng.standard_normal((n, n))
    prob = Problem.create(A @ A.T + np.eye(n), rng.standard_normal(n))
    for method in ("lemke-tableau", "lemke-revised", "murty", "dantzig", "pgs", "psor"):
        plain = solve(prob, method)
        traced = solve(prob, method, trace=True)
        assert traced.iterations == plain.iterations, method
        np.testing.assert_array_equal(traced.z, plain.z, err_msg=method)
        assert traced.status == plain.status == "solved"
        assert traced.trace and traced.trace[0]["kind"] in ("lemke", "principal", "dantzig",
                                                             "sweep")
