"""The seed 000 principal pivoting transform, ``lcpcli pivot``, ``solve --trace`` and the
revised Lemke method.

Numbers are checked by substitution into ``w = q + M z`` and against an independent dense
reference (the inverse of the basis matrix of ``[I, -Maug] (w, z) = q``), not only literals.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from lcpcli.analysis.pivoting import (
    all_vars,
    augment,
    parse_tuple,
    parse_var,
    principal_pivot,
)
from lcpcli.core.errors import ProblemError

SEED_M = np.array([[0, -1, 2, 1], [2, 0, -2, 1], [-1, 1, 0, 1]], dtype=float)
SEED_Q = np.array([-3, 6, -1], dtype=float)
SEED_DEP = "z4,w2,z3"
SEED_IND = "w1,w3,z2,z1"


def seed_transform(**kw):
    n = 3
    return principal_pivot(SEED_M, SEED_Q, parse_tuple(SEED_DEP, n), parse_tuple(SEED_IND, n),
                           **kw)


def assemble(t, xprime: np.ndarray, wprime: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Original (w, z) from the values of the pivoted tuples."""
    n = t.n
    w, z = np.full(n, np.nan), np.full(n + 1, np.nan)
    for vals, tup in ((wprime, t.dependent), (xprime, t.independent)):
        for v, (kind, idx) in zip(vals, tup, strict=True):
            (w if kind == "w" else z)[idx] = v
    assert not np.isnan(w).any() and not np.isnan(z).any()
    return w, z


def check_by_substitution(t, M: np.ndarray, q: np.ndarray, rng: np.random.Generator) -> None:
    """Any z' with w' = q' + M' z' must satisfy w = q + M z (checks q' and every column)."""
    for _ in range(3):
        x = rng.standard_normal(t.n + 1)
        wp = t.q_prime + t.full @ x
        w, z = assemble(t, x, wp)
        np.testing.assert_allclose(w, q + M @ z, atol=1e-9 * (1 + np.abs(w).max()))


def dense_reference(M: np.ndarray, q: np.ndarray, dep, ind) -> tuple[np.ndarray, np.ndarray]:
    """q' and M' from the inverse of the basis matrix of [I, -M] (w; z) = q."""
    n = q.shape[0]
    A = np.hstack([np.eye(n), -M])
    col = {("w", i): i for i in range(n)} | {("z", j): n + j for j in range(n + 1)}
    Binv = np.linalg.inv(A[:, [col[v] for v in dep]])
    N = A[:, [col[v] for v in ind]]
    return Binv @ q, -Binv @ N


# --------------------------------------------------------------------------- seed example
def test_seed_index_sets_and_q_prime():
    t = seed_transform()
    d = t.to_dict()
    assert d["alpha"] == [1, 3] and d["alpha_prime"] == [1, 2]
    assert d["beta"] == [3, 4] and d["beta_prime"] == [3, 1]
    assert d["alpha_bar"] == [2] and d["alpha_bar_prime"] == [2]
    assert d["beta_bar"] == [1, 2] and d["beta_bar_prime"] == [4, 3]
    np.testing.assert_array_equal(t.M_ab, [[2, 1], [0, 1]])
    np.testing.assert_array_equal(t.M_abar_b, [[-2, 1]])
    np.testing.assert_array_equal(t.q_a, [-3, -1])
    np.testing.assert_array_equal(t.q_abar, [6])
    np.testing.assert_allclose(t.q_prime, [1, 5, 1])
    # q' by substitution: z' = 0 gives z3 = 1, z4 = 1, w2 = 5 and w = q + M z holds
    w, z = assemble(t, np.zeros(4), t.q_prime)
    np.testing.assert_allclose(w, SEED_Q + SEED_M @ z)


