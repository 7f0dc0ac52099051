"""The islands' dense blocks: one compiled pass over the scene's CSR matrix gives exactly the
principal blocks that slicing the permuted matrix gives, and a stack of equal-size islands is a
view of one buffer (no copy in lcpcli.solve_each)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.contact import build, islands
from lcpcli.contact.examples import box_stacks
from lcpcli.core.problem import Problem
from lcpcli.stacks import _stacked


def _sliced(M: sp.csr_matrix, lay: islands.IslandLayout) -> list[np.ndarray]:
    """The reference: each island's block of the dense matrix, by fancy indexing."""
    D = M.toarray()
    return [D[np.ix_(lay.unknowns(k), lay.unknowns(k))] for k in range(lay.count)]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 6), min_size=1, max_size=7), st.integers(0, 2**32 - 1),
       st.booleans(), st.booleans())
def test_dense_blocks_equal_the_sliced_blocks(sizes, seed, duplicates, wide) -> None:
    """Random block-diagonal matrices in a shuffled unknown order (islands of mixed sizes,
    duplicate CSR entries that add up, int32 or int64 indices)."""
    rng = np.random.default_rng(seed)
    N = sum(sizes)
    perm = rng.permutation(N)
    offsets = np.concatenate(([0], np.cumsum(sizes)))
    rows, cols, vals = [], [], []
    for k in range(len(sizes)):
        u = perm[offsets[k]: offsets[k + 1]]
        mask = rng.random((u.size, u.size)) < 0.7
        r, c = np.nonzero(mask)
        rows += u[r].tolist()
        cols += u[c].tolist()
        vals += rng.normal(size=r.size).tolist()
    if duplicates and rows:
        rows, cols, vals = rows + rows[:3], cols + cols[:3], vals + vals[:3]
    M = sp.csr_matrix((vals, (rows, cols)), shape=(N, N))  # sums duplicates...
    if duplicates and rows:  # ...so keep them as separate stored entries
        coo = sp.coo_matrix((vals, (rows, cols)), shape=(N, N))
        M = sp.csr_matrix((coo.data, (coo.row, coo.col)), shape=(N, N))
        M.has_canonical_format = False
    if wide:
        M.indices = M.indices.astype(np.int64)
        M.indptr = M.indptr.astype(np.int64)
    lay = islands.IslandLayout(perm=perm, offsets=offsets)
    blocks = islands._dense_blocks(M, lay, "auto")
    assert blocks is not None
    for got, want in zip(blocks, _sliced(M, lay), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)
        assert got.flags.c_contiguous


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(1, 9), min_size=1, max_size=40), st.integers(0, 2**32 - 1),
       st.sampled_from([2, 3]), st.booleans())
def test_scatter_in_threads_equals_one_thread(sizes, seed, threads, across) -> None:
    """scatter_blocks split between OpenMP threads (the buffer zeroed by each thread in its
    part first), or with each row zeroing its own block row (a reused buffer), writes the same
    buffer as one thread on a zeroed one, and refuses an entry across blocks the same way (the
    threads' path, which islands take on large scenes, on small matrices)."""
    from lcpcli.contact._blocks import scatter_blocks

    rng = np.random.default_rng(seed)
    N = sum(sizes)
    blocks = [rng.normal(size=(k, k)) * (rng.random((k, k)) < 0.6) for k in sizes]
    M = sp.csr_matrix(sp.block_diag(blocks))
    if across and N > 1:
        M = sp.csr_matrix(M + sp.csr_matrix(([1.0], ([0], [N - 1])), shape=(N, N)))
    lay = islands.IslandLayout(perm=np.arange(N), offsets=np.concatenate(([0],
                                                                          np.cumsum(sizes))))
    size = np.asarray(sizes, np.int64)
    start = np.concatenate(([0], np.cumsum(size * size)[:-1]))
    island = np.repeat(np.arange(len(sizes)), size)
    local = np.arange(N) - np.repeat(lay.offsets[:-1], size)
    row_start = start[island] + local * size[island]
    got = []
    # one thread on a zeroed buffer; threads on fresh memory (zeroed there first); each row
    # zeroing its own block row (sizes=) in a buffer holding anything, one thread or several
    for t, kw in ((1, {}), (threads, {}), (1, {"sizes": size, "fresh": False}),
                  (threads, {"sizes": size, "fresh": False})):
        buf = np.full(int((size * size).sum()), np.nan if t > 1 or kw else 0.0)
        ok = scatter_blocks(M.data, M.indices, M.indptr, row_start, local, island, buf, t,
                            **kw)
        got.append((ok, buf))
    assert all(ok == (not (across and sizes[0] < N)) for ok, _ in got)
    if got[0][0]:
        for _, buf in got[1:]:
            np.testing.assert_array_equal(got[0][1], buf)


