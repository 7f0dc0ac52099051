"""Exact traces (issue 27): the replicas run on fractions and print 4/3, not 1.33333.

Invariants: every state of an exact Lemke / Murty trace is an exact solution of the original
system at its basic point and along each nonbasic column; the exact trace makes the
floating-point trace's pivots on the samples, and its numbers round to the float trace's.
"""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.api import solve
from lcpcli.core.problem import Problem
from lcpcli.io import load
from lcpcli.solvers.trace.exact import (
    exact_data,
    exact_trace,
    gauss_jordan,
    rational,
    rational_array,
    same_pivots,
    wants_exact,
)


def lcp(M: np.ndarray, q: np.ndarray) -> Problem:
    return Problem.create(M, q)


SAMPLES = Path(__file__).resolve().parents[2] / "samples"
TEXT = {"NO_COLOR": "1", "COLUMNS": "100"}


def _index(name: str, n: int) -> int:
    """Position of a variable in ``x = (w1..wn, z1..zn, z0)``."""
    if name == "z0":
        return 2 * n
    return int(name[1:]) - 1 + (0 if name[0] == "w" else n)


def _residual(M: np.ndarray, q: np.ndarray, d: np.ndarray | None, x: list) -> list:
    """``w - M z - d z0 - q`` at ``x`` (exact)."""
    n = len(q)
    w, z = x[:n], x[n:2 * n]
    z0 = x[2 * n] if d is not None else 0
    return [w[i] - sum(M[i, j] * z[j] for j in range(n)) - (d[i] * z0 if d is not None else 0)
            - q[i] for i in range(n)]


def check_states(trace: list, M: np.ndarray, q: np.ndarray, d: np.ndarray | None) -> None:
    """Each recorded dictionary ``x_B = q' + M' x_N`` is the original system, exactly."""
    n = len(q)
    size = 2 * n + (1 if d is not None else 0)
    for state in trace:
        if state.get("tableau") is None or state.get("rule") in ("ray", "bad_pivot"):
            continue
        assert all(isinstance(v, Fraction) for v in state["q_prime"])
        base = [Fraction(0)] * size
        for b, v in zip(state["basis"], state["q_prime"], strict=True):
            base[_index(b, n)] = v
        assert _residual(M, q, d, base) == [0] * n  # the basic point
        for j, name in enumerate(state["nonbasic"]):
            x = list(base)
            x[_index(name, n)] += 1
            for r, b in enumerate(state["basis"]):
                x[_index(b, n)] += state["tableau"][r][j]
            assert _residual(M, q, d, x) == [0] * n  # one step along column j


def test_rational_reading():
    assert rational(0.1) == Fraction(1, 10) and rational(4 / 3) == Fraction(4, 3)
    assert rational(np.pi) is None and rational(float("inf")) is None
    assert rational_array([[1, 0.5], [-2, 3]]).tolist() == [[1, Fraction(1, 2)], [-2, 3]]
    assert rational_array([1e6]) is None  # above the magnitude limit
    A = rational_array([[2, 1], [1, 2]])
    x, det = gauss_jordan(A, rational_array([[1], [0]]))
    assert det == 3 and x[:, 0].tolist() == [Fraction(2, 3), Fraction(-1, 3)]
    assert gauss_jordan(rational_array([[1, 2], [2, 4]]), rational_array([[1], [1]]))[0] is None


@pytest.mark.parametrize("name", ["seed000.json", "seed004.json", "degenerate.json",
                                  "degenerate_lex.json", "box_small.json"])
@pytest.mark.parametrize("method", ["lemke", "murty", "dantzig"])
def test_exact_trace_matches_the_float_trace(name, method):
    prob = load(str(SAMPLES / name))
    data = exact_data(prob)
    assert data is not None
    try:
        float_trace = solve(prob, method, trace=True).trace or []
    except Exception:  # noqa: BLE001 - a method that does not take this kind of problem
        pytest.skip(f"{method} does not take {prob.kind}")
    exact = exact_trace(prob, method, data)
    assert same_pivots(float_trace, exact)
    for a, b in zip(float_trace, exact, strict=True):
        for key in ("q_prime", "z"):
            if a.get(key) is not None:
                assert np.allclose(np.array(b[key], dtype=float), a[key], atol=1e-12)
    if method != "dantzig":
        d = np.ones(prob.n, dtype=object) if method == "lemke" else None
        check_states(exact, data.M, data.q, d)


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 5).flatmap(lambda n: st.tuples(
    st.lists(st.integers(-4, 4), min_size=n * n, max_size=n * n),
    st.lists(st.integers(-6, 6), min_size=n, max_size=n))))