def test_seed_driving_z2_and_w1():
    t = seed_transform(driving=parse_var("z2", 3))
    assert t.driving_case == "z"
    np.testing.assert_allclose(t.g_alpha, [-1, 1])
    np.testing.assert_allclose(t.g_alpha_bar, [0])
    np.testing.assert_allclose(t.driving_column, [-1, -3, 1])  # z4 falls, w2 falls by 3, z3 rises
    t = seed_transform(driving=parse_var("w1", 3))
    assert t.driving_case == "w"
    # seeds guide: M'_driving^{beta'} = (0.5, 0), M'_driving^{alpha-bar'} = (-1); w' = (z4, w2, z3)
    np.testing.assert_allclose(t.driving_column, [0, -1, 0.5])


@pytest.mark.parametrize("name", ["w1", "w3", "z2", "z1"])
def test_seed_every_driving_variable_by_substitution(name):
    t = seed_transform(driving=parse_var(name, 3))
    k = t.names(t.independent).index(name)
    for step in (0.5, 2.0):
        x = np.zeros(4)
        x[k] = step  # only the driving variable moves away from 0
        wp = t.q_prime + step * t.driving_column
        w, z = assemble(t, x, wp)
        np.testing.assert_allclose(w, SEED_Q + SEED_M @ z, atol=1e-12)


def test_seed_full_tableau_matches_reference():
    t = seed_transform(full=True)
    qp, Mp = dense_reference(SEED_M, SEED_Q, t.dependent, t.independent)
    np.testing.assert_allclose(t.q_prime, qp, atol=1e-12)
    np.testing.assert_allclose(t.full, Mp, atol=1e-12)
    check_by_substitution(t, SEED_M, SEED_Q, np.random.default_rng(0))


def test_z0_alias_and_default_independent_order():
    n = 3
    t = principal_pivot(SEED_M, SEED_Q, parse_tuple("z0,w2,z3", n))
    assert t.names(t.independent) == ["w1", "w3", "z1", "z2"]
    np.testing.assert_allclose(t.q_prime, [1, 5, 1])


# --------------------------------------------------------------------------- random bases
def random_basis(n: int, rng: np.random.Generator):
    """A random (almost) complementary basis in random order."""
    gap = int(rng.integers(0, n + 1))  # == n: z0 nonbasic (complementary basis)
    dep = [("z", n)] if gap < n else []
    for i in range(n):
        if i != gap:
            dep.append(("w", i) if rng.random() < 0.5 else ("z", i))
    if gap == n:
        dep = dep[:n]
    dep = [dep[k] for k in rng.permutation(len(dep))]
    ind = [v for v in all_vars(n) if v not in dep]
    ind = [ind[k] for k in rng.permutation(len(ind))]
    return tuple(dep), tuple(ind)


def test_random_bases_against_dense_reference():
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(60):
        n = int(rng.integers(1, 9))
        Maug = augment(rng.standard_normal((n, n)), rng.uniform(0.5, 2, n))
        q = rng.standard_normal(n)
        dep, ind = random_basis(n, rng)
        if len(dep) != n:
            continue
        t = principal_pivot(Maug, q, dep, ind, full=True,
                            driving=ind[int(rng.integers(0, n + 1))])
        qp, Mp = dense_reference(Maug, q, dep, ind)
        scale = 1 + np.abs(Mp).max()
        np.testing.assert_allclose(t.q_prime, qp, atol=1e-9 * scale * (1 + np.abs(qp).max()))
        np.testing.assert_allclose(t.full, Mp, atol=1e-9 * scale ** 2)
        np.testing.assert_allclose(t.driving_column, t.full[:, ind.index(t.driving)],
                                   atol=1e-12 * scale)
        check_by_substitution(t, Maug, q, rng)
        # the index-set invariants of the seed
        for i, p in zip(t.alpha, t.alpha_prime, strict=True):
            assert t.independent[p] == ("w", i)
        for j, p in zip(t.beta, t.beta_prime, strict=True):
            assert t.dependent[p] == ("z", j)
        for i, p in zip(t.alpha_bar, t.alpha_bar_prime, strict=True):
            assert t.dependent[p] == ("w", i)
        for j, p in zip(t.beta_bar, t.beta_bar_prime, strict=True):
            assert t.independent[p] == ("z", j)
        checked += 1
    assert checked >= 40


