"""The single-source kernels (lcpcli/solvers/kernels/src/lcp_stack.h), compiled for the CPU.

The "cuda" backend compiles the same C text for a device; CI has no GPU, so these tests are
where that code is checked on every run: the "c" backend (the text through the C compiler)
must give what the "cpu" backend gives, problem by problem (status, z, pivots or sweeps, the
certified error), on stacks of every kind: positive definite, P, PSD, degenerate (ties that
need the lexicographic ratio test), infeasible, badly scaled (equilibrated first), box LCPs.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.api import solve_many
from lcpcli.core.errors import OptionError
from lcpcli.core.tolerances import PIVOT_TOL, POLISHED, TIE_TOL
from lcpcli.solvers import batched
from lcpcli.solvers.backends import cuda
from lcpcli.solvers.kernels import stack_c


def same_answers(M, q, method, lower=None, upper=None, **options):
    """solve_many with backend "c" and "cpu": identical arrays, problem by problem."""
    a = solve_many(M, q, method, lower=lower, upper=upper, threads=2, **options)
    b = solve_many(M, q, method, lower=lower, upper=upper, threads=2, backend="c", **options)
    np.testing.assert_array_equal(a.status, b.status)
    np.testing.assert_array_equal(a.z, b.z)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    np.testing.assert_array_equal(a.error, b.error)
    assert a.method == b.method
    return a, b


def kernel_codes(M, q, balance=(4, 8, 12), polished=POLISHED, warp=False):
    """The single-source Lemke kernel alone (no CPU fallback): code, z, pivots, error;
    ``warp``: the warp-per-problem code paths, with one lane."""
    K, n = q.shape
    z, w = np.zeros((K, n)), np.zeros((K, n))
    code, it = np.ones(K, np.int8), np.zeros(K, np.int64)
    err, res = np.full(K, np.inf), np.full(K, np.nan)
    stack_c.lemke_stack(M, q, None, 10 * n + 10, PIVOT_TOL, TIE_TOL, 1e-9, polished, balance,
                        z, w, code, it, err, res, 1, warp)
    return code, z, it, err


def pd(K, n, seed):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    B = rng.standard_normal((K, n, n)) * 0.3
    return A @ A.transpose(0, 2, 1) / n + np.eye(n) + (B - B.transpose(0, 2, 1)), \
        rng.standard_normal((K, n))


def test_the_c_kernel_certifies_a_positive_definite_stack_itself():
    """Not a pass-through: the single-source kernel certifies (almost) every PD problem, with
    the CPU kernel's bits."""
    M, q = pd(400, 9, seed=3)
    code, z, it, err = kernel_codes(M, q)
    assert (code == batched.KERNEL_SOLVED).mean() > 0.95
    res = solve_many(M, q, "lemke", threads=1)
    ok = code == batched.KERNEL_SOLVED
    np.testing.assert_array_equal(z[ok], res.z[ok])
    np.testing.assert_array_equal(it[ok], res.iterations[ok])
    np.testing.assert_array_equal(err[ok], res.error[ok])


@pytest.mark.parametrize("scale", [1.0, 1e6, 1e-7])
def test_badly_scaled_stacks_are_equilibrated_as_on_the_cpu(scale):
    M, q = pd(200, 12, seed=4)
    rng = np.random.default_rng(5)
    D = 2.0 ** rng.integers(-20, 20, size=(200, 12))
    M = M * D[:, :, None] * scale
    q = q * D
    code, *_ = kernel_codes(M, q)
    assert (code == batched.KERNEL_SOLVED).mean() > 0.9
    same_answers(M, q, "lemke")


KINDS = ["pd", "p", "psd", "degenerate", "infeasible", "mixed", "scaled"]


