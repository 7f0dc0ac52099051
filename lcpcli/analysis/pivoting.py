"""The principal pivoting transform of Dai & Drumwright, as pure functions.

System (Dai & Drumwright; sign convention of the whole package): ``w = q + M z`` with
``w = (w_1..w_n)`` and ``z = (z_1..z_n, z_{n+1})``, where ``M`` is ``n x (n+1)`` and its last
column belongs to the artificial variable ``z_{n+1}`` (the covering vector), displayed as
``z0`` (Lemke's name; :data:`ARTIFICIAL`) while the index sets keep its position ``n + 1``.

A *basis* is the dependent tuple ``w'`` (n variables) and the independent tuple ``z'``
(the other n+1 variables, in a chosen order; by default the order of the original tuples).
The pivoted system is ``w' = q' + M' z'``.  Index sets (kept 0-based here, shown 1-based by
the CLI and in :meth:`PivotTransform.to_dict`, as in Dai & Drumwright):

* ``alpha``: positions in ``w`` of the w's that are independent (ascending);
  ``alpha'``: their positions in ``z'``;
* ``beta``: positions in ``z`` of the z's that are dependent (ascending);
  ``beta'``: their positions in ``w'``;
* ``alpha_bar``: positions in ``w`` of the w's that stay dependent (ascending);
  ``alpha_bar'``: their positions in ``w'``;
* ``beta_bar``: positions in ``z`` of the z's that stay independent (ascending; Dai &
  Drumwright's "one greater than" is a slip: its example uses the positions); ``beta_bar'``:
  their positions in ``z'``.

Then (Dai & Drumwright, eqs 2-3) ``q'[beta'] = -(M^{alpha beta})^{-1} q^alpha`` and
``q'[alpha_bar'] = q^{alpha_bar} + M^{alpha_bar beta} q'[beta']``; the column of ``M'`` that
multiplies a driving variable is, for ``w_{alpha_gamma}`` (eqs 5-6),
``M'_d[beta'] = (M^{alpha beta})^{-1} e_gamma``,
``M'_d[alpha_bar'] = M^{alpha_bar beta} M'_d[beta']``,
and for ``z_zeta`` (eqs 7-8), with ``g = M[:, zeta]``,
``M'_d[beta'] = -(M^{alpha beta})^{-1} g^alpha``,
``M'_d[alpha_bar'] = g^{alpha_bar} + M^{alpha_bar beta} M'_d[beta']``.

``M^{alpha beta}`` is factorised once (LU with partial pivoting); a singular block means the
tuples are not a basis and raises :class:`~lcpcli.core.errors.ProblemError`.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import binary_exponents, ldexp_exact

#: A block whose reciprocal condition number is below this is treated as singular.
RCOND_MIN = 1e-14

_NAME = re.compile(r"^\s*([wWzZ])\s*_?\s*(\d+)\s*$")

Var = tuple[str, int]  # ("w", i) or ("z", j), 0-based; ("z", n) is the artificial variable

#: Display name of the artificial variable everywhere (Lemke's and the textbooks' name); its
#: position in Dai & Drumwright's vector ``z`` is ``n + 1``, and ``z{n+1}`` is accepted as an
#: input alias.
ARTIFICIAL = "z0"


def var_name(var: Var, n: int) -> str:
    """1-based display name: ``w1``, ``z3``; the artificial variable ``("z", n)`` is ``z0``."""
    if var == ("z", n):
        return ARTIFICIAL
    return f"{var[0]}{var[1] + 1}"


def parse_var(name: str, n: int) -> Var:
    """Parse ``w1..wn``, ``z1..zn``, ``z0`` (the artificial variable) or its alias ``z{n+1}``."""
    m = _NAME.match(str(name))
    shown = str(name) if len(str(name)) <= 40 else f"{str(name)[:20]}...({len(str(name))} chars)"
    if not m:
        raise ProblemError(f"unknown variable name {shown!r} (expected w1..w{n}, z1..z{n} or "
                           f"{ARTIFICIAL}, alias z{n + 1})")
    digits = m.group(2).lstrip("0") or "0"
    # an index longer than n + 1 has digits is out of range (int() of 5,000 digits would raise)
    idx = int(digits) if len(digits) <= len(str(n + 1)) else n + 2
    kind = m.group(1).lower()
    if kind == "z" and idx == 0:
        return ("z", n)
    top = n if kind == "w" else n + 1
    if not 1 <= idx <= top:
        raise ProblemError(f"variable {shown!r} out of range (w1..w{n}, z1..z{n}, {ARTIFICIAL} "
                           f"alias z{n + 1})")
    return (kind, idx - 1)


def parse_tuple(text: str | list[str] | tuple[str, ...], n: int) -> tuple[Var, ...]:
    """A comma/space separated list of variable names."""
    items = text if isinstance(text, (list, tuple)) else re.split(r"[,\s]+", str(text).strip())
    items = [s for s in items if str(s).strip()]
    return tuple(parse_var(s, n) for s in items)


def all_vars(n: int) -> list[Var]:
    """``w_1..w_n, z_1..z_{n+1}`` in Dai & Drumwright's order."""
    return [("w", i) for i in range(n)] + [("z", j) for j in range(n + 1)]


