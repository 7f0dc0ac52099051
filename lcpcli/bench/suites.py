"""Built-in benchmark suites: deterministic problem generators with known right outcomes.

Every generator is a pure function of its size and seed (``numpy.random.default_rng(seed)``), so
the same call gives the same problems on every machine.  Each problem comes as a :class:`Case`
that states the right outcome (``expected``: ``"solvable"`` or ``"infeasible"``), a known solution
when there is one (planted, or from the literature), and the facts that make the case hard.

Sign convention: ``w = M z + q``; indices are 0-based here (the CLI shows 1-based names).

Suites (:func:`suite`):

* ``hard``    classic worst cases and numerical traps (see :func:`hard_suite`);
* ``random``  PD, PSD, P and sparse contact-like problems, sizes 10..2000 (:func:`random_suite`);
* ``siconos`` the Siconos test data beside the checkout, when present (:func:`siconos_suite`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.core.errors import OptionError
from lcpcli.core.problem import Problem

SOLVABLE = "solvable"
INFEASIBLE = "infeasible"

#: Condition numbers of the ill-conditioned PD family.
CONDITION_NUMBERS = (1e2, 1e4, 1e6, 1e8, 1e10, 1e12)
#: Sizes of the random suite (those <= ``n`` are used).
RANDOM_SIZES = (10, 50, 200, 500, 1000, 2000)
#: Default size parameter of each suite.
DEFAULT_N = {"hard": 8, "random": 2000, "siconos": 0}


@dataclass
class Case:
    """One benchmark problem and what the right answer is.

    ``expected`` is ``"solvable"`` or ``"infeasible"``; ``solution`` is a known solution (the only
    one when ``unique``), ``farkas`` a vector ``y >= 0`` with ``M^T y <= 0``, ``q^T y < 0`` that
    proves infeasibility; ``facts`` holds case-specific numbers (e.g. ``lemke_pivots``).
    """

    problem: Problem
    expected: str = SOLVABLE
    note: str = ""
    solution: np.ndarray | None = None
    unique: bool = False
    farkas: np.ndarray | None = None
    facts: dict[str, Any] = field(default_factory=dict)
    source: str = ""

    @property
    def name(self) -> str:
        return self.problem.name

    @property
    def n(self) -> int:
        return self.problem.n


def solution_of_stored_data(M: np.ndarray, q: np.ndarray, z: np.ndarray,
                            max_steps: int = 10) -> np.ndarray:
    """The planted ``z`` made a solution of the data as stored, to about an ulp.

    A planted ``q = w - M z`` is rounded, so the exact solution of the stored ``(M, q)`` lies
    about ``cond(M) eps`` from ``z`` (2e-10 at cond 1e12, n = 32): a forward error measured
    against ``z`` would show the suite's rounding, not the method's.  On the support ``S`` of
    ``z`` this solves ``M_SS z_S = -q_S`` by iterative refinement (Wilkinson), each residual
    ``M_SS z_S + q_S`` the exact value rounded once (the exactly rounded dot products of
    :mod:`lcpcli.analysis.proof`); it converges while ``cond(M_SS) eps < 1``.  The caller keeps
    the strict complementarity margins (``z_S >= 0.5``, ``w >= 0.5`` off ``S``), far above
    the change.
    """
    from lcpcli.analysis.proof import _exact_dots  # the one exactly rounded dot product

    S = np.flatnonzero(z > 0)
    if S.size == 0:
        return z
    A = np.asarray(M, dtype=float)[np.ix_(S, S)]
    b = np.asarray(q, dtype=float)[S]
    ext = np.vstack([A.T, b[None, :]])  # (ext^T [x; 1])_i = (A x + b)_i
    cols = np.arange(S.size)
    x = np.asarray(z, dtype=float)[S].copy()
    for _ in range(max_steps):
        y = np.append(x, 1.0)
        e = int(np.frexp(np.max(np.abs(y)))[1])  # max |y 2^-e| < 1, scaled exactly
        r = np.ldexp(_exact_dots(ext, np.ldexp(y, -e), cols), e)
        d = np.linalg.solve(A, -r)
        x = x + d
        if np.max(np.abs(d)) <= np.finfo(float).eps * np.max(np.abs(x)):
            break
    out = np.array(z, dtype=float)
    out[S] = x
    return out


def _case(M: Any, q: Any, name: str, note: str, **kw: Any) -> Case:
    prob = Problem.create(M, q, name=name, description=note)
    return Case(problem=prob, note=note, **kw)


# ------------------------------------------------------------------ classic families
def murty_matrix(n: int) -> np.ndarray:
    """Murty's upper-triangular matrix: 1 on the diagonal, 2 above it (a P-matrix)."""
    return np.triu(np.full((n, n), 2.0), 1) + np.eye(n)


