"""Rendering only renders: every decision a page states comes from analysis/ or solvers/.

* ``lcpcli enumerate`` (n = 2): the region digits and the ``▒`` cells of the character drawing
  are :func:`lcpcli.analysis.enumeration.cone_interiors_2d` at the cells' points; the picture's
  "(degenerate)" legend is :func:`degenerate_2d`; interiors lie in the closed cones of
  :func:`in_cone_2d`.
* ``lcpcli pivot``: "this complementary basis solves the LCP" is printed exactly when
  :attr:`PivotTransform.solves`, and then the basic solution passes the certificate.
* ``--trace`` of Murty's method: "this basis solves the LCP" is printed exactly when the
  replica recorded ``end = "solved"``, which is exactly when the method converged.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.analysis.enumeration import (
    complementary_matrix,
    cone_interiors_2d,
    degenerate_2d,
    in_cone_2d,
)
from lcpcli.analysis.pivoting import augment, principal_pivot
from lcpcli.cli.render.doc import to_markdown
from lcpcli.cli.render.enumerate import draw_cones_text, text_grid
from lcpcli.cli.render.pivot import full_pages, pivot_pages
from lcpcli.core.certificate import DEFAULT_TOL, certify
from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem

entries = st.integers(-4, 4).map(float)
SOLVES_PIVOT = "complementary basis solves the LCP"
SOLVES_MURTY = "this basis solves the LCP"
LIMIT_MURTY = "The pivot limit stops the method here."


def _matrix(n: int) -> st.SearchStrategy[np.ndarray]:
    return st.lists(entries, min_size=n * n, max_size=n * n).map(
        lambda xs: np.array(xs).reshape(n, n))


def _cone_number(code: int) -> int:
    """The renderer's numbering r = 1..4 of the 2 x 2 cones (written out independently)."""
    return {0: 1, 2: 2, 1: 3, 3: 4}[code]


# ---------------------------------------------------------------------------- enumerate
@settings(max_examples=60, deadline=None)
@given(M=_matrix(2), q=st.lists(entries, min_size=2, max_size=2).map(np.array))
def test_drawn_regions_are_the_analysis_cone_interiors(M, q):
    width, height = 49, 21
    rows = draw_cones_text(M, q, width, height).plain.splitlines()[:height]
    inside = cone_interiors_2d(M, text_grid(width, height)).reshape(4, height, width)
    cover = inside.sum(axis=0)
    for i, row in enumerate(rows):
        for j, ch in enumerate(row):
            if ch == "▒":
                assert cover[i, j] >= 2, (i, j)
            elif ch in "1234" and (j == 0 or row[j - 1] not in "wz"):  # not a label's digit
                assert cover[i, j] == 1, (i, j)
                assert int(ch) == _cone_number(int(np.argmax(inside[:, i, j]))), (i, j)
            elif ch == " " and (cover[i, j] >= 2 or cover[i, j] == 1 and j % 2 == 0):
                # a region cell left blank: only as the one-cell margin of a label
                around = row[max(j - 1, 0)] + row[j + 1:j + 2]
                assert around.strip(), (i, j)


@settings(max_examples=80, deadline=None)
@given(M=_matrix(2), x=st.lists(st.floats(-3, 3), min_size=2, max_size=2).map(np.array))
def test_cone_interiors_lie_in_the_closed_cones(M, x):
    inside = cone_interiors_2d(M, x[:, None])[:, 0]
    for code in range(4):
        A = complementary_matrix(M, code)
        if inside[code]:
            assert not degenerate_2d(A) and in_cone_2d(A, x)
        if degenerate_2d(A):
            assert not inside[code]


@pytest.mark.parametrize("M", [[[2.0, 1.0], [1.0, 2.0]], [[0.0, 0.0], [1.0, 1.0]],
                               [[1.0, 2.0], [2.0, 4.0]], [[1e6, 0.0], [0.0, 1e-6]]])
def test_figure_legend_marks_the_analysis_degenerate_cones(M):
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from lcpcli.cli.render.enumerate import cones_figure

    M = np.array(M)
    fig = cones_figure(M, np.array([-1.0, -1.0]))
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()][:4]
    plt.close(fig)
    by_number = {_cone_number(code): degenerate_2d(complementary_matrix(M, code))
                 for code in range(4)}
    assert [label.endswith("(degenerate)") for label in labels] == \
        [by_number[r] for r in range(1, 5)]


# ---------------------------------------------------------------------------- pivot
@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 3), data=st.data())
def test_pivot_page_says_solves_exactly_when_the_transform_does(n, data):
    M = data.draw(_matrix(n))
    q = np.array(data.draw(st.lists(entries, min_size=n, max_size=n)))
    z_basic = data.draw(st.lists(st.booleans(), min_size=n, max_size=n))
    dependent = tuple(("z", i) if b else ("w", i) for i, b in enumerate(z_basic))
    Maug = augment(M)
    try:
        t = principal_pivot(Maug, q, dependent)
    except ProblemError:
        assume(False)  # a singular block: no transform to render
    text = to_markdown(pivot_pages([(t, None)], Maug, q))
    assert (SOLVES_PIVOT in text) is t.solves
    z = t.basic_solution()
    if t.solves:  # the certificate agrees with the exact-sign test
        assert certify(Problem.create(M, q), z).error <= DEFAULT_TOL
    else:
        assert min(t.q_prime) < 0


def test_a_non_complementary_basis_with_nonnegative_q_prime_does_not_solve():
    """With --any-basis, w1 and z1 both dependent: w2 = -z1 + 2 = 0 gives z1 = 2, w1 = z1 + 1
    = 3, so q' >= 0 but z1 w1 = 6 > 0: no solution (the page must not say it is one)."""
    M, q = np.array([[1.0, 0.0], [-1.0, 1.0]]), np.array([1.0, 2.0])
    Maug = augment(M)
    t = principal_pivot(Maug, q, (("w", 0), ("z", 0)), any_basis=True)
    assert min(t.q_prime) >= 0 and not t.solves
    assert SOLVES_PIVOT not in to_markdown(pivot_pages([(t, None)], Maug, q))


# ---------------------------------------------------------------------------- Murty's trace
@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 4), limit=st.integers(1, 6), data=st.data())
def test_murty_trace_page_says_solves_exactly_when_the_method_converged(n, limit, data):
    A = data.draw(_matrix(n))
    M = A @ A.T + n * np.eye(n)  # positive definite: a P-matrix, Murty's method is finite
    q = np.array(data.draw(st.lists(entries, min_size=n, max_size=n)))
    result = lcpcli.solve(M, q, "murty", trace=True, max_iter=limit)
    end = result.trace[-1]["end"]
    assert end == ("solved" if result.termination == "converged" else "limit")
    text = to_markdown(full_pages(result.trace))
    assert (SOLVES_MURTY in text) is (end == "solved")
    assert (LIMIT_MURTY in text) is (end == "limit")
    if end == "solved":
        assert result.status == "solved"
