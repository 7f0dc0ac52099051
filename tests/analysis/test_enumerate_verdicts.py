"""``enumerate`` on extreme data: every solution it lists passes the certificate in the user's
units, and ``no_solution`` comes with a Farkas vector (issue 22).

Checked independently: ``tests/references.py`` (``componentwise_error``, ``farkas_certifies``).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st
from references import componentwise_error, farkas_certifies

from lcpcli.analysis.enumeration import enumerate_cones
from lcpcli.core.problem import Problem

#: Entries spanning the double range, with signs and zeros.
EXTREME = [1e300, -1e300, 1e-300, -1e-300, 1.0, -1.0, 0.0, 1e200, -1e200, 1e-200, 5e-324]


def _pair(n: int) -> st.SearchStrategy:
    entries = st.sampled_from(EXTREME)
    return st.tuples(st.lists(entries, min_size=n * n, max_size=n * n),
                     st.lists(entries, min_size=n, max_size=n))


@settings(max_examples=300, deadline=None)
@given(st.integers(1, 3).flatmap(_pair))
@example(([1e-300, 1.0, 1e-300, 1e-300, 1e-200, 1e300, 1.0, 5e-324, 1e-300],
          [1e300, 1e300, 1e300]))  # a cone's determinant: divide by zero in LAPACK's det
@example(([1e300, -1e200, 1e300, 1e300, -1e200, -1e300, 1e300, 1e300, 1e300],
          [1e-300, 1e-300, -1e300]))  # q_1 = q_2 = 1e-300 against terms of 1e200: no data
def test_every_listed_solution_is_certified_and_every_proof_checks(data) -> None:
    """... and no numpy warning escapes (the CLI would print each as a warning line), also
    with every cone's details."""
    flat, q = data
    n = len(q)
    M, q = np.array(flat).reshape(n, n), np.array(q)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        res = enumerate_cones(Problem.create(M, q))
        enumerate_cones(Problem.create(M, q), all_cones=True)
    with np.errstate(all="ignore"):
        for sol in res.solutions:
            assert np.all(np.isfinite(sol.z))
            assert componentwise_error(M, q, sol.z) <= 1e-8, (M.tolist(), q.tolist(), sol.z)
    if res.status == "solved":
        assert res.solutions
    elif res.status == "no_solution":
        assert res.verdict == "none" and farkas_certifies(M, q, res.proof.y)


def test_the_issue_examples_are_not_solved_falsely(cli) -> None:
    # found by a random search of 2 x 2 problems with entries 1e300 / 1e-300: cones contain q
    # on the equilibrated problem, but the point does not survive the way back
    for M, q in (([[1e-300, 1e200], [1e-300, -1e-300]], [-1.0, 1.0]),
                 ([[1.0, 1.0], [0.0, 1e-200]], [1e300, -1e300])):
        out = cli("enumerate", "-", "--json", stdin=json.dumps({"M": M, "q": q}))
        data = json.loads(out.stdout)
        for sol in data["solutions"]:
            z = np.array([np.nan if v is None else v for v in sol["z"]])
            with np.errstate(all="ignore"):
                assert componentwise_error(np.array(M), np.array(q), z) <= 1e-8
        assert out.returncode == (0 if data["status"] == "solved" else 1)


def test_the_cone_drawing_takes_data_near_the_float64_range(cli) -> None:
    """n = 2 draws the cones: generators and q whose length is past the float64 range
    (1.5e308 in both entries) are drawn by direction, with no warning line."""
    for M, q in (([[1.5e308, 1.5e308], [1.5e308, -1.5e308]], [-1.5e308, 1.5e308]),
                 ([[-1e300, 5e-324], [1.5e308, 1e308]], [1e-300, -1e308])):
        out = cli("enumerate", "-", "--all-cones", stdin=json.dumps({"M": M, "q": q}))
        assert out.returncode in (0, 1), out.stderr
        assert "warning" not in out.stderr, out.stderr


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 3).flatmap(lambda n: st.tuples(
    st.lists(st.integers(-4, 4), min_size=n * n, max_size=n * n),
    st.lists(st.integers(-4, 4), min_size=n, max_size=n),
    st.lists(st.integers(-500, 500), min_size=n, max_size=n),
    st.lists(st.integers(-500, 500), min_size=n, max_size=n))))
@example(([0, 3, -1, 0], [2, -3], [80, 270], [-115, -323]))
def test_the_verdict_does_not_change_under_power_of_two_scalings(data) -> None:
    """Rows scaled by 2^r_i and columns by 2^c_j (exact): the same status, and a no_solution
    comes with a proof that passes the exact reference.  The example: q 'seemed' to lie in two
    cones of the scaled copy of an infeasible problem, whose points fail the certificate, and
    the verdict was 'uncertified' (unsolved) with no proof search."""
    flat, q, r, c = data
    n = len(q)
    M, q = np.array(flat, dtype=float).reshape(n, n), np.array(q, dtype=float)
    Ms = np.ldexp(np.ldexp(M, np.array(r)[:, None]), np.array(c)[None, :])
    qs = np.ldexp(q, np.array(r))
    plain, scaled = enumerate_cones(Problem.create(M, q)), enumerate_cones(Problem.create(Ms, qs))
    assert scaled.status == plain.status, (plain.verdict, scaled.verdict)
    if scaled.status == "no_solution":
        with np.errstate(all="ignore"):
            assert farkas_certifies(Ms, qs, scaled.proof.y)
