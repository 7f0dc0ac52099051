"""Hostile input, table-driven (issue 17): every command and format, with the exit code and the
first words of the one-line message each bad input must produce.

Each case names the files it must leave untouched (checked by SHA-256: a refused run never
damages an input or an existing output) and the files it must not create.  Most cases run
``lcpcli.cli.main`` in this process under a SIGALRM kill switch; the ones that could hang
(FIFOs), read without bound (zip bombs, /dev/zero, lazy HDF5 datasets) or concern the process
itself (broken pipes, bare ``lcpcli``) run in a subprocess with a timeout and, for the memory
cases, an address-space limit of 1 GiB, so no case needs more than that.

Run as a script to count failures by kind against any checkout (the issue's survey)::

    python tests/cli/test_bad_inputs.py [--root PATH_TO_CHECKOUT]
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import re
import signal
import stat
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
#: Seconds a case may run (in-process: SIGALRM; subprocess: kill) before it counts as a hang.
TIMEOUT = 60
#: Address-space limit of the memory cases (bytes): what "no test needs more than 1 GB" means.
MEMORY_LIMIT = 2**30
SOLVED, NOT_SOLVED, BAD, INTERRUPTED = 0, 1, 2, 130


@dataclass
class Case:
    """One hostile run: ``lcpcli ARGS`` (``{d}`` = the fixture folder) and what must happen.

    ``kind`` is the issue's category (what goes wrong when the case is mishandled): data-loss,
    internal, hang, memory, lenient, exit-code, shell.  ``words`` must begin the reason of the
    message (after the file name): on stderr for a refused run, in an error row (``--json``)
    for a batch (``rows=True``).  ``protect`` files keep their hash, ``absent`` files are not
    created.  ``sub`` runs it in a subprocess (``memory``: under the 1 GiB limit).
    ``xfail`` names the other branch whose merge fixes the case.
    """

    id: str
    kind: str
    args: list[str]
    code: int
    words: str | None
    stdin: str | None = None
    protect: tuple[str, ...] = ()
    absent: tuple[str, ...] = ()
    rows: bool = False
    sub: bool = False
    memory: bool = False
    root_only: bool = False
    xfail: str | None = None
    env: dict[str, str] = field(default_factory=dict)
    timeout: int = 0  # seconds of the kill switch (0: TIMEOUT)


# ------------------------------------------------------------------------------ fixtures
OK = {"M": [[2, 1], [1, 2]], "q": [-5, -6]}

BAD_JSON = {
    "not_json": "{M: ]",
    "empty": "",
    "list": "[1, 2]",
    "no_q": '{"M": [[1]]}',
    "no_M": '{"q": [1]}',
    "unknown_key": '{"M": [[1]], "q": [1], "Q": 3}',
    "ragged": '{"M": [[1, 2], [3]], "q": [1, 2]}',
    "not_square": '{"M": [[1, 2]], "q": [1]}',
    "q_len": '{"M": [[1, 0], [0, 1]], "q": [1]}',
    "nan": '{"M": [[NaN]], "q": [1]}',
    "inf_q": '{"M": [[1]], "q": [Infinity]}',
    "text_M": '{"M": [["a"]], "q": [1]}',
    "numeric_text_M": '{"M": [["1.5", "0"], ["0", "1"]], "q": [1, 1]}',
    "bool_in_M": '{"M": [[true, 0.5], [0.5, 1.0]], "q": [1, 1]}',
    "bool_M": '{"M": [[true]], "q": [1]}',
    "text_q": '{"M": [[1]], "q": ["1"]}',
    "bool_q": '{"M": [[1, 0], [0, 1]], "q": [false, 1.5]}',
    "matrix_q": '{"M": [[1, 0], [0, 1]], "q": [[1, 2], [3, 4]]}',
    "object_q": '{"M": [[1]], "q": {"a": 1}}',
    "scalar_M": '{"M": 3, "q": [1]}',
    "text_M_whole": '{"M": "eye", "q": [1]}',
    "n_eq_text": '{"M": [[1, 0], [0, 1]], "q": [1, 1], "n_eq": "1"}',
    "n_eq_bool": '{"M": [[1, 0], [0, 1]], "q": [1, 1], "n_eq": true}',
    "n_eq_float": '{"M": [[1, 0], [0, 1]], "q": [1, 1], "n_eq": 1.5}',
    "n_eq_big": '{"M": [[1]], "q": [1], "n_eq": 5}',
    "n_eq_negative": '{"M": [[1]], "q": [1], "n_eq": -1}',
    "bounds_crossed": '{"M": [[1]], "q": [1], "lower": [2], "upper": [1]}',
    "bounds_text": '{"M": [[1]], "q": [1], "lower": ["abc"]}',
    "bounds_bool": '{"M": [[1]], "q": [1], "upper": [true]}',
    "bounds_len": '{"M": [[1, 0], [0, 1]], "q": [1, 1], "lower": [0]}',
    "bounds_object": '{"M": [[1]], "q": [1], "lower": {"a": 1}}',
    "both_forms": '{"M": [[1, 0], [0, 1]], "q": [1, 1], "n_eq": 1, "lower": [0, 0]}',
    "meta_list": '{"M": [[1]], "q": [1], "meta": [1, 2]}',
    "meta_deep": '{"M": [[1]], "q": [1], "meta": ' + '{"a": ' * 100 + "1" + "}" * 100 + "}",
    "name_number": '{"M": [[1]], "q": [1], "name": 123}',
    "description_object": '{"M": [[1]], "q": [1], "description": {"a": 1}}',
    "deep_M": '{"M": ' + "[" * 100_000 + "]" * 100_000 + ', "q": [1]}',
    "deep_object": '{"M": [[1]], "q": [1], "meta": ' + '{"a":' * 50_000 + "1" + "}" * 50_000
                   + "}",
    "int_400_digits": '{"M": [[1' + "0" * 400 + ']], "q": [1]}',
    "int_5000_digits": '{"M": [[1' + "0" * 5000 + ']], "q": [1]}',
    "sparse_format": '{"M": {"format": "dia", "shape": [1, 1], "data": [1]}, "q": [1]}',
    "sparse_format_number": '{"M": {"format": 3, "shape": [1, 1], "data": [1]}, "q": [1]}',
    "sparse_shape_text": '{"M": {"format": "coo", "shape": "1x1", "data": [1], "row": [0], '
                         '"col": [0]}, "q": [1]}',
    "sparse_shape_float": '{"M": {"format": "coo", "shape": [1.5, 1], "data": [1], "row": [0], '
                          '"col": [0]}, "q": [1]}',
    "sparse_shape_negative": '{"M": {"format": "coo", "shape": [-1, -1], "data": [], '
                             '"row": [], "col": []}, "q": []}',
    "sparse_shape_huge": '{"M": {"format": "csr", "shape": [1000000000, 1000000000], '
                         '"data": [], "indices": [], "indptr": [0]}, "q": [1]}',
    "sparse_index_out": '{"M": {"format": "coo", "shape": [2, 2], "data": [1], "row": [5], '
                        '"col": [0]}, "q": [1, 1]}',
    "sparse_indptr": '{"M": {"format": "csr", "shape": [2, 2], "data": [1, 2], '
                     '"indices": [0, 1], "indptr": [0, 3, 2]}, "q": [1, 1]}',
    "sparse_data_text": '{"M": {"format": "coo", "shape": [1, 1], "data": ["x"], "row": [0], '
                        '"col": [0]}, "q": [1]}',
    "sparse_index_float": '{"M": {"format": "coo", "shape": [2, 2], "data": [1, 1], '
                          '"row": [0.5, 1], "col": [0, 1]}, "q": [1, 1]}',
    "sparse_index_bool": '{"M": {"format": "coo", "shape": [2, 2], "data": [1, 1], '
                         '"row": [true, false], "col": [0, 1]}, "q": [1, 1]}',
    "sparse_coo_lengths": '{"M": {"format": "coo", "shape": [2, 2], "data": [1, 1], '
                          '"row": [0], "col": [0, 1]}, "q": [1, 1]}',
    "sparse_missing": '{"M": {"format": "csr", "shape": [2, 2], "data": [1]}, "q": [1, 1]}',
}

BAD_DAT = {
    "dat_nan_size": "nan\n0\n2\n2\n2 2\n1 0 0 1\n1 1\n",
    "dat_inf_size": "3\n0\ninf\n3\n3 3\n",
    "dat_huge_float_size": "1e400\n0\n1\n1\n1 1\n1\n1\n",
    "dat_negative": "-2\n0\n2\n2\n2 2\n1 0 0 1\n1 1\n",
    "dat_fraction": "2.5\n0\n2\n2\n2 2\n1 0 0 1\n1 1\n",
    "dat_truncated": "3\n0\n3\n3\n3 3\n1 2 3\n",
    "dat_text_value": "2\n0\n2\n2\n2 2\n1 0 x 1\n1 1\n",
    "dat_size_mismatch": "3\n0\n2\n2\n2 2\n1 0 0 1\n1 1 1\n",
    "dat_storage": "2\n7\n2\n2\n",
    "dat_empty": "",
    # sparse block storage: row pointer past the column indices (was an IndexError)
    "dat_sbm_rowptr": "2\n1\n2\n2\n1\n1\n1\n2\n2\n2\n1\n0 5\n0\n0\n1 0 0 1\n1 1\n",
    "dat_sbm_colidx": "2\n1\n2\n2\n1\n1\n1\n2\n2\n2\n1\n0 1\n7\n0\n1 0 0 1\n1 1\n",
    "dat_sbm_ends": "2\n1\n2\n2\n2\n2\n2\n2 1\n1 2\n3\n2\n0 1 2\n0 1\n0\n1\n1\n1\n1 1\n",
    "dat_sbm_rowptr_down": "2\n1\n2\n2\n2\n2\n2\n1 2\n1 2\n3\n2\n0 2 1\n0 1\n0\n1\n1\n1\n1 1\n",
    "dat_huge_dense": "100000\n0\n100000\n100000\n100000 100000\n",
    "dat_mlcp_bounds": "1\n0\n1\n1\n0 1 0\n0 1\n0\n2\n2\n2 2\n1 0 0 1\n1 1\n",
    "dat_mlcp_flags": "1\n0\n1\n1\n0 1 2\n0 7\n0\n2\n2\n2 2\n1 0 0 1\n1 1\n",
    "dat_mlcp_sizes": "0\n1\n-1\n1\n",
}


def _npz_raw(path: Path, members: dict[str, bytes],
             compression: int = zipfile.ZIP_DEFLATED) -> None:
    with zipfile.ZipFile(path, "w", compression) as zf:
        for name, data in members.items():
            zf.writestr(name, data)


def _npz_corrupt(path: Path, arrays: dict[str, np.ndarray], compression: int,
                 at: int | None = None) -> None:
    """An NPZ of ``arrays`` compressed by ``compression`` with 20 bytes of its first member's
    compressed data flipped (at byte ``at`` of the file; default: its middle)."""
    _npz_raw(path, {f"{k}.npy": _npy_bytes(v) for k, v in arrays.items()}, compression)
    data = bytearray(path.read_bytes())
    info = zipfile.ZipFile(path).infolist()[0]
    start = info.header_offset + 30 + len(info.filename) + info.compress_size // 2 \
        if at is None else at
    for i in range(start, start + 20):
        data[i] ^= 0xA5
    path.write_bytes(bytes(data))


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr, allow_pickle=True)
    return buf.getvalue()


def _npy_header(shape: tuple[int, ...]) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False,
                                               "shape": shape})
    return buf.getvalue()


def _zip_bomb(path: Path, members: dict[str, tuple[bytes, int]]) -> None:
    """A zip (zip64) whose members are ``prefix`` followed by ``zeros`` zero bytes, deflated.

    The zeros are written as one precomputed deflate block repeated (each block ends with a
    full flush, so it needs no history): a 1 GB member costs a few MB and no compression time.
    The CRC of a member with zeros is left 0: readers that check sizes from the headers never
    get there, and readers that do not have allocated the whole member before they could
    notice.
    """
    import struct
    import zlib

    block = bytes(2**22)
    with open(path, "wb") as fh:
        central = []
        for name, (prefix, zeros) in members.items():
            c = zlib.compressobj(1, zlib.DEFLATED, -15)
            head = c.compress(prefix) + c.flush(zlib.Z_FULL_FLUSH)
            full, rest = divmod(zeros, len(block))
            body = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH) if full else b""
            tail = c.compress(block[:rest]) + c.flush()
            csize = len(head) + full * len(body) + len(tail)
            usize = len(prefix) + zeros
            crc = 0 if zeros else zlib.crc32(prefix)
            offset = fh.tell()
            raw = name.encode()
            fh.write(struct.pack("<IHHHHHIIIHH", 0x04034B50, 45, 0, 8, 0, 0x21, crc,
                                 0xFFFFFFFF, 0xFFFFFFFF, len(raw), 20) + raw
                     + struct.pack("<HHQQ", 1, 16, usize, csize))
            fh.write(head)
            for _ in range(full):
                fh.write(body)
            fh.write(tail)
            central.append(struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 45, 45, 0, 8, 0,
                                       0x21, crc, 0xFFFFFFFF, 0xFFFFFFFF, len(raw), 28, 0, 0, 0,
                                       0, 0xFFFFFFFF) + raw
                           + struct.pack("<HHQQQ", 1, 24, usize, csize, offset))
        cd_offset = fh.tell()
        for entry in central:
            fh.write(entry)
        cd_size = fh.tell() - cd_offset
        end64 = fh.tell()
        fh.write(struct.pack("<IQHHIIQQQQ", 0x06064B50, 44, 45, 45, 0, 0, len(central),
                             len(central), cd_size, cd_offset))
        fh.write(struct.pack("<IIQI", 0x07064B50, 0, end64, 1))
        fh.write(struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 0xFFFF, 0xFFFF, 0xFFFFFFFF,
                             0xFFFFFFFF, 0))


def build_npz(d: Path) -> None:
    c = np.eye(2)
    q = np.array([-1.0, -1.0])
    np.savez(d / "ok.npz", M=c, q=q)
    np.savez(d / "npz_pickled.npz", M=c, q=np.array([None, 1], dtype=object))
    np.savez(d / "npz_complex.npz", M=c + 1j, q=q)
    np.savez(d / "npz_bool.npz", M=c > 0, q=q)
    np.savez(d / "npz_text.npz", M=np.array([["1", "0"], ["0", "1"]]), q=q)
    np.savez(d / "npz_structured.npz", M=np.zeros((2, 2), dtype=[("a", "f8")]), q=q)
    np.savez(d / "npz_dates.npz", M=c, q=np.array(["2020-01-01", "2021-01-01"],
                                                  dtype="datetime64[D]"))
    np.savez(d / "npz_q_len.npz", M=c, q=np.ones(3))
    np.savez(d / "npz_q_matrix.npz", M=c, q=np.ones((2, 2)))
    np.savez(d / "npz_M_3d.npz", M=np.ones((2, 2, 2)), q=q)
    np.savez(d / "npz_M_1d.npz", M=np.ones(4), q=q)
    np.savez(d / "npz_no_q.npz", M=c)
    np.savez(d / "npz_no_M.npz", q=q)
    np.savez(d / "npz_n_eq_array.npz", M=c, q=q, n_eq=np.array([1, 2]))
    np.savez(d / "npz_n_eq_float.npz", M=c, q=q, n_eq=np.array(1.5))
    np.savez(d / "npz_n_eq_text.npz", M=c, q=q, n_eq=np.array("1"))
    np.savez(d / "npz_name_array.npz", M=c, q=q, name=np.arange(3.0))
    np.savez(d / "npz_meta_text.npz", M=c, q=q, meta=np.array("{not json"))
    np.savez(d / "npz_meta_list.npz", M=c, q=q, meta=np.array("[1, 2]"))
    np.savez(d / "npz_meta_deep.npz", M=c, q=q, meta=np.array('{"a":' * 5000 + "1" + "}" * 5000))
    np.savez(d / "npz_lower_complex.npz", M=c, q=q, lower=np.zeros(2, dtype=complex))
    np.savez(d / "npz_lower_len.npz", M=c, q=q, lower=np.zeros(5))
    np.savez(d / "npz_sparse_format.npz", M_format=np.array(3), M_shape=np.array([2, 2]),
             M_data=np.ones(2), M_row=np.arange(2), M_col=np.arange(2), q=q)
    np.savez(d / "npz_sparse_shape.npz", M_format=np.array("coo"), M_shape=np.array([2, 2, 2]),
             M_data=np.ones(2), M_row=np.arange(2), M_col=np.arange(2), q=q)
    np.savez(d / "npz_sparse_index_float.npz", M_format=np.array("coo"), M_shape=np.array([2, 2]),
             M_data=np.ones(2), M_row=np.array([0.0, 1.0]), M_col=np.arange(2), q=q)
    np.savez(d / "npz_sparse_complex.npz", M_format=np.array("coo"), M_shape=np.array([2, 2]),
             M_data=np.ones(2, dtype=complex), M_row=np.arange(2), M_col=np.arange(2), q=q)
    (d / "npz_garbage.npz").write_bytes(b"PK\x03\x04garbage")
    (d / "npz_random.npz").write_bytes(os.urandom(2000))
    _npz_raw(d / "npz_truncated.npz", {"M.npy": _npy_bytes(c)[:-8], "q.npy": _npy_bytes(q)})
    _npz_raw(d / "npz_bad_header.npz", {"M.npy": b"\x93NUMPY\x01\x00\x10\x00{'descr': 'f", "q.npy":
                                        _npy_bytes(q)})
    for kind, compression in (("deflated", zipfile.ZIP_DEFLATED), ("lzma", zipfile.ZIP_LZMA)):
        # damaged compressed bytes: the auditor's flip of bytes 75..95, and one mid-stack
        _npz_corrupt(d / f"npz_corrupt_{kind}.npz", {"M": c, "q": q}, compression, at=75)
        _npz_corrupt(d / f"npz_corrupt_{kind}_z0.npz", {"z": np.arange(100.0)}, compression,
                     at=75)
        rng = np.random.default_rng(1)
        _npz_corrupt(d / f"npz_corrupt_{kind}_stack.npz",
                     {"M": np.eye(3) * 3 + rng.random((3000, 3, 3)),
                      "q": -rng.random((3000, 3))}, compression)
    _npz_raw(d / "npz_many.npz", {f"x{i}.npy": b"" for i in range(5000)})
    small = {k: (_npy_bytes(v), 0) for k, v in (("M.npy", c), ("q.npy", q))}
    _zip_bomb(d / "npz_bomb_q.npz", {"M.npy": small["M.npy"],  # q: 1.2 GB of zeros
                                     "q.npy": (_npy_header((150_000_000,)), 1_200_000_000)})
    _zip_bomb(d / "npz_bomb_M.npz", {  # 2.3 GB declared: over the dense limit
        "M.npy": (_npy_header((17_000, 17_000)), 8 * 17_000**2),
        "q.npy": (_npy_bytes(np.zeros(17_000)), 0)})
    parts = {f"{k}.npy": (_npy_bytes(v), 0) for k, v in (
        ("M_format", np.array("csr")), ("M_shape", np.array([2, 2])), ("M_data", np.ones(2)),
        ("M_indptr", np.array([0, 1, 2])), ("q", q))}
    index_head = _npy_header((150_000_000,)).replace(b"'<f8'", b"'<i8'")
    _zip_bomb(d / "npz_bomb_indices.npz", {**parts,
                                           "M_indices.npy": (index_head, 1_200_000_000)})


def build_hdf5(d: Path) -> None:
    import h5py

    def base(name: str, **extra: object) -> h5py.File:
        f = h5py.File(d / name, "w")
        f["M"] = np.eye(2)
        f["q"] = -np.ones(2)
        return f

    with h5py.File(d / "ok.h5", "w") as f:
        f["M"], f["q"] = np.eye(2), -np.ones(2)
    with h5py.File(d / "multi.h5", "w") as f:
        for k in range(3):
            g = f.create_group(f"p{k}")
            g["M"], g["q"] = np.eye(2) * (k + 1), -np.ones(2)
    (d / "h5_garbage.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 10)
    (d / "h5_text.h5").write_text("hello")
    with base("h5_n_eq_text.h5") as f:
        f.attrs["n_eq"] = "1"
    with base("h5_n_eq_array.h5") as f:
        f.attrs["n_eq"] = np.array([1, 2])
    with base("h5_n_eq_float.h5") as f:
        f.attrs["n_eq"] = 1.5
    with base("h5_meta_list.h5") as f:
        f.attrs["meta"] = "[1, 2]"
    with base("h5_meta_text.h5") as f:
        f.attrs["meta"] = "{oops"
    with base("h5_meta_number.h5") as f:
        f.attrs["meta"] = 3
    with base("h5_meta_deep.h5") as f:
        f.attrs["meta"] = '{"a":' * 5000 + "1" + "}" * 5000
    with base("h5_name_array.h5") as f:
        f.attrs["name"] = np.arange(3)
    with h5py.File(d / "h5_q_group.h5", "w") as f:
        f["M"] = np.eye(2)
        f.create_group("q")
    with h5py.File(d / "h5_M_group_bare.h5", "w") as f:
        f.create_group("M")
        f["q"] = np.ones(2)
    with h5py.File(d / "h5_M_1d.h5", "w") as f:
        f["M"], f["q"] = np.ones(4), np.ones(2)
    with h5py.File(d / "h5_q_matrix.h5", "w") as f:
        f["M"], f["q"] = np.eye(2), np.ones((2, 2))
    with h5py.File(d / "h5_q_null.h5", "w") as f:
        f["M"] = np.eye(2)
        f.create_dataset("q", data=h5py.Empty("f8"))
    with h5py.File(d / "h5_lazy_q.h5", "w") as f:  # 2.4 GB declared, nothing stored
        f["M"] = np.eye(2)
        f.create_dataset("q", shape=(300_000_000,), dtype="f8")
    with base("h5_lazy_lower.h5") as f:
        f.create_dataset("lower", shape=(300_000_000,), dtype="f8")
    with h5py.File(d / "h5_lazy_M.h5", "w") as f:
        f.create_dataset("M", shape=(10**6, 10**6), dtype="f8")
        f.create_dataset("q", shape=(10**6,), dtype="f8")
    for name, parts in {"h5_lazy_indices.h5": {"indices": 300_000_000},
                        "h5_lazy_data.h5": {"data": 600_000_000},
                        "h5_lazy_indptr.h5": {"indptr": 300_000_000}}.items():
        with h5py.File(d / name, "w") as f:
            g = f.create_group("M")
            g.attrs["format"], g.attrs["shape"] = "csr", [2, 2]
            sizes = {"data": 2, "indices": 2, "indptr": 3, **parts}
            for k, size in sizes.items():
                g.create_dataset(k, shape=(size,), dtype="f8" if k == "data" else "i8")
            f["q"] = np.ones(2)
    with h5py.File(d / "h5_complex.h5", "w") as f:
        f["M"], f["q"] = np.eye(2) + 1j, np.ones(2)
    with h5py.File(d / "h5_bool.h5", "w") as f:
        f["M"], f["q"] = np.eye(2) > 0, np.ones(2)
    with h5py.File(d / "h5_text_q.h5", "w") as f:
        f["M"] = np.eye(2)
        f.create_dataset("q", data=["1", "2"], dtype=h5py.string_dtype())
    with h5py.File(d / "h5_compound.h5", "w") as f:
        f["M"], f["q"] = np.zeros((2, 2), dtype=[("a", "f8")]), np.ones(2)
    with h5py.File(d / "h5_src.h5", "w") as f:
        f["x"] = np.eye(2)
    with h5py.File(d / "h5_extlink.h5", "w") as f:
        f["M"] = h5py.ExternalLink("h5_src.h5", "/x")
        f["q"] = np.ones(2)
    with h5py.File(d / "h5_extlink_fifo.h5", "w") as f:
        f["M"] = h5py.ExternalLink("fifo.h5", "/M")
        f["q"] = np.ones(2)
    with h5py.File(d / "h5_virtual.h5", "w") as f:
        f["M"] = np.eye(2)
        layout = h5py.VirtualLayout(shape=(2,), dtype="f8")
        layout[:] = h5py.VirtualSource(str(d / "h5_src.h5"), "x", shape=(2, 2))[0, :]
        f.create_virtual_dataset("q", layout)
    with h5py.File(d / "h5_external.h5", "w") as f:
        f["M"] = np.eye(2)
        f.create_dataset("q", shape=(2,), dtype="f8", external=[("/etc/hostname", 0, 16)])
    with h5py.File(d / "h5_dangling.h5", "w") as f:
        f["M"] = h5py.SoftLink("/nowhere")
        f["q"] = np.ones(2)
    with h5py.File(d / "h5_sparse_shape_text.h5", "w") as f:
        g = f.create_group("M")
        g.attrs["format"], g.attrs["shape"] = "csr", "2x2"
        g["data"], g["indices"], g["indptr"] = np.ones(2), np.arange(2), np.arange(3)
        f["q"] = np.ones(2)
    with h5py.File(d / "h5_sparse_format_number.h5", "w") as f:
        g = f.create_group("M")
        g.attrs["format"], g.attrs["shape"] = 5, [2, 2]
        g["data"], g["indices"], g["indptr"] = np.ones(2), np.arange(2), np.arange(3)
        f["q"] = np.ones(2)
    with h5py.File(d / "h5_sparse_index_float.h5", "w") as f:
        g = f.create_group("M")
        g.attrs["format"], g.attrs["shape"] = "csr", [2, 2]
        g["data"], g["indices"], g["indptr"] = np.ones(2), np.array([0.0, 1.0]), np.arange(3)
        f["q"] = np.ones(2)


def build(d: Path) -> None:
    """Every file the cases use, in ``d`` (cheap: the big ones are sparse or compressed)."""
    import h5py

    d.mkdir(parents=True, exist_ok=True)
    (d / "ok.json").write_text(json.dumps(OK))
    (d / "ok.dat").write_text("2\n0\n2\n2\n2 2\n2 1 1 2\n-5 -6\n")
    (d / "mlcp.json").write_text(json.dumps({**OK, "n_eq": 1}))
    (d / "three.json").write_text(json.dumps({"M": np.eye(3).tolist(), "q": [-1, -1, -1]}))
    (d / "n17.json").write_text(json.dumps({"M": np.eye(17).tolist(), "q": [-1] * 17}))
    (d / "none.json").write_text(json.dumps({"M": [[-1]], "q": [-1]}))
    rng = np.random.default_rng(0)
    A = rng.standard_normal((300, 300))
    (d / "big.json").write_text(json.dumps({"M": (A @ A.T + 300 * np.eye(300)).tolist(),
                                            "q": rng.standard_normal(300).tolist()}))
    (d / "z0_ok.json").write_text("[1, 2]")
    (d / "z0_three.json").write_text("[1, 2, 3]")
    (d / "z0_deep.json").write_text("[" * 100_000 + "]" * 100_000)
    (d / "z0_nulls.json").write_text('{"z": [null, 1]}')
    (d / "z0_text.json").write_text('["1", "2"]')
    (d / "z0_bools.json").write_text("[true, false]")
    (d / "z0_nested.json").write_text("[[1, 2], [3, 4]]")
    np.save(d / "z0_complex.npy", np.array([1 + 1j, 2]))
    np.save(d / "z0_matrix.npy", np.ones((3, 3)))
    np.savez(d / "z0_pickled.npz", z=np.array([None, 1], dtype=object))
    np.savez(d / "z0_two.npz", a=np.ones(2), b=np.ones(2))
    for name, text in BAD_JSON.items():
        (d / f"{name}.json").write_text(text)
    for name, text in BAD_DAT.items():
        (d / f"{name}.dat").write_text(text)
    (d / "binary.json").write_bytes(b"\xff\xfe\x00garbage\x80")
    (d / "binary.dat").write_bytes(b"\xff\xfe\x00garbage\x80")
    for name in ("huge.json", "huge.dat"):  # 300 MiB of zeros, stored sparse (no disk)
        with open(d / name, "wb") as fh:
            fh.truncate(300 * 2**20)
    build_npz(d)
    build_hdf5(d)
    for name in ("fifo.json", "fifo.npz", "fifo.h5", "fifo.dat", "fifo_z0.json"):
        os.mkfifo(d / name)
    for name in ("zero.json", "zero.npz", "zero.h5", "zero.dat"):
        os.symlink("/dev/zero", d / name)
    (d / "dir.json").mkdir()
    (d / "dir.h5").mkdir()
    (d / "empty_folder").mkdir()
    (d / "folder_no_problems").mkdir()
    (d / "folder_no_problems" / "notes.txt").write_text("x")
    (d / "nested" / "sub").mkdir(parents=True)
    (d / "nested" / "sub" / "p.json").write_text(json.dumps(OK))
    (d / "out_dir").mkdir()
    os.symlink("/proc/self/fd/1", d / "stdout_link.json")
    os.symlink(d / "ok.json", d / "regular_link.json")
    if os.geteuid() == 0:  # a character device of our own (never the system's /dev/null)
        os.mknod(d / "chardev.json", stat.S_IFCHR | 0o666, os.makedev(1, 3))
    # data-loss cases get their own copies, so that a run that damages one damages no other
    for name in ("same", "samehard", "enum_same", "conv_same", "conv_hard", "batch_in",
                 "md_in", "plot_in", "lock_in"):
        (d / f"{name}.json").write_text(json.dumps(OK))
    os.link(d / "samehard.json", d / "samehard_link.json")
    os.link(d / "conv_hard.json", d / "conv_hard_link.json")
    with h5py.File(d / "batch_in.h5", "w") as f:
        for k in range(2):
            g = f.create_group(f"p{k}")
            g["M"], g["q"] = np.eye(2), -np.ones(2)
    (d / "infolder").mkdir()
    for name in ("a.json", "b.json"):
        (d / "infolder" / name).write_text(json.dumps(OK))
    with h5py.File(d / "infolder" / "coll.h5", "w") as f:
        g = f.create_group("p0")
        g["M"], g["q"] = np.eye(2), -np.ones(2)
    (d / "bounds_box.json").write_text(json.dumps({**OK, "lower": [0, 0], "upper": [1, 1]}))
    (d / "scene.json").write_bytes((ROOT / "samples" / "scene_two_balls.json").read_bytes())
    (d / "overflow.json").write_text('{"M": [[1e300, 1e300], [1e300, 1e300]], "q": [-1, -1]}')
    (d / "existing.jsonl").write_text('{"source": "x", "problem": "x", "status": "solved"}\n')
    (d / "existing.json").write_text('{"keep": true}\n')
    os.mkfifo(d / "fifo_out.jsonl")


# ------------------------------------------------------------------------------ the table
def _json_cases() -> list[Case]:
    words = {
        "not_json": "invalid JSON", "empty": "invalid JSON", "list": "expected a JSON object",
        "no_q": "missing key 'q'", "no_M": "missing key 'M'", "unknown_key": "unknown key 'Q'",
        "ragged": "M must be a list of rows of equal length", "not_square": "M must be square",
        "q_len": "q has length 1", "nan": "M contains NaN", "inf_q": "q contains NaN or Inf",
        "text_M": "M holds strings", "numeric_text_M": "M holds strings",
        "bool_in_M": "M holds booleans", "bool_M": "M holds booleans",
        "text_q": "q holds strings", "bool_q": "q holds booleans",
        "matrix_q": "q must be a vector", "object_q": "q must be a list of numbers",
        "scalar_M": "M must be a list of rows", "text_M_whole": "M must be a list of rows",
        "n_eq_text": "'n_eq' must be an integer", "n_eq_bool": "'n_eq' must be an integer",
        "n_eq_float": "'n_eq' must be an integer", "n_eq_big": "n_eq = 5 is outside",
        "n_eq_negative": "n_eq = -1 is outside", "bounds_crossed": "lower > upper",
        "bounds_text": "lower holds strings", "bounds_bool": "upper holds booleans",
        "bounds_len": "lower has length 1", "bounds_object": "'lower' must be a list",
        "both_forms": "give either n_eq", "meta_list": "'meta' must be an object",
        "meta_deep": "'meta' is nested more than 64 levels",
        "name_number": "'name' must be a string",
        "description_object": "'description' must be a string",
        "deep_M": "invalid JSON: arrays or objects nested too deeply",
        "deep_object": "invalid JSON: arrays or objects nested too deeply",
        "int_400_digits": "M holds an integer too large",
        "int_5000_digits": "invalid JSON: Exceeds the limit",
        "sparse_format": "sparse M: format must be one of",
        "sparse_format_number": "sparse M: 'format' must be a string",
        "sparse_shape_text": "sparse M: 'shape' must be two integers",
        "sparse_shape_float": "sparse M: 'shape' must be two integers",
        "sparse_shape_negative": "negative matrix size",
        "sparse_shape_huge": "matrix of size 1000000000 x 1000000000 is too large",
        "sparse_index_out": "sparse M: an index is outside",
        "sparse_indptr": "sparse M: indptr/indices/data are inconsistent",
        "sparse_data_text": "sparse M data holds strings",
        "sparse_index_float": "sparse M row must hold integers",
        "sparse_index_bool": "sparse M row must hold integers",
        "sparse_coo_lengths": "sparse M: row, col and data differ",
        "sparse_missing": "sparse M: missing indices, indptr",
    }
    kind = {"numeric_text_M": "lenient", "bool_in_M": "lenient", "bool_M": "lenient",
            "text_q": "lenient", "bool_q": "lenient", "n_eq_text": "lenient",
            "n_eq_bool": "lenient", "n_eq_float": "lenient", "name_number": "lenient",
            "description_object": "lenient", "sparse_index_float": "lenient",
            "sparse_index_bool": "lenient", "bounds_bool": "lenient", "meta_deep": "internal",
            "deep_M": "internal", "deep_object": "internal", "int_400_digits": "internal",
            "int_5000_digits": "internal", "sparse_shape_float": "lenient",
            "sparse_format_number": "lenient"}
    cases = [Case(f"json-{name}", kind.get(name, "exit-code"), ["solve", f"{{d}}/{name}.json"],
                  BAD, w) for name, w in words.items()]
    assert set(words) == set(BAD_JSON), set(BAD_JSON) ^ set(words)
    cases += [
        Case("json-binary", "exit-code", ["solve", "{d}/binary.json"], BAD,
             "not a UTF-8 text file"),
        Case("json-huge-file", "memory", ["solve", "{d}/huge.json"], BAD,
             "a JSON problem file of 300 MiB is over the limit", sub=True, memory=True),
        Case("json-stdin-huge", "memory", ["solve", "-"], BAD, "stdin of", stdin="@huge.json",
             sub=True, memory=True),
        Case("json-stdin-empty", "exit-code", ["solve", "-"], BAD, "invalid JSON", stdin=""),
        Case("json-stdin-deep", "internal", ["solve", "-", "--json"], BAD, "invalid JSON",
             stdin="@deep_M.json"),
        Case("json-stdin-problem", "exit-code", ["solve", "-", "-p", "x"], BAD,
             "--problem applies to HDF5 files and stacked files only", stdin="@ok.json"),
        Case("json-info-bool", "lenient", ["info", "{d}/bool_in_M.json"], BAD, "M holds booleans"),
        Case("json-enum-text", "lenient", ["enumerate", "{d}/numeric_text_M.json"], BAD,
             "M holds strings"),
        Case("json-convert-deep", "internal", ["convert", "{d}/deep_object.json",
                                               "{d}/out_deep.npz"], BAD, "invalid JSON",
             absent=("out_deep.npz",)),
    ]
    return cases


def _npz_cases() -> list[Case]:
    table = [
        ("pickled", "exit-code", "array 'q' holds pickled Python objects"),
        ("complex", "lenient", "M holds complex numbers"),
        ("bool", "lenient", "M holds booleans"),
        ("text", "lenient", "M holds strings"),
        ("structured", "exit-code", "M holds structured records"),
        ("dates", "exit-code", "q holds dates"),
        ("q_len", "exit-code", "q has shape (3,) but M is 2 x 2"),
        ("q_matrix", "exit-code", "q has shape (2, 2) but M is 2 x 2"),
        ("M_3d", "exit-code", "q has shape (2,); expected (2, 2) for M of shape (2, 2, 2)"),
        ("M_1d", "exit-code", "M must be a 2-D matrix"),
        ("no_q", "exit-code", "missing array 'q'"),
        ("no_M", "exit-code", "missing array 'M'"),
        ("n_eq_array", "internal", "'n_eq' must be one integer"),
        ("n_eq_float", "lenient", "'n_eq' must be one integer"),
        ("n_eq_text", "lenient", "'n_eq' must be one integer"),
        ("name_array", "lenient", "'name' must be one string"),
        ("meta_text", "exit-code", "invalid JSON"),
        ("meta_list", "internal", "'meta' must be a JSON object"),
        ("meta_deep", "internal", "invalid JSON: arrays or objects nested too deeply"),
        ("lower_complex", "lenient", "lower holds complex numbers"),
        ("lower_len", "exit-code", "lower has shape (5,) but M is 2 x 2"),
        ("sparse_format", "lenient", "'M_format' must be one string"),
        ("sparse_shape", "exit-code", "sparse M: 'M_shape' must be two integers"),
        ("sparse_index_float", "lenient", "sparse M row holds floating-point numbers"),
        ("sparse_complex", "lenient", "sparse M data holds complex numbers"),
        ("garbage", "exit-code", "not a valid NPZ file"),
        ("random", "exit-code", "not a valid NPZ file"),
        ("truncated", "exit-code", "array 'M' is damaged"),
        ("bad_header", "exit-code", "array 'M': damaged .npy header"),
        ("many", "memory", "holds 5,000 zip entries"),
    ]
    cases = [Case(f"npz-{name}", kind, ["solve", f"{{d}}/npz_{name}.npz"], BAD, w)
             for name, kind, w in table]
    cases += [
        Case("npz-bomb-q", "memory", ["solve", "{d}/npz_bomb_q.npz"], BAD,
             "q has shape (150000000,) but M is 2 x 2", sub=True, memory=True),
        Case("npz-bomb-M", "memory", ["solve", "{d}/npz_bomb_M.npz"], BAD,
             "dense 17000 x 17000 matrix would need", sub=True, memory=True),
        Case("npz-bomb-indices", "memory", ["solve", "{d}/npz_bomb_indices.npz"], BAD,
             "sparse M: 'indices' has 150,000,000 entries", sub=True, memory=True),
        Case("npz-info-bomb", "memory", ["info", "{d}/npz_bomb_q.npz"], BAD, "q has shape",
             sub=True, memory=True),
        *[Case(f"npz-corrupt-{kind}-{cmd}", "internal",
               [cmd, f"{{d}}/npz_corrupt_{kind}.npz", *more], BAD, "not a valid NPZ file")
          for kind in ("deflated", "lzma")
          for cmd, more in (("solve", []), ("info", []), ("enumerate", []),
                            ("pivot", ["-d", "z1"]), ("convert", ["{d}/out_zc.json"]),
                            ("bench", ["-m", "lemke", "-r", "1", "--no-peers"]))],
        # the first chunk cannot be read: no result file is created (an empty out.jsonl was)
        *[Case(f"npz-corrupt-{kind}-stack-{more[1][-4:]}", "data-loss",
               [cmd, f"{{d}}/npz_corrupt_{kind}_stack.npz", *more], BAD,
               "not a valid NPZ file", absent=(more[1][len("{d}/"):],))
          for kind in ("deflated", "lzma")
          for cmd, more in (("solve", ["-o", f"{{d}}/out_zc_{kind}.jsonl"]),
                            ("solve", ["-o", f"{{d}}/out_zc_{kind}.h5"]),
                            ("solve", ["-o", f"{{d}}/out_zc_{kind}.csv"]),
                            ("solve", ["-o", f"{{d}}/out_zc_{kind}.npz"]))],
        Case("npz-corrupt-stack-keeps-previous", "data-loss",
             ["solve", "{d}/npz_corrupt_deflated_stack.npz", "-o", "{d}/existing.jsonl"], BAD,
             "not a valid NPZ file", protect=("existing.jsonl",)),
        *[Case(f"npz-corrupt-{kind}-z0-{cmd}", "internal",
               [*args, "--z0", f"{{d}}/npz_corrupt_{kind}_z0.npz"], BAD,
               "cannot read a vector")
          for kind in ("deflated", "lzma")
          for cmd, args in (("solve", ["solve", "{d}/ok.npz"]),
                            ("contact", ["contact-matrix", "{d}/scene.json", "--solve"]))],
        Case("npz-convert-complex", "lenient", ["convert", "{d}/npz_complex.npz",
                                                "{d}/out_c.json"], BAD,
             "M holds complex numbers", absent=("out_c.json",)),
    ]
    return cases


def _hdf5_cases() -> list[Case]:
    table = [
        ("garbage", "exit-code", "not a readable HDF5 file"),
        ("text", "exit-code", "not a readable HDF5 file"),
        ("n_eq_text", "internal", "attribute 'n_eq' must be one integer"),
        ("n_eq_array", "internal", "attribute 'n_eq' must be one integer"),
        ("n_eq_float", "lenient", "attribute 'n_eq' must be one integer"),
        ("meta_list", "internal", "attribute 'meta' must be a JSON object"),
        ("meta_text", "exit-code", "invalid JSON"),
        ("meta_number", "internal", "attribute 'meta' must be one string"),
        ("meta_deep", "internal", "invalid JSON: arrays or objects nested too deeply"),
        ("name_array", "lenient", "attribute 'name' must be one string"),
        ("q_group", "internal", "'q' is a group, expected a dataset"),
        ("M_group_bare", "internal", "sparse M: missing attribute 'format'"),
        ("M_1d", "exit-code", "M must be a 2-D matrix"),
        ("q_matrix", "exit-code", "q has shape (2, 2) but M is 2 x 2"),
        ("q_null", "internal", "'q' is an empty (null) dataset"),
        ("complex", "lenient", "'M' holds complex numbers"),
        ("bool", "lenient", "'M' holds booleans"),
        ("text_q", "lenient", "'q' holds mixed or non-numeric values"),
        ("compound", "exit-code", "'M' holds structured records"),
        ("extlink", "lenient", "'M' is an external link"),
        ("virtual", "lenient", "'q' keeps its data in other files"),
        ("external", "lenient", "'q' keeps its data in other files"),
        ("dangling", "exit-code", "'M' is a dangling link"),
        ("sparse_shape_text", "internal", "sparse M: attribute 'shape' must be two integers"),
        ("sparse_format_number", "lenient", "attribute 'format' must be one string"),
        ("sparse_index_float", "lenient", "'M/indices' holds floating-point numbers"),
    ]
    cases = [Case(f"h5-{name}", kind, ["solve", f"{{d}}/h5_{name}.h5"], BAD, w)
             for name, kind, w in table]
    cases += [
        Case("h5-lazy-q", "memory", ["solve", "{d}/h5_lazy_q.h5"], BAD,
             "q has shape (300000000,) but M is 2 x 2", sub=True, memory=True),
        Case("h5-lazy-lower", "memory", ["solve", "{d}/h5_lazy_lower.h5"], BAD,
             "lower has shape (300000000,)", sub=True, memory=True),
        Case("h5-lazy-M", "memory", ["solve", "{d}/h5_lazy_M.h5"], BAD,
             "dense 1000000 x 1000000 matrix", sub=True, memory=True),
        Case("h5-lazy-indices", "memory", ["solve", "{d}/h5_lazy_indices.h5"], BAD,
             "sparse M: 'indices' has 300,000,000 entries", sub=True, memory=True),
        Case("h5-lazy-data", "memory", ["solve", "{d}/h5_lazy_data.h5"], BAD,
             "sparse matrix with 600000000 stored entries is too large", sub=True, memory=True),
        Case("h5-lazy-indptr", "memory", ["solve", "{d}/h5_lazy_indptr.h5"], BAD,
             "sparse M: 'indptr' has 300,000,000 entries", sub=True, memory=True),
        Case("h5-lazy-q-batch", "memory", ["solve", "{d}/h5_lazy_q.h5", "{d}/ok.json", "--json"],
             BAD, "q has shape (300000000,)", rows=True, sub=True, memory=True),
        Case("h5-extlink-fifo", "hang", ["solve", "{d}/h5_extlink_fifo.h5"], BAD,
             "'M' is an external link", sub=True),
        Case("h5-no-such-group", "exit-code", ["solve", "{d}/multi.h5", "-p", "zz"], BAD,
             "no problem named 'zz'"),
        Case("h5-problem-on-json", "exit-code", ["solve", "{d}/ok.json", "-p", "x"], BAD,
             "--problem applies to HDF5 files and stacked files only"),
        Case("h5-info-n_eq", "internal", ["info", "{d}/h5_n_eq_array.h5"], BAD,
             "attribute 'n_eq' must be one integer"),
        Case("h5-enum-q-group", "internal", ["enumerate", "{d}/h5_q_group.h5"], BAD,
             "'q' is a group"),
        Case("h5-convert-meta", "internal", ["convert", "{d}/h5_meta_list.h5",
                                             "{d}/out_m.json"], BAD,
             "attribute 'meta' must be a JSON object", absent=("out_m.json",)),
        Case("h5-batch-q-group", "internal", ["solve", "{d}/h5_q_group.h5", "{d}/ok.json",
                                              "--json"], BAD, "'q' is a group", rows=True),
    ]
    return cases


def _dat_cases() -> list[Case]:
    table = [
        ("nan_size", "internal", "expected an integer for n, got 'nan'"),
        ("inf_size", "internal", "expected an integer for M size0, got 'inf'"),
        ("huge_float_size", "internal", "expected an integer for n, got '1e400'"),
        ("negative", "exit-code", "n = -2 is out of range"),
        ("fraction", "exit-code", "expected an integer for n"),
        ("truncated", "exit-code", "file ends early"),
        ("text_value", "exit-code", "not a number in M values: 'x'"),
        ("size_mismatch", "exit-code", "M is 2 x 2 but n = 3"),
        ("storage", "exit-code", "unknown storage type 7"),
        ("empty", "exit-code", "empty file"),
        ("sbm_rowptr", "internal", "block row pointer = 5 is out of range"),
        ("sbm_colidx", "internal", "block column index = 7 is out of range"),
        ("sbm_ends", "internal", "M block row end"),
        ("sbm_rowptr_down", "internal", "M: block row pointers must start at 0"),
        ("huge_dense", "exit-code", "dense 100000 x 100000 matrix would need"),
        ("mlcp_bounds", "exit-code", "block boundary = 0 is out of range"),
        ("mlcp_flags", "lenient", "block flag = 7 is out of range"),
        ("mlcp_sizes", "exit-code", "n (equalities) = -1 is out of range"),
    ]
    cases = [Case(f"dat-{name}", kind, ["solve", f"{{d}}/dat_{name}.dat"], BAD, w)
             for name, kind, w in table]
    assert {f"dat_{n}" for n, _, _ in table} == set(BAD_DAT)
    cases += [
        Case("dat-binary", "exit-code", ["solve", "{d}/binary.dat"], BAD, "not a text file"),
        Case("dat-huge-file", "memory", ["solve", "{d}/huge.dat"], BAD,
             "a Siconos .dat file of 300 MiB is over the limit", sub=True, memory=True),
        Case("dat-info-nan", "internal", ["info", "{d}/dat_nan_size.dat"], BAD,
             "expected an integer for n"),
        Case("dat-convert-sbm", "internal", ["convert", "{d}/dat_sbm_rowptr.dat",
                                             "{d}/out_s.json"], BAD, "block row pointer",
             absent=("out_s.json",)),
    ]
    return cases


def _file_kind_cases() -> list[Case]:
    fifo = "is a FIFO (named pipe), not a regular file"
    cases = [
        Case("fifo-solve", "hang", ["solve", "{d}/fifo.json"], BAD, fifo, sub=True),
        Case("fifo-info", "hang", ["info", "{d}/fifo.json"], BAD, fifo, sub=True),
        Case("fifo-enumerate", "hang", ["enumerate", "{d}/fifo.dat"], BAD, fifo, sub=True),
        Case("fifo-pivot", "hang", ["pivot", "{d}/fifo.json", "-d", "z1"], BAD, fifo, sub=True),
        Case("fifo-convert-npz", "hang", ["convert", "{d}/fifo.npz", "{d}/out_f.json"], BAD,
             fifo, sub=True, absent=("out_f.json",)),
        Case("fifo-convert-h5", "hang", ["convert", "{d}/fifo.h5", "{d}/out_f2.json"], BAD, fifo,
             sub=True, absent=("out_f2.json",)),
        Case("fifo-batch", "hang", ["solve", "{d}/fifo.h5", "{d}/ok.json", "--json"], BAD, fifo,
             rows=True, sub=True),
        Case("fifo-batch-json", "hang", ["solve", "{d}/fifo.json", "{d}/ok.json", "--json"], BAD,
             fifo, rows=True, sub=True),
        Case("fifo-z0", "hang", ["solve", "{d}/ok.json", "--z0", "{d}/fifo_z0.json"], BAD, fifo,
             sub=True),
        Case("zero-json", "memory", ["solve", "{d}/zero.json"], BAD,
             "is a character device, not a regular file", sub=True, memory=True),
        Case("zero-dat", "memory", ["info", "{d}/zero.dat"], BAD, "is a character device",
             sub=True, memory=True),
        Case("zero-npz", "memory", ["solve", "{d}/zero.npz"], BAD, "is a character device",
             sub=True, memory=True),
        Case("zero-h5", "memory", ["solve", "{d}/zero.h5"], BAD, "is a character device",
             sub=True, memory=True),
        Case("zero-z0", "memory", ["solve", "{d}/ok.json", "--z0", "{d}/zero.json"], BAD,
             "is a character device", sub=True, memory=True),
        # one line on stderr, as the README promises (issue 23: was an error row on stdout)
        Case("dir-solve", "exit-code", ["solve", "{d}/dir.json"], BAD,
             "is a directory, not a problem file", env={"COLUMNS": "300"}),
        Case("dir-solve-json", "exit-code", ["solve", "{d}/dir.json", "--json"], BAD,
             "is a directory, not a problem file"),
        Case("dir-info", "exit-code", ["info", "{d}/dir.h5"], BAD, "is a directory"),
        Case("dir-convert", "exit-code", ["convert", "{d}/dir.json", "{d}/out_d.json"], BAD,
             "is a directory", absent=("out_d.json",)),
        Case("empty-folder", "exit-code", ["solve", "{d}/empty_folder", "--json"], BAD,
             "no problem files in this folder", rows=True),
        Case("folder-no-problems", "exit-code", ["solve", "{d}/folder_no_problems", "--json"],
             BAD, "no problem files in this folder", rows=True),
        Case("folder-only-subfolders", "exit-code", ["solve", "{d}/nested", "--json"], BAD,
             "no problem files in this folder", rows=True),
        Case("glob-nothing", "exit-code", ["solve", "{d}/nothing_*.json", "--json"], BAD,
             "no file matches this pattern", rows=True),
        Case("missing-file", "exit-code", ["solve", "{d}/missing.json"], BAD, "no such file"),
        Case("missing-in-batch", "exit-code", ["solve", "{d}/missing.json", "{d}/ok.json",
                                               "--json"], BAD, "no such file", rows=True),
        Case("unknown-ext", "exit-code", ["solve", "{d}/stdout_link.txt"], BAD,
             "unknown file type .txt"),
        # a missing name without a problem extension is missing, not of an unknown type
        Case("missing-folder", "exit-code", ["solve", "{d}/no_such_dir/"], BAD,
             "no such file"),
        Case("missing-folder-in-batch", "exit-code", ["solve", "{d}/no_such_dir/",
                                                      "{d}/ok.json", "--json"], BAD,
             "no such file", rows=True),
        Case("missing-folder-info", "exit-code", ["info", "{d}/no_such_dir/"], BAD,
             "no such file"),
        Case("missing-folder-convert", "exit-code", ["convert", "{d}/no_such_dir/",
                                                     "{d}/o.json"], BAD,
             "no such file", absent=("o.json",)),
    ]
    return cases


def _output_cases() -> list[Case]:
    same = "is the same file as the input"
    return [
        Case("out-same-solve", "data-loss", ["solve", "{d}/same.json", "-o", "{d}/same.json"],
             BAD, same, protect=("same.json",)),
        Case("out-hardlink-solve", "data-loss", ["solve", "{d}/samehard.json", "-o",
                                                 "{d}/samehard_link.json"], BAD, same,
             protect=("samehard.json",)),
        Case("out-same-enumerate", "data-loss", ["enumerate", "{d}/enum_same.json", "-o",
                                                 "{d}/enum_same.json"], BAD, same,
             protect=("enum_same.json",)),
        Case("out-same-convert", "data-loss", ["convert", "{d}/conv_same.json",
                                               "{d}/conv_same.json", "--force"], BAD, same,
             protect=("conv_same.json",)),
        Case("out-hardlink-convert", "data-loss", ["convert", "{d}/conv_hard.json",
                                                   "{d}/conv_hard_link.json", "--force"], BAD,
             same, protect=("conv_hard.json",)),
        Case("out-same-z0", "data-loss", ["solve", "{d}/ok.json", "--z0", "{d}/z0_ok.json",
                                          "-o", "{d}/z0_ok.json"], BAD, same,
             protect=("z0_ok.json",)),
        Case("out-same-batch-h5", "data-loss", ["solve", "{d}/batch_in.h5", "{d}/ok.json",
                                                "-o", "{d}/batch_in.h5"], BAD, same,
             protect=("batch_in.h5",)),
        Case("out-in-input-folder", "data-loss", ["solve", "{d}/infolder", "-o",
                                                  "{d}/infolder/coll.h5"], BAD,
             "holds problems of this batch", protect=("infolder/coll.h5",)),
        Case("out-markdown-input", "data-loss", ["bench", "{d}/md_in.json", "--markdown",
                                                 "{d}/md_in.json", "-m", "lemke",
                                                 "--no-peers"], BAD, same,
             protect=("md_in.json",)),
        Case("out-markdown-plot-same", "data-loss", ["bench", "{d}/ok.json", "-m", "lemke",
                                                     "-r", "1", "--no-peers", "--timeout", "0",
                                                     "--markdown", "{d}/bm_same.md", "--plot",
                                                     "{d}/bm_same.md"], BAD,
             "--plot {d}/bm_same.md: is the same file as --markdown {d}/bm_same.md",
             absent=("bm_same.md",)),
        Case("out-dash-bench-markdown", "data-loss", ["bench", "{d}/ok.json", "-m", "lemke",
                                                      "-r", "1", "--no-peers", "--timeout", "0",
                                                      "--markdown", "-"], BAD,
             "--markdown: '-' is not a file here", absent=("-",)),
        Case("out-dash-enumerate-plot", "exit-code", ["enumerate", "{d}/ok.json", "--plot", "-"],
             BAD, "--plot: '-' is not a file here", absent=("-",)),
        Case("out-stdout-link", "data-loss", ["solve", "{d}/ok.json", "-o",
                                              "{d}/stdout_link.json"], BAD,
             "is a symbolic link (to /proc/self/fd/1)"),
        Case("out-regular-link", "data-loss", ["solve", "{d}/ok.json", "-o",
                                               "{d}/regular_link.json"], BAD,
             "is a symbolic link", protect=("ok.json",)),
        Case("out-chardev", "data-loss", ["solve", "{d}/ok.json", "-o", "{d}/chardev.json"],
             BAD, "is a character device, not a regular file: refusing", root_only=True),
        Case("out-chardev-convert", "data-loss", ["convert", "{d}/ok.json", "{d}/chardev.json",
                                                  "--force"], BAD, "is a character device",
             root_only=True),
        Case("out-dir-solve", "internal", ["solve", "{d}/ok.json", "-o", "{d}/out_dir"], BAD,
             "is a directory, not a regular file"),
        Case("out-dir-convert", "internal", ["convert", "{d}/ok.json", "{d}/out_dir", "--force",
                                             ], BAD, "unknown file type"),
        Case("out-dir-convert-ext", "internal", ["convert", "{d}/ok.json", "{d}/dir.json",
                                                 "--force"], BAD, "is a directory, not a "
                                                                  "regular file"),
        Case("out-fifo-batch", "hang", ["solve", "{d}/ok.json", "{d}/three.json", "-o",
                                        "{d}/fifo_out.jsonl"], BAD,
             "is a FIFO (named pipe), not a regular file", sub=True),
        Case("out-dash-solve", "data-loss", ["solve", "{d}/ok.json", "-o", "-"], BAD,
             "'-' is not a file here", absent=("-",)),
        Case("out-dash-enumerate", "data-loss", ["enumerate", "{d}/ok.json", "-o", "-"], BAD,
             "'-' is not a file here", absent=("-",)),
        Case("out-missing-folder", "exit-code", ["solve", "{d}/ok.json", "-o",
                                                 "{d}/nowhere/r.json"], BAD,
             "folder {d}/nowhere does not exist"),
        Case("out-exists-convert", "data-loss", ["convert", "{d}/ok.json",
                                                 "{d}/existing.json"], BAD,
             "exists already", protect=("existing.json",)),
        Case("out-bad-input-keeps-output", "data-loss", ["convert", "{d}/not_json.json",
                                                         "{d}/existing.json", "--force"], BAD,
             "invalid JSON", protect=("existing.json",)),
        Case("out-bad-batch-output", "exit-code", ["solve", "{d}/ok.json", "{d}/three.json",
                                                   "-o", "{d}/r.txt"], BAD,
             "--output {d}/r.txt: unknown result file type", absent=("r.txt",)),
        Case("out-lock-held", "data-loss", ["solve", "{d}/ok.json", "{d}/three.json", "-o",
                                            "{d}/existing.jsonl"], BAD,
             "is being written by another lcpcli run", protect=("existing.jsonl",)),
        Case("fifo-contact-scene", "hang", ["contact-matrix", "{d}/fifo.json"], BAD, "is a FIFO",
             sub=True, timeout=10),
        Case("zero-contact-scene", "memory", ["contact-matrix", "{d}/zero.json"], BAD,
             "is a character device", sub=True, memory=True, timeout=20),
        Case("out-contact-scene", "data-loss", ["contact-matrix", "{d}/scene.json", "-o",
                                                "{d}/scene.json"], BAD, same,
             protect=("scene.json",)),
    ]


def _option_cases() -> list[Case]:
    ok = "{d}/ok.json"
    return [
        Case("opt-max-iter-1e30", "internal", ["solve", ok, "--max-iter", "1e30"], BAD,
             "Invalid value for '--max-iter'"),
        Case("opt-max-iter-huge", "internal", ["solve", ok, "--max-iter", "1" + "0" * 20], BAD,
             "option 'max_iter' (--max-iter): must be at most 2,147,483,647"),
        Case("opt-max-iter-O-huge", "internal", ["solve", ok, "-m", "lemke", "-O",
                                                 "max_iter=" + "1" + "0" * 20], BAD,
             "option 'max_iter'"),
        Case("opt-max-iter-0", "exit-code", ["solve", ok, "--max-iter", "0"], BAD, "option"),
        Case("opt-tol-nan", "exit-code", ["solve", ok, "--tol", "nan"], BAD, "tolerance"),
        Case("opt-tol-inf", "exit-code", ["solve", ok, "--tol", "inf"], BAD, "tolerance"),
        Case("opt-tol-negative", "exit-code", ["solve", ok, "--tol", "-1"], BAD, "tolerance"),
        Case("opt-omega-nan", "exit-code", ["solve", ok, "-m", "psor", "--omega", "nan"], BAD,
             "option 'omega'"),
        Case("opt-covering-text", "exit-code", ["solve", ok, "-m", "lemke", "--covering", "1,x"],
             BAD, "option 'covering'"),
        Case("opt-covering-nan", "exit-code", ["solve", ok, "-m", "lemke", "--covering",
                                               "nan,1"], BAD, "option 'covering'"),
        Case("opt-O-no-equals", "exit-code", ["solve", ok, "-O", "junk"], BAD,
             "method option must look like KEY=VALUE"),
        Case("opt-O-unknown", "exit-code", ["solve", ok, "-m", "lemke", "-O", "zzz=1"], BAD,
             "method 'lemke-revised' has no option"),
        Case("opt-method-unknown", "exit-code", ["solve", ok, "-m", "nope"], BAD,
             "unknown method 'nope'"),
        Case("opt-unknown-option", "exit-code", ["solve", ok, "--bogus"], BAD,
             "No such option: --bogus"),
        Case("opt-unknown-command", "exit-code", ["frobnicate"], BAD, "No such command"),
        Case("opt-missing-argument", "exit-code", ["solve"], BAD, "Missing argument 'FILE'"),
        Case("z0-deep", "internal", ["solve", ok, "--z0", "{d}/z0_deep.json"], BAD,
             "invalid JSON: arrays or objects nested too deeply"),
        Case("z0-nulls", "exit-code", ["solve", ok, "--z0", "{d}/z0_nulls.json"], BAD,
             "the list holds null entries"),
        Case("z0-text", "lenient", ["solve", ok, "--z0", "{d}/z0_text.json"], BAD,
             "z0 holds strings"),
        Case("z0-bools", "lenient", ["solve", ok, "--z0", "{d}/z0_bools.json"], BAD,
             "z0 holds booleans"),
        Case("z0-nested", "exit-code", ["solve", ok, "--z0", "{d}/z0_nested.json"], BAD,
             "expected a list of numbers"),
        Case("z0-complex", "lenient", ["solve", ok, "--z0", "{d}/z0_complex.npy"], BAD,
             "z0 holds complex numbers"),
        Case("z0-matrix", "exit-code", ["solve", ok, "--z0", "{d}/z0_matrix.npy"], BAD,
             "expected a vector, got shape (3, 3)"),
        Case("z0-pickled", "exit-code", ["solve", ok, "--z0", "{d}/z0_pickled.npz"], BAD,
             "array 'z' holds pickled Python objects"),
        Case("z0-two-arrays", "exit-code", ["solve", ok, "--z0", "{d}/z0_two.npz"], BAD,
             "NPZ file has arrays"),
        Case("z0-dir", "exit-code", ["solve", ok, "--z0", "{d}/dir.json"], BAD,
             "is a directory, not a vector file"),
        Case("z0-missing", "exit-code", ["solve", ok, "--z0", "{d}/missing.json"], BAD,
             "no such file"),
        Case("z0-length", "exit-code", ["solve", "{d}/three.json", "-m", "pgs", "--z0",
                                        "{d}/z0_ok.json"], BAD,
             "--z0 {d}/z0_ok.json: has 2 values, the problem has n = 3"),
        Case("z0-length-json-long", "exit-code", ["solve", ok, "--z0", "{d}/z0_three.json"],
             BAD, "--z0 {d}/z0_three.json: has 3 values, the problem has n = 2"),
        Case("batch-jobs-0", "exit-code", ["solve", ok, "{d}/three.json", "-j", "0"], BAD,
             "Invalid value for '--jobs'"),
        Case("batch-timeout-nan", "exit-code", ["solve", ok, "{d}/three.json", "--timeout",
                                                "nan"], BAD, "--timeout must be a positive"),
        Case("batch-timeout-negative", "exit-code", ["solve", ok, "{d}/three.json",
                                                     "--timeout", "-1"], BAD,
             "--timeout must be a positive"),
        Case("batch-resume-no-output", "exit-code", ["solve", ok, "{d}/three.json", "--resume"],
             BAD, "--resume needs --output"),
        Case("batch-problem", "exit-code", ["solve", ok, "{d}/three.json", "-p", "x"], BAD,
             "--problem picks one problem"),
        Case("batch-stdin", "exit-code", ["solve", "-", ok], BAD,
             "'-' (stdin) cannot be part of a batch"),
        Case("batch-trace", "exit-code", ["solve", ok, "{d}/three.json", "--trace"], BAD,
             "--trace (and --layout, --pivot, --step, --format) shows one problem's steps"),
        Case("bench-budget-nan", "exit-code", ["bench", ok, "--budget", "nan"], BAD,
             "--budget must be a positive number"),
        Case("bench-budget-inf", "exit-code", ["bench", ok, "--budget", "inf"], BAD,
             "--budget must be a positive number"),
        Case("bench-budget-0", "exit-code", ["bench", ok, "--budget", "0"], BAD,
             "--budget must be a positive number"),
        Case("bench-timeout-nan", "exit-code", ["bench", ok, "--timeout", "nan"], BAD,
             "--timeout must be a finite number"),
        Case("bench-timeout-inf", "exit-code", ["bench", ok, "--timeout", "inf"], BAD,
             "--timeout must be a finite number"),
        Case("bench-repeat-negative", "exit-code", ["bench", ok, "--repeat", "-1"], BAD,
             "--repeat must be between 0 and"),
        Case("bench-repeat-huge", "exit-code", ["bench", ok, "--repeat", "1000000000"], BAD,
             "--repeat must be between 0 and"),
        Case("bench-tol-nan", "exit-code", ["bench", ok, "--tol", "nan"], BAD,
             "tolerance must lie in"),
        Case("bench-tol-text", "exit-code", ["bench", ok, "--tol", "x"], BAD,
             "--tol must be a comma-separated list"),
        Case("bench-suite-hard-huge", "exit-code", ["bench", "--suite", "hard", "--n",
                                                    "1000000000"], BAD,
             "--n 1000000000 is too large for the hard suite"),
        Case("bench-suite-random-huge", "exit-code", ["bench", "--suite", "random", "--n",
                                                      "1000000"], BAD,
             "--n 1000000 is too large for the random suite"),
        Case("bench-suite-n-0", "exit-code", ["bench", "--suite", "hard", "--n", "0"], BAD,
             "--n must be positive"),
        Case("bench-seed-negative", "internal", ["bench", "--suite", "random", "--n", "10",
                                                 "--seed", "-1"], BAD, "--seed must be >= 0"),
        Case("bench-suite-unknown", "exit-code", ["bench", "--suite", "nope"], BAD,
             "unknown suite 'nope'"),
        Case("bench-no-problems", "exit-code", ["bench"], BAD,
             "give problem files or folders"),
        Case("bench-method-unknown", "exit-code", ["bench", ok, "-m", "nope"], BAD,
             "unknown method"),
        Case("bench-bad-file", "exit-code", ["bench", "{d}/bool_M.json"], BAD,
             "M holds booleans"),
        Case("enum-max-n-0", "exit-code", ["enumerate", ok, "--max-n", "0"], BAD,
             "max-n must be between 1 and 62"),
        Case("enum-max-n-63", "exit-code", ["enumerate", ok, "--max-n", "63"], BAD,
             "max-n must be between 1 and 62"),
        Case("enum-too-big", "exit-code", ["enumerate", "{d}/n17.json", "--max-n", "16"], BAD,
             "n = 17 means 2^17"),
        Case("enum-all-cones-table", "exit-code", ["enumerate", "{d}/n17.json", "--all-cones",
                                                   "--max-n", "17"], BAD,
             "--all-cones lists 2^n = 131,072 cones"),
        Case("enum-mlcp", "exit-code", ["enumerate", "{d}/mlcp.json"], BAD,
             "enumeration handles plain LCPs only"),
        Case("enum-plot-n3", "exit-code", ["enumerate", "{d}/three.json", "--plot",
                                           "{d}/p.png"], BAD, "--plot draws the cones of 2 x 2",
             absent=("p.png",)),
        Case("pivot-bad-basis", "exit-code", ["pivot", ok, "-d", "z9,w1"], BAD, None),
        Case("convert-unknown-out", "exit-code", ["convert", ok, "{d}/x.txt"], BAD,
             "unknown file type .txt", absent=("x.txt",)),
        Case("convert-box-to-dat", "exit-code", ["convert", "{d}/bounds_box.json",
                                                 "{d}/box.dat"], BAD,
             "{d}/box.dat: the Siconos .dat format has no box LCPs", absent=("box.dat",)),
        Case("convert-box-to-dat-folder", "exit-code", ["convert", "{d}/bounds_box.json",
                                                        "{d}/boxdats", "--format", "dat"], BAD,
             "{d}/boxdats/bounds_box.dat: the Siconos .dat format has no box LCPs",
             absent=("boxdats",)),
        Case("enum-box", "exit-code", ["enumerate", "{d}/bounds_box.json"], BAD,
             "{d}/bounds_box.json: enumeration handles plain LCPs only"),
        Case("info-missing", "exit-code", ["info", "{d}/missing.npz"], BAD, "no such file"),
        Case("pivot-deep-json", "internal", ["pivot", "{d}/deep_M.json", "-d", "z1"], BAD,
             "invalid JSON"),
        Case("norm-overflow-info", "internal", ["info", "{d}/overflow.json"], SOLVED, None),
        Case("norm-overflow-enumerate", "internal", ["enumerate", "{d}/overflow.json"], SOLVED,
             None),
        Case("norm-overflow-solve", "internal", ["solve", "{d}/overflow.json"], SOLVED, None),
    ]


def cases() -> list[Case]:
    return (_json_cases() + _npz_cases() + _hdf5_cases() + _dat_cases() + _file_kind_cases()
            + _output_cases() + _option_cases())


# ------------------------------------------------------------------------------ running
@dataclass
class Outcome:
    code: int | None          # None: killed by the kill switch (a hang)
    stdout: str
    stderr: str


class _Hang(BaseException):
    """Raised by the SIGALRM kill switch (BaseException: main() must not swallow it)."""


def _alarm(signum: int, frame: object) -> None:
    raise _Hang()


def _argv(case: Case, d: Path) -> list[str]:
    return [a.replace("{d}", str(d)) for a in case.args]


def _stdin(case: Case, d: Path) -> tuple[bytes | None, Path | None]:
    if case.stdin is None:
        return None, None
    if case.stdin.startswith("@"):
        return None, d / case.stdin[1:]
    return case.stdin.encode(), None


def run_in_process(case: Case, d: Path) -> Outcome:
    """``lcpcli.cli.main`` in this process, stdout/stderr captured, under a kill switch."""
    from lcpcli.cli import main

    data, path = _stdin(case, d)
    if path is not None:
        data = path.read_bytes()
    saved = sys.stdin, sys.stdout, sys.stderr
    old_env = {k: os.environ.get(k) for k in case.env}
    os.environ.update(case.env)
    out, err = io.StringIO(), io.StringIO()
    sys.stdin = io.TextIOWrapper(io.BytesIO(data or b""))
    sys.stdout, sys.stderr = out, err
    old_handler = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(TIMEOUT)
    cwd = os.getcwd()
    os.chdir(d)
    code: int | None
    try:
        main(_argv(case, d))
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 0
    except _Hang:
        code = None
    finally:
        os.chdir(cwd)
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old_handler)
        sys.stdin, sys.stdout, sys.stderr = saved
        import warnings

        warnings.showwarning = warnings._showwarning_orig  # type: ignore[attr-defined]
        for k, v in old_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return Outcome(code, out.getvalue(), err.getvalue())


def _limit_memory() -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run_subprocess(case: Case, d: Path, root: Path = ROOT, timeout: float = TIMEOUT,
                   memory: bool | None = None) -> Outcome:
    """``python -m lcpcli`` from ``root`` with a timeout (and the 1 GiB limit if ``memory``)."""
    data, path = _stdin(case, d)
    env = {**os.environ, "PYTHONPATH": str(root), **case.env}
    env.pop("LCPCLI_DEBUG", None)
    limit = case.memory if memory is None else memory
    timeout = case.timeout or timeout
    stdin = open(path, "rb") if path is not None else None  # noqa: SIM115
    try:
        proc = subprocess.run([sys.executable, "-m", "lcpcli", *_argv(case, d)],
                              input=data if stdin is None else None,
                              stdin=stdin if stdin is not None else (
                                  None if data is not None else subprocess.DEVNULL),
                              capture_output=True, env=env, cwd=d, timeout=timeout,
                              preexec_fn=_limit_memory if limit else None)
        return Outcome(proc.returncode, proc.stdout.decode(errors="replace"),
                       proc.stderr.decode(errors="replace"))
    except subprocess.TimeoutExpired as exc:
        return Outcome(None, (exc.stdout or b"").decode(errors="replace"),
                       (exc.stderr or b"").decode(errors="replace"))
    finally:
        if stdin is not None:
            stdin.close()


def digest(path: Path) -> str:
    """What a data-loss check compares: the file's type and, for a regular file, its bytes."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return "missing"
    if not stat.S_ISREG(st.st_mode):
        return f"mode {stat.filemode(st.st_mode)}"
    return hashlib.sha256(path.read_bytes()).hexdigest()


