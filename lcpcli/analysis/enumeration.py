"""The enumeration method (Murty, ch. 1): complementary cones and all solutions of LCP(q, M).

Conventions: ``w = M z + q`` (Murty's ``w - M z = q``).  For each of the ``2^n`` choices of
complementary basic variables ``y_j in {w_j, z_j}`` the *complementary matrix* ``A_r`` has
column ``I_j`` where ``y_j = w_j`` and ``-M_j`` where ``y_j = z_j``; the cone
``Pos(A_r) = {A_r y : y >= 0}`` contains ``q`` exactly when ``A_r y = q`` has a solution
``y >= 0``, and then ``z_j = y_j`` (z basic), ``w_j = y_j`` (w basic), the other variable of each
pair 0, is a solution of the LCP.  Every solution lies in some cone, so visiting all ``2^n``
cones finds them all.

A cone is coded by the integer whose bit ``j`` (0-based) is set when ``z_j`` is basic; cone 0
is ``(w1, ..., wn)``.  ``det A_r = (-1)^|S| det M[S, S]`` with ``S`` the z-basic set.

Singular ``A_r`` (degenerate cones): the solutions in that cone form a polyhedron
``{y >= 0 : A_r y = q}``; an LP decides whether it is empty, one point, or a continuum (two
LPs with a random objective: max and min differ, or one is unbounded, exactly when the
polyhedron has more than one point).  The LCP has infinitely many solutions exactly when
some cone holds a continuum, since a nonsingular cone holds at most one point.

Tolerances are scaled by the data: a cone is feasible when ``min(mu z_S, w) >= -rtol (mu ||z||_inf
+ ||q||_inf)`` with ``mu = ||M||_inf`` (the units of :func:`lcpcli.core.certificate.certify`);
every reported solution is re-solved in numpy and certified.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcpcli.analysis._enum import (
    CANDIDATE,
    FEASIBLE,
    PRUNED,
    SINGULAR_CONSISTENT,
    SINGULAR_EMPTY,
    classify_chunk,
    classify_chunk_fast,
)
from lcpcli.analysis.proof import prove_infeasible, search_proof
from lcpcli.analysis.scaling import GEOMETRIC_SPREAD, Scaling, equilibrate, geometric, spread
from lcpcli.core.certificate import DEFAULT_TOL, Certificate, certify, matrix_norm_inf
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.limits import ENUM_ANNOUNCE_N, announce, power_of_two
from lcpcli.core.numeric import binary_exponents, unit_rows
from lcpcli.core.result import Status

#: Default refusal threshold (2^24 = 16.7 million cones).
DEFAULT_MAX_N = 24
#: Hard limit of the bit coding.
HARD_MAX_N = 62
#: Relative feasibility tolerance of the cone test.
RTOL = 1e-9
#: Pivot tolerance (times n) under which a principal block is singular, relative to the block
#: itself: the kernel equilibrates each block by powers of two (rows, then columns) first, so
#: the test is the same on any power-of-two row and column scaling of M.
PIVOT_RTOL = 1e-12
#: Relative tolerance of the n = 2 cone geometry (:func:`in_cone_2d`, :func:`cone_interiors_2d`,
#: the pictures of ``lcpcli enumerate``), on columns scaled to unit largest entry: a 2 x 2
#: complementary matrix whose determinant is at most this is degenerate (its cone a ray, a line
#: or a half-plane), and a point is inside a cone when its coordinates exceed it.
CONE_2D_TOL = 1e-12
#: First block of cones when stopping at the first solution (then doubling, aligned).
FIRST_CHUNK = 4096
#: Smallest n for which the fast (depth-first pivoting) kernel is used.
FAST_MIN_N = 6

UNIQUE = "unique"
FINITE = "finite"
CONTINUUM = "continuum"
NONE = "none"
FOUND = "found"  # stop_at_first: one solution found, the rest not examined
INCOMPLETE = "incomplete"  # solutions found, but some singular cones left unresolved
UNKNOWN = "unknown"  # no solution found, but some singular cones left unresolved
UNCERTIFIED = "uncertified"  # cones contain q, but no point of them passes the certificate

#: At most this many singular cones are resolved by LP (each costs about 3 LPs).
MAX_LPS = 2000
#: At most this many nonsingular cones that contain q but whose point failed the certificate
#: on the equilibrated problem are solved again on the data as given (see :func:`_rescue`).
MAX_RESCUES = 256


@dataclass
class Cone:
    """One complementary cone (0-based data; :meth:`basis_names` gives the 1-based names)."""

    code: int
    n: int
    feasible: bool
    singular: bool
    y: np.ndarray | None = None
    z: np.ndarray | None = None
    w: np.ndarray | None = None
    det: float | None = None
    rank: int | None = None
    continuum: bool = False

    @property
    def r(self) -> int:
        """1-based cone number in the usual order: (w1, w2), (w1, z2), (z1, w2), (z1, z2)."""
        return 1 + sum(1 << (self.n - 1 - j) for j in range(self.n) if (self.code >> j) & 1)

    @property
    def z_basic(self) -> list[int]:
        """0-based indices j with z_j basic."""
        return [j for j in range(self.n) if (self.code >> j) & 1]

    def basis_names(self) -> list[str]:
        """``["w1", "z2", ...]``: the complementary basic variables, 1-based."""
        return [("z" if (self.code >> j) & 1 else "w") + str(j + 1) for j in range(self.n)]

    def to_dict(self) -> dict[str, Any]:
        return {"r": self.r, "basis": self.basis_names(), "feasible": bool(self.feasible),
                "singular": bool(self.singular), "continuum": bool(self.continuum),
                "det": _jfloat(self.det), "rank": self.rank, "y": _jvec(self.y)}


@dataclass
class Solution:
    """A certified solution and the cones (codes) it was found in."""

    z: np.ndarray
    w: np.ndarray
    certificate: Certificate
    cones: list[int] = field(default_factory=list)
    continuum: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {"z": _jvec(self.z), "w": _jvec(self.w), "error": _jfloat(self.certificate.error),
                "residual": _jfloat(self.certificate.residual),
                "continuum": bool(self.continuum), "cones": len(self.cones)}


@dataclass
class Enumeration:
    """What :func:`enumerate_cones` found.

    ``verdict``: ``unique``, ``finite``, ``continuum``, ``none`` (no cone contains q) or
    ``found`` (``stop_at_first``: the rest not examined); ``incomplete`` / ``unknown`` when more
    than ``max_lp`` singular cones containing q would need an LP (solutions found / none found:
    nothing is proven then); ``uncertified`` when cones contain q but none of their points
    passes the certificate in the problem's units (extreme data).  Every solution listed passed
    :func:`lcpcli.core.certificate.certify` on the problem as given.  ``none`` is a floating-point
    search, not a proof: ``status`` is ``no_solution`` only with ``proof``, a Farkas vector that
    passed :func:`lcpcli.analysis.proof.check_farkas` (``unsolved`` without one).
    ``cones``: the feasible cones (all cones when asked for), in code order.
    """

    n: int
    verdict: str
    solutions: list[Solution]
    cones: list[Cone]
    examined: int
    total: int
    counts: dict[str, int]
    seconds: float
    complete: bool
    proof: Any = None
    #: Codes of nonsingular cones that contain q but whose point failed the certificate
    #: (at most :data:`MAX_RESCUES`; ``rescue_overflow``: more were met).
    rescue: list[int] = field(default_factory=list)
    rescue_overflow: bool = False

    @property
    def status(self) -> Status:
        if self.solutions:
            return Status.SOLVED
        if self.verdict == NONE and self.proof is not None:
            return Status.NO_SOLUTION
        return Status.UNSOLVED

    def to_dict(self) -> dict[str, Any]:
        return {"n": self.n, "status": self.status, "verdict": self.verdict,
                "cones": [c.to_dict() for c in self.cones],
                "solutions": [s.to_dict() for s in self.solutions],
                "examined": self.examined, "total": self.total, "counts": dict(self.counts),
                "complete": self.complete, "seconds": self.seconds,
                "farkas_y": None if self.proof is None else _jvec(self.proof.y)}


# ---------------------------------------------------------------------------- helpers
def _jfloat(x: Any) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if np.isfinite(x) else None


def _jvec(v: np.ndarray | None) -> list[float | None] | None:
    return None if v is None else [_jfloat(x) for x in np.asarray(v, dtype=float)]


def basis_names(code: int, n: int) -> list[str]:
    """1-based names of the complementary basic variables of cone ``code``."""
    return [("z" if (code >> j) & 1 else "w") + str(j + 1) for j in range(n)]


def complementary_matrix(M: np.ndarray, code: int) -> np.ndarray:
    """``A_r``: column ``I_j`` where ``w_j`` is basic, ``-M_j`` where ``z_j`` is basic."""
    n = M.shape[0]
    A = np.eye(n)
    for j in range(n):
        if (code >> j) & 1:
            A[:, j] = -M[:, j]
    return A


def check_problem(problem: Any, max_n: int = DEFAULT_MAX_N) -> np.ndarray:
    """The dense M of an LCP the method accepts; ProblemError/OptionError otherwise."""
    if problem.kind != "lcp":
        raise ProblemError(f"enumeration handles plain LCPs only, not {problem.kind.upper()} "
                           f"problems")
    try:
        max_n = int(max_n)
    except (TypeError, ValueError):
        raise OptionError(f"max-n must be an integer, got {max_n!r}") from None
    if max_n < 1 or max_n > HARD_MAX_N:
        raise OptionError(f"max-n must be between 1 and {HARD_MAX_N}, got {max_n}")
    n = problem.n
    if n > max_n:
        raise OptionError(f"n = {n} means {power_of_two(n)} complementary cones, above the "
                          f"limit max-n = {max_n} (2^{max_n} = {2**max_n:,}); raise it to run "
                          f"anyway (each extra variable doubles the time: 'lcpcli enumerate "
                          f"--max-n {n}', 'lcpcli solve -m enum -O max-n={n}', max_n={n} in "
                          f"Python), or use a pivoting method (-m lemke)")
    return np.ascontiguousarray(problem.dense_M(), dtype=np.float64)


def sign_masks(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bit masks of the strictly positive / strictly negative entries of each row of M."""
    n = M.shape[0]
    weights = np.left_shift(np.int64(1), np.arange(n, dtype=np.int64))
    pos = ((M > 0).astype(np.int64) * weights).sum(axis=1).astype(np.int64)
    neg = ((M < 0).astype(np.int64) * weights).sum(axis=1).astype(np.int64)
    return pos, neg


