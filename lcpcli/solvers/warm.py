"""Warm starts from a basis: the final basis of a previous solve starts the next one.

Conventions: ``w = M z + q``; a *basis* is each pair's state, the int8 codes of
:mod:`lcpcli.core.certificate` (``AT_LOWER`` 0: ``z_i`` at its lower bound, ``w_i`` basic;
``AT_UPPER`` 1: at its upper bound; ``BETWEEN`` 2: ``z_i`` basic, ``w_i = 0``).  Every
:class:`~lcpcli.core.result.Result` carries the basis of its ``z`` as the certificate scored it
(:func:`lcpcli.api.certify_outcome`), so one definition serves every method: ``z_i`` off its
bounds is basic; at a degenerate pair (``z_i`` and ``w_i`` both zero) the certificate's cheaper
state wins.

A warm start (:func:`warm_start`, ``lcpcli.solve(p, warm=...)``, ``lcpcli solve --z0 FILE``)
takes a previous :class:`Result`, a basis (booleans, True: ``z_i`` basic, or letters such as
``"FLLF"``), or a point ``z0`` (its basis is that of ``z0`` and ``w0 = M z0 + q``).  For an
LCP or MLCP with a dense M it runs block principal pivoting (:mod:`lcpcli.solvers.methods.bpp`)
from that basis: when the basis is still right, its basic solution is the answer after one
factorisation; when a few pairs changed, block pivots fix them in a few more.  For a box LCP
or a sparse M (never densified here) the basic solution of the basis (``z`` at the bounds of
the ``L``/``U`` pairs, the ``F`` rows solved, sparse LU for a sparse M) is tried.  A method
that declares a ``basis`` option (Murty's least-index method, Dantzig's principal pivoting)
runs from the basis itself instead, on an LCP (:func:`takes_basis`).  An answer
counts only when it passes the certificate; otherwise (a wrong basis on a matrix outside BPP's
class, a singular block) the caller solves the problem cold, so a warm start never gives a
worse verdict than a cold one, and never ``no_solution``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from lcpcli.core.certificate import AT_LOWER, AT_UPPER, BETWEEN, check
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.numeric import real_array
from lcpcli.core.result import BASIS_LETTERS, CONVERGED, Outcome, Result
from lcpcli.core.text import plural
from lcpcli.solvers.methods import bpp, lemke_warm
from lcpcli.solvers.registry import Cost, Method
from lcpcli.solvers.support import _solve_active_set, start_point

#: Below this n a warm start does not pivot from the basis (unless the method asked for is
#: bpp): the compiled cold kernels are faster there than one BPP iteration in Python
#: (benchmarks/bench_warm.py: at n = 100 a warm BPP step took about 2x a cold solve).
WARM_MIN_N = 200


#: BPP iterations a warm start may take before the cold solve takes over (a nearby basis ends
#: in a few; outside BPP's class the method may take its full limit, O(n^3) each).
WARM_MAX_ITER = 20


def takes_basis(spec: Method, problem: Any, options: Mapping[str, Any] | None = None) -> bool:
    """Does ``spec`` start from the warm start's basis itself?  The one rule: a method that
    declares a ``basis`` option gets the basis, as its ``basis`` (``murty``, ``dantzig``: their
    own pivots from that index set), on an LCP (an index set of basic z's is an LCP's basis; a
    box LCP's has three states); ``bpp``, which declares one too, gets it through
    :func:`warm_start` (its factors kept for the next step).  Not for a traced run (the trace
    shows the run from ``z0`` or z = 0, as before); a ``basis`` in ``options`` is the one the
    method starts from."""
    return (spec.name != "bpp" and "basis" in spec.options and problem.kind == "lcp"
            and not (options or {}).get("trace"))


def uses_warm_basis(spec: Method, problem: Any,
                    options: Mapping[str, Any] | None = None) -> bool:
    """Does a warm start try BPP (or warm Lemke) from the basis before running ``spec`` cold?
    For ``bpp``, and for ``auto`` and the pivoting methods that do not start from the basis
    themselves (:func:`takes_basis`) from n = :data:`WARM_MIN_N` on; iterative methods take the
    warm ``z0`` instead."""
    if spec.name == "bpp":
        return True
    if takes_basis(spec, problem, options):
        return False
    return (spec.planner or spec.cost == Cost.PIVOTING) and problem.n >= WARM_MIN_N


def check_warm(problem: Any, warm: Any) -> None:
    """OptionError unless ``warm`` (a Result, a basis or a point) has one entry per pair, a
    basis's letters are those of :data:`BASIS_LETTERS` and a point holds real numbers only (the
    data rule of :func:`lcpcli.core.numeric.real_array`), whatever the method does with it."""
    if isinstance(warm, str):
        _check_letters(warm)
    elif warm_point_given(warm):
        try:
            real_array(warm, "warm start z0")
        except ProblemError as exc:
            raise OptionError(str(exc)) from None
    size = warm.n if isinstance(warm, Result) else len(warm) if isinstance(warm, str) \
        else np.size(warm)
    if size != problem.n:
        what = "z0" if warm_point_given(warm) else "basis" if not isinstance(warm, Result) \
            else "result"
        raise OptionError(f"warm start {what} has length {size}, the problem has n = "
                          f"{problem.n}")


def _check_letters(basis: str) -> None:
    """OptionError unless every letter of ``basis`` is one of :data:`BASIS_LETTERS`."""
    unknown = set(basis) - set(BASIS_LETTERS)
    if unknown:
        raise OptionError(f"a basis is one letter per pair from {BASIS_LETTERS!r}, got "
                          f"{''.join(sorted(unknown))!r}")


def warm_point_given(warm: Any) -> bool:
    """Is ``warm`` a point ``z0`` (numbers), not a Result or a basis?"""
    return not isinstance(warm, (Result, str)) and np.asarray(warm).dtype.kind != "b"


def warm_point(problem: Any, warm: Any) -> np.ndarray | None:
    """The ``z0`` of a warm start (a Result's z, or the point given), or None for a basis."""
    if isinstance(warm, Result):
        return start_point(problem, warm.z)
    if isinstance(warm, str):
        return None
    arr = np.asarray(warm)
    if arr.dtype.kind == "b":
        return None
    return start_point(problem, arr)


def warm_basis(problem: Any, warm: Any) -> np.ndarray:
    """The basis (int8 state codes) of a warm start, made valid for ``problem`` (free MLCP
    variables basic; a pair never at an infinite bound).  OptionError on a length mismatch or
    an unknown letter."""
    n = problem.n
    if isinstance(warm, Result) and warm.basis is not None:
        states = np.asarray(warm.basis, dtype=np.int8)
    elif isinstance(warm, str):
        _check_letters(warm)
        states = np.array([BASIS_LETTERS.index(c) for c in warm], dtype=np.int8)
    elif not isinstance(warm, Result) and np.asarray(warm).dtype.kind == "b":
        states = np.where(np.asarray(warm).ravel(), BETWEEN, AT_LOWER).astype(np.int8)
    else:
        z0 = warm_point(problem, warm)
        states = np.empty(n, dtype=np.int8)
        check(problem, z0, state=states)
        return states
    if states.shape != (n,):
        raise OptionError(f"warm-start basis has length {states.size}, the problem has n = {n}")
    lo, up = problem.bounds()
    states = states.copy()
    states[(states == AT_LOWER) & ~np.isfinite(lo)] = AT_UPPER
    mask = (states == AT_UPPER) & ~np.isfinite(up)
    states[mask] = np.where(np.isfinite(lo[mask]), AT_LOWER, BETWEEN)
    states[:problem.n_eq] = BETWEEN
    return states


def warm_start(problem: Any, warm: Any, tol: float,
               method: str = "bpp") -> tuple[Outcome | None, str]:
    """Solve ``problem`` from the basis of ``warm`` (see the module docstring) with the
    warm-startable ``method``'s pivoting (``lemke*``: Lemke from the basis,
    :mod:`lcpcli.solvers.methods.lemke_warm`, for a dense LCP; otherwise BPP).

    Returns ``(outcome, note)``: an :class:`Outcome` that says it converged (the caller
    certifies it, and solves cold if it fails; ``info["method"]`` names what ran), or None and
    why the warm start ended without an answer.  Never a claim of infeasibility.
    """
    states = warm_basis(problem, warm)
    F = states == BETWEEN
    factors = warm.factors.fork() if isinstance(warm, Result) and warm.factors is not None \
        else None  # the Result's own stay as they are: the same answer for every later use
    if method.startswith("lemke") and problem.kind == "lcp" and not problem.sparse:
        M = np.ascontiguousarray(problem.dense_M(), dtype=np.float64)
        q = np.ascontiguousarray(problem.q, dtype=np.float64)
        out = lemke_warm.run(M, q, F, blocks=factors, problem=problem)
        if out.termination != CONVERGED:
            return None, out.message
        out.message = f"warm start: {out.message}"
        out.info.update(warm=True, method=method)
        return out, ""
    if problem.kind in ("lcp", "mlcp") and not problem.sparse:
        out = bpp.run(problem, tol=tol, basis=F, blocks=factors, keep_blocks=True,
                      max_iter=WARM_MAX_ITER)
        if out.termination != CONVERGED:
            return None, out.message
        final = np.zeros(problem.n, dtype=bool)
        final[out.info["basis"]] = True
        changed = int(np.count_nonzero(final != F))
        out.message = (f"warm start: {out.message} ({plural(changed, 'pair')} of "
                       f"{problem.n} changed state)")
        out.info["warm"] = True
        return out, ""
    lo, up = problem.bounds()
    z = _solve_active_set(problem, np.zeros(problem.n), states, lo, up)
    if z is None:
        return None, "the warm basis's block is singular"
    return Outcome(z, 1, CONVERGED, "warm start: the basic solution of the given basis "
                                    "(1 factorisation)", info={"warm": True}), ""