def make(kind, K=150, n=6):
    rng = np.random.default_rng(11)
    if kind == "pd":
        return pd(K, n, seed=6)
    if kind == "p":  # triangular with positive diagonal: P-matrices, not PD
        M = np.triu(rng.standard_normal((K, n, n)) * 4, 1) + np.eye(n) * rng.uniform(
            0.1, 2, (K, 1, n))
        return M, rng.standard_normal((K, n))
    if kind == "psd":  # rank-deficient A A^T: many solutions, rays possible
        A = rng.standard_normal((K, n, 2))
        return A @ A.transpose(0, 2, 1), rng.standard_normal((K, n))
    if kind == "degenerate":  # small integers: ties in the ratio test everywhere
        M = rng.integers(-2, 3, (K, n, n)).astype(float) + 3 * np.eye(n)
        return M, rng.integers(-2, 2, (K, n)).astype(float)
    if kind == "infeasible":  # M = -I, q < 0 somewhere: no solution (a ray)
        return np.broadcast_to(-np.eye(n), (K, n, n)).copy(), rng.standard_normal((K, n)) - 0.5
    if kind == "scaled":  # rows and columns 2^+-30 apart: equilibrated, some polished
        M, q = pd(K, n, seed=13)
        D, E = 2.0 ** rng.integers(-30, 30, (K, n)), 2.0 ** rng.integers(-30, 30, (K, n))
        return M * D[:, :, None] * E[:, None, :], q * D
    return rng.standard_normal((K, n, n)), rng.standard_normal((K, n))


@pytest.mark.parametrize("kind", KINDS)
def test_lemke_stacks_of_every_kind(kind):
    same_answers(*make(kind), "lemke")


@pytest.mark.parametrize("warp", [False, True])
@pytest.mark.parametrize("polished", [POLISHED, 0.0])  # 0: every end basis re-solved by LU
@pytest.mark.parametrize("kind", KINDS)
def test_the_kernel_alone_certifies_what_the_cpu_kernel_certifies(kind, polished, warp):
    """Kernel against kernel (no fallback): the same codes, pivots, z and errors, polish and
    equilibration included; for the thread and the warp code paths (the warp kernel's
    flattened pivot and label-propagation blocks, run with one lane)."""
    from lcpcli.solvers.kernels import batch

    M, q = make(kind)
    K, n = q.shape
    code, z, it, err = kernel_codes(M, q, polished=polished, warp=warp)
    o = batched.StackOut.empty(K, n)
    batch.lemke_stack(M, q, None, 10 * n + 10, PIVOT_TOL, TIE_TOL, 1e-9, o.z, o.w, o.code,
                      o.iterations, o.error, o.residual, 1, (4, 8, 12), polished)
    np.testing.assert_array_equal(code, o.code)
    ok = code == batched.KERNEL_SOLVED
    np.testing.assert_array_equal(z[ok], o.z[ok])
    np.testing.assert_array_equal(it[ok], o.iterations[ok])
    np.testing.assert_array_equal(err[ok], o.error[ok])


def test_lexicographic_rule_on_cycling_prone_ties():
    """Cyclic matrices with all-equal q (every ratio test ties): Lemke needs the
    lexicographic rule (Cottle-Pang-Stone 4.9); the kernel follows the CPU's pivots."""
    base = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 2.0], [2.0, 0.0, 1.0]])
    M = np.stack([base, base.T, base * 2, np.ones((3, 3)) + np.eye(3), np.eye(3)])
    q = -np.ones((5, 3))
    a, b = same_answers(M, q, "lemke")
    assert a.solved.all()
    code, *_ = kernel_codes(M, q)
    assert (code == batched.KERNEL_SOLVED).all()


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 7), st.integers(0, 2**32 - 1), st.sampled_from([1, 3, 100]))
def test_random_integer_stacks_match_the_cpu(n, seed, spread):
    rng = np.random.default_rng(seed)
    K = 20
    M = rng.integers(-spread, spread + 1, (K, n, n)).astype(float)
    M += np.eye(n) * rng.integers(0, 2 * spread + 1, (K, 1, 1))
    q = rng.integers(-spread, spread + 1, (K, n)).astype(float)
    same_answers(M, q, "lemke")