def problems(case: Case, out: Outcome, d: Path, before: dict[str, str]) -> list[str]:
    """What went wrong (empty when the case behaved), as ``kind: detail`` strings."""
    found = []
    for name, h in before.items():
        if digest(d / name) != h:
            found.append(f"data-loss: {name} changed")
    for name in case.absent:
        if os.path.lexists(d / name):
            found.append(f"data-loss: {name} was created")
    text = out.stdout + out.stderr
    if out.code is None:
        return found + ["hang: no answer within the time limit"]
    if "MemoryError" in text or "not enough memory" in text or "Cannot allocate" in text \
            or out.code in (-9, 137):
        return found + [f"memory: {text.strip().splitlines()[-1][:120] if text.strip() else ''}"]
    if "Traceback" in text:
        found.append("internal: traceback printed")
    if out.code == 3:
        return found + [f"internal: {out.stderr.strip()[:160]}"]
    if "Warning" in out.stderr and ".py:" in out.stderr:
        found.append("exit-code: a Python warning with a file path on stderr")
    if out.code != case.code:
        kind = "lenient" if out.code == 0 and case.code == BAD else "exit-code"
        return found + [f"{kind}: exit {out.code}, expected {case.code}: "
                        f"{out.stderr.strip()[:160]}"]
    if case.words is None:
        return found
    words = case.words.replace("{d}", str(d))
    if case.rows:
        messages = []
        for line in out.stdout.splitlines():
            try:
                row = json.loads(line)
            except ValueError:
                continue
            if isinstance(row, dict) and row.get("status") == "error":
                messages.append(str(row.get("message", "")))
        if not messages:  # a table (no --json): the reason is printed in it
            messages = [" ".join(out.stdout.split())]
    else:
        lines = out.stderr.strip().splitlines()
        if len(lines) != 1 or not lines[0].startswith("lcpcli: error: "):
            return found + [f"message: not one 'lcpcli: error:' line: {out.stderr[:200]!r}"]
        if out.stdout:
            found.append(f"message: stdout not empty: {out.stdout[:100]!r}")
        messages = [lines[0][len("lcpcli: error: "):]]
    pattern = re.compile(r"(^|: |\s)" + re.escape(words))
    if not any(pattern.search(m) for m in messages):
        found.append(f"message: {words!r} not in {messages[:2]!r}")
    return found


