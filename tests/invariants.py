"""Problems with answers known by construction, at every scale, and the independent checks of
the boundary invariants (issue 22): shared by tests/test_invariants_api.py and
tests/cli/test_invariants_cli.py.

A generated :class:`Case` is built from small integers (exact in double precision), in one of
these classes, then scaled by exact powers of two per row and column (``M' = D1 M D2``,
``q' = D1 q``, bounds ``D2^-1 l``; its solutions are ``z' = D2^-1 z``), from ``2^-1000`` to
``2^1000``, down into the subnormal range:

* ``pd`` (symmetric or not), ``p`` (a permuted triangular P-matrix), ``psd`` (rank deficient),
  ``copositive`` (nonnegative), ``degenerate`` (a pair with ``z_i = w_i = 0``): ``q = w* - M z*``
  for a complementary pair ``(z*, w*)``, so a solution exists;
* ``qpos``: ``q >= 0`` (``z = 0`` solves it), on a matrix of any class above;
* ``subnormal``: a diagonal P-matrix plus off-diagonal entries of ``5e-324`` .. ``1e-310``
  (strictly diagonally dominant, hence P: a solution exists for every ``q``);
* ``infeasible``: ``M`` the Laplacian of a weighted graph (PSD, ``M 1 = 0``) and ``sum(q) < 0``:
  ``y = 1`` is a Farkas vector (``y >= 0``, ``M^T y = 0``, ``q^T y < 0``), no ``z >= 0`` has
  ``M z + q >= 0`` (Cottle-Pang-Stone, section 3.8).

Box LCPs take finite bounds on both sides unless M is a P-matrix (a P-matrix box LCP, and a
box LCP on a bounded box, always has a solution: Cottle-Pang-Stone 3.9 and the variational
inequality on a compact set); MLCPs are built on P-matrices only (free variables first).

The checks work on the data scaled back to moderate size by the same powers of two (exact,
whatever rounding the scaled copy went through: ldexp of a double is exact unless it leaves the
range), where :func:`references.componentwise_error` computes the certificate's ``error``
independently; the certificate is invariant under these scalings.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import sys
import warnings
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
from hypothesis import strategies as st
from references import componentwise_error

from lcpcli.cli import main

#: Classes whose problems have a solution by construction.
SOLVABLE = ("pd", "p", "psd", "copositive", "degenerate", "qpos", "subnormal")
CLASSES = (*SOLVABLE, "infeasible")
#: Classes that are P-matrices (box LCPs and MLCPs of any bounds have a solution).
P_CLASSES = ("pd", "p", "subnormal")
#: Exponent range of the row and column scalings (issue 22: 2^-1000 .. 2^1000).
MAX_EXP = 1000


@dataclass
class Case:
    """A generated problem (scaled: the arguments of ``lcpcli.solve``) and how it was made."""

    cls: str
    kind: str                       # "lcp", "box" or "mlcp"
    M: np.ndarray                   # scaled data
    q: np.ndarray
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    n_eq: int = 0
    row_exp: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    col_exp: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    solvable: bool = True

    @property
    def n(self) -> int:
        return int(self.q.shape[0])

    def kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``lcpcli.solve(M, q, ...)`` beyond M and q."""
        out: dict[str, Any] = {}
        if self.kind == "box":
            out["lower"], out["upper"] = self.lower, self.upper
        if self.kind == "mlcp":
            out["n_eq"] = self.n_eq
        return out

    def to_json(self, sparse: bool = False) -> str:
        """The problem file (JSON; ``sparse``: M in CSR form); infinite bounds as null."""
        data: dict[str, Any] = {"q": self.q.tolist()}
        if sparse:
            import scipy.sparse as sp

            A = sp.csr_matrix(self.M)
            data["M"] = {"format": "csr", "shape": [self.n, self.n], "data": A.data.tolist(),
                         "indices": A.indices.tolist(), "indptr": A.indptr.tolist()}
        else:
            data["M"] = self.M.tolist()
        if self.kind == "box":
            data["lower"] = [x if math.isfinite(x) else None for x in self.lower.tolist()]
            data["upper"] = [x if math.isfinite(x) else None for x in self.upper.tolist()]
        if self.kind == "mlcp":
            data["n_eq"] = self.n_eq
        return json.dumps(data, allow_nan=False)

    # --------------------------------------------------------------- the scaled-back data
    def base(self, z: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                           np.ndarray | None, np.ndarray | None]:
        """``(M, q, lower, upper, z)``: the data (and ``z``, a point of the scaled problem) scaled
        back by ``D1^-1 . D2^-1`` (exact), then by up to ``2^600`` globally when it holds entries
        far below 1 (subnormal-born data: ``2^k M, 2^k q`` has the same solutions and the same
        certificate).  A column whose ``z_j`` would leave ``[2^-900, 2^900]`` keeps part of its
        scaling instead (any positive power-of-two column scaling is exact and leaves the
        certificate unchanged)."""
        r, c = self.row_exp, self.col_exp.copy()
        zb = None
        if z is not None:
            z = np.asarray(z, dtype=np.float64)
            e = np.where(z != 0, np.frexp(z)[1], 0).astype(np.int64)
            c = np.where(z != 0, np.clip(e + c, -900, 900) - e, c)
            zb = np.ldexp(z, c.astype(np.int32))
        Mb = np.ldexp(self.M, -(r[:, None] + c[None, :]).astype(np.int32)) if self.n else self.M
        qb = np.ldexp(self.q, (-r).astype(np.int32))
        lo = up = None
        if self.kind == "box":
            lo = np.ldexp(self.lower, c.astype(np.int32))
            up = np.ldexp(self.upper, c.astype(np.int32))
        data = np.concatenate([np.abs(Mb).ravel(), np.abs(qb)])
        tiny = data[data > 0]
        shift = 0
        if tiny.size and tiny.min() < 2.0 ** -900:  # as far up as the largest entry allows
            shift = max(0, min(600, 1000 - int(np.frexp(tiny.max())[1])))
        return np.ldexp(Mb, shift), np.ldexp(qb, shift), lo, up, zb


