"""The input digest of stacked result files (:mod:`lcpcli.batch.digest`): the compiled mxs128
against an independent pure-Python reference of its written definition, bit for bit, and
``--resume`` across digests (a file records its algorithm; one that records none was written
with SHA-256 and is verified with it; an unknown one is refused in one line)."""

from __future__ import annotations

import hashlib
import json
import struct

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.api import solve_many
from lcpcli.batch.digest import ALGORITHMS, LEGACY, STACKED, digest_of, mxs128
from lcpcli.batch.records import SolveOptions
from lcpcli.batch.run import run_batch
from lcpcli.core.errors import ProblemError
from lcpcli.core.result import NOT_DONE
from lcpcli.io.stack import write_stack

MASK = (1 << 64) - 1
P1, P2, P3 = 0x9E3779B185EBCA87, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9
P4, P5 = 0x85EBCA77C2B2AE63, 0x27D4EB2F165667C5


def rotl(x: int, r: int) -> int:
    return ((x << r) | (x >> (64 - r))) & MASK


def mix(v: int) -> int:
    v ^= v >> 33
    v = v * P2 & MASK
    v ^= v >> 29
    v = v * P3 & MASK
    return v ^ (v >> 32)


def reference_mxs128(data: bytes, seed: int = 0) -> bytes:
    """mxs128 as the docstring of lcpcli.batch.digest defines it, in Python integers."""
    L = len(data)
    padded = data + bytes(-L % 32)
    a = [(seed + P1 + P2) & MASK, (seed + P2) & MASK, seed, (seed - P1) & MASK]
    for off in range(0, len(padded), 32):
        words = struct.unpack_from("<4Q", padded, off)
        a = [rotl((a[i] + words[i] * P2) & MASK, 31) * P1 & MASK for i in range(4)]
    h1 = mix((rotl(a[0], 1) + rotl(a[1], 7) + rotl(a[2], 12) + rotl(a[3], 18) + L * P5) & MASK)
    h2 = mix((rotl(a[0], 18) + rotl(a[1], 12) + rotl(a[2], 7) + rotl(a[3], 1) + L * P4 + h1)
             & MASK)
    return struct.pack("<2Q", h1, h2)


@settings(max_examples=300, deadline=None)
@given(data=st.binary(min_size=0, max_size=300), seed=st.integers(0, 2**64 - 1))
def test_mxs128_equals_the_written_definition(data, seed):
    """Every length (0, partial words, partial stripes, several stripes) and seed."""
    assert mxs128(data, seed) == reference_mxs128(data, seed)


@pytest.mark.parametrize("length", [0, 1, 7, 8, 9, 24, 31, 32, 33, 63, 64, 65, 1000, 4099])
def test_mxs128_at_the_edges_of_words_and_stripes(length):
    """Empty input, partial 8-byte words, partial and whole 32-byte stripes."""
    data = np.random.default_rng(length).integers(0, 256, length, dtype=np.uint8).tobytes()
    assert mxs128(data) == reference_mxs128(data)
    assert mxs128(data, 12345) == reference_mxs128(data, 12345)


@settings(max_examples=50, deadline=None)
@given(values=st.lists(st.floats(allow_nan=False), min_size=0, max_size=40))
def test_mxs128_of_an_array_is_that_of_its_little_endian_bytes(values):
    """A float64 array is hashed in place, as its bytes (what chunk digests hash)."""
    a = np.asarray(values, dtype="<f8")
    assert mxs128(a) == reference_mxs128(a.tobytes()) == mxs128(a.tobytes())
    M = np.asarray(values[:36] + [0.0] * (36 - len(values[:36])), dtype="<f8").reshape(4, 3, 3)
    assert mxs128(M) == reference_mxs128(M.tobytes())