# ------------------------------------------------------------------------------ pytest
@pytest.fixture(scope="module")
def fixtures(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("hostile")
    build(d)
    return d


def _protected(case: Case, d: Path) -> dict[str, str]:
    return {name: digest(d / name) for name in case.protect}


CASES = cases()


def test_the_table_is_large_and_names_are_unique() -> None:
    assert len(CASES) >= 150
    assert len({c.id for c in CASES}) == len(CASES)
    assert {c.kind for c in CASES} <= {"data-loss", "internal", "hang", "memory", "lenient",
                                       "exit-code", "shell"}


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id, marks=[pytest.mark.xfail(
    reason=c.xfail, strict=False)] if c.xfail else []) for c in CASES])
def test_bad_input(case: Case, fixtures: Path) -> None:
    if case.root_only and not (fixtures / "chardev.json").exists():
        pytest.skip("creating a character device needs root")
    if case.id == "out-lock-held":  # another writer holds the output
        import fcntl

        from lcpcli.io.writing import lock_path

        fd = os.open(lock_path(fixtures / "existing.jsonl"), os.O_RDWR | os.O_CREAT)
        os.write(fd, b"4242\n")
        fcntl.flock(fd, fcntl.LOCK_EX)
    before = _protected(case, fixtures)
    try:
        out = run_subprocess(case, fixtures) if case.sub else run_in_process(case, fixtures)
    finally:
        if case.id == "out-lock-held":
            os.close(fd)
    assert problems(case, out, fixtures, before) == []


