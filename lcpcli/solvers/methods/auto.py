"""``auto``: classify M cheaply, pick a method, fall back to the next suitable one.

Problem: any kind (LCP, MLCP, box LCP), ``w = M z + q``. The class report comes from
:func:`lcpcli.analysis.classify.classify` (symmetric?, PD/PSD by eigenvalues or Cholesky, Z-matrix,
P-matrix by a sufficient test: PD, strictly diagonally dominant or H-matrix with positive diagonal,
exact principal minors for n <= 10; sparse?, size). :func:`plan` turns it into an ordered list of
methods with a reason each; every attempt is certified with :func:`lcpcli.core.certificate.certify`
and the first that passes is returned. A method's *proof* that no solution exists (Lemke's
secondary ray on a copositive-plus M, or a Farkas certificate) ends the search with
``no_solution``. ``message`` names the classification, the method that succeeded and every failed
attempt; ``info["attempts"]`` has the details.

Matrix classes: any; the guarantees are those of the methods it picks (see docs/methods.md).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from lcpcli.core.result import CONVERGED, ITERATION_LIMIT, Outcome, Status
from lcpcli.solvers.options import positive_int, vector_option
from lcpcli.solvers.registry import Method, Option, resolve

#: Dense problems up to this size are given to the pivoting methods first.
PIVOT_MAX_N = 1500
#: Dense problems above this size are never given to the O(n^3)-per-solve pivoting methods.
PIVOT_HARD_MAX_N = 5000
#: Sparse problems up to this size are treated like small dense ones (pivoting first).
SMALL_SPARSE_N = 200
#: Sparse LU fill ratio (nnz(L+U) / nnz(M)) under which Newton goes before PSOR.
LOW_FILL = 30.0
#: Sweep / iteration caps auto uses when the user gave no --max-iter (a fallback should fail fast).
AUTO_CAPS = {"pgs": 1000, "psor": 1000, "newton": 100, "newton-min": 50, "ip": 100}


def _describe(c: dict[str, Any]) -> str:
    """A short phrase for the class report."""
    parts = ["sparse" if c["sparse"] else "dense", f"n={c['n']}"]
    parts.append("symmetric" if c["symmetric"] else "non-symmetric")
    if c["definiteness"] is not None:
        parts.append({"pd": "PD", "psd": "PSD", "indefinite": "indefinite"}[c["definiteness"]])
    if c["p_matrix"]:
        parts.append("P-matrix")
    if c["z_matrix"]:
        parts.append("Z-matrix")
    if c["zero_diagonal"]:
        parts.append(f"{c['zero_diagonal']} zero diagonal entries")
    return ", ".join(parts)


def _resolve(name: str, available: dict[str, Any]) -> str | None:
    """The registered name of ``name`` (which may be an alias) if it is in ``available``."""
    key = resolve(name)
    return key if key in available else None


def plan(problem: Any, c: dict[str, Any], available: dict[str, Any]) -> list[tuple[str, str]]:
    """The ordered (method, reason) list for ``problem`` with class report ``c``.

    Only methods present in ``available`` (the registry) and handling ``problem.kind`` are kept.
    """
    n = c["n"]
    kind = problem.kind
    dense_small = n <= PIVOT_MAX_N and (not c["sparse"] or n <= SMALL_SPARSE_N)
    pivot_ok = n <= PIVOT_HARD_MAX_N
    sym, pd, psd, p = c["symmetric"], c["pd"], c["psd"], c["p_matrix"]
    posdiag, hplus = c["positive_diagonal"], c["h_matrix_positive_diagonal"]
    steps: list[tuple[str, str]] = []

    def add(name: str, why: str) -> None:
        name = _resolve(name, available)
        if name and kind in available[name].kinds and name not in [s[0] for s in steps]:
            steps.append((name, why))

    if kind == "mlcp":
        mixed = [name for name, m in available.items()
                 if "mlcp" in m.kinds and name not in ("auto", "newton", "newton-min")
                 and not name.startswith("enum")]
        for name in sorted(mixed, key=lambda k: (0 if "schur" in k else 1, k)):
            add(name, "a method for the mixed form")
        add("newton", "semismooth Newton handles free rows as plain equations")
        add("newton-min", "min-map Newton, fallback")
        return steps
    if kind == "box":
        if sym and psd:
            add("dantzig", "symmetric PSD box LCP: principal pivoting (Cottle-Dantzig)")
        if posdiag and ((sym and psd) or hplus):
            add("pgs", "symmetric PSD (or H-matrix) with positive diagonal: PGS converges")
        add("newton", "semismooth Newton on the box (Billups) function")
        add("newton-min", "Newton on the mid function, fallback")
        if posdiag:
            add("psor", "projected SOR, last resort")
        return steps
    # ---- LCP
    if dense_small:
        if sym and pd:  # Lemke measured faster than dantzig here (benchmarks/bench_methods.py)
            add("lemke", "symmetric PD (a P-matrix): Lemke is finite")
            add("dantzig", "symmetric PD: principal pivoting")
            add("murty", "P-matrix: Murty's method is finite")
        elif p:
            add("lemke", f"P-matrix ({c['p_matrix_reason']}): Lemke is finite")
            add("murty", "P-matrix: Murty's method is finite")
        elif psd:
            add("lemke", "PSD (copositive-plus): Lemke finds a solution or proves none exists")
            if sym:
                add("dantzig", "symmetric PSD: principal pivoting")
            add("ip", "monotone LCP: interior point")
        else:
            add("lemke", "no class known: Lemke first (solves many problems; proofs only "
                         "for copositive-plus)")
        add("newton", "semismooth Newton (Fischer-Burmeister), general fallback")
        if psd:
            add("ip", "monotone LCP: interior point")
        add("newton-min", "min-map Newton, fallback")
        add("ip", "interior point (no guarantee outside monotone problems)")
        if posdiag and sym:
            add("pgs", "projected Gauss-Seidel, last resort")
        return steps
    # sparse or large problems: iterative methods first
    size = "sparse" if c["sparse"] else "large"
    fill = c.get("factor_fill")
    if c["sparse"] and psd and fill is not None and fill <= LOW_FILL:
        add("newton", f"sparse monotone LCP whose factorisation fills in little "
                      f"(x{fill:.1f}): semismooth Newton with sparse LU")
    sor_first = posdiag and sym and psd and (c["sparse"] or pd)
    if sor_first:
        add("psor", f"{size}, symmetric {'PD' if pd else 'PSD'} with positive diagonal: "
                    f"projected SOR converges (cheap sweeps)")
    if posdiag and hplus:
        add("pgs", f"{size}, H-matrix with positive diagonal: PGS converges")
    if psd:
        add("ip", f"{size} monotone LCP: interior point (few factorisations)")
    add("newton", f"{size}: semismooth Newton (Fischer-Burmeister)")
    if posdiag and sym and psd:
        add("psor", "symmetric PSD with positive diagonal: projected SOR (slow if singular)")
    add("newton-min", "min-map Newton, fallback")
    if pivot_ok:
        add("lemke", "pivoting fallback (dense O(n^2) per pivot)")
        if p:
            add("murty", "P-matrix: Murty's method is finite")
    return steps


def prepare() -> None:
    """Warm up the compiled kernels of the LCP methods auto tries most (outside the timed
    region); other methods' hooks run inside ``run`` when they are tried (cached, cheap)."""
    from lcpcli.solvers.registry import get_method

    for name in ("lemke", "murty", "pgs", "dantzig", "mlcp-schur", "mlcp-lemke"):
        try:
            spec = get_method(name)
        except Exception:  # noqa: BLE001 - a method absent from this build
            continue
        spec.prepare_once()


