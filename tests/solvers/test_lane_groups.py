"""The single-source kernel's lane code paths, run on the CPU by threads standing in for lanes.

The device runs ``lcp_lemke_group`` (the warp kernel's body) on a group of 8, 16 or 32 lanes per
problem; the CPU build runs it with one lane.  ``lanes_harness.cpp`` compiles the same header with
``LCP_EMULATE_LANES`` (each lane a thread, ``LCP_SYNC`` a barrier, shuffles and votes exchanged
through memory), so that every split loop, reduction and hand-over between lanes is checked here
against the one-lane answers bit for bit, on a machine without a GPU.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.core.tolerances import PIVOT_TOL, POLISHED, TIE_TOL
from lcpcli.solvers.kernels import stack_c

SRC = Path(stack_c.__file__).parent / "src"
HARNESS = Path(__file__).with_name("lanes_harness.cpp")
CXX = shutil.which("g++") or shutil.which("clang++")
pytestmark = pytest.mark.skipif(CXX is None, reason="no C++ compiler for the lane harness")
F64 = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
I64 = np.ctypeslib.ndpointer(np.int64, flags="C_CONTIGUOUS")
I8 = np.ctypeslib.ndpointer(np.int8, flags="C_CONTIGUOUS")


def build_harness(folder, defines=(), src=SRC):
    """The lane harness compiled with the header's ``-D`` speed choices ``defines`` (``src``:
    the folder of lcp_stack.h), loaded."""
    lib = folder / "liblanes.so"
    subprocess.run([CXX, "-std=c++20", "-O1", "-shared", "-fPIC", "-pthread",
                    "-Drestrict=__restrict__", *defines, f"-I{src}", str(HARNESS), "-o",
                    str(lib)], check=True, capture_output=True, text=True)
    return load_harness(lib)


def load_harness(lib):
    """A built lane harness with its functions' argument types."""
    so = ctypes.CDLL(str(lib))
    ll, dbl, i32 = ctypes.c_longlong, ctypes.c_double, ctypes.c_int
    so.emu_lemke_stack.argtypes = [ll, ll, F64, F64, ctypes.c_void_p, ll, dbl, dbl, dbl, dbl,
                                   i32, i32, i32, i32, i32, F64, F64, I8, I64, F64, F64]
    so.emu_certify.argtypes = [ll, F64, F64, F64, ctypes.c_void_p, ctypes.c_void_p, i32, F64,
                               ctypes.POINTER(dbl), ctypes.POINTER(dbl)]
    return so


@pytest.fixture(scope="module")
def emu(tmp_path_factory):
    return build_harness(tmp_path_factory.mktemp("lanes"))


def outputs(K, n):
    return (np.zeros((K, n)), np.zeros((K, n)), np.ones(K, np.int8), np.zeros(K, np.int64),
            np.full(K, np.inf), np.full(K, np.nan))


def one_lane(M, q, stage, balance=(4, 8, 12)):
    K, n = q.shape
    out = outputs(K, n)
    stack_c.lemke_stack(M, q, None, 10 * n + 10, PIVOT_TOL, TIE_TOL, 1e-9, POLISHED, balance,
                        *out, 1, True, stage)
    return out


def lanes(emu, M, q, stage, count, balance=(4, 8, 12)):
    K, n = q.shape
    out = outputs(K, n)
    bal = balance or (-1, 0, 0)
    rc = emu.emu_lemke_stack(K, n, np.ascontiguousarray(M), np.ascontiguousarray(q), None,
                             10 * n + 10, PIVOT_TOL, TIE_TOL, 1e-9, POLISHED, *bal, int(stage),
                             count, *out)
    assert rc == 0, "the lanes of a group diverged (a collective they did not all reach)"
    return out