def solve_cone(M: np.ndarray, q: np.ndarray, code: int) -> tuple[np.ndarray, np.ndarray]:
    """(z, w) of a nonsingular cone, by LU with one step of iterative refinement, on the block
    equilibrated by powers of two as the kernel does (rows, then columns); NaN when the block
    is exactly singular after all (then the certificate rejects the point)."""
    n = q.shape[0]
    S = [j for j in range(n) if (code >> j) & 1]
    z = np.zeros(n)
    if S:
        with np.errstate(all="ignore"):  # inf or NaN here ends in a failed certificate
            z[S] = _solve_block(M[np.ix_(S, S)], q[S])
    with np.errstate(all="ignore"):
        w = M @ z + q
    w[S] = 0.0
    return z, w


def _solve_block(B: np.ndarray, qS: np.ndarray) -> np.ndarray:
    """``B^-1 (-qS)`` on ``B`` equilibrated by powers of two (rows, then columns), with one
    refinement step; NaN when ``B`` is exactly singular."""
    r = binary_exponents(np.max(np.abs(B), axis=1))
    Br = np.ldexp(B, -r[:, None])
    c = binary_exponents(np.max(np.abs(Br), axis=0))
    Bs = np.ldexp(Br, -c[None, :])
    rhs = np.ldexp(-qS, -r)
    try:
        ys = np.linalg.solve(Bs, rhs)
        ys = ys + np.linalg.solve(Bs, rhs - Bs @ ys)
    except np.linalg.LinAlgError:
        ys = np.full(qS.shape[0], np.nan)
    return np.ldexp(ys, -c)


