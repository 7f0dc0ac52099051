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

Trailing numbers (old reference solutions) are ignored.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.problem import Problem, check_size


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

    def int(self, what: str) -> int:
        tok = self._next(what)
        try:
            value = float(tok)
        except ValueError:
            raise ProblemError(f"expected an integer for {what}, got {tok!r}") from None
        if value != int(value):
            raise ProblemError(f"expected an integer for {what}, got {tok!r}")
        return int(value)

    def floats(self, count: int, what: str) -> np.ndarray:
        if self.pos + count > len(self.items):
            raise ProblemError(f"file ends early (while reading {what})")
        chunk = self.items[self.pos:self.pos + count]
        self.pos += count
        try:
            return np.array([float(t) for t in chunk], dtype=np.float64)
        except ValueError:
            bad = next(t for t in chunk if not _is_float(t))
            raise ProblemError(f"not a number in {what}: {bad!r}") from None


def _is_float(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


def read(path: Path) -> Problem:
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except UnicodeDecodeError:
        raise ProblemError("not a text file (is it really a Siconos .dat?)") from None
    tokens = _Tokens(text)
    if not tokens.items:
        raise ProblemError("empty file")
    first_line = text.strip().splitlines()[0].split()
    if "mlcp" in path.name.lower() or len(first_line) == 4:
        return _read_mlcp(tokens, path.stem)
    return _read_lcp(tokens, path.stem)


def _read_lcp(tok: _Tokens, name: str) -> Problem:
    n = tok.int("n")
    if n <= 0:
        raise ProblemError(f"n must be positive, got {n}")
    M = _read_matrix(tok, "M")
    if M.shape != (n, n):
        raise ProblemError(f"M is {M.shape[0]} x {M.shape[1]} but n = {n}")
    q = tok.floats(n, "q")
    return Problem.create(M, q, name=name, description="Siconos numerics LCP (.dat)")


def _read_matrix(tok: _Tokens, what: str) -> np.ndarray:
    storage = tok.int(f"{what} storage type")
    rows = tok.int(f"{what} size0")
    cols = tok.int(f"{what} size1")
    check_size(rows, cols)
    if storage == 0:
        tok.int(f"{what} size0 (repeated)")
        tok.int(f"{what} size1 (repeated)")
        vals = tok.floats(rows * cols, f"{what} values")
        return vals.reshape((cols, rows)).T.copy()  # column-major
    if storage == 1:
        return _read_sbm(tok, rows, cols, what)
    raise ProblemError(f"unknown storage type {storage} for {what} (0 dense, 1 sparse block)")


def _read_sbm(tok: _Tokens, rows: int, cols: int, what: str) -> np.ndarray:
    tok.int("number of blocks")
    nbrows = tok.int("block rows")
    nbcols = tok.int("block columns")
    row_ends = [tok.int("block row end") for _ in range(nbrows)]
    col_ends = [tok.int("block column end") for _ in range(nbcols)]
    if (row_ends and row_ends[-1] != rows) or (col_ends and col_ends[-1] != cols):
        raise ProblemError(f"{what}: block structure does not match the size {rows} x {cols}")
    filled1 = tok.int("filled1")
    filled2 = tok.int("filled2")
    rowptr = [tok.int("block row pointer") for _ in range(filled1)]
    colidx = [tok.int("block column index") for _ in range(filled2)]
    M = np.zeros((rows, cols))
    r_start = [0, *row_ends[:-1]]
    c_start = [0, *col_ends[:-1]]
    for br in range(len(rowptr) - 1):
        for k in range(rowptr[br], rowptr[br + 1]):
            tok.int("block number")
            bc = colidx[k]
            if not (0 <= br < nbrows and 0 <= bc < nbcols):
                raise ProblemError(f"{what}: block index out of range")
            h = row_ends[br] - r_start[br]
            w = col_ends[bc] - c_start[bc]
            vals = tok.floats(h * w, f"{what} block values")
            M[r_start[br]:row_ends[br], c_start[bc]:col_ends[bc]] = vals.reshape((w, h)).T
    return M


def _read_mlcp(tok: _Tokens, name: str) -> Problem:
    st1 = tok.int("st1")
    st2 = tok.int("st2")
    n = tok.int("n (equalities)")
    m = tok.int("m (complementarity rows)")
    if n < 0 or m < 0 or n + m == 0:
        raise ProblemError(f"bad MLCP sizes n = {n}, m = {m}")
    size = n + m
    desc = "Siconos numerics MLCP (.dat)"
    if st1:
        # block boundaries, then one flag per block
        bounds = [tok.int("block boundary")]
        while bounds[-1] < size:
            bounds.append(tok.int("block boundary"))
        flags = [tok.int("block flag") for _ in range(len(bounds) - 1)]
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


def _matrix_text(M: np.ndarray) -> str:
    rows, cols = M.shape
    lines = [f"0\n{rows}\n{cols}\n{rows}\t{cols}"]
    for j in range(cols):  # one text line per column
        lines.append(" ".join(f"{x:.17e}" for x in M[:, j]))
    return "\n".join(lines)


def write(problem: Problem, path: Path) -> None:
    if problem.kind == "box":
        raise ProblemError("the Siconos .dat format has no box LCPs; use .json, .npz or .h5")
    M = np.asarray(problem.dense_M())
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