def test_an_entry_across_islands_is_refused() -> None:
    """A matrix that is not block diagonal in the islands: None (the caller slices)."""
    M = sp.csr_matrix(np.array([[1.0, 2.0], [0.0, 1.0]]))
    lay = islands.IslandLayout(perm=np.array([0, 1]), offsets=np.array([0, 1, 2]))
    assert islands._dense_blocks(M, lay, "auto") is None
    assert islands._dense_blocks(M, lay, "sparse") is None  # sparse islands: sliced


def test_scene_islands_are_views_of_one_buffer_and_equal_the_sliced_ones() -> None:
    clcp = build(box_stacks(12, 3, seed=2), friction=4)
    problems = islands.island_problems(clcp.problem, clcp.layout, clcp.storage, "s")
    assert len(problems) == 12
    for p, want in zip(problems, _sliced(clcp.problem.M.tocsr(), clcp.layout), strict=True):
        np.testing.assert_array_equal(p.M, want)
    stack = _stacked([p.M for p in problems])
    assert np.shares_memory(stack, problems[0].M)  # no copy
    np.testing.assert_array_equal(stack, np.stack([p.M for p in problems]))


@pytest.mark.parametrize("order", ["reversed", "copies", "mixed"])
def test_stacked_copies_whatever_is_not_one_buffer_in_order(order) -> None:
    buf = np.arange(4 * 9, dtype=np.float64)
    views = [buf[9 * k: 9 * k + 9].reshape(3, 3) for k in range(4)]
    blocks = {"reversed": views[::-1], "copies": [v.copy() for v in views],
              "mixed": [views[0], views[1].copy(), views[2]]}[order]
    got = _stacked(blocks)
    np.testing.assert_array_equal(got, np.stack(blocks))
    assert not np.shares_memory(got, buf)


def test_island_problem_names_and_q() -> None:
    clcp = build(box_stacks(3, 2, seed=3), friction=4)
    problems = islands.island_problems(clcp.problem, clcp.layout, clcp.storage, "x")
    for k, p in enumerate(problems):
        assert isinstance(p, Problem) and p.name == f"x#{k + 1}"
        np.testing.assert_array_equal(p.q, clcp.problem.q[clcp.layout.unknowns(k)])


def test_cold_stacked_islands_are_certified_in_the_kernel() -> None:
    """Frictional box stacks have degenerate pairs whose basic z the tableau leaves at rounding
    level: the batched Lemke kernel certifies them with those set to 0 (TINY_Z) instead of
    handing the islands to the one-problem pipeline; same verdicts as one by one."""
    import lcpcli

    clcp = build(box_stacks(40, 3, seed=1), friction=4)
    problems = islands.island_problems(clcp.problem, clcp.layout, clcp.storage)
    M = np.stack([p.M for p in problems])
    q = np.stack([p.q for p in problems])
    res = lcpcli.solve_many(M, q, "lemke", threads=1)
    assert res.solved.all()
    assert not res.results  # none handed back
    for k in (0, 17, 39):
        assert lcpcli.solve(problems[k], "lemke").solved


def _next_step(stacks: int):
    import dataclasses

    from lcpcli.contact import solve

    scene = box_stacks(stacks, 3, seed=1)
    first = solve(build(scene, friction=4))
    rng = np.random.default_rng(0)
    nxt = build(dataclasses.replace(
        scene, velocity=scene.velocity * (1 + 0.01 * rng.normal(size=scene.velocity.shape)),
        omega=scene.omega * (1 + 0.01 * rng.normal(size=scene.omega.shape))), friction=4)
    return first, nxt


def test_the_pivoting_basis_starts_the_next_step_better_than_the_support() -> None:
    """Impact.basic (each island's basis as Lemke's kernel ended on it, degenerate pairs
    included) as the next step's basis0: same verdicts as cold and far fewer pivots than
    starting from z0's support, which the redundant contacts of a box stack make singular."""
    from lcpcli.contact import solve

    first, nxt = _next_step(30)
    assert first.basic is not None and first.basic.shape == (nxt.problem.n,)
    assert (first.basic >= (first.result.z > 0)).all()  # the support is basic, and more
    assert first.basic.sum() > (first.result.z > 0).sum()
    cold = solve(nxt)
    support = solve(nxt, z0=first.result.z)
    basis = solve(nxt, z0=first.result.z, basis0=first.basic)
    for impact in (cold, support, basis):
        assert impact.result.solved
    pivots = {k: sum(r["iterations"] for r in v.islands)
              for k, v in (("support", support), ("basis", basis))}
    assert pivots["basis"] < pivots["support"] / 2, pivots