# ------------------------------------------------------------------------------ survey
def survey(root: Path, d: Path, timeout: float, only: list[str] | None = None) -> dict[str, int]:
    """Run every case (or those named in ``only``) in a subprocess against the checkout at
    ``root`` under the 1 GiB limit; print what went wrong and count the cases by kind."""
    import fcntl
    from collections import Counter

    counts: Counter[str] = Counter()
    for case in CASES:
        if only and case.id not in only:
            continue
        if case.root_only and not (d / "chardev.json").exists():
            continue
        fd = None
        if case.id == "out-lock-held":
            fd = os.open(d / "existing.jsonl.lock", os.O_RDWR | os.O_CREAT)
            fcntl.flock(fd, fcntl.LOCK_EX)
        before = _protected(case, d)
        out = run_subprocess(case, d, root=root, timeout=timeout, memory=True)
        if fd is not None:
            os.close(fd)
        found = problems(case, out, d, before)
        kinds = sorted({f.split(":")[0] for f in found})
        for k in kinds:
            counts[k] += 1
        if found:
            print(f"{case.id:32s} {'; '.join(found)[:200]}", flush=True)
    return dict(counts)


if __name__ == "__main__":
    import argparse
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=ROOT, help="checkout to test")
    parser.add_argument("--timeout", type=float, default=20.0, help="seconds per case")
    parser.add_argument("--only", nargs="*", help="case ids to run (default: all)")
    ns = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "hostile"
        build(folder)
        result = survey(ns.root.resolve(), folder, ns.timeout, ns.only)
        print(f"{len(CASES)} cases; failures by kind: {json.dumps(result, sort_keys=True)}")


def test_out_of_memory_is_one_line_and_exit_2(monkeypatch, capsys, samples) -> None:
    """A valid problem whose work runs out of memory (a step no budget foresaw) is one line on
    stderr and exit 2, not an internal error."""
    import lcpcli.api
    from lcpcli.cli import main

    def no_memory(*args, **kwargs):
        raise MemoryError()

    monkeypatch.delenv("LCPCLI_DEBUG", raising=False)
    monkeypatch.setattr(lcpcli.api, "solve", no_memory)
    with pytest.raises(SystemExit) as exc:
        main(["solve", str(samples / "seed004.json"), "--json"])
    captured = capsys.readouterr()
    assert exc.value.code == 2
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: out of memory"), lines