def run(problem: Any, *, tol: float, max_iter: int | None = None,
        z0: np.ndarray | None = None, order: str | None = None) -> Outcome:
    """Classify, plan and try methods until one's answer passes the certificate."""
    from lcpcli.analysis.classify import classify
    from lcpcli.core.certificate import certify, matrix_norm_inf
    from lcpcli.core.errors import OptionError
    from lcpcli.solvers.registry import methods
    from lcpcli.solvers.support import start_point

    n = problem.n
    lo, _ = problem.bounds()
    if z0 is not None:
        z0 = start_point(problem, z0)  # length check before any method runs
    if problem.kind == "lcp" and (n == 0 or np.min(problem.q) >= 0):
        return Outcome(np.zeros(n), 0, CONVERGED, "auto: q >= 0, so z = 0 solves the problem",
                       info={"chosen": None, "attempts": []})
    t0 = time.perf_counter()
    c = classify(problem, thorough=False)
    t_class = time.perf_counter() - t0
    registry = {k: v for k, v in methods().items() if k != "auto"}
    if order:
        steps = []
        for name in order.replace(",", " ").split():
            key = _resolve(name, registry)
            spec = registry.get(key) if key else None
            if spec is None or problem.kind not in spec.kinds:
                raise OptionError(f"auto: method '{name}' in order= is unknown or does not "
                                  f"handle {problem.kind.upper()} problems")
            steps.append((spec.name, "given by order="))
    else:
        steps = plan(problem, c, registry)
    desc = _describe(c)
    norm_M = matrix_norm_inf(problem.M)
    attempts: list[dict[str, Any]] = []
    best: tuple[float, np.ndarray, str] | None = None
    total_it = 0
    for name, why in steps:
        spec = registry[name]
        opts: dict[str, Any] = {}
        if "max_iter" in spec.options:
            if max_iter is not None:
                opts["max_iter"] = max_iter
            elif name in AUTO_CAPS:
                opts["max_iter"] = AUTO_CAPS[name]
        if z0 is not None and "z0" in spec.options:
            opts["z0"] = z0
        if spec.densifies(problem):
            continue  # it would densify a huge sparse M (api.check_dense_ok refuses that too)
        spec.prepare_once()
        t1 = time.perf_counter()
        try:
            out: Outcome = spec.run(problem, tol=tol, **spec.parse_options(opts))
        except (np.linalg.LinAlgError, MemoryError, ValueError, RuntimeError) as exc:
            if isinstance(exc, OptionError):
                raise
            attempts.append({"method": name, "reason": why, "status": Status.ERROR,
                             "message": f"{type(exc).__name__}: {exc}",
                             "seconds": time.perf_counter() - t1})
            continue
        secs = time.perf_counter() - t1
        total_it += int(out.iterations)
        z = np.asarray(out.z, dtype=np.float64)
        cert = certify(problem, z, tol, norm_M=norm_M)
        rec = {"method": name, "reason": why, "termination": out.termination,
               "iterations": int(out.iterations), "error": cert.error, "seconds": secs,
               "message": out.message}
        if cert.passed:
            rec["status"] = Status.SOLVED
            attempts.append(rec)
            failed = "".join(f"; {a['method']} failed first ({a['message']})"
                             for a in attempts[:-1])
            return Outcome(z, total_it, CONVERGED,
                           f"auto ({desc}): solved by {name} ({why}){failed}",
                           info={"chosen": name, "attempts": attempts, "classification": c,
                                 "classify_seconds": t_class})
        if out.proven_infeasible:
            rec["status"] = Status.NO_SOLUTION
            attempts.append(rec)
            return Outcome(z, total_it, out.termination,
                           f"auto ({desc}): {name} proved that no solution exists: "
                           f"{out.message}", proven_infeasible=True,
                           info={"chosen": name, "attempts": attempts, "classification": c,
                                 "classify_seconds": t_class})
        rec["status"] = Status.UNSOLVED
        attempts.append(rec)
        if best is None or cert.error < best[0]:
            best = (cert.error, z, out.termination)
    tried = "; ".join(f"{a['method']}: {a['message']}" for a in attempts) or "no method applies"
    z = best[1] if best else np.clip(np.zeros(n), lo, None)
    return Outcome(z, total_it, best[2] if best else ITERATION_LIMIT,
                   f"auto ({desc}): every suitable method failed ({tried})",
                   info={"chosen": None, "attempts": attempts, "classification": c,
                         "classify_seconds": t_class})