def validate_basis(dependent: tuple[Var, ...], independent: tuple[Var, ...] | None, n: int, *,
                   any_basis: bool = False) -> tuple[tuple[Var, ...], tuple[Var, ...]]:
    """Check a (dependent, independent) pair; return it with the independent tuple completed.

    Rules: ``n`` dependent variables, ``n + 1`` independent ones, no variable twice, together
    exactly ``w_1..w_n, z_1..z_{n+1}`` (then Lemma 1, ``|alpha| = |beta|``, holds).  Unless
    ``any_basis``, the dependent tuple may not hold both ``w_i`` and ``z_i``: the transform is
    meant for Lemke's (almost) complementary bases.  Without ``independent`` the independent
    variables come in Dai & Drumwright's order ``w_1..w_n, z_1..z_{n+1}``.
    """
    def dupes(tup: tuple[Var, ...]) -> list[str]:
        seen: set[Var] = set()
        out = []
        for v in tup:
            if v in seen:
                out.append(var_name(v, n))
            seen.add(v)
        return out

    if dupes(dependent):
        raise ProblemError(f"dependent tuple lists {dupes(dependent)[0]} twice")
    if len(dependent) != n:
        n_iw = sum(1 for i in range(n) if ("w", i) not in dependent)
        n_dz = sum(1 for v in dependent if v[0] == "z")
        raise ProblemError(f"dependent tuple has {len(dependent)} variables, expected n = {n} "
                           f"(Lemma 1 of Dai & Drumwright fails: {n_iw} independent w but {n_dz} "
                           f"dependent z)")
    if independent is None:
        independent = tuple(v for v in all_vars(n) if v not in set(dependent))
    else:
        if dupes(independent):
            raise ProblemError(f"independent tuple lists {dupes(independent)[0]} twice")
        both = [var_name(v, n) for v in independent if v in set(dependent)]
        if both:
            raise ProblemError(f"{both[0]} is in both the dependent and the independent tuple")
        if len(independent) != n + 1:
            raise ProblemError(f"independent tuple has {len(independent)} variables, expected "
                               f"n + 1 = {n + 1}")
    missing = [var_name(v, n) for v in all_vars(n) if v not in set(dependent) | set(independent)]
    if missing:
        raise ProblemError(f"variable {missing[0]} is in neither tuple")
    if not any_basis:
        for i in range(n):
            if ("w", i) in dependent and ("z", i) in dependent:
                raise ProblemError(f"dependent tuple holds both w{i + 1} and z{i + 1}: not an "
                                   f"(almost) complementary basis (use --any-basis to allow)")
    return tuple(dependent), tuple(independent)