@pytest.mark.parametrize("method", ["pgs", "psor"])
def test_sor_stacks_and_box_lcps(method):
    M, q = pd(120, 8, seed=7)
    M = (M + M.transpose(0, 2, 1)) / 2
    same_answers(M, q, method)
    lo, up = -np.ones(8), np.full(8, 0.5)
    a, _ = same_answers(M, q, method, lower=lo, upper=up)
    assert a.solved.mean() > 0.9


def test_covering_vector_and_max_iter_options():
    M, q = pd(60, 5, seed=8)
    same_answers(M, q, "lemke", covering=[1.0, 2.0, 0.5, 1.0, 3.0])
    same_answers(M, q, "lemke", max_iter=2)


def test_the_source_ships_with_the_package_and_has_both_entry_points():
    text = cuda.source()
    for name in ("lcp_lemke_one", "lcp_sor_one", "lcp_certify", "__global__"):
        assert name in text
    dw, iw = stack_c.workspace("lemke", 12)
    assert dw > 12 * 13 and iw > 0


@pytest.mark.skipif(cuda.device_present(), reason="a CUDA device is present")
def test_cuda_without_a_device_is_one_clear_option_error():
    M, q = pd(4, 3, seed=9)
    with pytest.raises(OptionError, match="needs CuPy and a CUDA device"):
        solve_many(M, q, "lemke", backend="cuda")
    assert batched.choose_backend("auto", 10**7, 12) == "cpu"
    assert solve_many(M, q, "lemke", backend="auto").solved.all()


def test_cli_backend_c_gives_the_cpu_results(cli, tmp_path):
    import h5py

    from lcpcli.io.stack import write_stack

    M, q = pd(200, 6, seed=10)
    M[3], q[3] = 0.0, -1.0  # no solution (Farkas): handed back, proved by the CPU pipeline
    write_stack(tmp_path / "s.h5", M, q)
    outs = {}
    for name in ("cpu", "c"):
        out = tmp_path / f"{name}.h5"
        res = cli("solve", str(tmp_path / "s.h5"), "-o", str(out), "--backend", name, "-q")
        assert res.returncode == 1, res.stderr  # one problem has no solution
        with h5py.File(out) as f:
            outs[name] = (f["s"]["status"][...], f["s"]["z"][...])
    np.testing.assert_array_equal(outs["c"][0], outs["cpu"][0])
    np.testing.assert_array_equal(outs["c"][1], outs["cpu"][1])


@pytest.mark.skipif(cuda.device_present(), reason="a CUDA device is present")
def test_cli_backend_cuda_without_a_device_exits_2_with_one_line(cli, tmp_path):
    from lcpcli.io.stack import write_stack

    M, q = pd(10, 3, seed=12)
    write_stack(tmp_path / "s.h5", M, q)
    res = cli("solve", str(tmp_path / "s.h5"), "--backend", "cuda", "-q")
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [f"lcpcli: error: {cuda.NEEDS}"]
    res = cli("solve", str(tmp_path / "s.h5"), "--backend", "tpu", "-q")
    assert res.returncode == 2 and "unknown batch backend 'tpu'" in res.stderr


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 9), st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
def test_certificate_matches_the_core_definition(n, seed, box, blocks):
    """lcp_certify and its warp version (label propagation for the blocks) against
    lcpcli.core's certificate, on answers near and far from a solution, block-diagonal M
    (several blocks), zeros in z."""
    from lcpcli.core._certificate import certify_arrays

    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-3, 4, (n, 1))
    if blocks:
        part = rng.integers(0, 3, n)
        M = M * (part[:, None] == part[None, :])
    q = rng.standard_normal(n)
    z = np.where(rng.random(n) < 0.4, 0.0, rng.random(n))
    lo, up = (-rng.random(n), rng.random(n)) if box else (None, None)
    if box:  # some pairs on a bound, the rest inside
        z = np.clip(z, lo, up)
        at = rng.random(n) < 0.4
        z[at] = np.where(rng.random(n) < 0.5, lo, up)[at]
    ref = certify_arrays(M, q, z, 0, lo, up, np.zeros(n))
    for warp in (False, True):
        status, error, residual = stack_c.certify(M, q, z, lo, up, warp=warp)
        assert status == ref[0]
        if status == 0:
            assert error == ref[1] and residual == ref[4]


