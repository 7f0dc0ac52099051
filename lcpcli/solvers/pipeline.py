"""How every method is run: equilibrate, run, map the answer back, polish.

:func:`run_method` is the one place that does this, for :func:`lcpcli.solve` and for ``auto``'s
attempts alike, and certifies the answer (see "Dispatcher" below).  Conventions:
``w = M z + q``; options and results in the units of the problem the user gave.

1. **Equilibrate** (:mod:`lcpcli.analysis.scaling`) when the method asks for it
   (``Method.scaling``): ``"auto"`` scales a symmetric M as ``D M D`` (keeps symmetry and
   definiteness) and any other M two-sided as ``D1 M D2`` (undoes arbitrary row and column
   scalings, keeps the P property); ``"symmetric"`` always uses ``D M D``; ``"none"`` never
   scales (methods that are invariant under diagonal scaling, such as projected Gauss-Seidel).
   Warm starts and covering vectors are scaled with the problem; traces are never scaled (they
   show the user's numbers).
2. **Run** the method on the scaled problem and map ``z`` (and a Farkas vector) back exactly.
   When a two-sided run ends with neither an answer nor a proof, the method is run once more
   with ``D M D``, which keeps the matrix classes its guarantees are stated for (a secondary
   ray proves infeasibility only on a copositive-plus matrix).  When, after the polish below,
   there is still no certified answer and no proof while the scaled matrix's entries span
   more than ``2^GEOMETRIC_SPREAD``, the method is run once more on Curtis and Reid's
   geometric scaling (:func:`lcpcli.analysis.scaling.geometric`), which undoes any power-of-two
   row and column scaling of a matrix whose entries are of one size.
3. **Polish**: when a method says it converged but its answer fails the certificate,
   :func:`lcpcli.solvers.support.refine` re-solves the method's final basis (when it reports
   one) or the active set the certificate names (with sign repair); the better answer is kept.
   A method that gave up is not polished (its leftover is not an answer to refine), except a
   Lemke ray whose artificial variable ended at rounding level (``RAY_AT_ROUNDING``): its
   point solves the problem up to a change of q below rounding.  The
   verdict is always the certificate's (and a no_solution's proof is checked by the caller,
   :func:`lcpcli.analysis.proof.confirm`).

Dispatcher: :func:`run_method` is entered once per method run and is the only place that
certifies an answer or reuses a certificate (:func:`certified`); a method whose kernel
certifies its own answer (``lemke-revised``: balance test, kernel, polish and certificate in
one compiled call, ``Method.balance_test``) hands it over in ``Outcome.checked``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.classify import is_symmetric
from lcpcli.analysis.scaling import (
    BALANCE,
    GEOMETRIC_SPREAD,
    Scaling,
    equilibrate,
    geometric,
    is_balanced,
    spread,
)
from lcpcli.core.certificate import Certificate, check
from lcpcli.core.numeric import float64_array
from lcpcli.core.problem import Problem
from lcpcli.core.result import CONVERGED, RAY, Outcome
from lcpcli.solvers.support import RAY_AT_ROUNDING, refine

#: Options in the units of z and of w, scaled with the problem.
Z_OPTIONS = ("z0",)
W_OPTIONS = ("covering",)


def run_method(spec: Any, problem: Problem, tol: float, options: dict[str, Any]) -> Outcome:
    """The dispatcher: run ``spec`` on ``problem`` and certify its answer at ``tol``.

    Every solve enters here once per method run: :func:`lcpcli.solve` with its
    :class:`~lcpcli.solvers.request.Request`, and each attempt of a planner (``auto``, whose
    ``run`` calls this for every method it tries).  A planner runs as it is; any other method
    goes through the steps of the module docstring.  The returned Outcome's ``checked`` is
    always the certificate of its ``z`` at ``tol`` (:func:`certified`)."""
    if spec.planner and spec.scaling == "none":
        out = spec.run(problem, tol=tol, **options) if options else spec.run(problem, tol=tol)
        certified(problem, out, tol)
        return out
    requested = "none" if options and options.get("trace") else spec.scaling
    if requested == "none":
        out = spec.run(problem, tol=tol, **options)
    elif spec.balance_test and type(problem.M) is np.ndarray:  # the test inside run's own
        # compiled call (no `**options` when there are none: 0.1 us of a 4 us call)
        out = spec.run(problem, tol=tol, balance=BALANCE, **options) if options else \
            spec.run(problem, tol=tol, balance=BALANCE)
    else:  # one compiled pass; no symmetry test needed
        out = spec.run(problem, tol=tol, **options) if is_balanced(problem) else None
    if out is None:  # not balanced: nothing was solved
        out = _equilibrated(spec, problem, tol, options, requested)
    else:
        if _polish(problem, out, tol):
            return out  # certified: the small problems' path ends here
        if requested != "none":
            out = _geometric(spec, problem, tol, options, out, requested, None)
    certified(problem, out, tol)
    return out


def certified(problem: Problem, out: Outcome, tol: float,
              state: np.ndarray | None = None) -> tuple[Certificate, np.ndarray]:
    """``(certificate, w)`` of ``out.z`` at ``tol``, stored in ``out.checked``: the one rule for
    reusing a certificate.  ``out.checked`` is reused when it was made at this ``tol`` (by
    whoever last set ``out.z``: a kernel that certified its own answer, the polish, an earlier
    call); otherwise, or when the pair ``state`` codes are asked for, ``z`` is moved onto its
    bounds where a method's rounding left it outside (:meth:`Problem.inside`: the move the
    certificate judges anyway) and checked now (:func:`lcpcli.core.certificate.check`)."""
    checked = out.checked
    if checked is None or checked[0].tol != tol or state is not None:
        out.z = z = problem.inside(float64_array(out.z))
        checked = out.checked = check(problem, z, tol, state=state)
    return checked


def _equilibrated(spec: Any, problem: Problem, tol: float, options: dict[str, Any],
                  requested: str) -> Outcome:
    """Steps 1-3 of the module docstring for a problem that needs equilibrating."""
    symmetric = requested == "symmetric" or (requested == "auto" and is_symmetric(problem.M, 0.0))
    scaling = equilibrate(problem, symmetric)
    out = _run_scaled(spec, problem, tol, options, scaling)
    if (requested == "auto" and not symmetric and out.termination != CONVERGED
            and not out.proven_infeasible):
        again = _run_scaled(spec, problem, tol, options, equilibrate(problem, True))
        if again.proven_infeasible or again.termination == CONVERGED:
            again.message += " (rerun with D M D scaling, which keeps M's class)"
            again.iterations += out.iterations
            out = again
    if _polish(problem, out, tol):
        return out
    return _geometric(spec, problem, tol, options, out, requested, scaling)


def _geometric(spec: Any, problem: Problem, tol: float, options: dict[str, Any], out: Outcome,
               requested: str, scaling: Scaling | None) -> Outcome:
    """The end of step 2 for an answer that failed the certificate after its polish: when
    there is no proof either and the (scaled) matrix's entries span more than
    ``2^GEOMETRIC_SPREAD``, the run on Curtis and Reid's geometric scaling, if it does better."""
    if out.proven_infeasible or spread(problem, scaling) <= GEOMETRIC_SPREAD:
        return out
    # Ruiz's scaling balanced the row and column maxima but left entries far apart: rerun on
    # Curtis and Reid's least-squares scaling (invariant under row and column scalings)
    keep = requested == "symmetric" or (requested == "auto" and is_symmetric(problem.M, 0.0))
    geo = geometric(problem, keep)
    if geo is not None:
        again = _run_scaled(spec, problem, tol, options, geo)
        if _polish(problem, again, tol) or again.proven_infeasible:
            again.message = f"{out.message}; rerun on the geometric scaling: {again.message}"
            again.iterations += out.iterations
            out = again
    return out