@dataclass
class PivotTransform:
    """The pivoted system ``w' = q' + M' z'`` (0-based index sets, see the module docstring)."""

    n: int
    dependent: tuple[Var, ...]
    independent: tuple[Var, ...]
    alpha: list[int]
    alpha_prime: list[int]
    beta: list[int]
    beta_prime: list[int]
    alpha_bar: list[int]
    alpha_bar_prime: list[int]
    beta_bar: list[int]
    beta_bar_prime: list[int]
    M_ab: np.ndarray
    M_abar_b: np.ndarray
    q_a: np.ndarray
    q_abar: np.ndarray
    q_prime: np.ndarray
    driving: Var | None = None
    driving_case: str | None = None  # "w" (eqs 5-6) or "z" (eqs 7-8)
    driving_column: np.ndarray | None = None
    g_alpha: np.ndarray | None = None
    g_alpha_bar: np.ndarray | None = None
    full: np.ndarray | None = None  # M' (n x (n+1)), columns in z' order

    @property
    def m(self) -> int:
        return len(self.alpha)

    def names(self, tup: tuple[Var, ...]) -> list[str]:
        return [var_name(v, self.n) for v in tup]

    def basic_solution(self) -> np.ndarray:
        """``z`` (n entries, the artificial variable left out) of the basic solution: ``z' = 0``
        and ``w' = q'``, so ``z_j = q'_k`` where ``z_j`` is the k-th dependent variable, else
        0 (in the arithmetic of ``q'``: fractions for an exact transform)."""
        z = np.zeros(self.n, dtype=self.q_prime.dtype)
        for k, (kind, j) in enumerate(self.dependent):
            if kind == "z" and j < self.n:
                z[j] = self.q_prime[k]
        return z

    @property
    def solves(self) -> bool:
        """Whether this basis solves the LCP at ``z' = 0`` (Lemke's answer; Murty, ch. 1):
        the artificial variable is independent (so 0), ``q' >= 0`` (exactly, in the arithmetic
        of ``q'``), and no pair has ``w_i`` and ``z_i`` both positive (a non-complementary
        basis of ``--any-basis`` may).  The renderers state this, they do not decide it."""
        if ("z", self.n) in self.dependent or not all(v >= 0 for v in self.q_prime):
            return False
        value = dict(zip(self.dependent, self.q_prime, strict=True))
        return all(not (value.get(("w", i), 0) > 0 and value.get(("z", i), 0) > 0)
                   for i in range(self.n))

    def to_dict(self) -> dict[str, Any]:
        """The JSON schema of ``lcpcli pivot --json`` (index sets 1-based)."""
        def one(xs: list[int]) -> list[int]:
            return [int(x) + 1 for x in xs]

        out: dict[str, Any] = {
            "n": self.n,
            "m": self.m,
            "dependent": self.names(self.dependent),
            "independent": self.names(self.independent),
            "alpha": one(self.alpha), "alpha_prime": one(self.alpha_prime),
            "beta": one(self.beta), "beta_prime": one(self.beta_prime),
            "alpha_bar": one(self.alpha_bar), "alpha_bar_prime": one(self.alpha_bar_prime),
            "beta_bar": one(self.beta_bar), "beta_bar_prime": one(self.beta_bar_prime),
            "M_alpha_beta": self.M_ab.tolist(),
            "M_alpha_bar_beta": self.M_abar_b.tolist(),
            "q_alpha": self.q_a.tolist(),
            "q_alpha_bar": self.q_abar.tolist(),
            "q_prime": self.q_prime.tolist(),
            "driving": None if self.driving is None else var_name(self.driving, self.n),
            "driving_case": self.driving_case,
            "driving_column": None if self.driving_column is None
            else self.driving_column.tolist(),
        }
        if self.full is not None:
            out["M_prime"] = self.full.tolist()
        return out