def stack(kind, K, n, seed):
    """pd: random positive definite plus a skew part; ties: small integers (degenerate ratio
    tests: the lexicographic tie-break); scaled: rows and columns 2^+-30 apart (equilibrated
    first); general: Gaussian (rays and iteration limits: handed back); blocks: pd with the
    rows and columns in up to four blocks and no term across them (the certificate's blocks),
    some of them at 2^-20; degenerate: B B^T + I with B of -1, 0, 1 and q of -1 and 0 (solved,
    with ratio tests where several rows block at ratio 0)."""
    rng = np.random.default_rng(seed)
    if kind == "degenerate":
        B = rng.integers(-1, 2, (K, n, n)).astype(float)
        return B @ B.transpose(0, 2, 1) + np.eye(n), -rng.integers(0, 2, (K, n)).astype(float)
    if kind == "blocks":
        M, q = stack("pd", K, n, seed + 1)
        part = rng.integers(0, 4, (K, n))
        M = M * (part[:, :, None] == part[:, None, :])
        M *= np.where(part == 3, 2.0 ** -20, 1.0)[:, :, None]
        return M, q
    if kind == "ties":
        M = rng.integers(-2, 3, (K, n, n)).astype(float) + 3 * np.eye(n)
        return M, rng.integers(-2, 2, (K, n)).astype(float)
    if kind == "general":
        return rng.standard_normal((K, n, n)), rng.standard_normal((K, n))
    A = rng.standard_normal((K, n, n))
    S = rng.standard_normal((K, n, n)) * 0.2
    M = A @ A.transpose(0, 2, 1) / n + np.eye(n) + S - S.transpose(0, 2, 1)
    q = rng.standard_normal((K, n))
    if kind == "scaled":
        D, E = 2.0 ** rng.integers(-30, 30, (K, n)), 2.0 ** rng.integers(-30, 30, (K, n))
        M, q = M * D[:, :, None] * E[:, None, :], q * D
    return M, q


@pytest.mark.parametrize("count", [8, 16, 32])
@pytest.mark.parametrize("kind", ["pd", "ties", "scaled", "general"])
def test_groups_of_lanes_give_the_one_lane_answers(emu, kind, count):
    """z, w, code, pivots, error and residual equal bit for bit, staged and not, for sizes
    below, at and above the group's width (n = 1, 7, 12, 17, 40)."""
    solved = 0
    for n in (1, 7, 12, 17, 40):
        M, q = stack(kind, 4 if n == 40 else 6, n, seed=n + count)
        for stage in (True, False):
            ref = one_lane(M, q, stage)
            got = lanes(emu, M, q, stage, count)
            for a, b in zip(got, ref, strict=True):
                np.testing.assert_array_equal(a, b, err_msg=f"{kind} n={n} stage={stage}")
        solved += int((ref[2] == 0).sum())
    assert solved > 0  # the lanes' certificates were compared, not only hand-backs


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 24), st.sampled_from([8, 16, 32]), st.integers(0, 2**32 - 1),
       st.booleans())
def test_lane_groups_property(emu, n, count, seed, balance):
    """Any size, group width and seed: the lanes compute what one lane computes."""
    rng = np.random.default_rng(seed)
    M, q = stack(rng.choice(["pd", "ties", "scaled", "general"]), 3, n, seed)
    bal = (4, 8, 12) if balance else None
    ref = one_lane(M, q, True, bal)
    got = lanes(emu, M, q, True, count, bal)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.fixture(scope="module")
def emu_links(tmp_path_factory):
    """The harness with LCP_CERT_LINKS of one and of two words, by that count."""
    return {k: build_harness(tmp_path_factory.mktemp(f"lanes_links{k}"),
                             (f"-DLCP_CERT_LINKS={k}",)) for k in (1, 2)}


@pytest.mark.parametrize("links", [0, 1, 2])
@pytest.mark.parametrize("count", [8, 32])
def test_the_certificate_split_over_lanes(emu, emu_links, links, count):
    """lcp_certify_warp over lanes against one lane (LCP and box, zeros in z, blocks), as
    shipped (links 0) and with LCP_CERT_LINKS' masks (up to n = 32 or 64, the shipped
    propagation above)."""
    emu = emu_links[links] if links else emu
    rng = np.random.default_rng(count)
    for n in (1, 5, 12, 13, 16, 17, 31, 32, 33, 40, 63, 64, 65):
        M0 = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-3, 4, (n, 1))
        q = rng.standard_normal(n)
        z = np.where(rng.random(n) < 0.4, 0.0, rng.random(n))
        # two blocks of rows and columns: at random, and rows or columns by mask word (a
        # block's columns linked only to rows from 32 on, or the other way round: the second
        # word of LCP_CERT_LINKS=2, or past its largest n)
        rand, word = rng.integers(0, 2, (2, n)), (np.arange(n) >= 32).astype(np.int64)
        for rows, cols in ((rand[0], rand[1]), (rand[0], word), (word, rand[1])):
            M = M0 * (rows[:, None] == cols[None, :])
            for lo, up in ((None, None), (-rng.random(n), rng.random(n))):
                zz = z if lo is None else np.clip(z, lo, up)
                ref = stack_c.certify(M, q, zz, lo, up, warp=True)
                err, res, w = ctypes.c_double(), ctypes.c_double(), np.zeros(n)
                st_ = emu.emu_certify(n, M, q, zz, None if lo is None else lo.ctypes.data,
                                      None if up is None else up.ctypes.data, count, w,
                                      ctypes.byref(err), ctypes.byref(res))
                assert st_ == ref[0]
                if st_ == 0:
                    assert (err.value, res.value) == (ref[1], ref[2])


