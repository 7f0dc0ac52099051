"""The stacked island path (islands._solve_stacked: one solve_many call on the block buffer, the
answers read from the stack's arrays, a Result only for the islands the kernel did not certify)
gives exactly what the Result-per-island path gives (solve_problems on island_problems): the
same z, bases, methods, statuses, iterations, certified errors, warm flags and messages, and
the same scene verdict, certificate and report, cold and warm, with islands not solved."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.contact import build, islands, solve
from lcpcli.contact.examples import box_stacks

#: (method, options) of each case; max_iter = 3 and tol = 1e-16 leave islands not solved (the
#: kernel hands them back and their own solve fails too, or the certificate refuses them)
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "cold": ("auto", {}),
    "warm": ("auto", {"warm": "impulses"}),
    "warm_basis": ("auto", {"warm": "basis"}),
    "few_pivots": ("lemke", {"max_iter": 3}),
    "tiny_tol": ("auto", {"tol": 1e-16}),
    "warm_tiny_tol": ("auto", {"warm": "basis", "tol": 1e-16}),
}


def _pair(stacks: int, height: int, seed: int) -> tuple[Any, Any]:
    """A scene's contact LCP solved once (the previous step) and the next step's LCP (every
    velocity changed by about 1 %)."""
    scene = box_stacks(stacks, height, seed=seed)
    first = solve(build(scene, friction=4))
    rng = np.random.default_rng(seed)
    nxt = build(dataclasses.replace(
        scene, velocity=scene.velocity * (1 + 0.01 * rng.normal(size=scene.velocity.shape)),
        omega=scene.omega * (1 + 0.01 * rng.normal(size=scene.omega.shape))), friction=4)
    return first, nxt


def _arguments(case: str, first: Any) -> tuple[str, dict[str, Any]]:
    method, opts = CASES[case]
    opts = dict(opts)
    warm = opts.pop("warm", None)
    if warm is not None:
        opts["z0"] = first.result.z
    if warm == "basis":
        opts["basis0"] = first.basic
    return method, opts


def _same_answers(a: islands.IslandAnswers, b: islands.IslandAnswers) -> None:
    np.testing.assert_array_equal(a.z, b.z)
    np.testing.assert_array_equal(a.basic, b.basic)
    assert a.methods == b.methods
    assert a.status == b.status
    assert a.iterations == b.iterations
    np.testing.assert_array_equal(a.errors, b.errors)
    assert a.warm == b.warm
    assert a.results.keys() <= b.results.keys()
    for k, r in a.results.items():  # the islands with a full Result: the same one
        assert (r.status, r.message, r.termination) == (b.results[k].status,
                                                        b.results[k].message,
                                                        b.results[k].termination)
        np.testing.assert_array_equal(r.z, b.results[k].z)
    for k, st_ in enumerate(a.status):  # every island not solved has its full Result
        assert str(st_) == "solved" or k in a.results


def _same_certificate(a: Any, b: Any) -> None:
    """The same verdict, worst pair and numbers to rounding: the scene's certificate taken from
    its islands' (their blocks summed dense) against a CSR pass over the scene.  Rounding of
    w (sums of 72 terms of size about 1) moves the relative errors by about 1e-14 at most and
    the diagnostics in data units (|w_i|, |z_i w_i| near 0) by about as much in absolute; the
    worst pair, and the growth of its block, are compared where the error is more than
    rounding (among rounding-level errors the largest is rounding's pick)."""
    assert (a.passed, a.tol) == (b.passed, b.tol)
    if b.error > 1e-10:
        assert a.worst == b.worst
        assert a.growth == pytest.approx(b.growth, rel=1e-9)
    for name in ("error", "backward_error", "residual", "bound_violation", "w_violation",
                 "complementarity", "equality_residual"):
        assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-9, abs=1e-12), name


@settings(max_examples=12, deadline=None)
@given(st.integers(8, 14), st.sampled_from([1, 2, 3]), st.integers(0, 2**16),
       st.sampled_from(sorted(CASES)))
def test_stacked_islands_equal_one_result_per_island(stacks, height, seed, case) -> None:
    first, nxt = _pair(stacks, height, seed)
    method, opts = _arguments(case, first)
    lay, p = nxt.layout, nxt.problem
    tol = opts.pop("tol", None)
    z0, basis0 = opts.pop("z0", None), opts.pop("basis0", None)
    fast = islands._solve_stacked(p, lay, nxt.storage, "s", method, tol, z0, basis0, 1, opts)
    assert fast is not None  # the case this test is about: every island stacked
    reference = islands.solve_islands(p, lay, nxt.storage, "s", method, tol, z0, basis0,
                                      stacked=False, **opts)
    _same_answers(fast, reference)
    if case in ("few_pivots", "tiny_tol"):
        assert any(str(s) != "solved" for s in fast.status)