@pytest.mark.parametrize("dep, ind, needle", [
    ("z4,w2", None, "expected n = 3"),
    ("z4,w2,z4", None, "twice"),
    ("z4,w2,x3", None, "unknown variable"),
    ("z5,w2,z3", None, "out of range"),
    ("w1,z1,w2", None, "both w1 and z1"),
    ("z4,w2,z3", "w1,w3,z2", "expected n + 1"),
    ("z4,w2,z3", "w1,w3,z2,z4", "both the dependent and the independent"),
])
def test_bad_bases_raise(dep, ind, needle):
    with pytest.raises(ProblemError, match=re.escape(needle)):
        principal_pivot(SEED_M, SEED_Q, parse_tuple(dep, 3),
                        None if ind is None else parse_tuple(ind, 3))


def test_singular_block_raises():
    Maug = augment(np.ones((2, 2)))
    with pytest.raises(ProblemError, match="singular"):
        principal_pivot(Maug, np.array([-1.0, -1.0]), parse_tuple("z1,z2", 2))


# --------------------------------------------------------------------------- CLI
def test_cli_pivot_json_seed(cli, samples):
    p = cli("pivot", str(samples / "seed000_augmented.json"), "--dependent", SEED_DEP,
            "--independent", SEED_IND, "--driving", "z2", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    for key in ("alpha", "alpha_prime", "beta", "beta_prime", "alpha_bar", "alpha_bar_prime",
                "beta_bar", "beta_bar_prime", "q_prime", "driving_column", "dependent",
                "independent"):
        assert key in d
    assert d["q_prime"] == [1, 5, 1]
    assert d["driving_column"] == [-1, -3, 1]
    # one name for the artificial variable: z0 (the input said z4, its seed position)
    assert d["dependent"] == ["z0", "w2", "z3"] and d["beta"] == [3, 4]
    assert d["independent"] == ["w1", "w3", "z2", "z1"]
    p = cli("pivot", str(samples / "seed000_augmented.json"), "-d", SEED_DEP, "--json")
    assert json.loads(p.stdout)["driving_column"] is None


def test_cli_pivot_covering_square_file(cli, tmp_path):
    f = tmp_path / "cps2.json"
    f.write_text(json.dumps({"M": SEED_M[:, :3].tolist(), "q": SEED_Q.tolist()}))
    p = cli("pivot", str(f), "-d", SEED_DEP, "-i", SEED_IND, "--driving", "w1", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert d["q_prime"] == [1, 5, 1] and d["driving_column"] == [0, -1, 0.5]
    p = cli("pivot", str(f), "-d", SEED_DEP, "--covering", "2,2,2", "--json")
    assert p.returncode == 0, p.stderr
    # with d = 2 e: z4 = 0.5, w2 = 5, z3 = 1; check by substitution into w = q + [M, d] z
    qp = json.loads(p.stdout)["q_prime"]
    assert qp == pytest.approx([0.5, 5, 1])
    z = np.array([0, 0, qp[2], qp[0]])
    w = SEED_Q + augment(SEED_M[:, :3], np.full(3, 2.0)) @ z
    assert w[0] == pytest.approx(0) and w[2] == pytest.approx(0) and w[1] == pytest.approx(qp[1])


def test_cli_pivot_text_full(cli, samples):
    p = cli("pivot", str(samples / "seed000_augmented.json"), "-d", SEED_DEP, "-i", SEED_IND,
            "--driving", "z2", "--full", env={"NO_COLOR": "1", "COLUMNS": "120"})
    assert p.returncode == 0, p.stderr
    for text in ("alpha-bar'", "{3, 1}", "eqs 7 and 8", "pivoted tableau", "falls by 3"):
        assert text in p.stdout


@pytest.mark.parametrize("args, needle", [
    (["-d", "z4,w2"], "expected n = 3"),
    (["-d", "z4,w2,w2"], "twice"),
    (["-d", "z4,w2,q1"], "unknown variable"),
    (["-d", "w1,z1,z3"], "both w1 and z1"),
    (["-d", SEED_DEP, "--driving", "z4"], "not independent"),
    (["-d", SEED_DEP, "--covering", "1,1,1"], "drop --covering"),
])
def test_cli_pivot_bad_input_exit_2(cli, samples, args, needle):
    p = cli("pivot", str(samples / "seed000_augmented.json"), *args)
    assert p.returncode == 2
    assert needle in p.stderr
    assert "Traceback" not in p.stderr + p.stdout
    assert p.stdout == ""


def test_cli_pivot_singular_exit_2(cli, tmp_path):
    f = tmp_path / "sing.json"
    f.write_text(json.dumps({"M": [[1, 1], [1, 1]], "q": [-1, -1]}))
    p = cli("pivot", str(f), "-d", "z1,z2")
    assert p.returncode == 2 and "singular" in p.stderr and "Traceback" not in p.stderr


# --------------------------------------------------------------------------- trace
def kernel_record(M, q, limit=5000):
    from lcpcli.solvers.kernels.lemke import lemke_kernel
    from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL

    rec = np.full((limit, 3), -1, dtype=np.int64)
    out = lemke_kernel(M, q, np.ones(len(q)), limit, PIVOT_TOL, TIE_TOL, rec)
    return out, rec[: out[2]]


def trace_codes(trace, n):
    def code(name):
        if name == "z0":
            return 2 * n
        return int(name[1:]) - 1 + (n if name[0] == "z" else 0)

    return np.array([[code(s["entering"]), code(s["leaving"]), s["row"] - 1] for s in trace
                     if s["pivot"] >= 1 and s["leaving"] is not None],
                    dtype=np.int64).reshape(-1, 3)


def test_trace_seed004(cli, samples):
    p = cli("solve", str(samples / "seed004.json"), "--trace", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    start, *tr = d["trace"]
    assert start["pivot"] == 0 and start["basis"] == ["w1", "w2"]
    assert start["nonbasic"] == ["z1", "z2", "z0"] and start["q_prime"] == [-5, -6]
    assert start["tableau"] == [[2, 1, 1], [1, 2, 1]] and start["next_entering"] == "z0"
    assert [(s["entering"], s["leaving"]) for s in tr] == [("z0", "w2"), ("z2", "w1"),
                                                           ("z1", "z0")]
    for s in tr:
        assert {"pivot", "entering", "leaving", "basis", "q_prime"} <= set(s)
    assert [s["pivot"] for s in tr] == [1, 2, 3]
    assert tr[0]["basis"] == ["w1", "z0"] and tr[0]["q_prime"] == [1, 6]
    assert tr[-1]["basis"] == ["z2", "z1"]
    assert tr[-1]["q_prime"] == pytest.approx([7 / 3, 4 / 3])
    assert d["z"] == pytest.approx([4 / 3, 7 / 3])
    # each recorded tableau is the seed 000 transform of the recorded basis
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    for s in tr:
        t = principal_pivot(augment(M), np.array([-5.0, -6.0]),
                            parse_tuple(s["basis"], 2), parse_tuple(s["nonbasic"], 2), full=True)
        np.testing.assert_allclose(t.q_prime, s["q_prime"], atol=1e-12)
        np.testing.assert_allclose(t.full, s["tableau"], atol=1e-12)
    text = cli("solve", str(samples / "seed004.json"), "--trace",
               env={"NO_COLOR": "1", "COLUMNS": "120"})
    assert text.returncode == 0
    assert "Step 3: after pivot 3: z1 entered, z0 left" in text.stdout
    assert "Ratio test" in text.stdout and "z0 leaves (row 2)" in text.stdout


def test_trace_matches_kernel_on_siconos_files(siconos):
    from lcpcli.io import load
    from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL
    from lcpcli.solvers.trace.lemke import lemke_traced

    files = sorted((siconos / "lcp").glob("*.dat"))
    assert files
    for f in files:
        prob = load(f)
        M = np.ascontiguousarray(prob.dense_M())
        out, rec = kernel_record(M, prob.q)
        tout = lemke_traced(M, prob.q, np.ones(prob.n), 5000, PIVOT_TOL, TIE_TOL)
        assert tout[0] == out[0] and tout[2] == out[2], f.name
        np.testing.assert_array_equal(trace_codes(tout[-1], prob.n), rec, err_msg=f.name)
        np.testing.assert_array_equal(tout[1], out[1], err_msg=f.name)


def test_trace_matches_kernel_on_degenerate_integer_problems():
    from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL
    from lcpcli.solvers.trace.lemke import lemke_traced

    rng = np.random.default_rng(3)
    rules = set()
    for _ in range(150):
        n = int(rng.integers(2, 9))
        M = rng.integers(-2, 3, (n, n)).astype(float)
        if rng.random() < 0.5:
            M = M @ M.T  # PSD, many ties
        q = rng.integers(-2, 2, n).astype(float)  # many zeros and repeated values
        out, rec = kernel_record(M, q)
        tout = lemke_traced(M, q, np.ones(n), 5000, PIVOT_TOL, TIE_TOL)
        assert tout[0] == out[0] and tout[2] == out[2]
        np.testing.assert_array_equal(trace_codes(tout[-1], n), rec)
        rules |= {s["rule"] for s in tout[-1]}
    assert {"initial", "min_ratio", "lexicographic"} <= rules


def test_trace_large_n_has_columns_not_tableau():
    from lcpcli.api import solve
    from lcpcli.core.problem import Problem

    rng = np.random.default_rng(5)
    n = 12
    A = rng.standard_normal((n, n))
    M, q = A @ A.T + np.eye(n), rng.standard_normal(n) - 1
    res = solve(Problem.create(M, q), "lemke", trace=True)
    assert res.solved and len(res.trace) == res.iterations + 1
    assert all(s["tableau"] is None for s in res.trace)
    assert all(len(s["driving_column"]) == n for s in res.trace[:-1])
    assert res.trace[-1]["leaving"] == "z0" and res.trace[-1]["driving_column"] is None
    # the driving column is the seed 000 transform's column for the next entering variable
    for s in res.trace[:-1]:
        t = principal_pivot(augment(M), q, parse_tuple(s["basis"], n),
                            parse_tuple(s["nonbasic"], n),
                            driving=parse_var(s["next_entering"], n))
        np.testing.assert_allclose(t.driving_column, s["driving_column"], atol=1e-9)
        np.testing.assert_allclose(t.q_prime, s["q_prime"], atol=1e-9)


# --------------------------------------------------------------------------- revised Lemke
def test_revised_same_pivots_as_tableau_on_random_problems():
    from lcpcli.solvers.kernels.lemke_revised import lemke_revised_kernel
    from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL

    rng = np.random.default_rng(11)
    for trial in range(120):
        n = int(rng.integers(1, 25))
        A = rng.standard_normal((n, n))
        M = [A @ A.T + 0.1 * np.eye(n), A, A - A.T + 0.5 * np.eye(n)][trial % 3]
        q = rng.standard_normal(n)
        out, rec = kernel_record(M, q)
        rec2 = np.full((5000, 3), -1, dtype=np.int64)
        out2 = lemke_revised_kernel(M, q, np.ones(n), 5000, PIVOT_TOL, TIE_TOL, rec2,
                                    int(rng.integers(1, 30)))
        assert out2[0] == out[0] and out2[2] == out[2]
        np.testing.assert_array_equal(rec2[: out2[2]], rec)
        if out[0] == 0:
            np.testing.assert_allclose(out2[1], out[1], atol=1e-8 * (1 + np.abs(out[1]).max()))


def test_revised_same_pivots_on_degenerate_integer_problems():
    """Not required by the design (roundoff may legitimately split ties differently), but the
    refactorisation keeps degenerate zeros exact, so the sequences agree here too."""
    from lcpcli.solvers.kernels.lemke_revised import lemke_revised_kernel
    from lcpcli.solvers.methods.lemke import PIVOT_TOL, TIE_TOL

    rng = np.random.default_rng(4)
    for _ in range(150):
        n = int(rng.integers(2, 10))
        M = rng.integers(-2, 3, (n, n)).astype(float)
        if rng.random() < 0.5:
            M = M @ M.T
        q = rng.integers(-2, 2, n).astype(float)
        out, rec = kernel_record(M, q)
        rec2 = np.full((5000, 3), -1, dtype=np.int64)
        out2 = lemke_revised_kernel(M, q, np.ones(n), 5000, PIVOT_TOL, TIE_TOL, rec2,
                                    int(rng.integers(1, 6)))
        assert out2[0] == out[0]
        np.testing.assert_array_equal(rec2[: out2[2]], rec)


def test_revised_solves_what_tableau_solves(siconos):
    from lcpcli.api import solve
    from lcpcli.io import load

    for f in sorted((siconos / "lcp").glob("*.dat")) + sorted(
            (siconos / "fc2d_as_lcp").glob("*.npz")):
        prob = load(f)
        a = solve(prob, "lemke-tableau")
        for every in (1, 5, 1000):
            b = solve(prob, "lemke-revised", refactor_every=every)
            assert a.status == b.status, (f.name, every)
            assert a.iterations == b.iterations, (f.name, every)
            def head(message: str) -> str:  # the method's own words, before notes
                return message.split(" [")[0].split(";")[0].split(" (")[0]

            assert head(a.message) == head(b.message)
        if a.solved:
            assert b.error <= 1e-8


def test_revised_column_residual_detects_a_drifted_inverse():
    from lcpcli.solvers.kernels.lemke_revised import RESID_TOL, _column_residual

    Maug = np.array([[2.0, 1.0, 1.0], [1.0, 3.0, 1.0]])
    alpha = np.array([0, 1])
    beta = np.array([0, 2])  # z1 and the artificial column
    apos = np.array([0, 1])
    A = Maug[np.ix_(alpha, beta)]
    MT = np.ascontiguousarray(Maug.T)
    Ct = np.ascontiguousarray(Maug[:, beta].T)
    work = np.empty(2), np.empty(2)

    def resid(e, x):
        return _column_residual(MT, Ct, alpha, apos, 2, e, 2, x, *work)

    xb = -np.linalg.solve(A, Maug[alpha, 1])  # z2 (code n + 1) enters: A xb = -g^alpha
    assert resid(2 + 1, xb) < 1e-15
    assert resid(2 + 1, xb * (1 + 1e-6)) > RESID_TOL
    xw = np.linalg.solve(A, np.array([0.0, 1.0]))  # w2 (code 1) enters: A xb = e_2
    assert resid(1, xw) < 1e-15
    assert resid(1, xw + 1e-7) > RESID_TOL


def test_revised_cli_and_bad_option(cli, samples):
    p = cli("solve", str(samples / "seed004.json"), "-m", "lemke-revised", "--json")
    assert p.returncode == 0 and json.loads(p.stdout)["z"] == pytest.approx([4 / 3, 7 / 3])
    p = cli("solve", str(samples / "seed004.json"), "-m", "lemke-revised", "-O",
            "refactor_every=0")
    assert p.returncode == 2 and "Traceback" not in p.stderr


def test_sample_file_is_the_seed():
    d = json.loads((Path(__file__).resolve().parents[2] / "samples" /
                    "seed000_augmented.json").read_text())
    np.testing.assert_array_equal(d["M"], SEED_M)
    np.testing.assert_array_equal(d["q"], SEED_Q)
