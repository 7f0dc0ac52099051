"""The certificate of a candidate solution: the project's one definition of ``error``.

Every solver's answer goes through :func:`certify`; nothing is called ``solved`` otherwise.

Conventions: ``w = M z + q``; variable ``i`` lives in the box ``[l_i, u_i]`` of
:meth:`Problem.bounds` (LCP ``[0, inf)``; free MLCP variables ``(-inf, inf)``); the pair
``(z_i, w_i)`` is *complementary* when one of its states holds:

* ``L``: ``z_i = l_i`` and ``w_i >= 0`` (``l_i`` finite);
* ``U``: ``z_i = u_i`` and ``w_i <= 0`` (``u_i`` finite);
* ``F``: ``l_i <= z_i <= u_i`` and ``w_i = 0``.

**Row scale.**  Row ``i`` of ``w`` is judged against its own scale (Oettli and Prager, 1964; Higham,
*Accuracy and Stability of Numerical Algorithms*, 2nd ed., sections 7.1-7.2)::

    s_i = |q_i| + (|M| |z|)_i

A change of ``w_i`` by ``v`` is a relative change ``v / s_i`` of the row: the smallest relative
perturbation of the entries of row ``i`` of ``M`` and of ``q_i`` that absorbs it.

**Moves of z.**  A variable ``z_j`` that must move by ``x`` to reach a state (to its bound, or back
into its box) is judged by what the move does to ``w``: ``x kappa_j`` with
``kappa_j = max_i |M_ij| / s_i`` (an all-zero column has ``kappa_j = inf``: moving such a
``z_j`` changes nothing, so it must already sit where its state says).  A ``z_j`` is "zero" when
setting it to zero changes every row of ``w`` by a negligible fraction of that row, never by
comparison with the largest entry of the problem.

**Backward error of a pair.**  ``eps_i`` is the smallest, over the states of pair ``i``, of the
largest relative change that state needs (the move of ``z_i`` and the change of ``w_i``).  The
componentwise backward error is ``omega = max_i eps_i``.

**Growth.** A backward error says that ``z`` solves a nearby problem; that is worth little when the
rows balance only through the cancellation of huge terms, because then the nearby problem can be
qualitatively different (an infeasible positive semidefinite LCP is "solved" to any backward error
by a large enough ``z``). Row ``i`` has growth ``g_i = (|M| |z|)_i / (|q_i| + |w_i|)``. The size of
``z`` is fixed by the *equations*, the pairs scored in state ``F``. Rows are linked through ``z_j
!= 0`` wherever ``z_j`` counts in them (``|M_ij| / s_i >= 2^-10 kappa_j``, a share within ``2^-10``
of ``z_j``'s largest); linked rows form blocks, and a block's growth ``G`` is the smallest ``g_i``
among its equations with data, ``q_i != 0`` (one equation whose terms do not cancel anchors the
size of the ``z`` it shares; legitimate exact cancellation, such as MLCP equality chains or
friction-cone rows, is then fine; inactive rows cannot vouch for a size; an equation with ``q_i =
0`` fixes no size either: its ``g_i`` would be ``a_i / |w_i|``, rounding over rounding, and the
verdict would depend on the order in which ``w_i`` was summed). In a block whose equations carry no
data, a row with ``q_i != 0`` answers for its own growth; rows untouched by ``z`` have ``G = 1``.

**The certificate.**  ::

    error = max_i  eps_i * max(1, G_block(i))

``solved`` requires ``error <= tol`` and every number finite.  ``error`` is invariant (up to
rounding) under positive row scaling ``(D M, D q)``, column scaling ``(M D, z -> D^-1 z)`` and
global scaling of the data, because every quantity above is a ratio within a row or a product
``|M_ij z_j|``.  It cannot be passed by making ``z`` large: a large ``z`` raises ``s_i`` only with
the growth of its block.  Overflow cannot crash it: data whose products leave ``[2^-960, 2^960]``
are rescaled exactly by powers of two before the check (which does not change the result), and
so is a row whose every term ``M_ij z_j`` underflows to zero (its ``w_i`` and ``s_i`` would read
0); any Inf or NaN in ``z`` or ``w`` means not solved.

The certificate also reports, in the units of the data: ``residual`` ``= ||mid(z - l, z - u,
w)||_inf`` (``||min(z, w)||_inf`` for the LCP), ``bound_violation``, ``w_violation``,
``complementarity`` and ``equality_residual`` (MLCP rows); and ``backward_error`` (omega),
``growth`` (the growth of the block that decides ``error``) and ``worst`` (the pair that does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.core import _certificate
from lcpcli.core.errors import OptionError
from lcpcli.core.numeric import binary_exponents

#: Default tolerance on :attr:`Certificate.error` for the verdict ``solved``.
DEFAULT_TOL = 1e-8
#: The range a tolerance must lie in: below 1e-16 nothing computed in double precision can pass
#: (rounding alone is about 1e-16); above 1e-2 the verdict would certify answers off by percents.
MIN_TOL = 1e-16
MAX_TOL = 1e-2


@dataclass(slots=True)
class Certificate:
    """The checked numbers of a candidate solution (definitions in the module docstring)."""

    error: float
    backward_error: float
    growth: float
    residual: float
    bound_violation: float
    w_violation: float
    complementarity: float
    equality_residual: float
    worst: int
    tol: float
    passed: bool

    def as_dict(self) -> dict[str, Any]:
        # the fields by name (dataclasses.asdict deep-copies each value: 50 us per row)
        return {name: getattr(self, name) for name in self.__slots__}


def validate_tol(tol: Any) -> float:
    """``tol`` as a float in ``[MIN_TOL, MAX_TOL]``; :class:`OptionError` otherwise."""
    if type(tol) is float and MIN_TOL <= tol <= MAX_TOL:  # the usual case, in one step
        return tol
    try:
        value = float(tol)
    except (TypeError, ValueError):
        raise OptionError(f"tolerance must be a number, got {tol!r}") from None
    if not (MIN_TOL <= value <= MAX_TOL):  # also refuses NaN
        raise OptionError(f"tolerance must lie in [{MIN_TOL:g}, {MAX_TOL:g}] (the certificate's "
                          f"error is relative: 1e-16 is rounding level, 1e-2 is a 1% error), "
                          f"got {tol}")
    return value


#: The state of a pair that its score came from (:func:`pair_states`).
AT_LOWER, AT_UPPER, BETWEEN = 0, 1, 2
#: The "state" of every pair when none was scored (``z`` or ``w`` not finite): no basis.
NO_STATE = -1


def scored(state: np.ndarray) -> np.ndarray | None:
    """``state`` as :func:`check` filled it, or None when it scored no pair (``NO_STATE``)."""
    return None if state.size and state[0] == NO_STATE else state


def check(problem: Any, z: Any, tol: float = DEFAULT_TOL, *,
          state: np.ndarray | None = None) -> tuple[Certificate, np.ndarray]:
    """Certify ``z`` for ``problem``; return the certificate and ``w = M z + q`` (recomputed).

    ``passed`` is true when every number is finite and ``error <= tol``.  ``state`` (int8,
    length n), when given, receives each pair's state (``AT_LOWER``, ``AT_UPPER``, ``BETWEEN``),
    or ``NO_STATE`` in every entry when no pair could be scored (a ``z_j`` not finite).
    """
    if not (type(z) is np.ndarray and z.dtype == np.float64 and z.ndim == 1
            and z.flags.c_contiguous):
        z = np.ascontiguousarray(z, dtype=np.float64).ravel()
    n = problem.n
    if z.shape[0] != n:
        raise ValueError(f"z has length {z.shape[0]}, the problem has n = {n}")
    w = np.empty(n)
    lo, up = (problem.lower, problem.upper) if problem.lower is not None else (None, None)
    out = _certificate.certify_arrays(_matrix_arg(problem.M), _contiguous(problem.q), z,
                                      problem.n_eq, lo, up, w, state)
    if out[0] == 2:
        out, w = _rescaled_check(problem, z, state)
    if out[0] == 1 and not np.all(np.isfinite(z)):
        # a z_j not finite: seen first, or only on the rescaled copy when other entries of z
        # took the rescaled path (z = (4e306, 5e307, inf)), which left w and state unwritten
        _unscored(problem, z, w, state)
    return from_kernel(out, tol), w


def _unscored(problem: Any, z: np.ndarray, w: np.ndarray, state: np.ndarray | None) -> None:
    """The kernel's status 1: a ``z_j`` not finite, seen before anything was computed, so
    ``w`` and ``state`` are as the caller left them.  ``w`` becomes ``M z + q`` with the terms
    of the stored nonzeros only (as a sparse product: ``0 * inf`` is no term, so the rows that
    do not touch a non-finite ``z_j`` keep their value), ``state`` ``NO_STATE`` throughout."""
    M = problem.M
    bad = np.flatnonzero(~np.isfinite(z))
    with np.errstate(all="ignore"):
        if hasattr(M, "tocsr"):
            w[:] = np.asarray(M @ z).ravel() + problem.q
        else:
            w[:] = M @ np.where(np.isfinite(z), z, 0.0) + problem.q
            for j in bad.tolist():
                col = M[:, j]
                w += np.where(col != 0.0, col * z[j], 0.0)
    if state is not None:
        state.fill(NO_STATE)


def certify(problem: Any, z: Any, tol: float = DEFAULT_TOL) -> Certificate:
    """The :class:`Certificate` of ``z`` for ``problem`` (see :func:`check`)."""
    return check(problem, z, tol)[0]


def matrix_norm_inf(M: Any) -> float:
    """``||M||_inf`` (max absolute row sum) of a dense array or a scipy.sparse matrix, summed
    after an exact power-of-two scaling so that no partial sum overflows; a norm beyond the
    largest double (e.g. a row ``[1e308, 1e308]``) is returned as that largest double, never
    Inf, so callers may divide by it and compare with it."""
    if hasattr(M, "tocsr"):
        data = np.abs(M.data)
        if data.size == 0:
            return 0.0
        peak = float(data.max())
        if peak == 0.0:
            return 0.0
        e = _pow2_exponent(peak)
        # trailing empty rows start at nnz, which reduceat refuses: clip (empty rows are zeroed)
        starts = np.minimum(M.indptr[:-1], data.size - 1)
        rows = np.add.reduceat(np.ldexp(data, -e), starts)
        rows[np.diff(M.indptr) == 0] = 0.0
        return _times_pow2(float(rows.max()), e)
    if M.size == 0:
        return 0.0
    peak = float(np.max(np.abs(M)))
    if peak == 0.0:
        return 0.0
    e = _pow2_exponent(peak)
    return _times_pow2(float(np.max(np.sum(np.ldexp(np.abs(M), -e), axis=1))), e)


# ---------------------------------------------------------------------- internals
def _matrix_arg(M: Any) -> Any:
    if hasattr(M, "tocsr"):
        Mc = M if M.format == "csr" else M.tocsr()
        return (_contiguous(Mc.data), Mc.indices, Mc.indptr)
    return _contiguous(M)


def _contiguous(a: Any) -> np.ndarray:
    """``a`` as a C-contiguous float64 array (no copy when it is one already)."""
    if type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous:
        return a
    return np.ascontiguousarray(a, dtype=np.float64)


def from_kernel(out: tuple, tol: float) -> Certificate:
    """The :class:`Certificate` of a compiled certify call's tuple (``certify_arrays``, or a
    kernel that certifies inside its own call with ``certify_dense``): its numbers are Python
    floats and an int already, taken as they are (this is on the small-solve path)."""
    return certificate_of(*out, tol)


def certificate_of(status: int, error: float, backward_error: float, growth: float,
                   residual: float, bound_violation: float, w_violation: float,
                   complementarity: float, equality_residual: float, worst: int,
                   tol: float) -> Certificate:
    """The :class:`Certificate` of a compiled certify call's numbers, in the order of its
    tuple (:func:`from_kernel`), and ``tol``: the one rule for ``passed``.  ``status`` 0
    means ``z`` and ``w`` finite and in range."""
    # error < inf also refuses NaN
    return Certificate(error, backward_error, growth, residual, bound_violation, w_violation,
                       complementarity, equality_residual, worst, float(tol),
                       status == 0 and error <= tol and error < math.inf)


def from_row(row: Any, tol: float) -> Certificate:
    """The :class:`Certificate` of a row of a stacked kernel's ``cert`` output
    (:data:`lcpcli.solvers.kernels.batch.CERT_FIELDS` numbers: the first nine fields of
    :class:`Certificate` in order, ``worst`` as a float), written only for an answer the
    kernel certified (its status 0: z and w finite and in range)."""
    error, back, growth, res, bound, wv, comp, eq, worst = row.tolist()
    return certificate_of(0, error, back, growth, res, bound, wv, comp, eq, int(worst), tol)


def _pow2_exponent(x: float) -> int:
    """``e`` with ``2^e`` the power of two in ``[x, 2x)`` (``x > 0``; ``e`` may be 1024, one past
    the largest finite power of two, so it is applied with ``ldexp``, never formed)."""
    mant, exp = math.frexp(x)
    return exp if mant != 0.5 else exp - 1


def _times_pow2(x: float, e: int) -> float:
    """``x 2^e``, the largest double where that overflows (a norm, not a value to certify)."""
    try:
        return math.ldexp(x, e)
    except OverflowError:
        return float(np.finfo(np.float64).max)


_NO_EXP = np.iinfo(np.int64).min // 4    # a row with no term and q_i = 0
_NO_NEED = np.iinfo(np.int64).max // 4   # a column with no entry


def _rescaled_check(problem: Any, z: np.ndarray,
                    state: np.ndarray | None = None) -> tuple[tuple, np.ndarray]:
    """Certify data whose products leave the safe range: rescale rows and columns exactly by
    powers of two (``M' = D M cexp``, ``q' = D q``, ``z' = cexp^-1 z``; the certificate does not
    change), certify the rescaled copy, and map ``w`` back (``w = D^-1 w'``, Inf where the true
    ``w`` overflows)."""
    M = problem.M
    sparse = hasattr(M, "tocsr")
    Mc = M.tocoo() if sparse else None
    n = problem.n
    ez = np.where(z != 0.0, binary_exponents(z), 0)
    if sparse:
        rows, cols, vals = Mc.row, Mc.col, Mc.data
    else:
        rows, cols = np.nonzero(M)
        vals = M[rows, cols]
    em = binary_exponents(vals)
    # row exponent: the largest term |M_ij z_j| (by exponents, no product formed) or |q_i|
    live = z[cols] != 0.0
    rexp = np.full(n, _NO_EXP, dtype=np.int64)
    np.maximum.at(rexp, rows[live], em[live] + ez[cols[live]])
    nonzero_q = problem.q != 0.0
    rexp[nonzero_q] = np.maximum(rexp[nonzero_q], binary_exponents(problem.q[nonzero_q]))
    untouched = rexp == _NO_EXP
    rexp[untouched] = 0
    # columns with z_j = 0: scale so that their entries stay <= 1 after the row scaling
    cexp = ez.copy()
    dead = z == 0.0
    if dead.any():
        need = np.full(n, _NO_NEED, dtype=np.int64)
        np.minimum.at(need, cols, rexp[rows] - em)
        cexp[dead] = np.where(need[dead] == _NO_NEED, 0, need[dead])
    new_vals = np.ldexp(vals, (cexp[cols] - rexp[rows]).astype(np.int32))
    zs = np.ldexp(z, (-cexp).astype(np.int32))
    qs = np.ldexp(problem.q, (-rexp).astype(np.int32))
    if sparse:
        import scipy.sparse as sp  # only on this rare path (sparse data out of range)

        Ms = sp.csr_matrix((new_vals, (rows, cols)), shape=(n, n))
        Ms.sum_duplicates()
        marg: Any = (Ms.data, Ms.indices, Ms.indptr)
    else:
        marg = np.zeros((n, n))
        marg[rows, cols] = new_vals
    lo = up = None
    if problem.lower is not None:
        # a bound past the double range in the rescaled units stays infinite there: it lies
        # more than 2^1023 times |z_j| away, a move no state can make (clipped to the largest
        # double, a move to it looked small: a z_j = 1e-318 with w_j < 0 under an upper bound
        # of 4 passed as 'at the upper bound' with error 2^-33 where the true one is 0.11)
        with np.errstate(over="ignore"):
            lo = np.ldexp(problem.lower, (-cexp).astype(np.int32))
            up = np.ldexp(problem.upper, (-cexp).astype(np.int32))
    ws = np.empty(n)
    out = _certificate.certify_arrays(marg, qs, zs, problem.n_eq, lo, up, ws, state)
    if out[0] == 1:  # a z_j not finite: the kernel wrote nothing to ws (check() fills it)
        return out, ws
    with np.errstate(over="ignore"):
        w = np.ldexp(ws, rexp.astype(np.int32))
    res = list(out)
    if res[0] == 0:
        # the diagnostics in the units of the data (the dimensionless numbers are unchanged)
        res[4:9] = _unscaled_diagnostics(problem, z, w)
        if not np.all(np.isfinite(w)):
            res[0] = 1
    return tuple(res), w


def _unscaled_diagnostics(problem: Any, z: np.ndarray, w: np.ndarray) -> list[float]:
    lo, up = problem.bounds()
    with np.errstate(invalid="ignore", over="ignore"):
        r = np.maximum(z - up, np.minimum(z - lo, w))
        bviol = np.maximum(np.maximum(lo - z, z - up), 0.0)
        lo_f, up_f = np.isfinite(lo), np.isfinite(up)
        lower_only, upper_only = lo_f & ~up_f, ~lo_f & up_f
        free, both = ~lo_f & ~up_f, lo_f & up_f
        wviol = np.concatenate([np.maximum(-w[lower_only], 0.0), np.maximum(w[upper_only], 0.0)])
        comp = np.concatenate([np.abs((z - lo)[lower_only] * w[lower_only]),
                               np.abs((up - z)[upper_only] * w[upper_only]),
                               np.minimum(np.abs(z - lo), np.abs(up - z))[both] * np.abs(w[both])])
    return [_norm(r), _norm(bviol), _norm(wviol), _norm(comp), _norm(w[free])]


def _norm(x: np.ndarray) -> float:
    return float(np.max(np.abs(x))) if x.size else 0.0