# ----------------------------------------------------------- the cuda backend's host code
class _FakeArray(np.ndarray):
    """A host array standing in for a CuPy array (``get`` copies to numpy)."""

    @property
    def __cuda_array_interface__(self):  # what marks device memory to lcpcli.solve_many
        return {"shape": self.shape, "typestr": self.dtype.str, "version": 3}

    def get(self, stream=None, out=None, blocking=True):
        if out is None:
            return np.array(self)
        assert isinstance(out, np.ndarray) and out.flags.c_contiguous  # as CuPy requires
        out[...] = self
        return out

    def set(self, a, stream=None):
        assert self.shape == a.shape and a.flags.c_contiguous
        self[...] = a


class _FakeStream:
    """A stand-in CUDA stream: a context manager that makes itself current."""

    current = None

    def __init__(self, non_blocking=False):
        self.prev = None

    def __enter__(self):
        self.prev, _FakeStream.current = _FakeStream.current, self
        return self

    def __exit__(self, *exc):
        _FakeStream.current = self.prev

    def synchronize(self):
        pass


class _FakeKernel:
    """Checks each launch's arguments against the kernel's C signature (parsed from the
    shipped source), then runs the single-source CPU build with them."""

    C_TYPES = {"double *": np.float64, "const double *": np.float64, "lcp_i64 *": np.int64,
               "signed char *": np.int8}
    SCALARS = {"lcp_i64": np.int64, "int": np.int32, "double": np.float64}

    def __init__(self, name, params):
        self.name, self.params = name, params
        self.max_dynamic_shared_size_bytes = 0

    def __call__(self, grid, block, args, shared_mem=0):
        assert len(args) == len(self.params), (self.name, len(args), len(self.params))
        a = {}
        for (ctype, pname), value in zip(self.params, args, strict=True):
            if ctype in self.C_TYPES:
                assert isinstance(value, np.ndarray) and value.flags.c_contiguous, pname
                assert value.dtype == self.C_TYPES[ctype], (pname, value.dtype)
            else:
                assert type(value) is self.SCALARS[ctype], (pname, type(value), ctype)
            a[pname] = value
        K, n = int(a["K"]), int(a["n"])
        warp = "warp" in self.name
        kind = "lemke" if "lemke" in self.name else "sor"
        if warp:  # groups of `lanes` lanes, each with its fast and cold workspace
            lanes, stage = int(a["lanes"]), bool(a["stage"])
            assert lanes in (8, 16, 32) and block[0] % lanes == 0
            assert not stage or a["use_shared"]  # staging is in shared memory
            fast, cold = stack_c.group_slots(n)
            assert a["work"].size >= grid[0] * block[0] // lanes * (fast + cold)
            if a["use_shared"]:
                assert shared_mem >= block[0] // lanes * 8 * fast
        else:
            slots = grid[0] * block[0]
            dw, iw = stack_c.workspace(kind, n)
            assert a["work"].size >= slots * dw and a["iwork"].size >= slots * iw
        out = [a[k].reshape(K, -1)[:, :n] if k in ("z", "w") else a[k]
               for k in ("z", "w", "code", "iters", "err", "res")]
        M, q = a["M"].reshape(K, n, n), a["q"].reshape(K, n)
        if kind == "lemke":
            bal = None if a["balanced"] < 0 else (int(a["balanced"]), int(a["q_balanced"]),
                                                  int(a["max_rounds"]))
            stack_c.lemke_stack(M, q, a["d"] if a["use_d"] else None, int(a["max_iter"]),
                                float(a["piv_tol"]), float(a["tie_tol"]), float(a["tol"]),
                                float(a["polished"]), bal, *out, 1, warp,
                                bool(a["stage"]) if warp else True)
        else:
            lo, up = (a["lo"], a["up"]) if a["bounded"] else (None, None)
            stack_c.sor_stack(M, q, lo, up, float(a["omega"]), int(a["max_iter"]),
                              float(a["tol"]), *out, 1)