METHODS = [
    Method(
        name="auto",
        run=run,
        summary="classify M, pick a method, fall back to the next suitable one (the default)",
        matrix_classes="any (the guarantees of the method it picks; see 'lcpcli info FILE')",
        kinds=("lcp", "mlcp", "box"),
        sparse=True,
        options={
            "max_iter": Option(positive_int, None,
                               "iteration / pivot limit passed to each method tried"),
            "z0": Option(vector_option, None, "warm start passed to the methods that take one"),
            "order": Option(str, None, "comma-separated methods to try instead of the plan"),
        },
        prepare=prepare,
    ),
]


def applicability(problem: Any, c: dict[str, Any],
                  available: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """For each registered method: does it apply to ``problem`` (class report ``c``), and why.

    ``applies`` is ``"yes"`` (the problem is in the method's convergence class), ``"maybe"`` (it
    may work, without a guarantee) or ``"no"`` (wrong problem kind, or the method cannot start,
    e.g. PGS with a zero diagonal entry).  ``auto_rank`` is the 1-based position in auto's plan.
    """
    from lcpcli.solvers.registry import methods

    reg = available if available is not None else methods()
    steps = plan(problem, c, {k: v for k, v in reg.items() if k != "auto"})
    rank = {name: i + 1 for i, (name, _) in enumerate(steps)}
    kind = problem.kind
    sym, psd, p = c["symmetric"], c["psd"], c["p_matrix"]
    posdiag, hplus = c["positive_diagonal"], c["h_matrix_positive_diagonal"]
    rows = []
    for name, m in reg.items():
        if kind not in m.kinds:
            applies, why = "no", (f"handles {'/'.join(k.upper() for k in m.kinds)} problems, "
                                  f"not {kind.upper()}")
        elif name == "auto":
            applies, why = "yes", "picks a method from the classification"
        elif name.startswith("lemke"):
            if p:
                applies, why = "yes", "P-matrix: finite, unique solution"
            elif psd:
                applies, why = "yes", "PSD (copositive-plus): a solution or a proof of none"
            else:
                applies, why = "maybe", "not known copositive-plus: a ray would prove nothing"
        elif name == "murty":
            if p:
                applies, why = "yes", "P-matrix: finite (possibly 2^n pivots)"
            elif p is False:
                applies, why = "maybe", f"not a P-matrix ({c['p_matrix_reason']}): may stop " \
                                        "on a non-positive pivot"
            else:
                applies, why = "maybe", "P-matrix property unknown"
        elif name in ("pgs", "psor"):
            if not posdiag:
                applies, why = "no", (f"{c['zero_diagonal']} zero / non-positive diagonal "
                                      f"entries: the update is undefined")
            elif sym and psd:
                applies, why = "yes", "symmetric PSD with positive diagonal"
            elif hplus:
                applies, why = "yes", "H-matrix with positive diagonal"
            else:
                applies, why = "maybe", "not symmetric PSD nor H-matrix: may not converge"
        elif name == "newton":
            if p or psd:
                applies, why = "yes", ("P-matrix" if p else "monotone (PSD)") + \
                    ": globally convergent on the FB merit"
            else:
                applies, why = "maybe", "no class guarantee (may stop at a stationary point)"
        elif name == "newton-min":
            applies, why = "maybe", ("P-matrix: locally fast, not globally convergent" if p
                                     else "not globally convergent: may stall")
        elif name == "ip":
            if psd:
                applies, why = "yes", "monotone (PSD) LCP"
            elif psd is None:
                applies, why = "maybe", "monotonicity not tested (too large)"
            else:
                applies, why = "maybe", "not monotone: no guarantee"
        elif name == "dantzig":
            if sym and psd:
                applies, why = "yes", "symmetric PSD"
            else:
                applies, why = "maybe", "its class is symmetric PSD; this M is not"
        elif name.startswith("enum"):
            applies, why = ("yes" if c["n"] <= 20 else "no"), \
                f"enumerates 2^n complementary cones (n = {c['n']})"
        else:
            applies, why = "maybe", f"stated classes: {m.matrix_classes}"
        rows.append({"method": name, "applies": applies, "why": why,
                     "auto_rank": rank.get(name)})
    return rows


def info_report(problem: Any, file: str | None = None) -> dict[str, Any]:
    """The ``lcpcli info`` report: class report, per-method applicability, auto's plan (JSON-safe).

    Schema: ``{"file", "problem", "summary", "classification": {...}, "methods": [{"method",
    "applies", "why", "auto_rank"}], "auto_plan": [[method, reason], ...], "seconds"}``.
    """
    from lcpcli.analysis.classify import classify
    from lcpcli.solvers.registry import methods

    t0 = time.perf_counter()
    c = classify(problem)
    secs = time.perf_counter() - t0
    reg = methods()
    steps = plan(problem, c, {k: v for k, v in reg.items() if k != "auto"})
    clean = {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
             for k, v in c.items()}
    return {"file": file, "problem": problem.name, "summary": problem.summary(),
            "classification": clean, "methods": applicability(problem, c, reg),
            "auto_plan": [[name, why] for name, why in steps], "seconds": secs}