def _polish(problem: Problem, out: Outcome, tol: float) -> bool:
    """Step 3 of the module docstring on ``out``, in place; whether its answer passes the
    certificate (``out.checked`` is then set for the caller to reuse)."""
    ray = out.termination == RAY and bool(out.info.get(RAY_AT_ROUNDING))
    if out.termination != CONVERGED and not ray:
        return False
    cert = certified(problem, out, tol)[0]
    z = out.z
    if cert.passed:
        return True
    polished = refine(problem, z, basis=out.info.get("basis"))
    if polished is not None and polished[1] < cert.error:
        out.z, out.checked = polished[0], None
        certified(problem, out, tol)
        out.message += (f"; active-set polish: certified error {cert.error:.2g} -> "
                        f"{polished[1]:.2g}")
        out.info["polished"] = True
        if ray and out.checked[0].passed:
            out.termination = CONVERGED  # the ray's point, polished, is the answer
        return out.checked[0].passed
    return False


def _run_scaled(spec: Any, problem: Problem, tol: float, options: dict[str, Any],
                scaling: Scaling | None) -> Outcome:
    """A run on the problem scaled by ``scaling`` (None: as given), mapped back.  Floating-point
    exceptions inside it are not numpy warnings (the CLI would print each): scaled bounds or
    an answer past the float64 range become inf, and every inf or NaN ends in the method's
    own checks, a failed certificate or an unchecked proof."""
    with np.errstate(all="ignore"):
        return _scaled_run(spec, problem, tol, options, scaling)


def _scaled_run(spec: Any, problem: Problem, tol: float, options: dict[str, Any],
                scaling: Scaling | None) -> Outcome:
    if scaling is None:
        return spec.run(problem, tol=tol, **options)
    out = spec.run(scaling.apply(problem), tol=tol, **_scaled_options(options, scaling))
    out.z = scaling.unscale_z(out.z)
    out.checked = None  # a method's own certificate is of the scaled problem: w, units differ
    y = out.info.get("farkas_y")
    if y is not None:
        out.info["farkas_y"] = scaling.farkas_back(y).tolist()
    out.message += f" [{scaling.describe()}]"
    if not np.all(np.isfinite(out.z)):  # e.g. z = 2^2000 for M = 2^-1000, q = -2^1000
        out.message += "; its z overflows float64 in the problem's units"
    rows, cols = scaling.ranges
    out.info["scaling"] = {"kind": scaling.kind, "row_exponents": list(rows),
                           "column_exponents": list(cols)}
    return out


def _scaled_options(options: dict[str, Any], scaling: Scaling) -> dict[str, Any]:
    out = dict(options)
    for key in Z_OPTIONS:
        if out.get(key) is not None and np.size(out[key]) == scaling.col.size:
            out[key] = scaling.scale_z(out[key])
    for key in W_OPTIONS:
        value = out.get(key)
        if value is not None and np.size(value) == 1:
            value = np.full(scaling.row.size, float(np.ravel(value)[0]))
        if value is not None and np.size(value) == scaling.row.size:
            out[key] = scaling.scale_w(value)
    return out