class _Factor:
    """LU factorisation of the square block ``M^{alpha beta}`` (m may be 0).

    The block is first equilibrated by exact powers of two (:func:`_equilibrate`), so that
    whether it is singular does not depend on the units of the data: ``[[1e300, 1], [1e-300,
    1e-300]]`` and ``diag(5e-324, 1)`` are bases (Cottle-Pang-Stone 2.3: principal pivoting is
    invariant under positive row and column scaling).  Solves map back exactly:
    ``x = D_c (D_r A D_c)^-1 D_r b``.
    """

    def __init__(self, A: np.ndarray) -> None:
        self.m = A.shape[0]
        if self.m == 0:
            return
        if not np.all(np.isfinite(A)):
            raise ProblemError("M^{alpha beta} contains NaN or Inf")
        refusal = None
        for own_units in (False, True):  # the quick scaling, then the block's own units
            self.er, self.ec, As = _equilibrate(A, own_units=own_units)
            refusal = self._factor(As)
            if refusal is None:
                return
        raise refusal

    def _factor(self, As: np.ndarray) -> ProblemError | None:
        """LU of the equilibrated block; the refusal when it is singular (None if not)."""
        import scipy.linalg as sla  # scipy is imported on first use (start-up budget)

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.lu = sla.lu_factor(As, check_finite=False)
        diag = np.abs(np.diag(self.lu[0]))
        scale = max(float(np.max(np.abs(As))), np.finfo(float).tiny)
        if diag.min() <= RCOND_MIN * scale * self.m:
            return ProblemError("M^{alpha beta} is singular: these tuples are not a basis "
                                "(no pivoted system exists)")
        rcond = _rcond(self.lu, As)
        if rcond < RCOND_MIN:
            return ProblemError(f"M^{{alpha beta}} is singular to working precision "
                                f"(rcond {rcond:.1e}): these tuples are not a basis")
        return None

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b``; ``b`` is brought to its own unit ``2^s`` first (a column of the data
        in units far from the rows' would underflow in ``D_r b``: ``2^-461`` against rows in
        ``2^705``), and ``2^s`` is put back with ``D_c``."""
        if self.m == 0:
            return np.zeros(0)
        import scipy.linalg as sla  # scipy is imported on first use (start-up budget)

        b = np.asarray(b, dtype=np.float64)
        s = int(binary_exponents(np.max(np.abs(b))))
        with np.errstate(over="ignore", under="ignore"):  # x beyond the double range: Inf
            y = sla.lu_solve(self.lu, ldexp_exact(b, -(self.er + s)), check_finite=False)
            return ldexp_exact(y, s - self.ec)


def inverse(A: np.ndarray) -> np.ndarray:
    """``A^-1`` of a square matrix through the equilibrated LU of :class:`_Factor` (whether it
    is singular, and its entries, do not depend on the units of the rows and columns; an
    entry past the double range is inf); ProblemError when ``A`` is singular."""
    m = A.shape[0]
    f = _Factor(np.asarray(A, dtype=np.float64))
    return np.column_stack([f.solve(e) for e in np.eye(m)]) if m else np.zeros((0, 0))


#: Sweeps of alternating means that smooth the spanning-tree scaling of :func:`_equilibrate`.
LOG_SCALING_SWEEPS = 10


def _equilibrate(A: np.ndarray, own_units: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(e_r, e_c, D_r A D_c)`` with ``D_r = 2^-e_r``, ``D_c = 2^-e_c`` (exact).

    Every row, then every column, is scaled to a largest entry in ``[1/2, 1)``.  When the
    units of the rows and columns spread wider than the double range, that loses entries (a
    row's largest entry in one column pushes the entries of another column below ``2^-1074``:
    ``[[0, 2^-461], [-2^704, 2^-461]]`` became ``[[0, 1/2], [-1/2, 0]]`` and the transform was
    wrong, ``q' = -9`` for ``-7``) or leaves them far below the others (``1e-205`` against
    ``0.75``: a basis refused as singular).  Then (also with ``own_units``, which
    :class:`_Factor` asks for before it calls a block singular) the block is first brought to
    units of its own: the
    exponents ``r_i + c_j`` fit ``log2 |A_ij|`` on the nonzero entries, along a spanning tree of
    their graph (exact for data ``D1 A0 D2`` with powers of two ``D1``, ``D2``), smoothed by a
    few least-squares sweeps; the row and column steps follow, on entries that no longer
    underflow."""
    er = binary_exponents(np.max(np.abs(A), axis=1))
    As = np.ldexp(A, -er[:, None])
    ec = binary_exponents(np.max(np.abs(As), axis=0))
    As = np.ldexp(As, -ec[None, :])
    nz = A != 0
    if not own_units and not np.any(nz & (np.abs(As) < np.finfo(np.float64).tiny)):
        return er, ec, As
    m = A.shape[0]
    E = np.where(nz, binary_exponents(A), 0).astype(np.float64)
    r, c = np.zeros(m), np.zeros(m)
    seen_r, seen_c = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
    for start in range(m):  # breadth-first over the bipartite graph of the nonzero entries
        if seen_r[start]:
            continue
        seen_r[start] = True
        queue: list[tuple[str, int]] = [("r", start)]
        while queue:
            kind, k = queue.pop()
            if kind == "r":
                for j in np.flatnonzero(nz[k] & ~seen_c):
                    seen_c[j], c[j] = True, E[k, j] - r[k]
                    queue.append(("c", int(j)))
            else:
                for i in np.flatnonzero(nz[:, k] & ~seen_r):
                    seen_r[i], r[i] = True, E[i, k] - c[k]
                    queue.append(("r", int(i)))
    rows, cols = np.maximum(nz.sum(axis=1), 1), np.maximum(nz.sum(axis=0), 1)
    for _ in range(LOG_SCALING_SWEEPS):
        r = np.where(nz, E - c[None, :], 0.0).sum(axis=1) / rows
        c = np.where(nz, E - r[:, None], 0.0).sum(axis=0) / cols
    r, c = np.round(r).astype(np.int64), np.round(c).astype(np.int64)
    # each row's largest entry to [1/2, 1) in exponent arithmetic first (data that are not of
    # the form D1 A0 D2 may leave the fit far off the range: ldexp must not overflow)
    F = np.where(nz, E - r[:, None] - c[None, :], -np.inf)
    top = np.max(F, axis=1)
    r = r + np.where(np.isfinite(top), top, 0).astype(np.int64)
    with np.errstate(under="ignore"):  # entries far below their row's largest: 0
        A1 = ldexp_exact(A, -(r[:, None] + c[None, :]))
        ec = binary_exponents(np.max(np.abs(A1), axis=0))
        return r, c + ec, np.ldexp(A1, -ec[None, :])


