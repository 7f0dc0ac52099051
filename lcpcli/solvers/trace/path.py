"""Lemke's pivot rule on Dai & Drumwright's principal pivoting transform (``lcpcli pivot
--driving`` and ``--follow``).

Given a basis (dependent tuple ``w'``) and a driving variable, :func:`driving_step` applies
Lemke's ratio test (:func:`lcpcli.solvers.trace.lemke.ratio_test`, the same rule and
tolerances as the method) to ``q'`` and the driving column ``M'_driving`` of the transform
(eqs 2-8): which dependent variable blocks (leaves), at which level, and which variable
would enter next by the complementary rule.  :func:`follow` repeats this from basis to basis:
the blocking variable's slot of ``w'`` gets the driving variable, its complement drives next,
until ``z0`` leaves (the final basis is the last item), no row blocks (a ray), or
``max_steps``; its start must be a step of Lemke's path (:func:`off_lemke_path` says why
not).

When ``q'`` has negative entries the basis is not one of Lemke's feasible bases; with ``z0``
driving, the method's first pivot applies (``z0`` rises to ``max(-q'_i / c_i)``; the most
negative ratio leaves, ties to the last row), otherwise the test is refused with a reason.
With ``q' >= 0`` on a complementary basis and ``z0`` driving, the basis solves the LCP: no
test (rule ``solution``), as the method makes no pivot.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.pivoting import (
    ARTIFICIAL,
    PivotTransform,
    Var,
    all_vars,
    parse_var,
    principal_pivot,
    var_name,
)
from lcpcli.analysis.pivoting import inverse as float_inverse  # B^-1 in its own units
from lcpcli.core.errors import ProblemError
from lcpcli.core.tolerances import PIVOT_TOL, TIE_TOL
from lcpcli.solvers.trace.lemke import (
    initial_formula,
    initial_formula_murty,
    lexicographic,
    ratio_test,
)
from lcpcli.solvers.trace.tableau import as_numbers, complement, num, scalar

#: Steps of :func:`follow` when no limit is given.
FOLLOW_MAX_STEPS = 100


def basis_inverse(Maug: np.ndarray, dependent: tuple[Var, ...]) -> np.ndarray:
    """``B^-1`` of the basis: row ``i`` is ``d q'_i / d q`` (``w'`` order, columns ``q_1..q_n``).

    ``B`` holds the columns of the dependent variables in ``[I, -Maug] (w; z) = q``.
    """
    n = Maug.shape[0]
    exact = Maug.dtype == object  # fractions: the exact inverse
    eye = np.eye(n, dtype=np.int64).astype(object) if exact else np.eye(n)
    cols = [eye[:, v[1]] if v[0] == "w" else -Maug[:, v[1]] for v in dependent]
    if not n:
        return np.zeros((0, 0))
    if exact:
        from lcpcli.solvers.trace.exact import inverse

        return inverse(np.column_stack(cols))
    try:  # in the block's own units (np.linalg.inv called a basis of 9e-302 and 1.8e308
        return float_inverse(np.column_stack(cols))  # singular: exit 3)
    except ProblemError:  # singular in floating point: no key compares (the rows stay tied)
        return np.full((n, n), np.nan)


def driving_step(t: PivotTransform, Maug: np.ndarray, *, piv_tol: float = PIVOT_TOL,
                 tie_tol: float = TIE_TOL) -> dict[str, Any]:
    """Lemke's ratio test on ``t.driving_column``; the blocking (leaving) variable and why.

    Returns a JSON-ready dict: ``driving``, ``formula``, ``rows`` (every dependent variable
    with its ratio or why it cannot block), ``min_ratio``, ``blocking`` (``None``: no row
    blocks), ``row`` (1-based position in ``w'``), ``rule``, ``reason``, ``lexicographic``,
    ``next_entering`` (the blocking variable's complement; ``None`` when ``z0`` leaves) and
    ``next_dependent`` (``w'`` after the pivot).
    """
    if t.driving is None or t.driving_column is None:
        raise ValueError("the transform has no driving variable")
    names = t.names(t.dependent)
    drv = var_name(t.driving, t.n)
    col = as_numbers(t.driving_column)
    qp = as_numbers(t.q_prime)
    scale = max(1.0, float(np.max(np.abs(qp)))) if qp.size else 1.0
    out: dict[str, Any] = {"driving": drv, "lexicographic": None, "blocking": None,
                           "row": None, "next_entering": None, "next_dependent": None}
    if qp.size and float(np.min(qp)) < -1e-12 * scale:
        if drv != ARTIFICIAL or not np.all(col[qp < 0] > 0):
            out.update({"formula": None, "formula_murty": None, "rows": [], "min_ratio": None,
                        "rule": "infeasible",
                        "reason": (f"q' has negative entries, so this basis is not one of "
                                   f"Lemke's feasible bases: no ratio test (only {ARTIFICIAL} "
                                   f"entering from such a basis is Lemke's first pivot)")})
            return out
        # only the eligible rows (q'_i < 0, where c_i > 0) have a ratio; the others are +inf,
        # never the max (a row with q'_i = c_i = 0 made 0/0 = NaN, no row tied: exit 3)
        with np.errstate(over="ignore"):  # a ratio past the double range is -inf
            ratios = np.array([qp[i] / col[i] if qp[i] < 0 else np.inf for i in range(t.n)],
                              dtype=object if col.dtype == object else np.float64)
        best = np.min(ratios)
        tied = np.flatnonzero(ratios == best if best == -np.inf
                              else ratios - best <= tie_tol * abs(best))
        r = int(tied[-1])
        rows = [{"row": i + 1, "basic": names[i], "q": scalar(qp[i]), "column": scalar(col[i]),
                 "ratio": scalar(-ratios[i]) if qp[i] < 0 else None,
                 "eligible": bool(qp[i] < 0),
                 "tied": bool(i in tied) and tied.size > 1,
                 "why": "" if qp[i] < 0 else f"q' >= 0: {names[i]} >= 0 already"}
                for i in range(t.n)]
        out.update({"formula": initial_formula(tie_tol),
                    "formula_murty": initial_formula_murty(tie_tol), "rows": rows,
                    "min_ratio": scalar(-best),
                    "rule": "initial",
                    "reason": (f"Lemke's first pivot: {ARTIFICIAL} rises to {num(-best)}; row "
                               f"{r + 1} has the most negative q'_i / c_i" +
                               (f" ({tied.size} rows tie, the last one wins)"
                                if tied.size > 1 else ""))})
    elif drv == ARTIFICIAL and complementary(t.dependent, t.n):
        # q' >= 0 on a complementary basis: it solves the LCP, Lemke's method makes no pivot
        # (the test on z0's column said "secondary ray" when no entry was negative)
        out.update({"formula": None, "formula_murty": None, "rows": [], "min_ratio": None,
                    "rule": "solution",
                    "reason": (f"q' >= 0 on a complementary basis: it solves the LCP (each "
                               f"dependent variable equals its q', the others are 0), so "
                               f"Lemke's method makes no pivot and {ARTIFICIAL} does not "
                               f"enter")})
        return out
    else:
        test = ratio_test(col, qp, names, drv, piv_tol, tie_tol)
        cand = test["tied_rows"]
        out.update({"formula": test["formula"], "formula_murty": test["formula_murty"],
                    "rows": test["rows"], "min_ratio": test["min_ratio"]})
        if not cand:
            out.update({"rule": "ray",
                        "reason": (f"no entry of M'_driving is negative: {drv} rises without "
                                   f"bound (Lemke's secondary ray), nothing blocks")})
            return out
        tmin = test["min_ratio"]
        if test["z0_row"] >= 0:
            r = test["z0_row"]
            rule = "z0_preferred" if len(cand) > 1 else "min_ratio"
            reason = (f"{len(cand)} rows tie at {num(tmin)}; {ARTIFICIAL} is among them and "
                      f"leaves" if len(cand) > 1 else f"unique minimum ratio {num(tmin)}")
        elif len(cand) == 1:
            r, rule, reason = cand[0], "min_ratio", f"unique minimum ratio {num(tmin)}"
        else:
            binv = basis_inverse(Maug, t.dependent)
            r, lex = lexicographic(cand, col, lambda i: binv[i], names)
            out["lexicographic"] = lex
            rule = "lexicographic"
            reason = (f"{len(cand)} rows tie at {num(tmin)}; lexicographic tie-break on the rows "
                      f"of B^-1 divided by the pivot entry" +
                      (f", decided at column {lex['decided_by'][1:]} ({lex['decided_by']})"
                       if lex["decided_by"] else ": still tied, the first row wins"))
        out.update({"rule": rule, "reason": reason})
    blocking = names[r]
    nxt = complement(blocking)
    dep = list(names)
    dep[r] = drv
    out.update({"blocking": blocking, "row": r + 1, "next_entering": nxt,
                "next_dependent": dep,
                "pivot_element": {"row": r + 1, "column": drv, "value": scalar(col[r])}})
    if blocking == ARTIFICIAL:
        out["reason"] += f": {ARTIFICIAL} leaves, so Lemke's method ends with a solution"
    else:
        out["reason"] += (f": {blocking} leaves; by the complementary rule {nxt} enters at "
                          f"the next Lemke step")
    return out


def complementary(dependent: tuple[Var, ...], n: int) -> bool:
    """Whether the basis holds one variable of every pair (no ``z0``, no pair twice)."""
    return len({v[1] for v in dependent if v != ("z", n)}) == n


def canonical_independent(dependent: tuple[Var, ...], n: int) -> tuple[Var, ...]:
    """The variables not in ``dependent``, in the original order ``w1..wn, z1..zn, z0``."""
    dep = set(dependent)
    return tuple(v for v in all_vars(n) if v not in dep)


def off_lemke_path(dependent: tuple[Var, ...], driving: Var, n: int) -> str | None:
    """Why ``driving`` entering from the basis ``dependent`` is no step of Lemke's path (one
    line, in the user's terms, with what to give instead); None when it is one.

    Lemke's path runs through almost complementary bases: ``z0`` and one variable of each pair
    but one, whose two variables are both independent; one of them has just left and the
    other enters (the complementary rule).  It starts from a complementary basis (one variable
    of every pair, no ``z0``; ``w1..wn`` in the method) with ``z0`` entering.  A driving
    variable whose complement is dependent brings the basis back to a complementary one
    (when its complement blocks, the rule would make it enter again: it was "not
    independent") or to one holding a pair (``w_i`` and ``z_i`` both dependent).  Tuples that
    hold a pair (``--any-basis``) are not judged here.
    """
    art = ("z", n)
    names = ", ".join(var_name(v, n) for v in dependent)
    drv = var_name(driving, n)
    dep = set(dependent)
    if any(("w", i) in dep and ("z", i) in dep for i in range(n)):
        return None
    single = f"(--driving {drv} without --follow shows this one ratio test)"
    if art not in dep:
        if driving == art:
            return None
        return (f"--follow follows Lemke's path, which from a basis without {ARTIFICIAL} "
                f"({names}) starts with {ARTIFICIAL} entering (Lemke's first pivot), not "
                f"{drv}: give --driving {ARTIFICIAL} {single}")
    free = [i for i in range(n) if ("w", i) not in dep and ("z", i) not in dep]
    if driving[1] in free and driving != art:
        return None
    pair = " or ".join(f"--driving {var_name((k, i), n)}" for i in free for k in "wz")
    return (f"--follow follows Lemke's path, on which the variable entering a basis with "
            f"{ARTIFICIAL} ({names}) is one of the pair with neither variable dependent (one "
            f"of them just left, the other enters), not {drv}: give {pair} {single}")


def follow(Maug: np.ndarray, q: np.ndarray, dependent: tuple[Var, ...],
           independent: tuple[Var, ...] | None, driving: Var, *, full: bool = False,
           any_basis: bool = False, max_steps: int = FOLLOW_MAX_STEPS
           ) -> list[tuple[PivotTransform, dict[str, Any]]]:
    """Lemke's path through Dai & Drumwright's transforms, from a basis and a driving variable.

    Each item is the transform of one basis (with its driving column) and its
    :func:`driving_step`; when ``z0`` leaves, a last item holds the final basis (the solution)
    and ``None``.  Later bases list the independent variables in the original order.
    """
    n = q.shape[0]
    out = []
    dep, ind, drv = tuple(dependent), independent, driving
    if driving not in dep and (why := off_lemke_path(dep, driving, n)) is not None:
        raise ProblemError(why)
    for _ in range(max_steps):
        if out and drv in dep:  # from a start holding a pair (--any-basis) the rule can name
            # a dependent variable (it said "driving variable z1 is not independent")
            names = ", ".join(var_name(v, n) for v in dep)
            raise ProblemError(
                f"--follow: at step {len(out) - 1} {out[-1][1]['blocking']} left, and by the "
                f"complementary rule its complement {var_name(drv, n)} would enter next, but "
                f"it is dependent in the new basis ({names}): this path is not Lemke's, whose "
                f"bases hold {ARTIFICIAL} and one variable of every other pair (start from "
                f"w1..w{n} with --driving {ARTIFICIAL})")
        t = principal_pivot(Maug, q, dep, ind, driving=drv, full=full, any_basis=any_basis)
        step = driving_step(t, Maug)
        out.append((t, step))
        if step["blocking"] == ARTIFICIAL:  # the final basis: Lemke's solution
            dep = tuple(parse_var(s, n) for s in step["next_dependent"])
            out.append((principal_pivot(Maug, q, dep, canonical_independent(dep, n),
                                        full=full, any_basis=any_basis), None))
            break
        if step["blocking"] is None or step["next_entering"] is None:
            break
        dep = tuple(parse_var(s, n) for s in step["next_dependent"])
        ind = canonical_independent(dep, n)
        drv = parse_var(step["next_entering"], n)
    return out
