"""The input digests of stacked result files: which hash a chunk's fingerprint uses.

A stacked result file (``.h5``, ``.npz``) records, for each finished chunk, a 16-byte digest
of the chunk's input (:func:`lcpcli.batch.stack_output.chunk_digest`), which ``--resume``
compares with the input as it is then, and the name of the algorithm (:data:`ALGORITHMS`):

* ``mxs128`` (:data:`STACKED`, new stacked result files): :func:`mxs128`, a compiled
  non-cryptographic 128-bit hash at ~20 GB/s on one core (SHA-256: 1-2 GB/s, 60 ms for the
  125 MB of a stack of n = 12, K = 100,000, whose solve takes 0.15 s of CPU).  It detects
  an input changed by accident between a run and its ``--resume`` (another file, regenerated
  data, a damaged copy); it is no defence against someone who crafts a different input with
  the same digest.
* ``sha256`` (:data:`LEGACY`): files written before ``mxs128`` existed record no algorithm
  and mean this one; stacked row outputs (``.jsonl``, ``.csv``) keep it (their rows name no
  algorithm, and encoding a row costs far more than hashing its bytes).

**mxs128** (``mxs128.h``, the same text): all arithmetic modulo 2^64, ``rotl`` a left
rotation; P1 = 0x9E3779B185EBCA87, P2 = 0xC2B2AE3D27D4EB4F, P3 = 0x165667B19E3779F9,
P4 = 0x85EBCA77C2B2AE63, P5 = 0x27D4EB2F165667C5 (the primes of xxHash64, Yann Collet).  The
input, L bytes, is padded with zero bytes to a multiple of 32 (nothing when L = 0) and read as
stripes of four little-endian uint64 words ``w0..w3``.  Four lanes start at ``a0 = s + P1 +
P2``, ``a1 = s + P2``, ``a2 = s``, ``a3 = s - P1`` (``s``: the seed, 0 here) and take each
stripe as ``ai = rotl(ai + wi * P2, 31) * P1`` (xxHash64's round).  Then ``h1 = mix(rotl(a0,
1) + rotl(a1, 7) + rotl(a2, 12) + rotl(a3, 18) + L * P5)`` and ``h2 = mix(rotl(a0, 18) +
rotl(a1, 12) + rotl(a2, 7) + rotl(a3, 1) + L * P4 + h1)`` with ``mix(v)``: ``v ^= v >> 33; v
*= P2; v ^= v >> 29; v *= P3; v ^= v >> 32`` (xxHash64's avalanche).  The digest is ``h1`` then
``h2``, each as 8 little-endian bytes.  The padding is told apart from real zero bytes by L.
"""

from __future__ import annotations

from typing import Any

from lcpcli.batch._mxs128 import mxs128 as _mxs128
from lcpcli.batch.output import DIGEST_BYTES, new_digest
from lcpcli.core.errors import ProblemError

#: The digest of new stacked result files (``.h5``, ``.npz``).
STACKED = "mxs128"
#: The digest of files that record none (written before :data:`STACKED`), and of stacked rows.
LEGACY = "sha256"
#: Every digest a stacked result file may record.
ALGORITHMS = (STACKED, LEGACY)


def mxs128(data: Any, seed: int = 0) -> bytes:
    """The 16-byte mxs128 digest (module docstring) of the bytes of ``data``: bytes or any
    C-contiguous buffer (a numpy array: its memory as it is, so give little-endian data for a
    value independent of the machine).  Compiled; the GIL is released while it runs."""
    return _mxs128(data, seed)


def digest_of(algorithm: str, pieces: list[Any]) -> bytes:
    """The 16-byte digest of the bytes of ``pieces`` (bytes or C-contiguous buffers):
    SHA-256's first 16 bytes of their concatenation (``sha256``: :func:`new_digest`), or
    for ``mxs128`` the mxs128 of the concatenation of each piece's mxs128 (each piece hashed
    once, in place, without the GIL).  Note that for ``mxs128`` the split into pieces is part
    of the value."""
    if algorithm == STACKED:
        return mxs128(b"".join(mxs128(p) for p in pieces))
    if algorithm == LEGACY:
        h = new_digest()
        for p in pieces:
            h.update(p)
        return h.digest()[:DIGEST_BYTES]
    raise ValueError(f"unknown digest {algorithm!r}")


def recorded_algorithm(value: Any, path: Any, source: str) -> str:
    """The digest a result file records (``value``: its attribute or member; None when it
    records none: :data:`LEGACY`), refused with one line when this lcpcli does not know it."""
    if value is None:
        return LEGACY
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    name = str(value)
    if name not in ALGORITHMS:
        raise ProblemError(f"holds results of {source} fingerprinted with the digest "
                           f"{name[:40]!r}, which this lcpcli does not know (known: "
                           f"{', '.join(ALGORITHMS)}); run again without --resume",
                           str(path))
    return name