def _rcond(lu: Any, A: np.ndarray) -> float:
    """Reciprocal 1-norm condition estimate of a factorised block (LAPACK gecon)."""
    from scipy.linalg import lapack  # scipy is imported on first use (start-up budget)

    anorm = float(np.max(np.sum(np.abs(A), axis=0)))
    if anorm == 0:
        return 0.0
    rc, _info = lapack.dgecon(lu[0], anorm, norm="1")
    return float(rc)


def principal_pivot(M: np.ndarray, q: np.ndarray, dependent: tuple[Var, ...],
                    independent: tuple[Var, ...] | None = None, *,
                    driving: Var | None = None, full: bool = False,
                    any_basis: bool = False) -> PivotTransform:
    """Compute the pivoted system of ``w = q + M z`` (``M`` is ``n x (n+1)``).

    Returns q' in ``w'`` order and, for ``driving`` (a variable of ``z'``), the column of
    ``M'`` that multiplies it (``w'`` order); ``full`` computes every column of ``M'`` the
    same way (z' order).  Raises :class:`ProblemError` for a bad basis or a singular block.
    """
    M = np.asarray(M, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64).ravel()
    n = q.shape[0]
    if M.shape != (n, n + 1):
        raise ProblemError(f"M must be n x (n+1) = {n} x {n + 1} (artificial column last), "
                           f"got {M.shape[0]} x {M.shape[1]}")
    dependent, independent = validate_basis(tuple(dependent),
                                            None if independent is None else tuple(independent),
                                            n, any_basis=any_basis)
    pos_dep = {v: k for k, v in enumerate(dependent)}
    pos_ind = {v: k for k, v in enumerate(independent)}
    alpha = [i for i in range(n) if ("w", i) in pos_ind]
    alpha_p = [pos_ind[("w", i)] for i in alpha]
    beta = [j for j in range(n + 1) if ("z", j) in pos_dep]
    beta_p = [pos_dep[("z", j)] for j in beta]
    abar = [i for i in range(n) if ("w", i) in pos_dep]
    abar_p = [pos_dep[("w", i)] for i in abar]
    bbar = [j for j in range(n + 1) if ("z", j) in pos_ind]
    bbar_p = [pos_ind[("z", j)] for j in bbar]
    if len(alpha) != len(beta):  # Lemma 1 (cannot fail after validate_basis; kept as a guard)
        raise ProblemError(f"Lemma 1 fails: {len(alpha)} independent w but {len(beta)} "
                           f"dependent z")
    M_ab = M[np.ix_(alpha, beta)]
    M_abar_b = M[np.ix_(abar, beta)]
    q_a, q_abar = q[alpha], q[abar]
    lu = _Factor(M_ab)

    def column(var: Var) -> np.ndarray:
        col = np.empty(n)
        if var[0] == "w":  # eqs (5)-(6)
            gamma = alpha.index(var[1])
            e = np.zeros(len(alpha))
            e[gamma] = 1.0
            xb = lu.solve(e)
            col[beta_p] = xb
            with np.errstate(over="ignore", invalid="ignore"):
                col[abar_p] = M_abar_b @ xb
        else:  # eqs (7)-(8)
            g = M[:, var[1]]
            xb = -lu.solve(g[alpha])
            col[beta_p] = xb
            with np.errstate(over="ignore", invalid="ignore"):
                col[abar_p] = g[abar] + M_abar_b @ xb
        return col

    qp = np.empty(n)
    qb = -lu.solve(q_a)  # eq (2)
    qp[beta_p] = qb
    with np.errstate(over="ignore", invalid="ignore"):  # checked by _representable
        qp[abar_p] = q_abar + M_abar_b @ qb  # eq (3)
    _representable(qp, "q'")
    out = PivotTransform(n, dependent, independent, alpha, alpha_p, beta, beta_p, abar, abar_p,
                         bbar, bbar_p, M_ab, M_abar_b, q_a, q_abar, qp)
    if driving is not None:
        if driving not in pos_ind:
            raise ProblemError(f"driving variable {var_name(driving, n)} is not independent "
                               f"(it must be one of {', '.join(out.names(independent))})")
        out.driving = driving
        out.driving_case = driving[0]
        out.driving_column = _representable(column(driving), "the driving column")
        if driving[0] == "z":
            g = M[:, driving[1]]
            out.g_alpha, out.g_alpha_bar = g[alpha], g[abar]
    if full:
        out.full = _representable(np.column_stack([column(v) for v in independent])
                                  if n else np.zeros((0, 1)), "M'")
    return out


def _representable(x: np.ndarray, what: str) -> np.ndarray:
    """``x``, or ProblemError (one line, exit 2) when the pivoted system overflows: its
    entries are ratios of the data's, which can leave the double range (1e300 / 1e-300)."""
    if not np.all(np.isfinite(x)):
        raise ProblemError(f"{what} of this pivoted system is beyond double precision (an "
                           f"entry overflows: a ratio of the data's entries)")
    return x


def augment(M: np.ndarray, covering: np.ndarray | None = None) -> np.ndarray:
    """``[M, d]``: append the artificial column (default all ones) to an n x n matrix."""
    M = np.asarray(M, dtype=np.float64)
    n = M.shape[0]
    d = np.ones(n) if covering is None else np.asarray(covering, dtype=np.float64).ravel()
    if d.size == 1:
        d = np.full(n, float(d[0]))
    if d.shape[0] != n:
        raise ProblemError(f"covering vector has length {d.shape[0]}, expected {n}")
    if not np.all(np.isfinite(d)):
        raise ProblemError("covering vector contains NaN or Inf")
    return np.column_stack([M, d])