def test_basis0_is_checked() -> None:
    from lcpcli.contact import solve
    from lcpcli.core.errors import OptionError

    first, nxt = _next_step(2)
    with pytest.raises(OptionError, match="needs its warm start"):
        solve(nxt, basis0=first.basic)
    with pytest.raises(OptionError, match="booleans"):
        solve(nxt, z0=first.result.z, basis0=first.basic[:-1])
    with pytest.raises(OptionError, match="booleans"):
        solve(nxt, z0=first.result.z, basis0=first.result.z)


def test_stack_pivot_basis_is_the_certificate_basis_where_nothing_is_degenerate() -> None:
    """pivot_basis (Lemke's final complementary basis) and basis (the certificate's pair
    states) agree on nondegenerate answers; a warm stack from a StackResult starts from it."""
    import lcpcli
    from lcpcli.core.certificate import BETWEEN

    rng = np.random.default_rng(5)
    A = rng.normal(size=(40, 8, 8))
    M = A @ A.transpose(0, 2, 1) / 8 + np.eye(8)
    q = rng.normal(size=(40, 8))
    cold = lcpcli.solve_many(M, q, "lemke", pivot_basis=True, record_basis=True)
    assert (cold.pivot_basis >= 0).all()
    np.testing.assert_array_equal(cold.pivot_basis == 1, cold.basis == BETWEEN)
    warm = lcpcli.solve_many(M, q * 1.001, "lemke", warm=cold, pivot_basis=True)
    assert warm.solved.all() and warm.warmed.all()
    assert lcpcli.solve_many(M, q, "lemke").pivot_basis is None


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_impulses_files_carry_the_basis_matched_by_name(tmp_path, suffix) -> None:
    from lcpcli.contact.warmstart import warm_start, write_impulses

    f = tmp_path / f"imp{suffix}"
    write_impulses(f, ["n[a]", "n[b]", "n[gone]"], np.array([1.0, 0.0, 3.0]),
                   basic=np.array([True, True, False]))
    z0, basis0, note = warm_start(f, ["n[b]", "n[new]", "n[a]"])
    assert z0.tolist() == [0.0, 0.0, 1.0] and "with its basis" in note
    assert basis0.tolist() == [True, False, True]  # degenerate n[b] stays basic; new: not


@pytest.mark.parametrize("bad", [[1, 0], [True], "yes", [True, None]])
def test_a_bad_basis_in_a_json_impulses_file_is_one_line(tmp_path, bad) -> None:
    import json

    from lcpcli.contact.warmstart import warm_start
    from lcpcli.core.errors import ProblemError

    f = tmp_path / "imp.json"
    f.write_text(json.dumps({"unknowns": ["a", "b"], "z": [1.0, 0.0], "basic": bad}))
    with pytest.raises(ProblemError, match="'basic' must be a list of 2 booleans"):
        warm_start(f, ["a", "b"])


def test_a_bad_basis_in_an_npz_impulses_file_is_refused(tmp_path) -> None:
    from lcpcli.contact.warmstart import warm_start
    from lcpcli.core.errors import ProblemError

    f = tmp_path / "imp.npz"
    np.savez(f, z=np.array([1.0, 0.0]), unknowns=np.array(["a", "b"]),
             basic=np.array([1.0, 0.0]))
    with pytest.raises(ProblemError, match="'basic' must be 2 booleans"):
        warm_start(f, ["a", "b"])


def test_cli_steps_from_the_impulses_file_with_its_basis(tmp_path) -> None:
    """contact-matrix --solve --impulses writes the basis; --z0 of that file starts from it
    (fewer pivots than from the same impulses without their basis)."""
    import json

    from typer.testing import CliRunner

    from lcpcli.cli import app
    from lcpcli.contact.scene import write_scene_hdf5
    from lcpcli.contact.warmstart import write_impulses

    first, nxt = _next_step(12)
    scene_file = tmp_path / "next.h5"
    write_scene_hdf5(nxt.scene, scene_file)
    imp = tmp_path / "imp.json"

    write_impulses(imp, nxt.unknowns, first.result.z, basic=first.basic)
    bare = tmp_path / "bare.json"
    write_impulses(bare, nxt.unknowns, first.result.z)
    runner = CliRunner()
    pivots = {}
    for name, f in (("basis", imp), ("support", bare)):
        out = runner.invoke(app, ["contact-matrix", str(scene_file), "--friction", "4",
                                  "--solve", "--z0", str(f), "--json"])
        assert out.exit_code == 0, out.output
        data = json.loads(out.stdout)
        assert data["status"] == "solved"
        pivots[name] = sum(r["iterations"] for r in data["islands"]["per_island"])
    assert pivots["basis"] < pivots["support"], pivots
    again = tmp_path / "again.npz"
    out = runner.invoke(app, ["contact-matrix", str(scene_file), "--friction", "4", "--solve",
                              "--z0", str(imp), "--impulses", str(again)])
    assert out.exit_code == 0, out.output
    assert np.load(again)["basic"].dtype == bool