def _fake_cupy():
    import re
    import types

    source = cuda.source()
    kernels = {}  # kernel name -> [(C type, parameter name)], e.g. ("const double *", "M")
    for name, params in re.findall(
            r'extern "C" __global__ void (?:__launch_bounds__\([^)]*\) )?(\w+)\(([^)]*)\)',
            source):
        kernels[name] = [(m.group(1).strip(), m.group(2)) for m in
                         (re.match(r"(.*?)(\w+)$", " ".join(p.split())) for p in params.split(","))]

    def wrap(x):
        return np.asarray(x).view(_FakeArray)

    cp = types.SimpleNamespace(
        ndarray=_FakeArray, float64=np.float64, int64=np.int64, int8=np.int8,
        asarray=lambda x, dtype=None: wrap(np.asarray(x, dtype=dtype)),
        ascontiguousarray=lambda x, dtype=None: wrap(np.ascontiguousarray(x, dtype=dtype)),
        zeros=lambda *s, **k: wrap(np.zeros(*s, **k)), ones=lambda *s, **k: wrap(np.ones(*s, **k)),
        full=lambda *s, **k: wrap(np.full(*s, **k)), empty=lambda *s, **k: wrap(np.empty(*s, **k)),
        broadcast_to=lambda x, s: wrap(np.broadcast_to(x, s)),
        clip=lambda x, lo, up, out=None: np.clip(x, lo, up, out=out),
        from_dlpack=lambda x: wrap(np.from_dlpack(x)))
    pinned = []  # the stand-in's page-locked buffers (kept for the test's life)

    def alloc_pinned_memory(size):
        pinned.append(np.zeros(size, np.uint8))
        return pinned[-1]

    def pointerGetAttributes(ptr):  # noqa: N802 - CuPy's name
        inside = any(b.ctypes.data <= ptr < b.ctypes.data + b.size for b in pinned)
        return types.SimpleNamespace(type=1 if inside else 0)

    runtime = types.SimpleNamespace(getDeviceCount=lambda: 1, memGetInfo=lambda: (8 << 30, 8 << 30),
                                    pointerGetAttributes=pointerGetAttributes)
    module = types.SimpleNamespace(get_function=lambda name: _FakeKernel(name, kernels[name]))
    cp.cuda = types.SimpleNamespace(runtime=runtime, Device=lambda: types.SimpleNamespace(id=0),
                                    Stream=_FakeStream, alloc_pinned_memory=alloc_pinned_memory,
                                    get_current_stream=lambda: _FakeStream.current)
    cp.RawModule = lambda code, options: module
    assert len(kernels) == 3, sorted(kernels)  # every __global__ kernel's signature was read
    return cp


@pytest.fixture
def fake_device(monkeypatch):
    """The cuda backend with a stand-in for CuPy and a device (arguments checked against the
    C signatures; the kernels run by the CPU build of the same source)."""
    cp = _fake_cupy()
    monkeypatch.setattr(cuda, "_import_cupy", lambda: cp)
    monkeypatch.setattr(cuda, "device_present", lambda: True)
    cuda._module.cache_clear()
    batched._LOADED.pop("cuda", None)
    yield cp
    cuda._module.cache_clear()
    batched._LOADED.pop("cuda", None)


