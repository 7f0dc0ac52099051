"""How every method is run: equilibrate, run, map the answer back, polish.

:func:`run_method` is the one place that does this, for :func:`lcpcli.solve` and for ``auto``'s
attempts alike.  Conventions: ``w = M z + q``; options and results in the units of the problem
the user gave.

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
   A method that gave up is not polished (its leftover is not an answer to refine).  The
   verdict is always the certificate's (and a no_solution's proof is checked by the caller,
   :func:`lcpcli.analysis.proof.confirm`).

Small path: a method that declares ``Method.fast`` is first asked for its answer from one
compiled call (balance test, kernel, polish, certificate).  It answers only when the steps
above would do nothing more (the problem is balanced and the answer passes the certificate),
so the result is the same; otherwise it returns None and the steps above run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.classify import is_symmetric
from lcpcli.analysis.scaling import (
    GEOMETRIC_SPREAD,
    Scaling,
    equilibrate,
    geometric,
    is_balanced,
    spread,
)
from lcpcli.core.certificate import check
from lcpcli.core.numeric import float64_array
from lcpcli.core.problem import Problem
from lcpcli.core.result import CONVERGED, Outcome
from lcpcli.solvers.support import refine

#: Options in the units of z and of w, scaled with the problem.
Z_OPTIONS = ("z0",)
W_OPTIONS = ("covering",)


def run_method(spec: Any, problem: Problem, tol: float, options: dict[str, Any]) -> Outcome:
    """Run ``spec`` on ``problem`` as the module docstring says; return its :class:`Outcome`."""
    if spec.planner and getattr(spec, "scaling", "none") == "none":  # auto runs this pipeline
        plan_run = getattr(spec, "plan_run", None)                    # for each of its attempts
        if plan_run is not None:
            return plan_run(problem, tol, options)
        return spec.run(problem, tol=tol, **options)
    fast = getattr(spec, "fast", None)
    if fast is not None and type(problem.M) is np.ndarray:
        out = fast(problem, tol, options)  # a balanced problem, certified: nothing else to do
        if out is not None:
            return out
    requested = "none" if options.get("trace") else getattr(spec, "scaling", "none")
    kind = requested
    if kind != "none" and is_balanced(problem):
        kind = "none"  # nothing to equilibrate (one compiled pass; no symmetry test needed)
    symmetric = kind == "symmetric" or (kind == "auto" and is_symmetric(problem.M, 0.0))
    scaling = equilibrate(problem, symmetric) if kind != "none" else None
    out = _run_scaled(spec, problem, tol, options, scaling)
    if (kind == "auto" and not symmetric and out.termination != CONVERGED
            and not out.proven_infeasible):
        again = _run_scaled(spec, problem, tol, options, equilibrate(problem, True))
        if again.proven_infeasible or again.termination == CONVERGED:
            again.message += " (rerun with D M D scaling, which keeps M's class)"
            again.iterations += out.iterations
            out = again
    passed = _polish(problem, out, tol)
    if (requested != "none" and not passed and not out.proven_infeasible
            and spread(problem, scaling) > GEOMETRIC_SPREAD):
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
    if out.termination != CONVERGED:
        return False
    z = out.z = float64_array(out.z)
    if out.checked is None or out.checked[0].tol != tol:
        out.checked = check(problem, z, tol)
    cert = out.checked[0]
    if cert.passed:
        return True
    polished = refine(problem, z, basis=out.info.get("basis"))
    if polished is not None and polished[1] < cert.error:
        out.z = polished[0]
        out.checked = check(problem, out.z, tol)
        out.message += (f"; active-set polish: certified error {cert.error:.2g} -> "
                        f"{polished[1]:.2g}")
        out.info["polished"] = True
        return out.checked[0].passed
    return False


def _run_scaled(spec: Any, problem: Problem, tol: float, options: dict[str, Any],
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
    out.info["scaling"] = {"kind": scaling.kind, "row_exponents": [int(scaling.row.min()),
                                                                   int(scaling.row.max())],
                           "column_exponents": [int(scaling.col.min()), int(scaling.col.max())]}
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