def murty_lemke(n: int) -> Case:
    """Murty (1978): Lemke's method (covering vector e) takes 2^n pivots.

    ``M`` = :func:`murty_matrix`, ``q_i = -(2^(n+1) - 2^i)`` for i = 1..n (1-based), which is
    Siconos' ``lcp_exp_murty2.dat`` at n = 6.  Unique solution ``z = 2^n e_n``, ``w_i = 2^i``
    (i < n), ``w_n = 0``.  Pivot count: 2^n including the initial pivot that brings z0 into
    the basis (2^n - 1 complementary pivots after it), as counted by ``lemke-tableau``.
    """
    M = murty_matrix(n)
    q = -np.array([2.0 ** (n + 1) - 2.0 ** i for i in range(1, n + 1)])
    z = np.zeros(n)
    z[-1] = 2.0 ** n
    return _case(M, q, f"murty-lemke-{n}",
                 f"Murty 1978: Lemke needs 2^{n} = {2 ** n} pivots (incl. the z0 pivot)",
                 solution=z, unique=True, facts={"lemke_pivots": 2 ** n},
                 source="Murty 1978; Siconos lcp_exp_murty2 (n=6)")


def murty_least_index(n: int) -> Case:
    """Murty's least-index principal pivoting method takes 2^n - 1 pivots.

    Same ``M`` as :func:`murty_lemke`, ``q = -e`` (Siconos ``lcp_exp_murty.dat`` at n = 6).
    Started from ``z = 0``, the rule "exchange w_r and z_r for the least r whose basic value is
    negative" visits 2^n - 1 bases.  Unique solution ``z = e_n``.  Lemke needs only 2 pivots here.
    """
    M = murty_matrix(n)
    z = np.zeros(n)
    z[-1] = 1.0
    return _case(M, -np.ones(n), f"murty-least-index-{n}",
                 f"Murty's least-index method needs 2^{n} - 1 = {2 ** n - 1} principal pivots",
                 solution=z, unique=True, facts={"murty_pivots": 2 ** n - 1},
                 source="Murty 1974/1978; Siconos lcp_exp_murty (n=6)")


def kostreva() -> Case:
    """Kostreva's 3x3 cycling example (1979): cyclic P-matrix, ``q = -e``, z = e/3, w = 0.

    Fully degenerate (every ratio ties at the first step, every w_i = 0 at the solution):
    Lemke without an anti-cycling rule can cycle on it.
    """
    M = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 2.0], [2.0, 0.0, 1.0]])
    return _case(M, -np.ones(3), "kostreva-3",
                 "Kostreva 1979 cycling example: all ratios tie, solution e/3 with w = 0",
                 solution=np.full(3, 1.0 / 3.0), unique=True, source="Kostreva 1979")