@pytest.mark.parametrize("chunked", [False, True])
@pytest.mark.parametrize("variant", ["thread", "warp"])
@pytest.mark.parametrize("kind", ["pd", "degenerate", "scaled", "mixed"])
def test_cuda_backend_host_code_with_a_stand_in_device(fake_device, monkeypatch, kind, variant,
                                                       chunked):
    """Host arrays go in chunks on two streams (chunked: 7 problems a chunk, the last one
    short), device arrays in one launch: both give the CPU's answers."""
    monkeypatch.setattr(cuda, "LEMKE_VARIANT", variant)
    if chunked:
        n = make(kind)[1].shape[1]
        monkeypatch.setattr(cuda, "CHUNK_BYTES", 7 * 8 * n * n)
        assert len(cuda._chunks(150, n)) == 22
    M, q = make(kind)
    ref = solve_many(M, q, "lemke")
    res = solve_many(M, q, "lemke", backend="cuda")
    np.testing.assert_array_equal(res.status, ref.status)
    np.testing.assert_array_equal(res.z, ref.z)
    dev = solve_many(fake_device.asarray(M), fake_device.asarray(q), "lemke", backend="cuda")
    assert isinstance(dev.z, _FakeArray)
    np.testing.assert_array_equal(dev.status, ref.status)
    np.testing.assert_array_equal(np.asarray(dev.z), ref.z)
    np.testing.assert_array_equal(dev.iterations, ref.iterations)


@pytest.mark.parametrize("method", ["lemke", "pgs"])
def test_cuda_backend_pinned_in_pinned_out_with_a_stand_in_device(fake_device, monkeypatch,
                                                                   method):
    """A stack whose M is in pinned memory gets its results in pinned memory (copied chunk by
    chunk as the device goes on), with the CPU's answers; a pageable M, numpy's memory."""
    monkeypatch.setattr(cuda, "CHUNK_BYTES", 7 * 8 * 6 * 6)
    M, q = pd(50, 6, seed=21)
    M = (M + M.transpose(0, 2, 1)) / 2
    mem = fake_device.cuda.alloc_pinned_memory(M.nbytes)
    Mp = np.ndarray(M.shape, np.float64, buffer=mem)
    Mp[...] = M
    ref = solve_many(M, q, method)
    for a, pinned in ((Mp, True), (M, False)):
        res = solve_many(a, q, method, backend="cuda")
        for key in ("z", "w", "iterations", "error", "residual"):
            assert cuda._pinned(getattr(res, key), fake_device) is pinned, key
        np.testing.assert_array_equal(res.status, ref.status)
        np.testing.assert_array_equal(res.z, ref.z)
        np.testing.assert_array_equal(res.iterations, ref.iterations)


@pytest.mark.parametrize("chunked", [False, True])
def test_cuda_backend_sor_and_box_with_a_stand_in_device(fake_device, monkeypatch, chunked):
    """Projected SOR on LCPs and box LCPs (bounds shared or per problem), in one chunk or in
    chunks of 9 problems."""
    M, q = pd(80, 7, seed=14)
    M = (M + M.transpose(0, 2, 1)) / 2
    lo, up = -np.ones(7), np.full(7, 0.5)
    if chunked:
        monkeypatch.setattr(cuda, "CHUNK_BYTES", 9 * 8 * 7 * 7)
    per_problem = {"lower": np.tile(lo, (80, 1)) * np.linspace(0.5, 1, 80)[:, None],
                   "upper": np.tile(up, (80, 1))}
    for kw in ({}, {"lower": lo, "upper": up}, per_problem):
        ref = solve_many(M, q, "pgs", **kw)
        res = solve_many(M, q, "pgs", backend="cuda", **kw)
        np.testing.assert_array_equal(res.status, ref.status)
        np.testing.assert_array_equal(res.z, ref.z)
        dev = solve_many(fake_device.asarray(M), fake_device.asarray(q), "pgs",
                         backend="cuda", **kw)
        np.testing.assert_array_equal(dev.status, ref.status)
        np.testing.assert_array_equal(np.asarray(dev.z), ref.z)