# ---------------------------------------------------------------------------- generation
def _matrix(cls: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if cls == "pd" or cls == "degenerate":
        A = rng.integers(-3, 4, (n, n))
        S = A @ A.T + np.eye(n, dtype=np.int64)
        if rng.random() < 0.5:
            return S.astype(np.float64)
        K = rng.integers(-3, 4, (n, n))
        return (S + K - K.T).astype(np.float64)
    if cls == "p":
        T = np.triu(rng.integers(-8, 9, (n, n)), 1) + np.diag(rng.integers(1, 4, n))
        perm = rng.permutation(n)
        return T[np.ix_(perm, perm)].astype(np.float64)
    if cls == "psd":
        k = int(rng.integers(0, n)) if n else 0
        A = rng.integers(-3, 4, (n, k))
        K = rng.integers(-2, 3, (n, n))
        return (A @ A.T + K - K.T).astype(np.float64)
    if cls == "copositive":
        return rng.integers(0, 5, (n, n)).astype(np.float64)
    if cls == "subnormal":
        M = np.diag(rng.integers(2, 6, n).astype(np.float64))
        tiny = rng.choice(np.array([0.0, 5e-324, -5e-324, 3 * 5e-324, 1e-310, -1e-310]),
                          size=(n, n))
        return M + np.where(np.eye(n, dtype=bool), 0.0, tiny)
    raise AssertionError(cls)


def _known_solution(M: np.ndarray, rng: np.random.Generator,
                    degenerate: bool) -> np.ndarray:
    """``q = w* - M z*`` for a complementary pair with small integer entries."""
    n = M.shape[0]
    support = rng.random(n) < 0.5
    z = np.where(support, rng.integers(1, 6, n), 0).astype(np.float64)
    w = np.where(support, 0, rng.integers(0, 6, n)).astype(np.float64)
    if degenerate and n:
        i = int(rng.integers(0, n))
        z[i] = w[i] = 0.0
    return w - M @ z


def _laplacian(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    W = np.triu(rng.integers(0, 4, (n, n)), 1)
    W = W + W.T
    L = (np.diag(W.sum(axis=1)) - W).astype(np.float64)
    q = rng.integers(-5, 6, n).astype(np.float64)
    if q.sum() >= 0:
        q[0] -= q.sum() + 1
    return L, q


def base_problem(cls: str, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``(M, q)`` of class ``cls`` and size ``n`` (small integers, or subnormal entries)."""
    if cls == "infeasible":
        return _laplacian(n, rng)
    if cls == "qpos":
        M = _matrix(str(rng.choice(["pd", "p", "psd", "copositive"])), n, rng)
        return M, rng.integers(0, 5, n).astype(np.float64)
    M = _matrix(cls, n, rng)
    if cls == "subnormal":
        return M, rng.integers(-5, 6, n).astype(np.float64)
    return M, _known_solution(M, rng, degenerate=cls == "degenerate")


def scale(M: np.ndarray, q: np.ndarray, mode: str,
          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Row and column exponents for ``mode``: ``none``, ``global`` (one power of two, the
    whole range down to subnormal entries), ``rows_cols`` (independent per row and column,
    entries up to ``2^+-1000``), ``rows`` (rows only, up to ``2^+-1000``) or ``top`` (the
    largest entry in ``[2^1022, 2^1024)``: ``M z`` overflows)."""
    n = q.shape[0]
    zero = np.zeros(n, dtype=np.int64)
    if mode == "none" or n == 0:
        return zero, zero.copy()
    if mode == "global":
        return np.full(n, int(rng.integers(-1066, MAX_EXP + 1)), dtype=np.int64), zero
    if mode == "top":  # the largest entry just below the largest double (products overflow)
        peak = max(float(np.max(np.abs(M))), float(np.max(np.abs(q))))
        top = 1023 - int(np.frexp(peak)[1]) if peak > 0 else 0
        return np.full(n, top, dtype=np.int64), zero
    if mode == "rows":
        return rng.integers(-MAX_EXP, MAX_EXP + 1, n), zero
    return rng.integers(-MAX_EXP // 2, MAX_EXP // 2 + 1, n), \
        rng.integers(-MAX_EXP // 2, MAX_EXP // 2 + 1, n)


@st.composite
def cases(draw: Any, max_n: int = 8, kinds: tuple[str, ...] = ("lcp", "box", "mlcp"),
          classes: tuple[str, ...] = CLASSES, min_n: int = 0) -> Case:
    """A :class:`Case` (see the module docstring)."""
    n = draw(st.integers(min_n, max_n))
    cls = draw(st.sampled_from(classes))
    kind = draw(st.sampled_from(kinds))
    mode = draw(st.sampled_from(("none", "global", "rows_cols", "rows", "top")))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if n == 0 and cls == "infeasible":
        cls = "pd"  # the empty problem is solved by z = ()
    if kind == "mlcp" and (n == 0 or cls not in P_CLASSES):
        kind = "lcp"
    M, q = base_problem(cls, n, rng)
    lower = upper = None
    n_eq = 0
    solvable = cls != "infeasible"
    if kind == "box":
        lower = -rng.integers(0, 4, n).astype(np.float64)
        upper = rng.integers(1, 6, n).astype(np.float64)
        if cls in P_CLASSES:  # P-matrix: any bounds (infinite ones too)
            lower = np.where(rng.random(n) < 0.3, -np.inf, lower)
            upper = np.where(rng.random(n) < 0.3, np.inf, upper)
        solvable = True  # bounded box or P-matrix: a solution exists
    if kind == "mlcp":
        n_eq = int(rng.integers(1, n + 1))
    r, c = scale(M, q, mode, rng)
    with np.errstate(under="ignore"):
        Ms = np.ldexp(M, (r[:, None] + c[None, :]).astype(np.int32)) if n else M
        qs = np.ldexp(q, r.astype(np.int32))
        if kind == "box":
            lower = np.ldexp(lower, (-c).astype(np.int32))
            upper = np.ldexp(upper, (-c).astype(np.int32))
    return Case(cls, kind, Ms, qs, lower, upper, n_eq, r, c, solvable)


# ---------------------------------------------------------------------------- checks
def strict_json(text: str) -> Any:
    """``json.loads`` that refuses the non-standard tokens NaN, Infinity and -Infinity."""
    def refuse(token: str) -> Any:
        raise ValueError(f"non-standard JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def check_solved(case: Case, z: Any, tol: float) -> None:
    """An answer called ``solved`` passes the independent componentwise check (reference
    implementation of the certificate, on the exactly scaled-back data)."""
    z = np.asarray([np.nan if x is None else x for x in np.asarray(z, dtype=object).ravel()],
                   dtype=np.float64) if not isinstance(z, np.ndarray) else z
    assert z.shape == (case.n,), (z.shape, case.n)
    assert np.all(np.isfinite(z)), f"solved with a non-finite z: {z}"
    Mb, qb, lo, up, zb = case.base(z)
    assert np.all(np.isfinite(zb)), "z leaves the double range when scaled back"
    err = componentwise_error(Mb, qb, zb, lo, up, n_eq=case.n_eq)
    if err > tol * (1 + 1e-6):
        # the definition judges rows that balance by cancellation through w's rounding (a row
        # with q_i = 0 whose w_i is exactly 0 carries no data; w_i = 1e-14 makes its growth
        # huge): evaluate it again with the exact w = M z + q, rounded once
        err = min(err, componentwise_error(Mb, qb, zb, lo, up, n_eq=case.n_eq,
                                           w=exact_w(Mb, qb, zb)))
    assert err <= tol * (1 + 1e-6), (f"'solved' but the independent check gives error {err:.3g} "
                                     f"> tol {tol:g} ({case.cls}, {case.kind}, n = {case.n})")


def exact_w(M: np.ndarray, q: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``M z + q`` in rational arithmetic, rounded once to the nearest double."""
    Z = [Fraction(float(v)) for v in z]
    return np.array([float(Fraction(float(q[i])) + sum(Fraction(float(M[i, j])) * Z[j]
                                                       for j in range(len(Z)) if M[i, j]))
                     for i in range(len(Z))])


def farkas_ok(case: Case, y: Any) -> bool:
    """Whether ``y`` (for the scaled problem) proves infeasibility of an LCP or MLCP, checked
    exactly in rational arithmetic on the scaled-back data: ``y_i >= 0`` on inequality rows,
    ``(M^T y)_j <= 0`` on sign-constrained columns and ``= 0`` on free ones, to a margin of
    ``2^-30`` of ``(|M|^T |y|)_j``, and ``q^T y < -2^-30 |q|^T |y|``."""
    y = np.asarray(y, dtype=np.float64)
    if y.shape != (case.n,) or not np.all(np.isfinite(y)):
        return False
    Mb, qb, _, _, _ = case.base()
    n_eq = case.n_eq
    if np.any(y[n_eq:] < 0):
        return False
    # y = D1 y', exactly (a Farkas vector of data near 2^-1000 may itself be near 2^-1000)
    Y = [Fraction(float(v)) * Fraction(2) ** int(e) for v, e in zip(y, case.row_exp, strict=True)]
    margin = Fraction(1, 2**30)
    for j in range(case.n):
        col = [Fraction(float(Mb[i, j])) for i in range(case.n)]
        mty = sum(c * v for c, v in zip(col, Y, strict=True))
        size = sum(abs(c) * abs(v) for c, v in zip(col, Y, strict=True))
        if mty > margin * size or (j < n_eq and -mty > margin * size):
            return False
    qy = sum(Fraction(float(a)) * v for a, v in zip(qb, Y, strict=True))
    return qy < -margin * sum(abs(Fraction(float(a))) * abs(v) for a, v in zip(qb, Y, strict=True))


#: Where a result may carry its Farkas vector (the key is the proof's; first found is used).
FARKAS_KEYS = ("farkas_y", "farkas", "y")


def farkas_vector(info: dict[str, Any]) -> Any:
    """The Farkas vector a result carries in ``info`` (None if it carries none)."""
    for key in FARKAS_KEYS:
        if info.get(key) is not None:
            return info[key]
    proof = info.get("proof")
    if isinstance(proof, dict):
        for key in FARKAS_KEYS:
            if proof.get(key) is not None:
                return proof[key]
    return None


def check_verdict(case: Case, status: str, message: str, method: str,
                  info: dict[str, Any] | None) -> None:
    """A ``no_solution`` must be true: only on a problem infeasible by construction (never on
    a box LCP with a solution), and its Farkas vector, when the result carries one, must pass
    the exact check of :func:`farkas_ok`."""
    assert status in ("solved", "no_solution", "unsolved"), status
    if status != "no_solution":
        return
    assert not case.solvable, (f"false no_solution by {method} on a solvable {case.cls} "
                               f"{case.kind} problem (n = {case.n}): {message}")
    y = farkas_vector(info or {})
    assert y is None or farkas_ok(case, y), \
        f"no_solution whose Farkas vector fails the check ({method}): {message}"


# ---------------------------------------------------------------------------- the CLI in-process
def cli(*args: str, stdin: str | None = None) -> tuple[int, str, str]:
    """``lcpcli ARGS`` in this process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    saved = sys.stdin, warnings.showwarning
    if stdin is not None:
        sys.stdin = io.TextIOWrapper(io.BytesIO(stdin.encode()), encoding="utf-8")
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main([str(a) for a in args])
                code = 0
            except SystemExit as exc:
                code = int(exc.code or 0)
    finally:
        sys.stdin, warnings.showwarning = saved
    return code, out.getvalue(), err.getvalue()


def one_line_error(code: int, err: str) -> None:
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: "), err