def test_exact_lemke_and_murty_states_are_exact(data):
    """Random small integer P-matrices (A A^T + I): every state exact, same pivots."""
    entries, qv = data
    n = len(qv)
    A = np.array(entries, dtype=float).reshape(n, n)
    M = A @ A.T + np.eye(n)
    prob = lcp(M, np.array(qv, dtype=float))
    ex = exact_data(prob, max_den=1, max_abs=10**6)
    assert ex is not None
    for method, d in (("lemke", np.ones(n, dtype=object)), ("murty", None)):
        trace = exact_trace(prob, method, ex)
        check_states(trace, ex.M, ex.q, d)
        float_trace = solve(prob, method, trace=True).trace or []
        if same_pivots(float_trace, trace) and trace:
            z = solve(prob, method).z
            last = trace[-1]
            zx = np.zeros(n)
            for b, v in zip(last["basis"], last["q_prime"], strict=True):
                if b.startswith("z") and b != "z0":
                    zx[int(b[1:]) - 1] = float(v)
            assert np.allclose(zx, z, atol=1e-9)


def test_automatic_only_for_small_rational_data():
    small = lcp(np.array([[2.0, 1], [1, 2]]), np.array([-5.0, -6]))
    assert wants_exact(small, None) is not None and wants_exact(small, False) is None
    odd = lcp(np.array([[2.0, 1], [1, 2]]), np.array([-np.pi, -6]))
    assert wants_exact(odd, None) is None and wants_exact(odd, True) is None
    big = lcp(np.eye(9) * 2, -np.ones(9))
    assert wants_exact(big, None) is None and wants_exact(big, True) is not None
    fine = lcp(np.array([[2.0, 1], [1, 2]]), np.array([-1 / 3000, -6]))  # denominator 3000
    assert wants_exact(fine, None) is None and wants_exact(fine, True) is not None


# ------------------------------------------------------------------------ command line
def test_solve_trace_prints_fractions(cli, samples):
    p = cli("solve", str(samples / "degenerate_lex.json"), "--layout", "murty", "--pivot", "4",
            env=TEXT)
    assert p.returncode == 0, p.stderr
    assert "-4/3" in p.stdout and "7/3" in p.stdout and "1.33333" not in p.stdout
    p = cli("solve", str(samples / "degenerate_lex.json"), "--layout", "murty", "--pivot", "4",
            "--no-exact", env=TEXT)
    assert "-1.33333" in p.stdout and "4/3" not in p.stdout
    for method in ("murty", "dantzig"):
        p = cli("solve", str(samples / "seed004.json"), "-m", method, "--trace", env=TEXT)
        assert p.returncode == 0 and "4/3" in p.stdout, (method, p.stdout)


def test_exact_json_keeps_floats_and_the_verdict(cli, samples):
    p = cli("solve", str(samples / "seed004.json"), "--trace", "--exact", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert d["status"] == "solved" and d["trace"][-1]["q_prime"][0] == pytest.approx(7 / 3)


def test_exact_notes(cli, samples, tmp_path):
    p = cli("solve", str(samples / "seed004.json"), "-m", "pgs", "--trace", "--exact",
            env=TEXT)
    assert p.returncode == 0 and "stays in decimals" in p.stderr
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps({"M": [[2, 1], [1, 2]], "q": [-3.14159265358979, -6]}))
    p = cli("solve", str(odd), "--trace", "--exact", env=TEXT)
    assert p.returncode == 0 and "not fractions" in p.stderr
    p = cli("enumerate", str(odd), "--exact", env=TEXT)
    assert p.returncode == 0 and "not fractions" in p.stderr and "3.14159" in p.stdout
    tenth = tmp_path / "tenth.json"
    tenth.write_text(json.dumps({"M": [[2, 1], [1, 2]], "q": [-0.1, -0.3]}))
    p = cli("solve", str(tenth), "--trace", env=TEXT)
    assert p.returncode == 0 and "1/10" in p.stdout and p.stderr == ""


def test_pivot_and_enumerate_print_fractions(cli, samples):
    p = cli("pivot", str(samples / "seed000_augmented.json"), "-d", "z0,w2,z3", "--driving",
            "w1", "--full", env=TEXT)
    assert p.returncode == 0, p.stderr
    assert "rises by 1/2" in p.stdout and "-1/2" in p.stdout and "0.5" not in p.stdout
    p = cli("enumerate", str(samples / "seed004.json"), "--all-cones", env=TEXT)
    assert "z1 = 5/2" in p.stdout and "(4/3, 7/3)" in p.stdout
    md = cli("enumerate", str(samples / "seed004.json"), "--format", "markdown").stdout
    assert "z1 = 4/3, z2 = 7/3" in md
    j = json.loads(cli("enumerate", str(samples / "seed004.json"), "--json").stdout)
    assert j["solutions"][0]["z"][0] == pytest.approx(4 / 3)