@settings(max_examples=100, deadline=None)
@given(data=st.binary(min_size=1, max_size=100), at=st.data())
def test_mxs128_sees_a_changed_bit_and_trailing_zeros(data, at):
    """One flipped bit anywhere changes the digest; so do zero bytes appended (which the
    padding alone would not tell apart: the length is mixed in)."""
    i = at.draw(st.integers(0, len(data) - 1))
    bit = at.draw(st.integers(0, 7))
    changed = bytearray(data)
    changed[i] ^= 1 << bit
    assert mxs128(bytes(changed)) != mxs128(data)
    assert mxs128(data + b"\0") != mxs128(data)


def test_digest_of_by_algorithm():
    """sha256: the first 16 bytes of SHA-256 of the concatenation (what older files hold);
    mxs128: mxs128 of the pieces' mxs128 digests; anything else refused."""
    pieces = [b"abc", np.arange(5.0), b"-"]
    joined = b"abc" + np.arange(5.0).tobytes() + b"-"
    assert digest_of(LEGACY, pieces) == hashlib.sha256(joined).digest()[:16]
    inner = b"".join(reference_mxs128(bytes(memoryview(p).cast("B"))) for p in pieces)
    assert digest_of(STACKED, pieces) == reference_mxs128(inner)
    with pytest.raises(ValueError):
        digest_of("md5", pieces)
    assert set(ALGORITHMS) == {LEGACY, STACKED}


# ------------------------------------------------------------------ resume across digests
K, N, CHUNK = 1000, 5, 96


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


def old_digest(M: np.ndarray, q: np.ndarray) -> bytes:
    """A chunk's digest as lcpcli wrote it before mxs128 (SHA-256 of the bytes of M, q and
    "-" for each absent bound, first 16 bytes), written out here independently."""
    h = hashlib.sha256()
    for part in (M.astype("<f8").tobytes(), q.astype("<f8").tobytes(), b"-", b"-"):
        h.update(part)
    return h.digest()[:16]


@pytest.fixture
def chunked(monkeypatch, tmp_path):
    """A stack of K problems read in chunks of CHUNK, and where its results go."""
    import lcpcli.io.stack as stack_mod

    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: CHUNK)
    M, q = pd_stack(K, N, seed=3)
    path = tmp_path / "s.h5"
    write_stack(path, M, q)
    return M, q, path, tmp_path / "r.h5"


def interrupt_after(out, chunks: int) -> None:
    """Make ``out`` what a run stopped after ``chunks`` chunks leaves: the later chunks'
    status -1 and digests zero (the datasets are allocated in full when the file is made)."""
    with h5py.File(out, "a") as f:
        g = f["s"]
        g["status"][chunks * CHUNK:] = NOT_DONE
        g["z"][chunks * CHUNK:] = np.nan
        g["chunk_digest"][chunks:] = 0


def make_old_format(out, M: np.ndarray, q: np.ndarray) -> None:
    """Turn a result file into what an lcpcli before mxs128 wrote: no ``digest`` attribute
    and the SHA-256 digest of each recorded chunk."""
    with h5py.File(out, "a") as f:
        g = f["s"]
        del g.attrs["digest"]
        d = g["chunk_digest"]
        for c in range(d.shape[0]):
            if d[c].any():
                s = slice(c * CHUNK, (c + 1) * CHUNK)
                d[c] = np.frombuffer(old_digest(M[s], q[s]), np.uint8)


def test_a_new_file_records_mxs128_and_resumes_after_an_interruption(chunked):
    M, q, path, out = chunked
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    with h5py.File(out, "r") as f:
        assert f["s"].attrs["digest"] == STACKED
        d = f["s"]["chunk_digest"][...]
    assert bytes(d[0]) == digest_of(STACKED, [M[:CHUNK], q[:CHUNK], b"-", b"-"])
    interrupt_after(out, 3)
    report = run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2,
                       resume=True)
    assert report.skipped == 3 * CHUNK and report.new == K - 3 * CHUNK
    ref = solve_many(M, q, "lemke")
    with h5py.File(out, "r") as f:
        np.testing.assert_array_equal(f["s"]["z"][...], ref.z)
        np.testing.assert_array_equal(f["s"]["chunk_digest"][...], d)


