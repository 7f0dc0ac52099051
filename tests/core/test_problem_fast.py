"""``Problem.create``'s fast path (native float64 arrays of a dense LCP) against its general path.

The fast path must be taken for the usual call and must give the same record, or the same
ProblemError, as the general path (which the same data reach when given as nested lists).
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.core import problem as problem_module
from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem


def _fields(p: Problem) -> dict:
    return {f.name: getattr(p, f.name) for f in fields(Problem)}


def _same(a: Problem, b: Problem) -> None:
    fa, fb = _fields(a), _fields(b)
    assert fa.keys() == fb.keys()
    for key in fa:
        x, y = fa[key], fb[key]
        if isinstance(x, np.ndarray):
            assert type(y) is np.ndarray and x.dtype == y.dtype == np.float64
            assert x.flags.c_contiguous and y.flags.c_contiguous
            np.testing.assert_array_equal(x, y)
        else:
            assert x == y, key


def test_the_fast_path_is_taken(monkeypatch):
    def general(*_a, **_k):
        raise AssertionError("the general path ran")

    monkeypatch.setattr(problem_module, "_as_matrix", general)
    monkeypatch.setattr(problem_module, "_as_vector", general)
    M, q = np.eye(3), np.array([-1.0, 2.0, 0.5])
    p = Problem.create(M, q, name="x", meta={"a": 1})
    assert p.M is M and p.q is not q  # M is not copied, q is (as on the general path)
    assert p.name == "x" and p.meta == {"a": 1} and p.n_eq == 0 and p.lower is None


def test_the_record_has_every_field():
    p = Problem.create(np.eye(2), np.ones(2))
    assert set(vars(p)) == {f.name for f in fields(Problem)}


def test_the_general_path_still_runs_for_other_forms():
    M = np.asfortranarray(np.arange(9.0).reshape(3, 3) + 10 * np.eye(3))
    p = Problem.create(M, np.ones((3, 1)))
    assert p.M.flags.c_contiguous and p.q.shape == (3,)
    q32 = Problem.create(np.eye(2, dtype=np.float32), np.ones(2, dtype=np.float32))
    assert q32.M.dtype == np.float64 and q32.q.dtype == np.float64


def _outcome(M, q):
    try:
        return Problem.create(M, q)
    except ProblemError as exc:
        return str(exc)


values = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                   st.sampled_from([0.0, -0.0, 5e-324, 1e308, -1e308, 2.0 ** -1000]))


@settings(max_examples=150, deadline=None)
@given(n=st.integers(0, 5), m=st.integers(0, 5), data=st.data())
def test_fast_and_general_paths_agree(n, m, data):
    M = np.array(data.draw(st.lists(values, min_size=n * m, max_size=n * m)),
                 dtype=np.float64).reshape(n, m)
    k = data.draw(st.integers(0, 5))
    q = np.array(data.draw(st.lists(values, min_size=k, max_size=k)), dtype=np.float64)
    fast = _outcome(M, q)
    general = _outcome(M.tolist() if n * m else M.astype(np.float32), q.tolist())
    if isinstance(fast, str) or isinstance(general, str):
        assert isinstance(fast, str) and isinstance(general, str)
        assert ("NaN" in fast) == ("NaN" in general)
    else:
        _same(fast, general)


@pytest.mark.parametrize("n_eq", [True, 0.0, "0", np.int64(0)])
def test_n_eq_of_another_type_takes_the_general_rule(n_eq):
    if isinstance(n_eq, np.integer):
        assert Problem.create(np.eye(2), np.ones(2), n_eq=n_eq).n_eq == 0
    else:
        with pytest.raises(ProblemError, match="n_eq must be an integer"):
            Problem.create(np.eye(2), np.ones(2), n_eq=n_eq)
