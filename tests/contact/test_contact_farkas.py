"""A contact scene whose island has no solution: the island's checked Farkas vector, padded
with zeros, is the scene's proof (issue 22), not a linear program on the whole scene."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import lcpcli
from lcpcli.analysis import proof
from lcpcli.contact import build, solve
from lcpcli.contact.examples import box_stacks
from lcpcli.contact.model import scene_farkas


def _scene_with_an_infeasible_island(k: int) -> tuple[object, np.ndarray]:
    """Three box stacks (three islands of 12 unknowns); island ``k``'s block replaced by the
    Laplacian of a path (PSD, L 1 = 0) and its q by one with a negative sum: no z >= 0 has
    L z + q >= 0 there (y = 1 on the island proves it), and no single row proves it alone."""
    clcp = build(box_stacks(3), friction=0)
    M = clcp.problem.dense_M().copy()
    q = clcp.problem.q.copy()
    rows = clcp.layout.unknowns(k)
    m = rows.size
    L = 2 * np.eye(m) - np.eye(m, k=1) - np.eye(m, k=-1)
    L[0, 0] = L[-1, -1] = 1.0
    M[np.ix_(rows, rows)] = L
    qk = np.ones(m)
    qk[m // 2] = -2.0 * m
    q[rows] = qk
    return dataclasses.replace(clcp, problem=lcpcli.Problem.create(M, q)), rows


@pytest.mark.parametrize("method", ["auto", "lemke"])
def test_infeasible_island_proves_the_scene_infeasible(monkeypatch: pytest.MonkeyPatch,
                                                        method: str) -> None:
    clcp, rows = _scene_with_an_infeasible_island(1)
    n = clcp.problem.n
    searched: list[int] = []
    lp = proof._lp_candidate

    def recording(problem):  # which problems needed the linear program
        searched.append(problem.n)
        return lp(problem)

    monkeypatch.setattr(proof, "_lp_candidate", recording)
    res = solve(clcp, method).result
    assert res.status == "no_solution", res.message
    assert n not in searched  # the scene's proof came from its island, checked as it is
    y = np.asarray(res.info["farkas_y"])
    outside = np.setdiff1d(np.arange(n), rows)
    assert np.all(y[outside] == 0) and np.all(y[rows] >= 0) and np.any(y[rows] > 0)
    lo, up = clcp.problem.bounds()
    assert proof.check_farkas(clcp.problem.M, clcp.problem.q, lo, up, y).passed


def test_scene_farkas_pads_the_first_island_vector() -> None:
    clcp, rows = _scene_with_an_infeasible_island(2)

    class Fake:
        def __init__(self, y):
            self.info = {} if y is None else {"farkas_y": y}

    y = scene_farkas(clcp.problem.n, clcp.layout,
                     [(0, Fake(None)), (2, Fake(list(range(1, rows.size + 1))))])
    assert y is not None and np.array_equal(y[rows], np.arange(1, rows.size + 1))
    assert np.count_nonzero(y) == rows.size
    assert scene_farkas(clcp.problem.n, clcp.layout, [(0, Fake(None))]) is None
    assert scene_farkas(clcp.problem.n, clcp.layout, [(2, Fake([1.0]))]) is None  # wrong size
