"""Regenerate the bundled samples (run from the repository root: python samples/make_samples.py).

* seed000.json      - Cottle, Pang and Stone, The Linear Complementarity Problem, Example
                      4.4.7 (without the artificial column of Lemke's method)
* degenerate.json   - a degenerate LCP (zeros in q, a tie in the first ratio test) resolved
                      by the lexicographic rule
* degenerate_lex.json - a degenerate 4 x 4 P-matrix LCP whose second Lemke pivot is decided
                      by the lexicographic rule at column w2 (docs/pivot.md, teaching)
* collection.h5     - several problems in one HDF5 file (one group each), dense and sparse
* sparse_chain.npz  - a sparse (CSR) tridiagonal symmetric PD LCP, n = 200
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from lcpcli.core.problem import Problem
from lcpcli.io import save
from lcpcli.io.hdf5_format import write_many

HERE = Path(__file__).resolve().parent


def seed000() -> Problem:
    return Problem.create([[0, -1, 2], [2, 0, -2], [-1, 1, 0]], [-3, 6, -1], name="seed000",
                          description="Cottle, Pang and Stone, The Linear Complementarity "
                                      "Problem, Example 4.4.7 (without the artificial column "
                                      "of Lemke's method); solution z = (0, 1, 3)")


def degenerate() -> Problem:
    # cyclic matrix with a degenerate right-hand side: zeros in q and tied ratios
    M = np.array([[1, 2, 0, 0], [0, 1, 2, 0], [0, 0, 1, 2], [2, 0, 0, 1]], dtype=float)
    q = np.array([-1, 0, 0, -1], dtype=float)
    return Problem.create(M, q, name="degenerate",
                          description="degenerate LCP: zeros in q and tied ratios, "
                                      "resolved by the lexicographic rule")


def degenerate_lex() -> Problem:
    # P-matrix; q gives a 3-way tie at the first pivot and a 2-way tie at zero at the second,
    # which the rows of B^-1 decide at their second column
    M = np.array([[2, 2, 0, 0], [0, 2, 0, 1], [-1, -1, 2, 1], [0, 1, 0, 2]], dtype=float)
    q = np.array([1, -2, -2, -2], dtype=float)
    return Problem.create(M, q, name="degenerate_lex",
                          description="degenerate P-matrix LCP: Lemke's second pivot is a "
                                      "tie decided by the lexicographic rule (column w2); "
                                      "solution z = (0, 2/3, 1, 2/3)")


def sparse_chain(n: int = 200) -> Problem:
    main = np.full(n, 4.0)
    off = np.full(n - 1, -1.0)
    M = sp.diags([off, main, off], [-1, 0, 1], format="csr")
    q = np.sin(np.arange(n)) - 0.2
    return Problem.create(M, q, name="sparse_chain",
                          description="sparse symmetric PD tridiagonal LCP (CSR storage)")


def main() -> None:
    save(seed000(), HERE / "seed000.json")
    save(degenerate(), HERE / "degenerate.json")
    save(degenerate_lex(), HERE / "degenerate_lex.json")
    save(sparse_chain(), HERE / "sparse_chain.npz")
    seed004 = Problem.create([[2, 1], [1, 2]], [-5, -6], name="seed004",
                             description="Murty's textbook LCP (K. G. Murty, Linear "
                                         "Complementarity, Linear and Nonlinear Programming): "
                                         "z = (4/3, 7/3)")
    trivial = Problem.create(np.diag(np.arange(1.0, 10.0)), -np.ones(9), name="trivial",
                             description="M = diag(1..9), q = -1: z_i = 1/i")
    write_many([seed004, seed000(), degenerate(), trivial, sparse_chain(50)],
               HERE / "collection.h5")


if __name__ == "__main__":
    main()