#: The header's speed macros as the device sweep builds them (gpu_device_run.sh's VARIANTS),
#: each with the sizes, kinds and staging whose code paths it changes: n = 12, 16 and 17 about
#: the 8-lane kernel's sizes, 32 and 33 about LCP_CERT_LINKS' words (64 and 65, its largest n
#: and past it: test_the_certificate_split_over_lanes); degenerate: ties in the ratio test
#: (LCP_RATIO_FUSED's second pass) on problems that are solved; blocks: the certificate's
#: blocks; staged and not: the certificate's M in the workspace or as given.
SPEED_CHOICES = [
    (("-DLCP_PIVOT_ROWS=1", "-DLCP_COPY_BATCH=1"), (1, 5, 12, 23, 40), ("pd", "ties", "scaled"),
     (True,)),
    (("-DLCP_PIVOT_ROWS=4", "-DLCP_COPY_BATCH=8"), (1, 5, 12, 23, 40), ("pd", "ties", "scaled"),
     (True,)),
    (("-DLCP_PIVOT_ROWS=16", "-DLCP_COPY_BATCH=2"), (1, 5, 12, 23, 40),
     ("pd", "ties", "scaled"), (True,)),
    (("-DLCP_CERT_LINKS=1",), (1, 12, 16, 17, 32), ("pd", "degenerate", "scaled", "blocks"),
     (True, False)),
    (("-DLCP_CERT_LINKS=2",), (12, 33, 40), ("pd", "degenerate", "blocks"), (True, False)),
    ((), (1, 2, 12, 16, 17, 40), ("pd", "degenerate", "scaled", "blocks"), (True,)),
    (("-DLCP_RATIO_FUSED=0",), (1, 2, 12, 16, 17, 40), ("pd", "degenerate", "scaled", "blocks"),
     (True,)),
    (("-DLCP_CERT_LINKS=1", "-DLCP_RATIO_FUSED=1", "-DLCP_PIVOT_ROWS=4"), (12, 17, 40),
     ("pd", "degenerate", "blocks"), (False,)),
]


@pytest.mark.parametrize(("defines", "sizes", "kinds", "stages"), SPEED_CHOICES,
                         ids=[" ".join(c[0]) or "shipped" for c in SPEED_CHOICES])
def test_the_speed_choices_change_no_answer(tmp_path, defines, sizes, kinds, stages):
    """The header's speed macros (pivot row blocks, the copy's batch, the certificate's link
    masks, the fused ratio test: the device sweep's VARIANTS) give the one-lane answers of the
    shipped build bit for bit, over 8 and 32 lanes."""
    so = build_harness(tmp_path, defines)
    for kind in kinds:
        for n in sizes:
            M, q = stack(kind, 3, n, seed=n)
            for stage in stages:
                ref = one_lane(M, q, stage)
                for count in (8, 32):
                    got = lanes(so, M, q, stage, count)
                    for a, b in zip(got, ref, strict=True):
                        np.testing.assert_array_equal(
                            a, b, err_msg=f"{defines} {kind} n={n} stage={stage}")


def test_lanes_that_disagree_on_the_pivot_row_are_reported_not_crashed(tmp_path):
    """A planted defect (lane 1 pivots on the row above the others') stops the group at the
    next LCP_UNIFORM check: the run returns -1 (the assertion in ``lanes``), it neither writes
    out of bounds nor hangs.  Run in a child process, so that a crash fails this test only."""
    src = tmp_path / "kernels" / "src"
    shutil.copytree(SRC, src)
    for h in SRC.parent.glob("*.h"):  # the headers lcp_stack.h includes from its parent
        shutil.copy(h, src.parent)
    header = src / "lcp_stack.h"
    text = header.read_text()
    check = "        LCP_UNIFORM(r);\n        if (r < 0) {\n            status = LCP_RAY;"
    assert text.count(check) == 1
    header.write_text(text.replace(check, "        r -= (lane == 1 && r > 0);\n" + check))
    build_harness(tmp_path, src=src)  # built here, run in the child
    child = f"""
import sys
sys.path.insert(0, {str(Path(__file__).parent)!r})
import test_lane_groups as t
so = t.load_harness({str(tmp_path / "liblanes.so")!r})
for seed in range(6):  # seed 0 wrote out of bounds (a bus error) before LCP_UNIFORM
    M, q = t.stack("pd", 2, 12, seed=seed)
    try:
        t.lanes(so, M, q, True, 8)
    except AssertionError as e:
        print("reported:", e)
"""
    run = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.count("reported: the lanes of a group diverged") == 6, run.stdout