def cone_y(code: int, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The basic values ``y_j`` (``z_j`` or ``w_j``) of cone ``code``."""
    n = z.shape[0]
    return np.array([z[j] if (code >> j) & 1 else w[j] for j in range(n)])


def singular_cone_lp(M: np.ndarray, q: np.ndarray, code: int,
                     seed: int = 0) -> tuple[np.ndarray | None, bool]:
    """For a singular cone: a point ``y >= 0`` with ``A_r y = q`` (or None) and whether the
    polyhedron of such points is more than one point (a continuum of LCP solutions)."""
    from scipy.optimize import linprog  # scipy is imported on first use (start-up budget)

    n = q.shape[0]
    A = complementary_matrix(M, code)
    res = linprog(np.zeros(n), A_eq=A, b_eq=q, bounds=[(0, None)] * n, method="highs")
    if res.status != 0:
        return None, False
    y0 = np.maximum(res.x, 0.0)
    c = np.random.default_rng(seed + code).standard_normal(n)
    lo = linprog(c, A_eq=A, b_eq=q, bounds=[(0, None)] * n, method="highs")
    hi = linprog(-c, A_eq=A, b_eq=q, bounds=[(0, None)] * n, method="highs")
    if lo.status == 3 or hi.status == 3:
        return y0, True
    if lo.status != 0 or hi.status != 0:
        return y0, False
    spread = float(np.max(np.abs(lo.x - hi.x)))
    scale = max(float(np.max(np.abs(y0))), 1e-300)
    return y0, spread > 1e-7 * scale


def _y_to_zw(M: np.ndarray, q: np.ndarray, code: int, y: np.ndarray) -> tuple[np.ndarray,
                                                                               np.ndarray]:
    n = q.shape[0]
    bits = np.array([(code >> j) & 1 for j in range(n)], dtype=bool)
    z = np.where(bits, y, 0.0)
    w = M @ z + q
    w[bits] = 0.0
    return z, w


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    scale = 1.0 + max(float(np.max(np.abs(a))), float(np.max(np.abs(b))))
    return bool(np.max(np.abs(a - b)) <= 1e-7 * scale)


# ---------------------------------------------------------------------------- engine
def enumerate_cones(problem: Any, *, stop_at_first: bool = False, all_cones: bool = False,
                    max_n: int = DEFAULT_MAX_N, tol: float = DEFAULT_TOL, rtol: float = RTOL,
                    progress: Callable[[int, int], None] | None = None,
                    chunk: int = 1 << 18, keep_cones: int = 100_000,
                    fast: bool = True, max_lp: int = MAX_LPS) -> Enumeration:
    """Visit the ``2^n`` complementary cones of ``problem`` (an LCP) and collect the solutions.

    The cones are examined on the equilibrated problem (:mod:`lcpcli.analysis.scaling`: Ruiz's,
    or Curtis and Reid's geometric scaling when Ruiz's leaves the entries more than
    ``2^GEOMETRIC_SPREAD`` apart): a positive row and column scaling maps every complementary
    cone onto the same cone, so the verdict does not depend on units, and nothing overflows
    (data of size 1e300 has determinants of size 1e300^n).  Solutions, ``y``, ``w`` and
    determinants are reported in the units of ``problem`` (a determinant beyond the double
    range is Inf).

    ``stop_at_first``: stop at the first certified solution (verdict ``found``).
    ``all_cones``: return every cone (with ``y``, ``det`` and ``rank``) instead of the feasible
    ones only; meant for small n (memory grows as 2^n n).
    ``progress(done, total)`` is called after each chunk of cones.  At most ``keep_cones``
    feasible cones are kept in ``cones`` (the counts stay exact).  ``fast``: use the
    depth-first principal-pivoting kernel (candidates re-checked by the direct LU kernel,
    unsafe pivots sent to it); ``fast=False`` uses the direct kernel for every cone.
    """
    check_problem(problem, max_n)
    if problem.n == 0:  # one cone, the empty basis, and z = () solves the problem
        return _empty_enumeration(problem, tol)
    if problem.n >= ENUM_ANNOUNCE_N:  # the work budget of lcpcli.core.limits: say the cost first
        announce(f"enumerating up to {power_of_two(problem.n)} complementary cones "
                 f"(each extra variable doubles the time; --max-n / -O max-n={max_n} allows it)")
    scaling = equilibrate(problem, symmetric=False)
    if spread(problem, scaling) > GEOMETRIC_SPREAD:  # Ruiz balanced the maxima only
        scaling = geometric(problem, False) or scaling
    work = scaling.apply(problem) if scaling is not None else problem
    found = _enumerate(work, stop_at_first=stop_at_first, all_cones=all_cones, max_n=max_n,
                       tol=tol, rtol=rtol, progress=progress, chunk=chunk,
                       keep_cones=keep_cones, fast=fast, max_lp=max_lp)
    if scaling is not None:
        _unscale(found, scaling, problem, tol)
    _rescue(found, problem, tol)
    # no cone holds q, or the cones that seemed to hold it in floating point hold no point
    # that passes the certificate (rows scaled 2^80, 2^270 and columns 2^-115, 2^-323 put q
    # "inside" two cones of an infeasible 2 x 2 problem): a Farkas vector that passes its
    # exact check decides
    if found.verdict == NONE or (not found.solutions and found.verdict in (UNCERTIFIED,
                                                                          UNKNOWN)):
        proof = search_proof(problem, scaling=scaling) if scaling is not None else \
            prove_infeasible(problem, search=True)
        if proof is not None:
            found.proof, found.verdict = proof, NONE
    return found


def _empty_enumeration(problem: Any, tol: float) -> Enumeration:
    """The enumeration of an LCP with n = 0: its one cone holds its one solution, z = ()."""
    z = np.zeros(0)
    cert = certify(problem, z, tol)
    cone = Cone(0, 0, True, False, y=z, z=z, w=z, det=1.0, rank=0)
    counts = {"feasible": 1, "singular": 0, "singular_with_q": 0, "pruned": 0,
              "uncertified": 0, "singular_unresolved": 0}
    return Enumeration(0, UNIQUE, [Solution(z, z.copy(), cert, [0])], [cone], 1, 1, counts,
                       0.0, True)


def _unscale(found: Enumeration, scaling: Scaling, problem: Any, tol: float) -> None:
    """Map an enumeration of the scaled problem back to the units of ``problem``, in place."""
    kept = []
    for sol in found.solutions:
        with np.errstate(over="ignore", under="ignore"):
            sol.z = scaling.unscale_z(sol.z)
            sol.w = scaling.unscale_w(sol.w)
        sol.certificate = certify(problem, sol.z, tol)
        if sol.certificate.passed:  # rounding to the problem's units may lose it (extreme data)
            kept.append(sol)
        else:
            found.counts["uncertified"] += 1
            _note_rescue(found, sol.cones[0])
    if len(kept) < len(found.solutions):
        found.solutions = kept
        if not kept:
            found.verdict = UNCERTIFIED
        elif found.verdict in (UNIQUE, FINITE):
            found.verdict = UNIQUE if len(kept) == 1 else FINITE
    shift = scaling.row + scaling.col   # det A_r = det A~_r * 2^-(sum over z-basic of r_j + c_j)
    for cone in found.cones:
        zb = np.array([(cone.code >> j) & 1 for j in range(cone.n)], dtype=bool)
        if cone.z is not None:
            cone.z = scaling.unscale_z(cone.z)
        if cone.w is not None:
            cone.w = scaling.unscale_w(cone.w)
        if cone.y is not None:
            cone.y = np.where(zb, scaling.unscale_z(cone.y), scaling.unscale_w(cone.y))
        if cone.det is not None:
            with np.errstate(over="ignore"):
                cone.det = float(np.ldexp(cone.det, -int(shift[zb].sum())))


def _note_rescue(found: Enumeration, code: int) -> None:
    """Remember cone ``code`` for :func:`_rescue` (up to :data:`MAX_RESCUES` cones)."""
    if len(found.rescue) < MAX_RESCUES:
        found.rescue.append(code)
    else:
        found.rescue_overflow = True


def _rescue(found: Enumeration, problem: Any, tol: float) -> None:
    """Solve again, on the data as given, the nonsingular cones that contain q but whose point
    failed the certificate on the equilibrated problem, and keep the points that pass it.

    The equilibration that makes the cone search independent of units can push a component
    of the solution into the subnormal range, where it keeps few digits (a P-matrix with rows
    scaled 2^-980 .. 2^978 whose solution has ``z_2 = 1.7e-311``): the same cone solved in
    the problem's own units (each block equilibrated by itself, :func:`solve_cone`) may hold
    the digits.  Only certified points are added, so nothing uncertified is ever reported;
    the verdict counts them as if found by the search."""
    if not found.rescue:
        return
    M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    added = 0
    for code in found.rescue:
        with np.errstate(all="ignore"):
            z, w = solve_cone(M, q, code)
        if any(_same(sol.z, z) for sol in found.solutions if np.all(np.isfinite(z))):
            continue
        cert = certify(problem, z, tol)
        if not cert.passed:
            continue
        found.solutions.append(Solution(z, w, cert, [code]))
        cone = Cone(code, found.n, True, False, cone_y(code, z, w), z, w)
        listed = [i for i, c in enumerate(found.cones) if c.code == code]  # all_cones lists it
        if listed:
            cone.det, cone.rank = found.cones[listed[0]].det, found.cones[listed[0]].rank
            found.cones[listed[0]] = cone
        else:
            found.cones.append(cone)
        found.counts["uncertified"] -= 1
        found.counts["feasible"] += 1
        added += 1
    found.rescue = []
    if not added:
        return
    found.cones.sort(key=lambda c: c.r)
    if found.verdict in (UNCERTIFIED, UNIQUE, FINITE):
        found.verdict = (INCOMPLETE if found.rescue_overflow else
                         UNIQUE if len(found.solutions) == 1 else FINITE)
    elif found.verdict == UNKNOWN:
        found.verdict = INCOMPLETE


def _enumerate(problem: Any, *, stop_at_first: bool, all_cones: bool, max_n: int, tol: float,
               rtol: float, progress: Callable[[int, int], None] | None, chunk: int,
               keep_cones: int, fast: bool, max_lp: int) -> Enumeration:
    """:func:`enumerate_cones` on a problem in its own units (the caller scales)."""
    M = check_problem(problem, max_n)
    q = np.ascontiguousarray(problem.q, dtype=np.float64)
    n = q.shape[0]
    total = 1 << n
    mu = matrix_norm_inf(M)
    mu = mu if mu > 0 else 1.0
    qnorm = float(np.max(np.abs(q)))
    piv_tol = PIVOT_RTOL * n  # relative to each block, equilibrated in the kernel
    prune_tol = rtol * qnorm
    pos, neg = sign_masks(M)
    start_time = time.perf_counter()

    solutions: list[Solution] = []
    feasible_cones: list[Cone] = []
    counts = {"feasible": 0, "singular": 0, "singular_with_q": 0, "pruned": 0,
              "uncertified": 0, "singular_unresolved": 0}
    lps = 0
    uncertified: list[int] = []
    continuum_seen = False
    done = 0
    size = min(FIRST_CHUNK, total) if stop_at_first else min(chunk, total)
    stopped = False
    while done < total and not stopped:
        count = min(size, total - done)
        status = np.empty(count, dtype=np.uint8)
        aligned = count & (count - 1) == 0 and done % count == 0
        if fast and aligned and n >= FAST_MIN_N:
            classify_chunk_fast(M, q, done, count, pos, neg, piv_tol, rtol, mu, qnorm,
                                prune_tol, status)
            one = np.empty(1, dtype=np.uint8)
            for t in np.flatnonzero(status == CANDIDATE):  # the direct path decides
                classify_chunk(M, q, done + int(t), 1, pos, neg, piv_tol, rtol, mu, qnorm,
                               prune_tol, one)
                status[t] = one[0]
        else:
            classify_chunk(M, q, done, count, pos, neg, piv_tol, rtol, mu, qnorm, prune_tol,
                           status)
        counts["pruned"] += int(np.count_nonzero(status == PRUNED))
        counts["singular"] += int(np.count_nonzero((status == SINGULAR_CONSISTENT)
                                                   | (status == SINGULAR_EMPTY)))
        for t in np.flatnonzero((status == FEASIBLE) | (status == SINGULAR_CONSISTENT)):
            code = done + int(t)
            if status[t] == FEASIBLE:
                z, w = solve_cone(M, q, code)
                cone = Cone(code, n, True, False, cone_y(code, z, w), z, w)
                continuum = False
            else:
                # once a continuum is known the verdict cannot change: skip further LPs
                if continuum_seen or lps >= max_lp:
                    counts["singular_unresolved"] += 1
                    continue
                lps += 1
                y, continuum = singular_cone_lp(M, q, code)
                continuum_seen = continuum_seen or continuum
                if y is None:
                    continue
                z, w = _y_to_zw(M, q, code, y)
                cone = Cone(code, n, True, True, y, z, w, continuum=continuum)
                counts["singular_with_q"] += 1
            for sol in solutions:
                if _same(sol.z, z):
                    sol.cones.append(code)
                    sol.continuum = sol.continuum or continuum
                    break
            else:
                cert = certify(problem, z, tol)
                if not cert.passed:
                    counts["uncertified"] += 1
                    if status[t] == FEASIBLE:
                        uncertified.append(code)
                    continue
                with np.errstate(over="ignore", invalid="ignore"):  # w in the problem's units
                    w_user = M @ z + q  # may pass float64's range where the certificate's
                    # row scaling does not (the certificate passed: z is an answer)
                solutions.append(Solution(z, w_user, cert, [code], continuum))
            counts["feasible"] += 1
            if len(feasible_cones) < keep_cones:
                feasible_cones.append(cone)
            if stop_at_first:
                stopped = True
                done = code + 1
                break
        if not stopped:
            done += count
        if progress is not None:
            progress(done, total)
        if stop_at_first:
            size = min(done, chunk, total - done) if done >= FIRST_CHUNK else size  # aligned

    if stopped:
        verdict = FOUND
    elif any(s.continuum for s in solutions):
        verdict = CONTINUUM
    elif counts["singular_unresolved"]:
        verdict = INCOMPLETE if solutions else UNKNOWN
    elif not solutions and counts["uncertified"]:
        verdict = UNCERTIFIED
    elif not solutions:
        verdict = NONE
    elif len(solutions) == 1:
        verdict = UNIQUE
    else:
        verdict = FINITE
    seconds = time.perf_counter() - start_time
    cones = all_cone_details(M, q, feasible_cones) if all_cones else _add_det(M, feasible_cones)
    cones.sort(key=lambda c: c.r)
    found = Enumeration(n=n, verdict=verdict, solutions=solutions, cones=cones, examined=done,
                        total=total, counts=counts, seconds=seconds, complete=not stopped)
    for code in uncertified:
        _note_rescue(found, code)
    return found


def _add_det(M: np.ndarray, cones: list[Cone]) -> list[Cone]:
    for c in cones:
        A = complementary_matrix(M, c.code)
        with np.errstate(all="ignore"):
            c.det = float(np.linalg.det(A))  # past the float64 range: +-inf (or 0, nan)
            c.rank = int(np.linalg.matrix_rank(A))
    return cones


def all_cone_details(M: np.ndarray, q: np.ndarray, feasible: list[Cone]) -> list[Cone]:
    """Every cone in code order: det, rank, and ``y = A_r^-1 q`` for the nonsingular ones
    (negative entries mean q is outside the cone); the feasible ones as found."""
    n = q.shape[0]
    found = {c.code: c for c in feasible}
    out: list[Cone] = []
    block = 1 << 12
    for lo in range(0, 1 << n, block):
        codes = np.arange(lo, min(lo + block, 1 << n), dtype=np.int64)
        bits = ((codes[:, None] >> np.arange(n)) & 1).astype(bool)  # (B, n)
        A = np.where(bits[:, None, :], -M[None, :, :], np.eye(n)[None, :, :])
        with np.errstate(all="ignore"):
            dets = np.linalg.det(A)  # past the float64 range: +-inf
            ranks = np.linalg.matrix_rank(A)
        for t, code in enumerate(codes.tolist()):
            if code in found:
                c = found[code]
                c.det, c.rank = float(dets[t]), int(ranks[t])
                out.append(c)
                continue
            singular = bool(ranks[t] < n)
            y = None if singular else np.linalg.solve(A[t], q)
            out.append(Cone(code, n, False, singular, y, det=float(dets[t]),
                            rank=int(ranks[t])))
    return out


# ---------------------------------------------------------------------------- n = 2 geometry
def generators_2d(M: np.ndarray) -> dict[str, np.ndarray]:
    """The four complementary columns of a 2 x 2 problem: I_1, I_2, -M_1, -M_2 by name."""
    return {"w1": np.array([1.0, 0.0]), "w2": np.array([0.0, 1.0]),
            "z1": -np.asarray(M[:, 0], dtype=float), "z2": -np.asarray(M[:, 1], dtype=float)}


def _unit(v: np.ndarray) -> np.ndarray:
    """``v`` scaled to unit largest entry (a zero vector stays zero)."""
    peak = float(np.max(np.abs(v)))
    return v / peak if peak > 0 else v


def direction_2d(v: Any) -> np.ndarray | None:
    """The unit-length direction of the 2-vector ``v`` (None for zero or non-finite), without
    overflow (:func:`lcpcli.core.numeric.unit_rows`)."""
    v = np.asarray(v, dtype=float)
    if not np.all(np.isfinite(v)) or not np.any(v):
        return None
    return unit_rows(v[None, :])[0][0]


def length_2d(v: Any) -> float:
    """The length of the 2-vector ``v`` (inf past the float64 range, with no warning)."""
    v = np.asarray(v, dtype=float)
    peak = float(np.max(np.abs(v)))
    if not (0.0 < peak < np.inf):
        return peak
    return float(unit_rows(v[None, :])[1][0])


def unit_columns_2d(A: np.ndarray) -> np.ndarray:
    """The 2 x 2 ``A`` with each column scaled to unit largest entry: cone membership does not
    change when a generator is scaled by a positive factor, so the tests on the result are
    relative and nothing overflows (columns of size 1e300)."""
    return np.column_stack([_unit(np.asarray(A[:, j], dtype=float)) for j in range(2)])


def degenerate_2d(A: np.ndarray) -> bool:
    """Whether the cone ``Pos(A)`` of a 2 x 2 ``A`` is degenerate (a ray, a line or a
    half-plane, no interior of its own): ``|det|`` of the unit columns at most
    :data:`CONE_2D_TOL` (a zero column included)."""
    U = unit_columns_2d(A)
    return not abs(U[0, 0] * U[1, 1] - U[0, 1] * U[1, 0]) > CONE_2D_TOL


def in_cone_2d(A: np.ndarray, x: np.ndarray, rtol: float = CONE_2D_TOL) -> bool:
    """Whether ``x`` is in ``Pos(A)`` for a 2 x 2 ``A`` (degenerate A: rays / a line).

    Membership does not change when a column of ``A`` or ``x`` is scaled by a positive factor,
    so each is normalised to unit largest entry first (:func:`unit_columns_2d`).
    """
    A = unit_columns_2d(A)
    x = _unit(np.asarray(x, dtype=float))
    if not degenerate_2d(A):
        y = np.linalg.solve(A, x)
        return bool(np.all(y >= -rtol * max(1.0, float(np.max(np.abs(y))))))
    for j in range(2):  # degenerate: x must be a nonnegative multiple of a column
        a = A[:, j]
        if np.max(np.abs(a)) == 0:
            continue
        cross = a[0] * x[1] - a[1] * x[0]
        if abs(cross) <= CONE_2D_TOL and a @ x >= 0:
            return True
    return bool(np.max(np.abs(x)) == 0)


def cone_interiors_2d(M: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(4, P) booleans for a 2 x 2 ``M`` and points ``pts`` (2, P): row ``code`` says which
    points lie strictly inside the complementary cone ``Pos(A_code)`` (every coordinate above
    :data:`CONE_2D_TOL` on the unit columns); a degenerate cone (:func:`degenerate_2d`) holds
    none.  The regions that ``lcpcli enumerate`` draws for n = 2."""
    pts = np.asarray(pts, dtype=float)
    out = np.zeros((4, pts.shape[1]), dtype=bool)
    for code in range(4):
        A = complementary_matrix(np.asarray(M, dtype=float), code)
        if degenerate_2d(A):
            continue
        out[code] = np.all(np.linalg.solve(unit_columns_2d(A), pts) > CONE_2D_TOL, axis=0)
    return out


def covers_plane(M: Any) -> bool:
    """For n = 2: whether K(M), the union of the four complementary cones, is all of R^2.

    Independent of q.  Exact test: the cones are closed, so they cover the plane iff they
    cover the direction halfway between each pair of consecutive generator directions.
    """
    M = np.asarray(M, dtype=float)
    if M.shape != (2, 2):
        raise ValueError("covers_plane needs a 2 x 2 matrix")
    gens = generators_2d(M)
    angles = sorted({float(np.arctan2(v[1], v[0])) % (2 * np.pi)
                     for v in gens.values() if np.max(np.abs(v)) > 0})
    mats = [complementary_matrix(M, code) for code in range(4)]
    for i, a in enumerate(angles):
        b = angles[(i + 1) % len(angles)] + (2 * np.pi if i + 1 == len(angles) else 0.0)
        mid = 0.5 * (a + b) if b > a else a + np.pi
        x = np.array([np.cos(mid), np.sin(mid)])
        if not any(in_cone_2d(A, x) for A in mats):
            return False
    return True
