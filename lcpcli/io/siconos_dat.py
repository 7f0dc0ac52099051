"""Siconos numerics ``.dat`` files (LCP and MLCP), read and write.

The format is a whitespace-separated token stream (see ``shared/data/siconos/README.md``):

* LCP: ``n``, then a matrix, then ``q`` (n values).  Matrix: ``storageType size0 size1``;
  dense (0): ``size0 size1`` again, then the values COLUMN-MAJOR; sparse block (1):
  ``nbblocks nbrows nbcols``, cumulative block-row ends, cumulative block-column ends,
  ``filled1 filled2``, block-row pointers, block-column indices, then per block its number and
  its values column-major.
* MLCP: ``st1 st2 n m``; if st1: block boundaries, per-block flags, a matrix as above and
  ``q``; if st2: A (n x n), B (m x m), C (n x m), D (m x n), a, b in row-major order.
  The problem is ``A u + C v + a = 0``, ``0 <= v _|_ D u + B v + b >= 0``.

Whether a file is an LCP or an MLCP is told from its numbers alone (:func:`_mlcp_header`), not
from its name or its line breaks, so what :func:`write` writes reads back under any name.
Trailing numbers (old reference solutions) are ignored.  Sizes and counts are checked before
anything is allocated (integers must be finite whole numbers, block structures consistent);
a sparse-block M with more than :data:`SBM_DENSE_MAX_ENTRIES` entries is kept sparse (CSR), and
a sparse M is written in sparse-block storage (1 x 1 blocks), never densified.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem, check_size, is_sparse
from lcpcli.io.files import MAX_TEXT_BYTES, decode_text, read_input_bytes

#: A sparse-block M up to this many entries (rows x cols) is returned dense, larger as CSR.
SBM_DENSE_MAX_ENTRIES = 4_000_000


class _Tokens:
    def __init__(self, text: str) -> None:
        self.items = text.split()
        self.pos = 0

    def _next(self, what: str) -> str:
        if self.pos >= len(self.items):
            raise ProblemError(f"file ends early (while reading {what})")
        tok = self.items[self.pos]
        self.pos += 1
        return tok

    def int(self, what: str, low: int = 0, high: int | None = None) -> int:
        """A whole number in ``[low, high]`` (``1e3`` and ``3.0`` count; nan, inf, 2.5 do not)."""
        tok = self._next(what)
        try:
            value = int(tok)
        except ValueError:
            try:
                f = float(tok)
            except ValueError:
                raise ProblemError(f"expected an integer for {what}, got {tok[:30]!r}") from None
            if not (np.isfinite(f) and f == int(f)):
                raise ProblemError(f"expected an integer for {what}, got {tok[:30]!r}") from None
            value = int(f)
        if value < low or (high is not None and value > high):
            bounds = f"{low}..{high}" if high is not None else f">= {low}"
            raise ProblemError(f"{what} = {value} is out of range ({bounds})")
        return value

    def floats(self, count: int, what: str) -> np.ndarray:
        if count < 0 or self.pos + count > len(self.items):
            raise ProblemError(f"file ends early (while reading {what})")
        chunk = self.items[self.pos:self.pos + count]
        self.pos += count
        try:
            return np.array(chunk, dtype=np.float64)
        except ValueError:
            bad = next(t for t in chunk if not _is_float(t))
            raise ProblemError(f"not a number in {what}: {bad[:30]!r}") from None


def _is_float(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


def read(path: Path) -> Problem:
    data = read_input_bytes(path, MAX_TEXT_BYTES, "a Siconos .dat file")
    text = decode_text(data, "a text file (is it really a Siconos .dat?)")
    tokens = _Tokens(text)
    if not tokens.items:
        raise ProblemError("empty file")
    readers = [_read_lcp, _read_mlcp]
    if _mlcp_header(tokens.items):
        readers.reverse()
    try:
        return readers[0](tokens, path.stem)
    except ProblemError as first:
        try:  # the other layout; its error would only confuse, so the first one is raised
            return readers[1](_Tokens(text), path.stem)
        except ProblemError:
            raise first from None


def _whole(tok: str) -> int | None:
    try:
        value = float(tok)
    except ValueError:
        return None
    return int(value) if np.isfinite(value) and value == int(value) else None


def _mlcp_header(items: list[str]) -> bool:
    """Whether the tokens start like an MLCP (``st1 st2 n m``, then block boundaries from 0).

    The file's name and line breaks play no part.  An LCP starts ``n s n n`` with ``s`` its
    matrix storage (0 or 1); an MLCP's two storage flags are 0 or 1, not both 0, and with
    ``st1`` the first block boundary (the fifth number) is 0.  The two layouts overlap only in
    the first four numbers of a 1 x 1 LCP, which the fifth one tells apart.  :func:`read` tries
    the other layout when this guess does not read.
    """
    head = [_whole(t) for t in items[:5]]
    if len(head) < 4 or head[0] not in (0, 1) or head[1] not in (0, 1) or head[:2] == [0, 0]:
        return False
    return head[0] == 0 or (len(head) == 5 and head[4] == 0)


def _read_lcp(tok: _Tokens, name: str) -> Problem:
    n = tok.int("n")
    check_size(n, n, sparse=True)
    M = _read_matrix(tok, "M")
    if M.shape != (n, n):
        raise ProblemError(f"M is {M.shape[0]} x {M.shape[1]} but n = {n}")
    q = tok.floats(n, "q")
    return Problem.create(M, q, name=name, description="Siconos numerics LCP (.dat)")


def _read_matrix(tok: _Tokens, what: str) -> Any:
    storage = tok.int(f"{what} storage type")
    rows = tok.int(f"{what} size0")
    cols = tok.int(f"{what} size1")
    if storage == 0:
        check_size(rows, cols)
        again = (tok.int(f"{what} size0 (repeated)"), tok.int(f"{what} size1 (repeated)"))
        if again != (rows, cols):
            raise ProblemError(f"{what} is {rows} x {cols} but its repeated size is "
                               f"{again[0]} x {again[1]}")
        vals = tok.floats(rows * cols, f"{what} values")
        return vals.reshape((cols, rows)).T.copy()  # column-major
    if storage == 1:
        check_size(rows, cols, sparse=True)
        return _read_sbm(tok, rows, cols, what)
    raise ProblemError(f"unknown storage type {storage} for {what} (0 dense, 1 sparse block)")


def _ends(tok: _Tokens, count: int, size: int, what: str) -> list[int]:
    """Cumulative block ends: strictly increasing, the last equal to ``size``."""
    ends = [tok.int(what, 1, size) for _ in range(count)]
    if any(b <= a for a, b in zip(ends, ends[1:], strict=False)) or (ends and ends[-1] != size) \
            or (size and not ends):
        raise ProblemError(f"{what}s do not split the size {size} into blocks")
    return ends


def _read_sbm(tok: _Tokens, rows: int, cols: int, what: str) -> Any:
    """A sparse-block matrix (storage 1); every count and index is checked before use."""
    nbblocks = tok.int("number of blocks", 0, rows * cols)
    nbrows = tok.int("block rows", 0, rows)
    nbcols = tok.int("block columns", 0, cols)
    row_ends = _ends(tok, nbrows, rows, f"{what} block row end")
    col_ends = _ends(tok, nbcols, cols, f"{what} block column end")
    filled1 = tok.int("filled1", 0, nbrows + 1)
    filled2 = tok.int("filled2", 0, nbblocks)
    rowptr = [tok.int("block row pointer", 0, filled2) for _ in range(filled1)]
    if any(b < a for a, b in zip(rowptr, rowptr[1:], strict=False)) \
            or (rowptr and rowptr[0] != 0):
        raise ProblemError(f"{what}: block row pointers must start at 0 and never decrease")
    if filled2 and not nbcols:
        raise ProblemError(f"{what}: blocks given but no block columns")
    colidx = [tok.int("block column index", 0, nbcols - 1) for _ in range(filled2)]
    if rowptr and rowptr[-1] > len(colidx):
        raise ProblemError(f"{what}: block row pointers go past the {len(colidx)} column "
                           f"indices")
    r_start = [0, *row_ends[:-1]]
    c_start = [0, *col_ends[:-1]]
    ii: list[np.ndarray] = []
    jj: list[np.ndarray] = []
    vv: list[np.ndarray] = []
    for br in range(len(rowptr) - 1):
        for k in range(rowptr[br], rowptr[br + 1]):
            tok.int("block number")
            bc = colidx[k]
            h = row_ends[br] - r_start[br]
            w = col_ends[bc] - c_start[bc]
            vals = tok.floats(h * w, f"{what} block values").reshape((w, h)).T  # column-major
            r, c = np.meshgrid(np.arange(r_start[br], row_ends[br]),
                               np.arange(c_start[bc], col_ends[bc]), indexing="ij")
            ii.append(r.ravel())
            jj.append(c.ravel())
            vv.append(vals.ravel())
    i = np.concatenate(ii) if ii else np.zeros(0, dtype=np.int64)
    j = np.concatenate(jj) if jj else np.zeros(0, dtype=np.int64)
    v = np.concatenate(vv) if vv else np.zeros(0)
    if rows * cols <= SBM_DENSE_MAX_ENTRIES:
        M = np.zeros((rows, cols))
        M[i, j] = v  # a block given twice: the last one wins, as in a dense copy
        return M
    import scipy.sparse as sp  # only for large sparse-block files

    check_size(rows, cols, sparse=True, nnz=v.size)
    return sp.csr_matrix((v, (i, j)), shape=(rows, cols))


def _read_mlcp(tok: _Tokens, name: str) -> Problem:
    st1 = tok.int("st1")
    st2 = tok.int("st2")
    n = tok.int("n (equalities)")
    m = tok.int("m (complementarity rows)")
    if n + m == 0:
        raise ProblemError(f"bad MLCP sizes n = {n}, m = {m}")
    size = n + m
    check_size(size, size, sparse=bool(st1))
    desc = "Siconos numerics MLCP (.dat)"
    if st1:
        # block boundaries, then one flag per block
        bounds = [tok.int("block boundary", 0, size)]
        while bounds[-1] < size:
            bounds.append(tok.int("block boundary", bounds[-1] + 1, size))
        flags = [tok.int("block flag", 0, 1) for _ in range(len(bounds) - 1)]
        M = _read_matrix(tok, "M")
        if M.shape != (size, size):
            raise ProblemError(f"M is {M.shape[0]} x {M.shape[1]}; an MLCP with n = {n}, "
                               f"m = {m} needs a square {size} x {size} matrix")
        q = tok.floats(size, "q")
        eq_rows = sum(b - a for a, b, f in zip(bounds, bounds[1:], flags, strict=False) if f == 0)
        if eq_rows != n:
            raise ProblemError(f"block flags give {eq_rows} equality rows, header says {n}")
        return Problem.create(M, q, n_eq=n, name=name, description=desc)
    if st2:
        A = tok.floats(n * n, "A").reshape(n, n)
        B = tok.floats(m * m, "B").reshape(m, m)
        C = tok.floats(n * m, "C").reshape(n, m)
        D = tok.floats(m * n, "D").reshape(m, n)
        a = tok.floats(n, "a")
        b = tok.floats(m, "b")
        M = np.block([[A, C], [D, B]])
        return Problem.create(M, np.concatenate([a, b]), n_eq=n, name=name, description=desc)
    raise ProblemError("MLCP header has neither storage (st1 = st2 = 0)")


def _matrix_text(M: Any) -> str:
    if is_sparse(M):
        return _sbm_text(M)
    rows, cols = M.shape
    lines = [f"0\n{rows}\n{cols}\n{rows}\t{cols}"]
    for j in range(cols):  # one text line per column
        lines.append(" ".join(f"{x:.17e}" for x in M[:, j]))
    return "\n".join(lines)


def _sbm_text(M: Any) -> str:
    """Sparse-block storage with 1 x 1 blocks: one block per stored entry (CSR order)."""
    csr = M.tocsr()
    csr.sum_duplicates()
    rows, cols = csr.shape
    nnz = int(csr.nnz)
    lines = [f"1\n{rows}\n{cols}\n{nnz}\n{rows}\n{cols}",
             " ".join(str(k) for k in range(1, rows + 1)),
             " ".join(str(k) for k in range(1, cols + 1)),
             f"{rows + 1}\n{nnz}",
             " ".join(str(int(k)) for k in csr.indptr),
             " ".join(str(int(k)) for k in csr.indices)]
    lines += [f"{k}\n{x:.17e}" for k, x in enumerate(csr.data)]
    return "\n".join(lines)


def write(problem: Problem, path: Path) -> None:
    if problem.kind == "box":
        raise ProblemError("the Siconos .dat format has no box LCPs; use .json, .npz or .h5")
    M = problem.M
    q = " ".join(f"{x:.17e}" for x in problem.q)
    if problem.kind == "lcp":
        text = f"{problem.n}\n{_matrix_text(M)}\n{q}\n"
    else:
        n, size = problem.n_eq, problem.n
        m = size - n
        flags = "0 1" if m else "0"
        bounds = f"0 {n} {size}" if m else f"0 {n}"
        text = f"1\n0\n{n}\n{m}\n{bounds}\n{flags}\n{_matrix_text(M)}\n{q}\n"
    path.write_text(text)