@pytest.mark.parametrize("case", sorted(CASES))
def test_scene_verdict_and_report_unchanged(case, monkeypatch) -> None:
    """contact.solve through the stacked path and through one Result per island: the same
    verdict, whole-scene certificate, message, impulses, basis and per-island report (all but
    the measured seconds)."""
    first, nxt = _pair(9, 3, 5)
    method, opts = _arguments(case, first)
    fast = solve(nxt, method, **opts)
    monkeypatch.setattr(islands, "_solve_stacked", lambda *a: None)
    slow = solve(nxt, method, **opts)
    assert fast.result.status == slow.result.status
    assert fast.result.message == slow.result.message
    _same_certificate(fast.result.certificate, slow.result.certificate)
    np.testing.assert_allclose(fast.result.w, slow.result.w, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(fast.result.z, slow.result.z)
    np.testing.assert_array_equal(fast.basic, slow.basic)
    drop = [{k: v for k, v in r.items() if k != "seconds"} for r in fast.islands]
    assert drop == [{k: v for k, v in r.items() if k != "seconds"} for r in slow.islands]
    assert [type(v) for v in fast.islands[0].values()] == \
        [type(v) for v in slow.islands[0].values()]
    if case == "few_pivots":
        assert fast.result.status != "solved"


def test_sparse_islands_and_mixed_sizes_take_the_per_island_path() -> None:
    """Islands stored sparse, or of two sizes: no stacked path (None); solve_islands then
    answers with one Result per island."""
    clcp = build(box_stacks(10, 3, seed=1), friction=4, storage="sparse")
    assert islands._solve_stacked(clcp.problem, clcp.layout, clcp.storage, "s", "auto", None,
                                  None, None, 1, {}) is None
    ans = islands.solve_islands(clcp.problem, clcp.layout, clcp.storage, "s")
    assert sorted(ans.results) == list(range(10))
    one = build(box_stacks(10, 3, seed=1), friction=4)
    lay = one.layout
    two = islands.IslandLayout(perm=lay.perm, offsets=np.concatenate(
        (lay.offsets[:1], lay.offsets[2:])))  # the first two islands as one: two sizes
    assert islands._solve_stacked(one.problem, two, one.storage, "s", "auto", None, None, None,
                                  1, {}) is None


@settings(max_examples=10, deadline=None)
@given(st.integers(8, 14), st.integers(0, 2**16), st.sampled_from(["cold", "warm_basis"]))
def test_scene_certificate_from_the_islands_is_the_scenes(stacks, seed, case) -> None:
    """Every island certified in the kernel: the scene's certificate is its islands' combined
    (scene_check: the largest error, the first worst row in the scene's order, its island's
    growth, the largest diagnostics), exactly the combination of each island's own certificate
    (check on its dense block), and the scene's certificate by a CSR pass over the whole scene
    to rounding, with the same verdict."""
    from lcpcli.core.certificate import check

    first, nxt = _pair(stacks, 3, seed)
    method, opts = _arguments(case, first)
    lay, p = nxt.layout, nxt.problem
    ans = islands._solve_stacked(p, lay, nxt.storage, "s", method, None, opts.get("z0"),
                                 opts.get("basis0"), 1, {})
    assert ans is not None and p.sparse and ans.checked is not None
    cert, w = ans.checked
    scene, w_scene = check(p, ans.z, cert.tol)
    _same_certificate(cert, scene)
    np.testing.assert_allclose(w, w_scene, rtol=0, atol=1e-12)
    own = []  # each island's certificate on its own dense block, and its first worst row
    blocks = islands._dense_blocks(p.M, lay, nxt.storage)
    for k, block in enumerate(blocks):
        rows = lay.unknowns(k)
        c, wk = check(islands.Problem(M=block, q=p.q[rows]), ans.z[rows], cert.tol)
        np.testing.assert_array_equal(wk, w[rows])
        own.append((c, int(rows[c.worst])))
    top = max(c.error for c, _ in own)
    worst, growth = min((r, c.growth) for c, r in own if c.error == top)
    assert (cert.error, cert.worst, cert.growth) == (top, worst, growth)
    for name in ("backward_error", "residual", "bound_violation", "w_violation",
                 "complementarity", "equality_residual"):
        assert getattr(cert, name) == max(getattr(c, name) for c, _ in own), name
    assert cert.passed == all(c.passed for c, _ in own)


def test_an_island_not_certified_leaves_the_scene_to_its_own_check() -> None:
    """An island the kernel did not certify (tol = 1e-16): no combined certificate, and the
    scene's Result carries exactly the certificate of a check on the whole scene."""
    from lcpcli.core.certificate import check

    first, nxt = _pair(9, 3, 5)
    ans = islands._solve_stacked(nxt.problem, nxt.layout, nxt.storage, "s", "auto", 1e-16,
                                 None, None, 1, {})
    assert ans is not None and ans.checked is None
    out = solve(nxt, tol=1e-16)
    assert out.result.certificate == check(nxt.problem, out.result.z, 1e-16)[0]


def test_the_block_buffer_is_kept_only_when_nothing_refers_to_it() -> None:
    """solve_islands keeps its island-block buffer for the next call (the same answers from a
    reused buffer, which every row zeroes again), but never one that a view still refers to."""
    first, nxt = _pair(9, 3, 5)
    lay, p = nxt.layout, nxt.problem
    islands._block_pool.clear()
    a = islands._solve_stacked(p, lay, nxt.storage, "s", "auto", None, None, None, 1, {})
    assert len(islands._block_pool) == 1
    islands._block_pool[0][:] = np.nan  # whatever the last scene left there
    kept = id(islands._block_pool[0])  # (no reference held: the pool keeps it alive)
    b = islands._solve_stacked(p, lay, nxt.storage, "s", "auto", None, None, None, 1, {})
    assert [id(x) for x in islands._block_pool] == [kept]  # taken, filled, given back
    _same_answers(a, b)
    assert a.checked[0] == b.checked[0]
    islands._block_pool.clear()
    buf = islands._block_buffer(p.M, lay, nxt.storage, pooled=True)[0]
    view = buf[:3]
    islands._keep_buffer(buf)
    assert not islands._block_pool  # a view of it lives on
    del view
    islands._keep_buffer(buf)
    assert islands._block_pool == [buf]