def test_an_old_file_is_verified_with_sha256_and_stays_sha256(chunked):
    """A file without the attribute (written before mxs128): its SHA-256 digests are checked,
    the rest solved and fingerprinted with SHA-256 as well; the file names no digest still."""
    M, q, path, out = chunked
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    interrupt_after(out, 4)
    make_old_format(out, M, q)
    report = run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2,
                       resume=True)
    assert report.skipped == 4 * CHUNK and report.new == K - 4 * CHUNK
    with h5py.File(out, "r") as f:
        g = f["s"]
        assert "digest" not in g.attrs
        np.testing.assert_array_equal(g["z"][...], solve_many(M, q, "lemke").z)
        for c in range(g["chunk_digest"].shape[0]):
            s = slice(c * CHUNK, (c + 1) * CHUNK)
            assert bytes(g["chunk_digest"][c]) == old_digest(M[s], q[s])


@pytest.mark.parametrize("fmt", ["old", "new"])
def test_changed_input_is_detected_by_either_digest(chunked, fmt):
    """One value of a finished chunk changed: refused, whichever digest the file has."""
    M, q, path, out = chunked
    run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2)
    interrupt_after(out, 4)
    if fmt == "old":
        make_old_format(out, M, q)
    M2 = M.copy()
    M2[2 * CHUNK + 7, 1, 3] = np.nextafter(M2[2 * CHUNK + 7, 1, 3], np.inf)  # one ulp
    write_stack(path, M2, q)
    with pytest.raises(ProblemError, match="other data"):
        run_batch([str(path)], SolveOptions(method="lemke"), output=out, jobs=2, resume=True)


def one_line(res, reason: str) -> None:
    assert res.returncode == 2, (res.returncode, res.stderr[-1500:])
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: "), res.stderr[-1500:]
    assert reason in lines[0], lines[0]


def test_a_digest_named_wrongly_or_unknown_is_refused(cli, tmp_path):
    """mxs128 digests under the name sha256: they do not verify (other data); a digest this
    lcpcli does not know: one line; the file unchanged by either refusal."""
    M, q = pd_stack(60, 4)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    for ext in ("h5", "npz"):
        out = tmp_path / f"r.{ext}"
        assert cli("solve", str(stack), "-o", str(out)).returncode == 0
        for name, reason in ((LEGACY, "other data"), ("blake3", "does not know")):
            if ext == "h5":
                with h5py.File(out, "a") as f:
                    f["s"].attrs["digest"] = name
            else:
                with np.load(out) as data:
                    arrays = {k: data[k] for k in data.files}
                arrays["digest"] = np.asarray(name)
                np.savez(out, **arrays)
            before = out.read_bytes()
            one_line(cli("solve", str(stack), "-o", str(out), "--resume"), reason)
            assert out.read_bytes() == before


def test_an_old_npz_without_digest_resumes_with_sha256(cli, tmp_path):
    """An NPZ result of an older lcpcli (no ``digest`` member, SHA-256 digests) resumes:
    every problem skipped; with one problem changed, refused."""
    M, q = pd_stack(60, 4)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / "r.npz"
    assert cli("solve", str(stack), "-o", str(out)).returncode == 0
    with np.load(out) as data:
        arrays = {k: data[k] for k in data.files if k != "digest"}
    assert int(arrays["chunk"]) >= 60
    arrays["chunk_digest"][0] = np.frombuffer(old_digest(M, q), np.uint8)
    np.savez(out, **arrays)
    res = cli("solve", str(stack), "-o", str(out), "--resume", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 60
    with np.load(out) as data:
        assert "digest" in data.files and str(data["digest"]) == LEGACY
    write_stack(stack, M, -q)
    one_line(cli("solve", str(stack), "-o", str(out), "--resume"), "other data")
