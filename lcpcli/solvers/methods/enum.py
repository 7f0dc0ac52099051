"""Enumeration of the complementary cones (Murty, ch. 1): the exhaustive method.

Problem: LCP(q, M), ``w = M z + q``.  Visits the ``2^n`` complementary matrices ``A_r`` (column
``I_j`` for ``w_j`` basic, ``-M_j`` for ``z_j`` basic) and solves ``A_r y = q, y >= 0``; see
:mod:`lcpcli.analysis.enumeration`.

Matrix classes: any square M (no assumption at all), for small n: the cost is ``2^n`` small
LU solves.  By default it stops at the first solution; with ``all=true`` it visits every cone
and reports how many distinct solutions exist.  When no cone contains q the LCP has no
solution; the verdict is ``no_solution`` when a Farkas vector then proves it
(:mod:`lcpcli.analysis.proof`), else ``unsolved``.  ``max_n`` (default 24)
refuses larger problems.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.analysis.enumeration import basis_names, enumerate_cones
from lcpcli.core.result import CONVERGED, INFEASIBLE, NUMERICAL, Outcome
from lcpcli.core.text import plural
from lcpcli.solvers.options import bool_option
from lcpcli.solvers.registry import Cost, Guarantee, Method, Option, when


def _max_n(value: Any) -> int:
    v = int(value)
    if v < 1:
        raise ValueError("must be a positive integer")
    return v


#: Largest n enumerated unless the ``max_n`` option says otherwise.
DEFAULT_MAX_N = 24
#: Largest n at which ``auto`` tries the enumeration, last, when every other method failed
#: (2^12 = 4,096 cones: about a millisecond).
AUTO_MAX_N = 12


def run(problem: Any, *, tol: float, max_n: int = DEFAULT_MAX_N,
        all: bool = False) -> Outcome:  # noqa: A002
    """Enumerate the cones of ``problem``; return the first solution (or all, counted)."""
    res = enumerate_cones(problem, stop_at_first=not all, max_n=max_n, tol=tol)
    n = res.n
    info = {"verdict": res.verdict, "cones_examined": res.examined, "cones_total": res.total,
            "solutions": len(res.solutions), **res.counts}
    if not res.solutions and res.verdict != "none":
        why = (f"q lies in {plural(res.counts['uncertified'], 'cone')}, but no point found "
               f"there passes the certificate (extreme data, or an ill-conditioned cone)"
               if res.verdict == "uncertified" else
               f"{plural(res.counts['singular_unresolved'], 'singular cone')} containing q "
               f"not resolved (LP limit)")
        return Outcome(np.zeros(n), res.examined, NUMERICAL,
                       f"no solution found: {why}; nothing is proven", info=info)
    if not res.solutions:
        counted = (f"({res.counts['pruned']:,} excluded by sign tests, "
                   f"{res.counts['singular']:,} singular)")
        searched = f"none of the 2^{n} = {res.total:,} complementary cones contains q {counted}"
        seemed = res.counts["uncertified"] + res.counts["singular_unresolved"]
        if seemed:
            searched = (f"no point of the 2^{n} = {res.total:,} complementary cones passes the "
                        f"certificate (q seemed to lie in {plural(seemed, 'cone')} in "
                        f"floating point)")
        if res.proof is None:  # the floating-point tests saw no cone: that proves nothing
            return Outcome(np.zeros(n), res.examined, NUMERICAL,
                           f"no complementary cone of the 2^{n} = {res.total:,} was found to "
                           f"contain q in floating point {counted}, and no Farkas vector "
                           f"proves infeasibility: a solution may still exist (in an "
                           f"ill-conditioned cone, with z far larger than the data); nothing "
                           f"is proven", info=info)
        return Outcome(np.zeros(n), res.examined, INFEASIBLE,
                       f"{searched}; {res.proof.describe()}", proven_infeasible=True,
                       info={**info, "farkas_y": res.proof.y.tolist()})
    first = res.solutions[0]
    cone = ", ".join(basis_names(first.cones[0], n))
    if all:
        kind = {"unique": "the unique solution", "finite": f"{len(res.solutions)} distinct "
                f"solutions (the first is returned)", "continuum": "a continuum of solutions "
                "(one point returned)"}.get(res.verdict, res.verdict)
        msg = f"{kind}; all {res.total:,} cones examined, the first in cone ({cone})"
    else:
        msg = (f"first solution found in cone ({cone}) after {res.examined:,} of "
               f"{res.total:,} cones (-O all=true counts all solutions)")
    return Outcome(first.z, res.examined, CONVERGED, msg, info=info)


METHODS = [
    Method(
        name="enum",
        run=run,
        summary="Enumeration of the 2^n complementary cones (Murty), exhaustive",
        guarantees=(Guarantee(when(), "every solution (2^n cones); no_solution with a checked "
                                        "Farkas vector"),),
        max_n=DEFAULT_MAX_N,
        cost=Cost.EXHAUSTIVE,
        fallback="every complementary cone: the last resort on a small problem",
        auto_max_n=AUTO_MAX_N,
        kinds=("lcp",),
        options={
            "max_n": Option(_max_n, DEFAULT_MAX_N,
                            f"refuse problems with more variables (default {DEFAULT_MAX_N})"),
            "all": Option(bool_option, False, "visit every cone and count the distinct solutions"),
        },
        aliases=("enumerate", "enumeration"),
        # enumerate_cones equilibrates by itself (Ruiz, else Curtis-Reid) and solves a cone
        # whose point fails there again in the problem's units: a second scaling around it
        # would hide those units
        scaling="none",
    ),
]