@pytest.mark.parametrize("n", [1, 2, 40, 130])  # 130: the warp's tableau in global memory
def test_cuda_backend_sizes_with_a_stand_in_device(fake_device, monkeypatch, n):
    monkeypatch.setattr(cuda, "LEMKE_VARIANT", "warp")
    M, q = pd(12, n, seed=15)
    ref = solve_many(M, q, "lemke")
    res = solve_many(M, q, "lemke", backend="cuda")
    np.testing.assert_array_equal(res.status, ref.status)
    np.testing.assert_array_equal(res.z, ref.z)


def test_device_arrays_with_auto_and_with_a_host_backend(fake_device):
    M, q = pd(40, 6, seed=16)
    ref = solve_many(M, q)
    dev = solve_many(fake_device.asarray(M), fake_device.asarray(q), backend="auto")
    assert dev.method == ref.method
    np.testing.assert_array_equal(dev.status, ref.status)
    np.testing.assert_array_equal(np.asarray(dev.z), ref.z)
    with pytest.raises(OptionError, match="device memory"):
        solve_many(fake_device.asarray(M), fake_device.asarray(q), backend="cpu")


def test_warp_launch_shapes_fit_their_shared_memory():
    """The warp kernel's launch shape for every size: whole groups per warp, at most
    SHARED_BYTES per block, staged when asked, device memory (never staged) when one warp's
    groups do not fit."""
    for n in range(1, 200):
        for lanes in (8, 16, 32):
            for stage in (True, False):
                g = cuda.warp_launch(n, lanes, stage)
                fast, cold = stack_c.group_slots(n)
                assert g.lanes == lanes and g.groups == g.warps * 32 // lanes
                assert g.slots == fast + cold
                if g.shared:
                    assert g.shared == g.groups * 8 * fast <= cuda.SHARED_BYTES
                    assert g.stage == stage
                else:
                    assert 8 * fast * 32 // lanes > cuda.SHARED_BYTES and not g.stage
    with pytest.raises(OptionError, match="8, 16 or 32"):
        cuda.warp_launch(12, 4)
    assert cuda.warp_row(10**9) == cuda.WARP_TABLE[-1]


def test_warps_per_block_put_the_most_warps_on_a_multiprocessor():
    """The block shape by shared memory and registers: at n = 50 (32 lanes, 27,832 bytes of
    shared memory a problem with the device's 32-bit indices two to a slot) blocks of 2 warps
    place 8 problems on a multiprocessor where blocks of 3, the most SHARED_BYTES holds, place
    6; every choice is a block within SHARED_BYTES whose residency no other size beats."""
    fast, _ = stack_c.group_slots(50)
    assert 8 * fast == 27_832
    assert cuda.warps_per_block(8 * fast, 1) == 2

    def resident(w, warp_bytes, mb):
        blocks = min(cuda.SM_SHARED_BYTES // (w * warp_bytes + cuda.BLOCK_RESERVED_BYTES),
                     8 * mb // w)
        return w * blocks

    assert resident(2, 8 * fast, 1) == 8 and resident(3, 8 * fast, 1) == 6
    for n in range(1, 120):
        fast, _ = stack_c.group_slots(n)
        for per_warp in (1, 2, 4):
            warp_bytes = 8 * fast * per_warp
            if warp_bytes > cuda.SHARED_BYTES:
                continue
            for mb in (1, 2, 3, 4):
                w = cuda.warps_per_block(warp_bytes, mb)
                assert 1 <= w <= cuda.WARPS_PER_BLOCK and w * warp_bytes <= cuda.SHARED_BYTES
                fits = [v for v in range(1, cuda.WARPS_PER_BLOCK + 1)
                        if v * warp_bytes <= cuda.SHARED_BYTES]
                assert resident(w, warp_bytes, mb) == max(resident(v, warp_bytes, mb)
                                                          for v in fits)
