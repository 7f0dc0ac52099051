"""The "cuda" backend against the CPU, on a CUDA device (skipped where there is none: CI).

The kernels are the single-source ones tests/solvers/test_single_source.py checks on the CPU
on every run; here the device build must give the same verdicts (and, compiled without FMA
contraction, the same z) as ``backend="cpu"``, from host arrays and from device arrays.
"""

from __future__ import annotations

import numpy as np
import pytest

from lcpcli.api import solve_many
from lcpcli.solvers.backends import cuda

cp = pytest.importorskip("cupy")
if not cuda.device_present():
    pytest.skip("no CUDA device", allow_module_level=True)


def stack(kind: str, K: int, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    if kind == "pd":
        A = rng.standard_normal((K, n, n))
        M = A @ A.transpose(0, 2, 1) / n + np.eye(n)
    elif kind == "degenerate":
        M = rng.integers(-2, 3, (K, n, n)).astype(float) + 3 * np.eye(n)
        return M, rng.integers(-2, 2, (K, n)).astype(float)
    elif kind == "scaled":
        A = rng.standard_normal((K, n, n))
        D = 2.0 ** rng.integers(-20, 20, (K, n))
        M = (A @ A.transpose(0, 2, 1) + np.eye(n)) * D[:, :, None]
        return M, rng.standard_normal((K, n)) * D
    else:
        M = rng.standard_normal((K, n, n))
    return M, rng.standard_normal((K, n))


def assert_same(a, b):
    np.testing.assert_array_equal(a.status, b.status)
    np.testing.assert_array_equal(b.z.get() if isinstance(b.z, cp.ndarray) else b.z, a.z)
    np.testing.assert_array_equal(a.iterations, b.iterations)


@pytest.fixture(params=["thread", "warp"])
def variant(request, monkeypatch):
    """Lemke's device kernel: one thread, or a group of lanes of a warp, per problem."""
    monkeypatch.setattr(cuda, "LEMKE_VARIANT", request.param)
    return request.param


@pytest.mark.parametrize("kind", ["pd", "degenerate", "scaled", "mixed"])
@pytest.mark.parametrize("method", ["lemke", "pgs"])
def test_cuda_matches_cpu_from_host_arrays(kind, method, variant):
    M, q = stack(kind, 3000, 12, seed=1)
    if method == "pgs":
        M = (M + M.transpose(0, 2, 1)) / 2
    assert_same(solve_many(M, q, method), solve_many(M, q, method, backend="cuda"))


@pytest.mark.parametrize("n", [1, 5, 33, 50, 130])  # 130: the warp's tableau in global memory
def test_cuda_sizes(n, variant):
    M, q = stack("pd", 300, n, seed=5)
    assert_same(solve_many(M, q, "lemke"), solve_many(M, q, "lemke", backend="cuda"))


def test_cuda_from_device_arrays_returns_device_arrays(variant):
    M, q = stack("pd", 5000, 50, seed=2)
    ref = solve_many(M, q, "lemke")
    res = solve_many(cp.asarray(M), cp.asarray(q), "lemke", backend="cuda")
    assert isinstance(res.z, cp.ndarray) and isinstance(res.w, cp.ndarray)
    assert_same(ref, res)


def test_cuda_takes_dlpack_producers_without_a_host_copy():
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("torch without CUDA")
    M, q = stack("pd", 1000, 12, seed=3)
    res = solve_many(torch.as_tensor(M, device="cuda"), torch.as_tensor(q, device="cuda"),
                     "lemke", backend="cuda")
    assert isinstance(res.z, cp.ndarray)
    assert_same(solve_many(M, q, "lemke"), res)
    assert torch.from_dlpack(res.z).is_cuda


def test_box_lcps_on_the_device():
    M, q = stack("pd", 2000, 10, seed=4)
    M = (M + M.transpose(0, 2, 1)) / 2
    lo, up = -np.ones(10), np.full(10, 0.5)
    assert_same(solve_many(M, q, "pgs", lower=lo, upper=up),
                solve_many(M, q, "pgs", lower=lo, upper=up, backend="cuda"))


def test_auto_picks_the_device_for_large_stacks():
    from lcpcli.solvers import batched

    K = batched.AUTO_CUDA_MIN_BYTES // (8 * 12 * 12) + 1
    assert batched.choose_backend("auto", K, 12) == "cuda"
    assert batched.choose_backend("auto", K - 2, 12) == "cpu"


@pytest.mark.parametrize("n", [12, 50])
@pytest.mark.parametrize("blocks", [1, 4])
def test_warp_register_budgets_change_no_answer(n, blocks, monkeypatch):
    """The warp kernel built with another __launch_bounds__ register budget (a speed choice,
    WARP_MIN_BLOCKS) gives the CPU's status, z and pivots."""
    monkeypatch.setattr(cuda, "LEMKE_VARIANT", "warp")
    monkeypatch.setattr(cuda, "EXTRA_OPTIONS", (f"-DLCP_WARP_MIN_BLOCKS={blocks}",))
    M, q = stack("mixed", 1500, n, seed=9)
    assert_same(solve_many(M, q, "lemke"), solve_many(M, q, "lemke", backend="cuda"))


@pytest.mark.parametrize("n", [3, 12, 24, 40])
@pytest.mark.parametrize("lanes", [8, 16, 32])
@pytest.mark.parametrize("stage", [True, False])
def test_lane_groups_and_staging_change_no_answer(n, lanes, stage, monkeypatch):
    """Every WARP_TABLE choice (lanes per problem, M/q/z/w staged in shared memory or not)
    gives the CPU's status, z and pivots: several problems per warp when lanes < 32."""
    monkeypatch.setattr(cuda, "LEMKE_VARIANT", "warp")
    monkeypatch.setattr(cuda, "WARP_TABLE", ((1 << 62, lanes, stage, 4 if n <= 32 else 1),))
    for kind in ("mixed", "degenerate"):
        M, q = stack(kind, 700, n, seed=n + lanes)
        assert_same(solve_many(M, q, "lemke"), solve_many(M, q, "lemke", backend="cuda"))


@pytest.mark.parametrize("method", ["lemke", "pgs"])
def test_host_stacks_in_many_chunks(method, monkeypatch):
    """A host stack cut into many chunks (two streams) gives the CPU's answers and the
    one-chunk run's numbers, every problem in its place: a stack of uneven length, so the
    last chunk is short, with box bounds for PGS."""
    M, q = stack("mixed", 1001, 12, seed=11)
    bounds = {}
    if method == "pgs":
        M = (M + M.transpose(0, 2, 1)) / 2
        bounds = {"lower": -np.ones(12), "upper": np.full(12, 0.5)}
    whole = solve_many(M, q, method, backend="cuda", **bounds)
    monkeypatch.setattr(cuda, "CHUNK_BYTES", 37 * 8 * 12 * 12)
    assert len(cuda._chunks(1001, 12)) == 28
    got = solve_many(M, q, method, backend="cuda", **bounds)
    assert_same(solve_many(M, q, method, **bounds), got)
    for key in ("z", "w", "status", "iterations", "error", "residual"):
        np.testing.assert_array_equal(getattr(got, key), getattr(whole, key), err_msg=key)


def test_pinned_in_pinned_out(monkeypatch):
    """A host stack in pinned memory, in several chunks: results in pinned memory, the CPU's
    answers, and the same numbers as from pageable memory."""
    import cupyx

    monkeypatch.setattr(cuda, "CHUNK_BYTES", 300 * 8 * 12 * 12)  # 7 chunks, the last short
    M, q = stack("mixed", 2000, 12, seed=12)
    Mp = cupyx.empty_pinned(M.shape, np.float64)
    Mp[...] = M
    pageable = solve_many(M, q, "lemke", backend="cuda")
    got = solve_many(Mp, q, "lemke", backend="cuda")
    assert cuda._pinned(got.z, cp) and not cuda._pinned(pageable.z, cp)
    assert_same(solve_many(M, q, "lemke"), got)
    for key in ("z", "w", "status", "iterations", "error", "residual"):
        np.testing.assert_array_equal(getattr(got, key), getattr(pageable, key), err_msg=key)
