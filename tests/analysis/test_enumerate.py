"""The enumeration method (seed 004): engine, solver method ``enum`` and ``lcpcli enumerate``."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

import lcpcli
from lcpcli.analysis.enumeration import (
    complementary_matrix,
    covers_plane,
    enumerate_cones,
)
from lcpcli.core.certificate import certify
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.problem import Problem
from lcpcli.io import load

SEED_M = [[2.0, 1.0], [1.0, 2.0]]
SEED_Q = [-5.0, -6.0]


def is_solution(M, q, z, tol=1e-9):
    """Independent check by substitution: z >= 0, w = Mz + q >= 0, z_i w_i = 0."""
    M, q, z = np.asarray(M), np.asarray(q), np.asarray(z)
    w = M @ z + q
    scale = 1.0 + np.max(np.abs(q)) + np.max(np.abs(M)) * np.max(np.abs(z))
    return bool(np.all(z >= -tol * scale) and np.all(w >= -tol * scale)
                and np.max(np.abs(z * w)) <= tol * scale * (1 + np.max(np.abs(z))))


def brute_force_solutions(M, q):
    """Reference: every subset S, z_S = -M_SS^-1 q_S (nonsingular blocks only), by numpy."""
    n = len(q)
    sols = []
    for k in range(n + 1):
        for S in itertools.combinations(range(n), k):
            z = np.zeros(n)
            if S:
                B = M[np.ix_(S, S)]
                if abs(np.linalg.det(B)) < 1e-9:
                    continue
                z[list(S)] = np.linalg.solve(B, -q[list(S)])
            if is_solution(M, q, z) and not any(np.allclose(z, s, atol=1e-8) for s in sols):
                sols.append(z)
    return sols


# ------------------------------------------------------------------------ seed 004
def test_seed004_table_and_solution(samples):
    p = load(samples / "seed004.json")
    res = enumerate_cones(p, all_cones=True)
    assert res.verdict == "unique" and res.status == "solved"
    assert len(res.solutions) == 1
    z = res.solutions[0].z
    np.testing.assert_allclose(z, [4 / 3, 7 / 3], atol=1e-14)
    np.testing.assert_allclose(res.solutions[0].w, [0, 0], atol=1e-14)
    # the seed's table, in its order r = 1..4
    assert [c.basis_names() for c in res.cones] == [["w1", "w2"], ["w1", "z2"], ["z1", "w2"],
                                                    ["z1", "z2"]]
    seed_tables = [[[1, 0], [0, 1]], [[1, -1], [0, -2]], [[-2, 0], [-1, 1]],
                   [[-2, -1], [-1, -2]]]
    M = np.array(SEED_M)
    for c, expect in zip(res.cones, seed_tables, strict=True):
        np.testing.assert_array_equal(complementary_matrix(M, c.code), expect)
        assert c.det == pytest.approx(np.linalg.det(np.array(expect, dtype=float)))
        assert c.rank == 2 and not c.singular
        # y solves A_r y = q in every nonsingular cone; feasible only in (z1, z2)
        np.testing.assert_allclose(np.array(expect) @ c.y, SEED_Q, atol=1e-12)
        assert c.feasible == (c.basis_names() == ["z1", "z2"])
        assert c.feasible == bool(np.all(c.y >= 0))
    assert covers_plane(M)


def test_seed004_cli_text(cli, samples):
    out = cli("enumerate", str(samples / "seed004.json"), "--no-exact")  # decimals (issue 27)
    assert out.returncode == 0, out.stderr
    assert "z1 = 1.33333" in out.stdout and "w1 = -5" not in out.stdout  # feasible cones only
    assert "unique solution" in out.stdout
    assert "K(M) = R^2" in out.stdout
    assert "1.33333" in out.stdout and "2.33333" in out.stdout
    out = cli("enumerate", str(samples / "seed004.json"), "--all-cones", "--no-exact")
    assert out.returncode == 0
    # the seed's four complementary matrices and y = A_r^-1 q in each cone
    for row in ("[1 0]", "[0 1]", "[ 1 -1]", "[ 0 -2]", "[-2  0]", "[-1  1]", "[-2 -1]",
                "[-1 -2]"):
        assert row in out.stdout
    for value in ("w1 = -5", "w2 = -6", "w1 = -2", "z2 = 3", "z1 = 2.5", "w2 = -3.5",
                  "z1 = 1.33333", "z2 = 2.33333"):
        assert value in out.stdout


def test_json_schema(cli, samples):
    out = cli("enumerate", str(samples / "seed004.json"), "--json", "--all-cones")
    assert out.returncode == 0 and out.stderr == ""
    data = json.loads(out.stdout)
    for key in ("n", "cones", "solutions", "status", "seconds", "verdict", "covers_plane"):
        assert key in data
    assert data["n"] == 2 and data["status"] == "solved" and data["verdict"] == "unique"
    assert data["covers_plane"] is True
    assert len(data["cones"]) == 4
    for cone in data["cones"]:
        assert set(cone) >= {"basis", "feasible", "singular", "y"}
        assert len(cone["basis"]) == 2
    assert [c["feasible"] for c in data["cones"]] == [False, False, False, True]
    (sol,) = data["solutions"]
    assert sol["z"] == pytest.approx([4 / 3, 7 / 3]) and sol["w"] == pytest.approx([0, 0])
    out = cli("enumerate", str(samples / "seed004.json"), "--json")
    assert [c["basis"] for c in json.loads(out.stdout)["cones"]] == [["z1", "z2"]]


# ------------------------------------------------------------------------ Siconos files
def test_cps3_three_solutions(siconos):
    p = load(siconos / "lcp" / "lcp_CPS_3.dat")
    res = enumerate_cones(p)
    assert res.verdict == "finite" and len(res.solutions) == 3
    M = p.dense_M()
    zs = [s.z for s in res.solutions]
    for z in zs:
        assert is_solution(M, p.q, z)
    for a, b in itertools.combinations(zs, 2):
        assert np.max(np.abs(a - b)) > 1e-3
    # same set as the independent brute force
    ref = brute_force_solutions(M, p.q)
    assert len(ref) == 3
    for z in ref:
        assert any(np.allclose(z, s, atol=1e-9) for s in zs)


def test_cps1_continuum(siconos, cli):
    p = load(siconos / "lcp" / "lcp_CPS_1.dat")
    res = enumerate_cones(p)
    assert res.verdict == "continuum"
    assert any(c.singular and c.continuum for c in res.cones)
    for s in res.solutions:  # M = ones, q = -1: z1 + z2 = 1
        assert s.z.sum() == pytest.approx(1.0) and is_solution(p.dense_M(), p.q, s.z)
    out = cli("enumerate", str(siconos / "lcp" / "lcp_CPS_1.dat"), "--json")
    assert out.returncode == 0 and json.loads(out.stdout)["verdict"] == "continuum"


def test_inf_sol_perturbed_is_a_ray(siconos):
    # z = (1, t, t + 1e-4) solves it for every t >= 0
    p = load(siconos / "lcp" / "lcp_inf_sol_perturbed.dat")
    for t in (0.0, 2.5):
        assert is_solution(p.dense_M(), p.q, np.array([1.0, t, t + 1e-4]))
    assert enumerate_cones(p).verdict == "continuum"


def test_pang_isolated_degenerate_solution(siconos):
    p = load(siconos / "lcp" / "lcp_Pang_isolated_sol.dat")
    res = enumerate_cones(p)
    assert res.verdict == "unique"
    np.testing.assert_allclose(res.solutions[0].z, [1, 0, 0], atol=1e-12)


def test_pang_perturbed_no_solution(siconos, cli):
    f = str(siconos / "lcp" / "lcp_Pang_isolated_sol_perturbed.dat")
    res = enumerate_cones(load(f))
    assert res.verdict == "none" and res.status == "no_solution" and not res.solutions
    out = cli("enumerate", f, "--json")
    assert out.returncode == 1
    data = json.loads(out.stdout)
    assert data["status"] == "no_solution" and data["solutions"] == []
    out = cli("solve", f, "--method", "enum", "--json")
    assert out.returncode == 1
    assert json.loads(out.stdout)["status"] == "no_solution"


@pytest.mark.parametrize("name", ["lcp_CPS_2.dat", "lcp_CPS_4.dat", "lcp_ortiz.dat",
                                  "lcp_exp_murty2.dat", "lcp_enum_fails.dat", "lcp_trivial.dat"])
def test_siconos_unique_matches_brute_force(siconos, name):
    p = load(siconos / "lcp" / name)
    res = enumerate_cones(p)
    ref = brute_force_solutions(p.dense_M(), p.q)
    assert len(res.solutions) == len(ref) == 1
    np.testing.assert_allclose(res.solutions[0].z, ref[0], atol=1e-9)


# ------------------------------------------------------------------------ random problems
def test_random_p_matrix_agrees_with_lemke():
    rng = np.random.default_rng(4)
    for trial in range(12):
        n = int(rng.integers(2, 11))
        A = rng.standard_normal((n, n))
        C = rng.standard_normal((n, n))
        M = A @ A.T + 0.1 * np.eye(n) + (C - C.T)  # positive definite, hence a P-matrix
        q = rng.standard_normal(n) * 3
        p = Problem.create(M, q)
        res = enumerate_cones(p)
        assert res.verdict == "unique", trial
        ref = lcpcli.solve(p, method="lemke")
        assert ref.status == "solved"
        np.testing.assert_allclose(res.solutions[0].z, ref.z, atol=1e-8 * (1 + np.abs(ref.z).max()))
        via = lcpcli.solve(p, method="enum")
        assert via.status == "solved"
        np.testing.assert_allclose(via.z, ref.z, atol=1e-8 * (1 + np.abs(ref.z).max()))


def test_random_general_matrices_match_brute_force():
    rng = np.random.default_rng(11)
    for _ in range(15):
        n = int(rng.integers(2, 7))
        M = rng.standard_normal((n, n))
        q = rng.standard_normal(n)
        res = enumerate_cones(Problem.create(M, q))
        ref = brute_force_solutions(M, q)
        assert len(res.solutions) == len(ref)
        for z in ref:
            assert any(np.allclose(z, s.z, atol=1e-8) for s in res.solutions)
        assert res.verdict == {0: "none", 1: "unique"}.get(len(ref), "finite")


def test_fast_kernel_agrees_with_direct_kernel():
    """The depth-first pivoting kernel against the LU-per-cone kernel, on hard structures:
    integer matrices (many singular minors), zero diagonals, low rank, wild column scaling."""
    rng = np.random.default_rng(5)
    for trial in range(60):
        n = int(rng.integers(6, 10))
        kind = trial % 5
        if kind == 0:
            M, q = rng.standard_normal((n, n)), rng.standard_normal(n)
        elif kind == 1:
            M = rng.integers(-2, 3, (n, n)).astype(float)
            q = rng.integers(-2, 3, n).astype(float)
        elif kind == 2:
            M, q = rng.standard_normal((n, n)), rng.standard_normal(n)
            np.fill_diagonal(M, 0.0)
        elif kind == 3:
            A = rng.standard_normal((n, 2))
            M, q = A @ A.T, rng.standard_normal(n)
        else:
            M = rng.standard_normal((n, n)) * np.logspace(-6, 6, n)
            q = rng.standard_normal(n)
        p = Problem.create(M, q)
        a = enumerate_cones(p, fast=True)
        b = enumerate_cones(p, fast=False)
        assert a.verdict == b.verdict and a.counts["feasible"] == b.counts["feasible"], trial
        assert [c.code for c in a.cones] == [c.code for c in b.cones]
        for s in a.solutions:
            assert certify(p, s.z).passed
            if kind != 4:  # wild scaling: the certificate's scaled units are the judge
                assert is_solution(M, q, s.z)


def test_lp_limit_and_zero_matrix(siconos):
    # M = 0, q = 0: every z >= 0 solves it; 1023 singular cones, but once the continuum is
    # known no more LPs are needed
    res = enumerate_cones(Problem.create(np.zeros((10, 10)), np.zeros(10)))
    assert res.verdict == "continuum" and res.counts["singular_unresolved"] == 1022
    # with no LP allowed, the degenerate cones stay unresolved and nothing is claimed
    p = load(siconos / "lcp" / "lcp_CPS_1.dat")
    res = enumerate_cones(p, max_lp=0)
    assert res.verdict == "incomplete" and res.status == "solved"
    p = Problem.create([[0.0, 0.0], [0.0, 1.0]], [0.0, -1.0])  # z = (t, 1), t >= 0
    assert enumerate_cones(p).verdict == "continuum"
    p = Problem.create([[0.0]], [0.0])
    assert enumerate_cones(p).verdict == "continuum"


def test_q_zero_degenerate_all_cones_one_solution():
    M = np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 2.0]])
    res = enumerate_cones(Problem.create(M, np.zeros(3)))
    assert res.counts["feasible"] == 8 and len(res.solutions) == 1
    assert res.verdict == "unique" and np.all(res.solutions[0].z == 0)
    assert len(res.solutions[0].cones) == 8


def test_stop_at_first_and_solver_message(samples):
    p = Problem.create(np.eye(6), np.ones(6))  # q >= 0: cone (w1..w6) is the first one
    res = enumerate_cones(p, stop_at_first=True)
    assert res.verdict == "found" and res.examined == 1 and not res.complete
    r = lcpcli.solve(p, method="enum")
    assert r.status == "solved" and "after 1 of 64 cones" in r.message
    p3 = load(samples / "seed004.json")
    r = lcpcli.solve(p3, method="enum", all=True)
    assert r.status == "solved" and "unique" in r.message


def test_solver_counts_all(siconos):
    p = load(siconos / "lcp" / "lcp_CPS_3.dat")
    r = lcpcli.solve(p, method="enum", all="true")
    assert r.status == "solved" and "3 distinct solutions" in r.message
    assert r.info["solutions"] == 3


# ------------------------------------------------------------------------ K(M) for n = 2
def test_covers_plane_examples():
    assert covers_plane(np.array(SEED_M))
    assert not covers_plane(-np.eye(2))  # all four cones are the first quadrant
    assert covers_plane(np.ones((2, 2)))  # CPS_1: (z1, w2) and (w1, z2) fill the gaps
    assert not covers_plane(np.array([[1.0, -1.0], [-1.0, 1.0]]))  # CPS_5: q = (1, 1) ...
    # ... is solvable, but q = (-1, -1) + (0, 0.5) lies in no cone:
    p = Problem.create([[1.0, -1.0], [-1.0, 1.0]], [-1.0, -0.5])
    assert enumerate_cones(p).verdict == "none"
    assert covers_plane(np.array([[1.0, 0.0], [0.0, 1.0]]))


def test_covers_plane_against_sampling():
    """Independent reference: q on 720 directions, each tested against the four 2 x 2 systems."""
    rng = np.random.default_rng(2)
    angles = np.linspace(0, 2 * np.pi, 721)[:-1] + 1e-3
    Q = np.vstack([np.cos(angles), np.sin(angles)])
    for _ in range(40):
        M = rng.standard_normal((2, 2))
        solvable = np.zeros(Q.shape[1], dtype=bool)
        for cols in itertools.product((0, 1), repeat=2):
            A = np.column_stack([-M[:, j] if c else np.eye(2)[:, j] for j, c in enumerate(cols)])
            y = np.linalg.solve(A, Q)
            solvable |= np.all(y >= -1e-12, axis=0)
        assert covers_plane(M) == bool(solvable.all())


# ------------------------------------------------------------------------ plotting
def test_plot_png(cli, samples, tmp_path):
    pytest.importorskip("matplotlib")
    target = tmp_path / "cones.png"
    out = cli("enumerate", str(samples / "seed004.json"), "--plot", str(target))
    assert out.returncode == 0, out.stderr
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert list(tmp_path.iterdir()) == [target]  # no temporary left behind


def test_terminal_drawing_marks_q_in_its_cone():
    from lcpcli.cli.render.enumerate import draw_cones_text

    text = draw_cones_text(np.array(SEED_M), np.array(SEED_Q)).plain
    rows = text.splitlines()[:-2]
    (r,) = [i for i, row in enumerate(rows) if "q" in row]
    c = rows[r].index("q")
    # q = (-5, -6) lies in cone 4 = (z1, z2): its neighbours on the row are 4s or rays
    assert "4" in rows[r][max(0, c - 3): c + 4]
    assert "2" not in rows[r][max(0, c - 3): c + 4] and "3" not in rows[r][max(0, c - 3): c + 4]
    for label in ("w1", "w2", "z1", "z2"):
        assert label in text


# ------------------------------------------------------------------------ bad input
def _write(tmp_path, name, obj):
    f = tmp_path / name
    f.write_text(json.dumps(obj))
    return f


def test_bad_input_exit_2(cli, tmp_path, samples):
    big = _write(tmp_path, "big.json", {"M": np.eye(25).tolist(), "q": [-1.0] * 25})
    out = cli("enumerate", str(big))
    assert out.returncode == 2 and "max-n" in out.stderr and "Traceback" not in out.stderr
    assert out.stdout == ""
    out = cli("enumerate", str(big), "--max-n", "30", "--json", "--all-cones")
    assert out.returncode == 2 and "Traceback" not in out.stderr
    mid = _write(tmp_path, "mid.json", {"M": np.eye(13).tolist(), "q": [1.0] * 13})
    out = cli("enumerate", str(mid), "--all-cones")
    assert out.returncode == 2 and "--json" in out.stderr
    mlcp = _write(tmp_path, "mlcp.json", {"M": np.eye(3).tolist(), "q": [1, 2, 3], "n_eq": 1})
    out = cli("enumerate", str(mlcp))
    assert out.returncode == 2 and "LCP" in out.stderr and "Traceback" not in out.stderr
    three = _write(tmp_path, "three.json", {"M": np.eye(3).tolist(), "q": [1, 2, 3]})
    target = tmp_path / "p.png"
    out = cli("enumerate", str(three), "--plot", str(target))
    assert out.returncode == 2 and not target.exists() and "Traceback" not in out.stderr


def test_library_errors():
    with pytest.raises(OptionError):
        enumerate_cones(Problem.create(np.eye(25), np.ones(25)))
    with pytest.raises(ProblemError):
        enumerate_cones(Problem.create(np.eye(2), np.ones(2), n_eq=1))
    with pytest.raises(OptionError, match="max-n"):
        enumerate_cones(Problem.create(np.eye(2), np.ones(2)), max_n=0)
    with pytest.raises(OptionError, match="max-n"):
        lcpcli.solve(Problem.create(np.eye(25), np.ones(25)), method="enum")
    with pytest.raises(OptionError):
        lcpcli.solve(Problem.create(np.eye(2), np.ones(2)), method="enum", all="maybe")