def degenerate_p(n: int, seed: int = 0) -> Case:
    """Row-diagonally dominant nonsymmetric P-matrix with 3/4 of ``q`` zero (ties everywhere)."""
    rng = np.random.default_rng(seed)
    M = rng.uniform(-1.0, 1.0, (n, n))
    np.fill_diagonal(M, 0.0)
    np.fill_diagonal(M, 1.05 * np.abs(M).sum(axis=1) + 0.1)
    q = np.zeros(n)
    idx = rng.choice(n, size=max(1, n // 4), replace=False)
    q[idx] = rng.uniform(-1.0, -0.1, idx.size)
    return _case(M, q, f"degenerate-p-{n}",
                 "diagonally dominant P-matrix, 75% of q zero: degenerate ratio tests",
                 unique=True)


def degenerate_psd(n: int, seed: int = 1) -> Case:
    """Singular PSD ``M = A A^T`` (rank n/2), ``q = -M z*``: z* solves it with ``w = 0`` everywhere.

    z* has half its entries zero, so those pairs are doubly degenerate (z_i = w_i = 0).
    """
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, max(1, n // 2)))
    M = A @ A.T
    z = rng.uniform(0.5, 2.0, n)
    z[rng.choice(n, size=n // 2, replace=False)] = 0.0
    q = -(M @ z)
    return _case(M, q, f"degenerate-psd-{n}",
                 "singular PSD, rank n/2; planted solution with w = 0 and half of z = 0",
                 solution=z)


def cube_contact(contacts: int = 4, spin: bool = False) -> Case:
    """Unit cube (mass 1, side 1) falling flat on a plane: ``M = J W J^T``, singular PSD.

    Contacts lie at the cube's bottom face (z = -1/2): the 4 corners, or the 4 corners plus the 4
    edge midpoints (8 coplanar contacts).  ``J`` rows are ``[n^T, (r x n)^T]`` with normal
    ``n = e_z``; ``W = diag(I3 / m, I^-1)`` with ``I = (m/6) I3``.  Rank of M is 3 (the normal
    force and two tilting moments), so M is singular for 4 and 8 contacts.  ``q = J v`` with the
    falling velocity ``v = (0, 0, -1)`` (and angular velocity (0.3, -0.2, 0) when ``spin``).
    Without spin ``z = (m / k) e`` (k contacts) stops the cube: a known solution with w = 0.
    """
    h = 0.5
    pts = [(-h, -h), (h, -h), (h, h), (-h, h)]
    if contacts == 8:
        pts += [(0.0, -h), (h, 0.0), (0.0, h), (-h, 0.0)]
    elif contacts != 4:
        raise OptionError("cube_contact: contacts must be 4 or 8")
    normal = np.array([0.0, 0.0, 1.0])
    J = np.array([np.concatenate([normal, np.cross(np.array([x, y, -h]), normal)])
                  for x, y in pts])
    mass, inertia = 1.0, 1.0 / 6.0
    W = np.diag([1 / mass] * 3 + [1 / inertia] * 3)
    M = J @ W @ J.T
    v = np.array([0.0, 0.0, -1.0, 0.3, -0.2, 0.0]) if spin else np.array([0.0, 0, -1, 0, 0, 0])
    q = J @ v
    name = f"cube-{contacts}{'-spin' if spin else ''}"
    sol = None if spin else np.full(contacts, mass / contacts)
    return _case(M, q, name,
                 f"cube on a plane, {contacts} coplanar contacts: PSD of rank 3, "
                 "a continuum of solutions", solution=sol,
                 facts={"rank": int(np.linalg.matrix_rank(M))})


def illcond_pd(n: int, cond: float, seed: int = 2) -> Case:
    """Symmetric PD ``M = Q diag(logspace(0, -log10 cond)) Q^T`` with a planted unique solution.

    Half of the planted z* is positive (w* = 0 there), the other half zero (w* > 0): strict
    complementarity, so the solution is unique and the forward error can be measured; z* is
    then the solution of the stored data (:func:`solution_of_stored_data`).
    """
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    d = np.logspace(0.0, -np.log10(cond), n)
    M = (Q * d) @ Q.T
    M = 0.5 * (M + M.T)
    z = np.zeros(n)
    w = np.zeros(n)
    support = rng.permutation(n)[: n // 2]
    z[support] = rng.uniform(0.5, 1.5, support.size)
    rest = np.setdiff1d(np.arange(n), support)
    w[rest] = rng.uniform(0.5, 1.5, rest.size)
    q = w - M @ z
    return _case(M, q, f"illcond-pd-{n}-1e{int(round(np.log10(cond)))}",
                 f"symmetric PD, cond {cond:.0e}, planted strictly complementary solution",
                 solution=solution_of_stored_data(M, q, z), unique=True, facts={"cond": cond})


def bimatrix_cps() -> Case:
    """Cottle-Pang-Stone Example 4.4.23 (Siconos lcp_CPS_3): a bimatrix game, q = -e.

    ``M = [[0, A], [B^T, 0]]`` with positive A, B: copositive, not copositive-plus.  Lemke's
    method (covering e) ends on a secondary ray after its first pivot though solutions exist.
    """
    M = np.array([[0.0, 0, 10, 20], [0, 0, 30, 15], [10, 20, 0, 0], [30, 15, 0, 0]])
    # pure equilibrium (row 1, column 1 of the cost game): z = (1/10, 0, 1/10, 0)
    z = np.array([0.1, 0.0, 0.1, 0.0])
    return _case(M, -np.ones(4), "bimatrix-cps-4",
                 "bimatrix game (CPS 4.4.23): Lemke ends on a ray though solutions exist",
                 solution=z, facts={"lemke": "ray"}, source="Cottle-Pang-Stone Ex. 4.4.23")


def bimatrix_ray(n: int, seed: int = 3) -> Case:
    """A random positive bimatrix game ``M = [[0, A], [B^T, 0]]``, ``q = -e``, of size n.

    Copositive (M >= 0) but not copositive-plus (e_1^T M e_1 = 0, (M + M^T) e_1 != 0).
    Lemke with covering e: after the z0 pivot on row r, the entering z_r's column is
    ``M[:, r] >= 0``, so the method stops on a ray at once.  Yet a solution exists: a planted pure
    equilibrium (i*, j*) with ``A[i*, j*]`` minimal in its column and ``B[i*, j*]`` minimal in its
    row gives ``x = e_i* / B[i*, j*]``, ``y = e_j* / A[i*, j*]``.
    """
    n1 = max(1, n // 2)
    n2 = max(1, n - n1)
    rng = np.random.default_rng(seed)
    A = rng.uniform(1.0, 10.0, (n1, n2))
    B = rng.uniform(1.0, 10.0, (n1, n2))
    i, j = int(rng.integers(n1)), int(rng.integers(n2))
    A[i, j] = A[:, j].min() * 0.9
    B[i, j] = B[i, :].min() * 0.9
    M = np.zeros((n1 + n2, n1 + n2))
    M[:n1, n1:] = A
    M[n1:, :n1] = B.T
    z = np.zeros(n1 + n2)
    z[i] = 1.0 / B[i, j]
    z[n1 + j] = 1.0 / A[i, j]
    return _case(M, -np.ones(n1 + n2), f"bimatrix-ray-{n1 + n2}",
                 "positive bimatrix game: Lemke ends on a ray; a planted pure equilibrium "
                 "solves it", solution=z, facts={"lemke": "ray"})


def infeasible_psd(n: int, seed: int = 4) -> Case:
    """PSD ``M = C S C^T`` with the columns of ``C`` orthogonal to ``y > 0`` and ``q^T y < 0``.

    ``M y = 0 = M^T y``, so for every z >= 0, ``y^T (M z + q) = q^T y < 0``: some w_i < 0, no
    feasible point, no solution.  ``y`` is the Farkas certificate (``Case.farkas``).  M is
    PSD hence copositive-plus, so Lemke's ray also proves it.  Every entry is a small integer
    (``y_i`` in {1, 2}, ``C``'s columns ``y_{j+1} e_j - y_j e_{j+1}``, ``S = A A^T + I`` of an
    integer ``A``), so the data are exactly what they say: singular and infeasible, where a
    product rounded in floating point would be another matrix.

    Ill-posed on purpose: a relative perturbation of M at roundoff level makes it feasible, so a
    huge z can pass a certificate that does not bound growth (w_min ~ -0.1); Siconos' Lemke
    returns such a z (and reports failure).  :func:`infeasible_robust` is the well-posed
    counterpart.
    """
    rng = np.random.default_rng(seed)
    y = rng.integers(1, 3, n).astype(float)
    y[0] = 1.0
    C = np.zeros((n, n - 1))
    for j in range(n - 1):
        C[j, j], C[j + 1, j] = y[j + 1], -y[j]
    A = rng.integers(-2, 3, (n - 1, n - 1)).astype(float)
    M = C @ (A @ A.T + np.eye(n - 1)) @ C.T  # small integers: exact
    q = rng.integers(-3, 4, n).astype(float)
    q[0] = -1.0 - float(q[1:] @ y[1:])  # now q^T y = -1 (y_0 = 1)
    return _case(M, q, f"infeasible-psd-{n}",
                 "PSD, q^T y < 0 with M y = 0, y > 0: no feasible z (Farkas)",
                 expected=INFEASIBLE, farkas=y)


def infeasible_robust(n: int, seed: int = 5) -> Case:
    """Nonmonotone ``M`` with ``M^T y = -c`` (``y, c > 0``) and ``q^T y = -1``: robustly infeasible.

    For every z >= 0, ``y^T w = -c^T z - 1 <= -1``, so min(w) <= -1 / sum(y) whatever z is and
    the certificate cannot be fooled by a large z.  ``y`` is the Farkas certificate.
    """
    rng = np.random.default_rng(seed)
    y = rng.uniform(0.5, 1.5, n)
    c = rng.uniform(0.5, 1.5, n)
    A = rng.standard_normal((n, n))
    M = A - np.outer(y, A.T @ y + c) / (y @ y)
    q = rng.standard_normal(n)
    q -= (q @ y + 1.0) / (y @ y) * y
    return _case(M, q, f"infeasible-robust-{n}",
                 "nonmonotone, M^T y < 0 and q^T y < 0 with y > 0: robustly infeasible",
                 expected=INFEASIBLE, farkas=y)


#: A 3x3 P-matrix (principal minors 1, 1, 1, 2, 1, 4 and det 2) and a q on which the plain
#: Newton-min iteration from z = 0 cycles through three index sets (found by a search over small
#: integer matrices; tests/test_bench.py replays the cycle).
NEWTON_MIN_M = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, 1.0], [3.0, -3.0, 1.0]])
NEWTON_MIN_Q = np.array([-1.0, 1.0, -1.0])


def newton_min_cycle(n: int = 3) -> Case:
    """A P-matrix on which plain Newton-min (no globalisation, from z = 0) cycles.

    Block diagonal with ``n // 3`` copies of :data:`NEWTON_MIN_M` (plus 1s on the diagonal for the
    remainder, with q = -1 there): block-diagonal P is P, the blocks decouple, and each block
    cycles as in the 3x3 case (cf. Ben Gharbia & Gilbert 2012: plain Newton-min need not converge
    on P-matrices for n >= 3).  The unique solution is computed by enumeration of each block.
    """
    k = max(1, n // 3)
    m = max(n, 3)
    M = np.eye(m)
    q = -np.ones(m)
    zb = enumerate_solutions(NEWTON_MIN_M, NEWTON_MIN_Q)[0]
    z = np.ones(m)
    for b in range(k):
        s = slice(3 * b, 3 * b + 3)
        M[s, s] = NEWTON_MIN_M
        q[s] = NEWTON_MIN_Q
        z[s] = zb
    return _case(M, q, f"newton-min-cycle-{m}",
                 "P-matrix on which plain Newton-min from z = 0 cycles (3 index sets)",
                 solution=z, unique=True, facts={"newton_min": "cycles"})


def enumerate_solutions(M: np.ndarray, q: np.ndarray, tol: float = 1e-9) -> list[np.ndarray]:
    """All solutions at complementary bases with a nonsingular block (2^n subsets; small n).

    A reference for tests and small cases: solves ``M_SS z_S = -q_S`` for every support S and
    keeps the z that satisfy ``z >= 0``, ``w >= 0`` within ``tol`` (relative to ||q||).
    """
    n = q.shape[0]
    scale = max(1.0, float(np.max(np.abs(q))))
    found: list[np.ndarray] = []
    for mask in range(1 << n):
        S = [i for i in range(n) if mask >> i & 1]
        z = np.zeros(n)
        if S:
            block = M[np.ix_(S, S)]
            if abs(np.linalg.det(block)) < 1e-12:
                continue
            z[S] = np.linalg.solve(block, -q[S])
        w = M @ z + q
        if z.min() >= -tol * scale and w.min() >= -tol * scale:
            z = np.maximum(z, 0.0)
            if not any(np.allclose(z, f) for f in found):
                found.append(z)
    return found


# ------------------------------------------------------------------ suites
def hard_suite(n: int | None = None, seed: int = 0) -> list[Case]:
    """The hard-case suite at size ``n`` (default 8; the Murty families use 2^n pivots)."""
    n = DEFAULT_N["hard"] if n is None else int(n)
    if n < 3:
        raise OptionError("the hard suite needs n >= 3")
    cases = [murty_lemke(n), murty_least_index(n), kostreva(), degenerate_p(4 * n, seed),
             degenerate_psd(4 * n, seed + 1), cube_contact(4), cube_contact(8),
             cube_contact(8, spin=True)]
    cases += [illcond_pd(4 * n, c, seed + 2) for c in CONDITION_NUMBERS]
    cases += [bimatrix_cps(), bimatrix_ray(2 * n, seed + 3), infeasible_psd(2 * n, seed + 4),
              infeasible_robust(2 * n, seed + 5),
              newton_min_cycle(3), newton_min_cycle(3 * n)]
    return cases


def random_pd(n: int, seed: int) -> Case:
    """Nonsymmetric positive definite ``M = B B^T / n + I/10 + K`` (K skew), planted solution."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n))
    K = rng.standard_normal((n, n))
    M = B @ B.T / n + 0.1 * np.eye(n) + 0.5 * (K - K.T) / np.sqrt(n)
    z, q = _plant(M, rng)
    return _case(M, q, f"random-pd-{n}", "nonsymmetric PD, planted solution",
                 solution=solution_of_stored_data(M, q, z), unique=True)


def random_psd(n: int, seed: int) -> Case:
    """Symmetric PSD of rank n/2, planted solution (not unique in general)."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, max(1, n // 2)))
    M = A @ A.T / n
    z, q = _plant(M, rng)
    return _case(M, q, f"random-psd-{n}", "symmetric PSD rank n/2, planted solution",
                 solution=z)


def random_p(n: int, seed: int) -> Case:
    """Nonsymmetric row-diagonally dominant P-matrix (symmetric part may be indefinite)."""
    rng = np.random.default_rng(seed)
    M = rng.uniform(-1.0, 1.0, (n, n)) * rng.uniform(0, 3, (1, n))
    np.fill_diagonal(M, 0.0)
    np.fill_diagonal(M, 1.01 * np.abs(M).sum(axis=1) + 0.1)
    z, q = _plant(M, rng)
    return _case(M, q, f"random-p-{n}", "diagonally dominant nonsymmetric P-matrix, planted",
                 solution=solution_of_stored_data(M, q, z), unique=True)


def random_contact(n: int, seed: int) -> Case:
    """Sparse contact-like ``M = J W J^T + 1e-6 I`` (CSR): 3-D bodies, each row couples two.

    ``n`` contact rows between ``max(2, n // 3)`` bodies with 6 velocity dofs each (random
    normals and lever arms), ``W`` = inverse masses/inertias, a small CFM term makes it PD.
    ``q = J v`` with random body velocities (approaching and separating contacts).
    """
    import scipy.sparse as sp

    rng = np.random.default_rng(seed)
    bodies = max(2, n // 3)
    rows, cols, vals = [], [], []
    for i in range(n):
        a, b = rng.choice(bodies, size=2, replace=False)
        normal = rng.standard_normal(3)
        normal /= np.linalg.norm(normal)
        for body, sign in ((a, 1.0), (b, -1.0)):
            arm = rng.uniform(-0.5, 0.5, 3)
            row = sign * np.concatenate([normal, np.cross(arm, normal)])
            rows += [i] * 6
            cols += list(range(6 * body, 6 * body + 6))
            vals += list(row)
    J = sp.csr_matrix((vals, (rows, cols)), shape=(n, 6 * bodies))
    inv_mass = np.repeat(1.0 / rng.uniform(0.5, 2.0, bodies), 6)
    M = (J @ sp.diags(inv_mass) @ J.T + 1e-6 * sp.identity(n)).tocsr()
    q = J @ rng.standard_normal(6 * bodies)
    return _case(M, q, f"random-contact-{n}",
                 "sparse contact-like J W J^T + 1e-6 I (CSR)", unique=True)


def _plant(M: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A strictly complementary (z*, q) pair for M: half of z* positive, w* > 0 elsewhere."""
    n = M.shape[0]
    z = np.zeros(n)
    w = np.zeros(n)
    support = rng.permutation(n)[: n // 2]
    z[support] = rng.uniform(0.5, 1.5, support.size)
    rest = np.setdiff1d(np.arange(n), support)
    w[rest] = rng.uniform(0.5, 1.5, rest.size)
    return z, w - np.asarray(M @ z).ravel()


def random_suite(n: int | None = None, seed: int = 0) -> list[Case]:
    """PD, PSD, P and sparse contact-like problems of each size in :data:`RANDOM_SIZES` <= n."""
    n = DEFAULT_N["random"] if n is None else int(n)
    sizes = [s for s in RANDOM_SIZES if s <= n] or [max(2, n)]
    cases: list[Case] = []
    for k, size in enumerate(sizes):
        s = seed + 10 * k
        cases += [random_pd(size, s), random_psd(size, s + 1), random_p(size, s + 2),
                  random_contact(size, s + 3)]
    return cases


# ------------------------------------------------------------------ Siconos data
#: Known answers from the Siconos data README (0-based arrays); files not listed are solvable.
SICONOS_INFEASIBLE = {"lcp_Pang_isolated_sol_perturbed"}
SICONOS_SOLUTIONS: dict[str, list[float]] = {
    "lcp_deudeu": [4 / 3, 7 / 3],
    "lcp_trivial": [1.0 / i for i in range(1, 10)],
    "lcp_ortiz": [2 / 3, 0, 1 / 3, 0],
    "lcp_exp_murty": [0, 0, 0, 0, 0, 1],
    "lcp_exp_murty2": [0, 0, 0, 0, 0, 64],
    "lcp_CPS_2": [0, 1, 3],
    "lcp_CPS_4": [2, 2, 2, 92],
    "lcp_CPS_4bis": [3, 3, 0, 83],
    "lcp_Pang_isolated_sol": [1, 0, 0],
    "lcp_inf_sol_perturbed": [1, 0, 1e-4],
}
#: Files that are bad input on purpose (skipped by the suite).
SICONOS_BAD_INPUT = {"Rectangular_mlcp"}


def siconos_root() -> Path | None:
    """``../shared/data/siconos`` beside the checkout (or ``$LCPCLI_SICONOS_DATA``), if present."""
    import os

    env = os.environ.get("LCPCLI_SICONOS_DATA")
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve().parents[1]
    candidates += [here.parent / "shared" / "data" / "siconos",
                   here.parent.parent / "shared" / "data" / "siconos"]
    for c in candidates:
        if c.is_dir():
            return c
    return None


def siconos_suite(n: int | None = None, seed: int = 0) -> list[Case]:
    """The Siconos LCP, MLCP and 2-D contact files, with the README's expectations.

    ``n`` (when positive) skips problems larger than n.  Raises OptionError if the data folder
    is missing.  Expectations: every file is solvable except ``lcp_Pang_isolated_sol_perturbed``
    (row 1 of M <= 0 with q_1 < 0: no feasible point).  A known solution is ``unique`` (so the
    forward error is measured against it) when M is a P-matrix, decided by
    :func:`lcpcli.analysis.classify.is_p_matrix_exact` (n <= its ``EXACT_P_MAX_N``).
    """
    from lcpcli.analysis.classify import EXACT_P_MAX_N, is_p_matrix_exact
    from lcpcli.io import load

    root = siconos_root()
    if root is None:
        raise OptionError("the Siconos data folder (../shared/data/siconos or "
                          "$LCPCLI_SICONOS_DATA) was not found")
    files = sorted((root / "lcp").glob("*.dat")) + sorted((root / "fc2d_as_lcp").glob("*.npz")) \
        + sorted((root / "mlcp").glob("*.dat"))
    cases = []
    for f in files:
        if f.stem in SICONOS_BAD_INPUT:
            continue
        prob = load(f)
        prob.name = f.stem
        if n and prob.n > n:
            continue
        sol = SICONOS_SOLUTIONS.get(f.stem.removesuffix("_block"))
        unique = (sol is not None and prob.kind == "lcp" and prob.n <= EXACT_P_MAX_N
                  and is_p_matrix_exact(prob.dense_M()))
        cases.append(Case(
            problem=prob,
            expected=INFEASIBLE if f.stem in SICONOS_INFEASIBLE else SOLVABLE,
            note=f"Siconos test data {f.parent.name}/{f.name}",
            solution=None if sol is None else np.asarray(sol, dtype=float), unique=unique,
            source=str(f)))
    return cases


SUITES: dict[str, Callable[..., list[Case]]] = {
    "hard": hard_suite,
    "random": random_suite,
    "siconos": siconos_suite,
}


def suite(name: str, n: int | None = None, seed: int = 0) -> list[Case]:
    """The cases of the suite called ``name`` (``hard``, ``random``, ``siconos``)."""
    key = name.strip().lower()
    if key not in SUITES:
        raise OptionError(f"unknown suite '{name}' (available: {', '.join(SUITES)})")
    if n is not None and n < 1:
        raise OptionError(f"--n must be positive, got {n}")
    return SUITES[key](n, seed)
