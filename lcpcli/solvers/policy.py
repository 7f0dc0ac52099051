"""``auto``'s policy as data: which method to try, in which order, and why.

Everything here is derived from two tables:

* :data:`REGIMES` (this module): by size and storage, the order of the cost classes
  (:class:`~lcpcli.solvers.registry.Cost`) in which auto tries methods; a cost class absent
  from a regime's order is not tried there (e.g. dense pivoting above n = 5000);
* the rows declared by the methods themselves (:func:`rows`): one row per
  :class:`~lcpcli.solvers.registry.Guarantee` (condition on the class report -> method, claim)
  and one fallback row (any M -> method) for a method that declares a ``fallback``.

In a regime the rows are ordered by tier (plain guarantees, then slow ones, then fallbacks),
cost class (the regime's order), the method's ``preference``, and name, the exhaustive ones
(enumeration, small problems only: ``Method.auto_max_n``) last; the plan is that list,
keeping for each method its first row whose condition holds and dropping methods that cannot
start (a :class:`~lcpcli.solvers.registry.Requirement` that fails, ``n > max_n``, a sparse M
too large to densify).  :func:`plan` (auto), :func:`applicability` (``lcpcli info``) and
:func:`markdown` (the tables of docs/methods.md) all read these tables; no method is named here.

Optimism: in a regime marked optimistic, auto's first attempt is planned with
:meth:`Classifier.cheap` (only the O(n) and O(n^2) tests a row needs run), an open condition
counting as true; after a failure, and in the other regimes from the start, the rows are
evaluated lazily (:func:`iter_plan`), each running the tests its condition names.  The
certificate decides, never the classification.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Any, NamedTuple

from lcpcli.analysis.classify import Classifier, ClassReport, diagonal_facts
from lcpcli.solvers.memo import OPENINGS, ORDERS
from lcpcli.solvers.registry import Condition, Cost, Method, methods, when
from lcpcli.solvers.registry import version as registry_version

#: Dense problems up to this size (sparse ones up to :data:`SMALL_SPARSE_N`) go to the
#: pivoting methods first.
PIVOT_MAX_N = 1500
#: Dense problems above this size are never given to the O(n^3)-per-solve pivoting methods.
PIVOT_HARD_MAX_N = 5000
#: Sparse problems up to this size are treated like small dense ones (pivoting first).
SMALL_SPARSE_N = 200
#: Sparse LU fill ratio (nnz(L+U) / nnz(S)) up to which a sparse PSD problem goes to the
#: factoring methods (sparse LU) first.
LOW_FILL = 30.0

TIERS = ("guarantee", "slow guarantee", "fallback")


@dataclass(frozen=True)
class Regime:
    """A row of the regime table: problems where ``test`` holds try cost classes in ``order``;
    ``optimistic``: the first attempt is planned on the cheap tests only (else on all the tests
    the rows need, when a failed attempt costs more than the O(n^3) tests)."""

    name: str
    text: str
    test: Callable[[Classifier], bool]
    order: tuple[Cost, ...]
    optimistic: bool


def _small(c: Classifier) -> bool:
    r = c.report
    return r.n <= (SMALL_SPARSE_N if r.sparse else PIVOT_MAX_N)


def _sparse_low_fill(c: Classifier) -> bool:
    r = c.report
    if not r.sparse:
        return False
    c.get("psd")  # the sparse definiteness test measures the fill of the factorisation
    return bool(r.psd) and r.factor_fill is not None and r.factor_fill <= LOW_FILL


#: The regime table, first match wins.  Optimism where a wrong first attempt costs about
#: what the O(n^3) tests cost (a pivoting method on a small problem, sparse LU once the
#: factorisation is known to be cheap); tests first where it may cost much more (1000 sweeps
#: of a method that does not converge, or a dense factorisation per Newton step).
REGIMES: tuple[Regime, ...] = (
    Regime("small", f"dense with n <= {PIVOT_MAX_N:,}, or sparse with n <= {SMALL_SPARSE_N}",
           _small, (Cost.PIVOTING, Cost.FACTORING, Cost.SWEEPING, Cost.EXHAUSTIVE), True),
    Regime("sparse, cheap to factor", f"sparse PSD whose factorisation fills in little "
                                      f"(nnz(L+U)/nnz(S) <= {LOW_FILL:g})",
           _sparse_low_fill, (Cost.FACTORING, Cost.SWEEPING, Cost.PIVOTING), True),
    Regime("large", f"dense with n <= {PIVOT_HARD_MAX_N:,}, or sparse with n <= "
                    f"{PIVOT_HARD_MAX_N:,}",
           lambda c: c.report.n <= PIVOT_HARD_MAX_N,
           (Cost.SWEEPING, Cost.FACTORING, Cost.PIVOTING), False),
    Regime("huge", f"n > {PIVOT_HARD_MAX_N:,}", lambda c: True,
           (Cost.SWEEPING, Cost.FACTORING), False),
)


@dataclass(frozen=True)
class Row:
    """A row of the policy table: when ``when`` holds, ``method`` may be tried, for ``reason``."""

    when: Condition
    method: str
    reason: str
    tier: int  # index into TIERS
    cost: Cost
    preference: int
    #: The reason when the condition is assumed (optimistic first attempt).
    assumed_reason: str = ""
    #: The method's record (None in tables built without one).
    spec: Method | None = None


class Step(NamedTuple):
    """One entry of a plan: the method, why, and whether its condition is established
    (``True``), assumed because not tested yet (``None``, optimistic planning) or not
    needed (``False``: a fallback)."""

    method: str
    reason: str
    established: bool | None


def rows(kind: str, registry: Mapping[str, Method]) -> list[Row]:
    """The (unordered) policy rows of the methods handling ``kind``."""
    out = []
    for name, m in registry.items():
        if m.planner or kind not in m.kinds:
            continue
        for g in m.guarantees:
            if g.applies_to(kind):
                reason = f"{g.when}: {g.claim}" if g.when.props else g.claim
                assumed = (f"assumed, not tested before this first attempt: if M is {g.when}, "
                           f"{g.claim}")
                out.append(Row(g.when, name, reason, 1 if g.slow else 0, m.cost, m.preference,
                               assumed, m))
        if m.fallback is not None:
            pref = m.preference if m.fallback_preference is None else m.fallback_preference
            out.append(Row(when(), name, m.fallback, 2, m.cost, pref, m.fallback, m))
    return out


def ordered(rows_: Iterable[Row], regime: Regime) -> list[Row]:
    """``rows_`` in the regime's order (rows of a cost class the regime does not try dropped)."""
    keep = [r for r in rows_ if r.cost in regime.order]
    # an exponential method is the last resort whatever its tier
    return sorted(keep, key=lambda r: (r.cost is Cost.EXHAUSTIVE, r.tier,
                                       regime.order.index(r.cost), r.preference, r.method))


def plannable(m: Method) -> bool:
    """Can auto ever try ``m`` (it is not the planner and some regime tries its cost class)?"""
    return not m.planner and any(m.cost in r.order for r in REGIMES)


def regime_of(c: Classifier) -> Regime:
    """The first regime whose test holds."""
    for regime in REGIMES:
        if regime.test(c):
            return regime
    raise AssertionError("the last regime holds for every problem")


def cannot_start(m: Method, c: Classifier, value: Callable[[str], bool | None], *,
                 needs: bool = True) -> str | None:
    """Why ``m`` cannot start on the problem (too large, it would densify a huge sparse M,
    a failed requirement: unless ``needs`` is False), or None when it can."""
    if m.max_n is None and not m.needs and (m.sparse or not c.report.sparse):
        return None
    n = c.report.n
    if m.max_n is not None and n > m.max_n:
        return f"n = {n} is above its limit max_n = {m.max_n}"
    if m.densifies(c.problem):
        return f"would densify a sparse {n} x {n} matrix"
    if needs:
        failed = next((r for r in m.needs if r.when.evaluate(value) is False), None)
        if failed is not None:
            return f"needs {failed.when}: {failed.why}"
    return None


def table_key(kind: str, regime: Regime,
              registry: Mapping[str, Method] | None) -> tuple[Any, ...]:
    """The key of :data:`lcpcli.solvers.memo.ORDERS`: the ordered rows depend on the kind,
    the regime and the registry (its version for the live one, else its records)."""
    if registry is None:
        return (kind, regime.name, registry_version())
    return (kind, regime.name, tuple(map(id, registry.values())))


def _table(kind: str, regime: Regime, registry: Mapping[str, Method] | None) -> list[Row]:
    """The ordered rows (memoised by :func:`table_key`; None: the live registry)."""
    key = table_key(kind, regime, registry)
    table = ORDERS.get(key)
    if table is None:
        reg = methods() if registry is None else registry
        table = ORDERS.put(key, ordered(rows(kind, reg), regime))
    return table


def plan(problem: Any, c: Classifier, registry: Mapping[str, Method] | None = None, *,
         optimistic: bool = False, skip: Iterable[str] = (), first: bool = False,
         regime: Regime | None = None) -> list[Step]:
    """The ordered steps for ``problem`` (classifier ``c``; ``regime``: ``regime_of(c)``).

    ``optimistic``: conditions are evaluated with the cheap tests only
    (:meth:`Classifier.cheap`) and an open one counts as true; otherwise every test a row needs
    is run (:meth:`Classifier.get`) and an undecided condition counts as false.  ``skip``:
    methods already tried.  ``first``: stop at the first step (auto's first attempt).
    """
    steps = iter_plan(problem, c, registry, optimistic=optimistic, skip=skip, regime=regime)
    return list(islice(steps, 1)) if first else list(steps)


def opening_key(c: Classifier) -> tuple[Any, ...] | None:
    """The key of :data:`lcpcli.solvers.memo.OPENINGS` for a dense problem (None: sparse,
    never memoised), after the O(n) diagonal test: the kind, n (the dense regimes depend on n
    only), the registry's version and every fact that test decides
    (:func:`lcpcli.analysis.classify.diagonal_facts`)."""
    r = c.report
    if r.sparse:
        return None
    if r.positive_diagonal is None:
        c.run("positive_diagonal")
    return (r.kind, r.n, registry_version(), diagonal_facts(r))


def opening(problem: Any, c: Classifier) -> tuple[Regime, Step | None]:
    """The problem's regime and, when the regime is optimistic, the step tried first
    (``plan(problem, c, optimistic=True, first=True, regime=regime)``'s; None otherwise, or
    when no method applies).

    Memoised (:func:`opening_key`) for a dense problem whose plan needed only the O(n)
    diagonal test, so a repeated small solve skips the regime and row walks.  Anything else is
    planned afresh."""
    key = opening_key(c)
    if key is not None:
        found = OPENINGS.get(key)
        if found is not None:
            return found
    before = c.tests_run
    regime = regime_of(c)
    step = None
    if regime.optimistic:
        steps = plan(problem, c, optimistic=True, first=True, regime=regime)
        step = steps[0] if steps else None
    if key is not None and c.tests_run == before:
        OPENINGS.put(key, (regime, step))
    return regime, step


def first_step(problem: Any, c: Classifier) -> tuple[Regime, Step | None]:
    """``auto``'s first attempt and the regime: in an optimistic regime the :func:`opening`
    (cheap tests only), otherwise the first step of the plan with every test it needs."""
    regime, step = opening(problem, c)
    if not regime.optimistic:
        step = next(iter_plan(problem, c, regime=regime), None)
    return regime, step


def iter_plan(problem: Any, c: Classifier, registry: Mapping[str, Method] | None = None, *,
              optimistic: bool = False, skip: Iterable[str] = (),
              regime: Regime | None = None) -> Iterator[Step]:
    """:func:`plan`, lazily: each row's tests run only when the steps before it are consumed
    (so auto runs no test that the method it ends up using did not need)."""
    table = _table(c.report.kind, regime or regime_of(c), registry)
    value = c.cheap if optimistic else c.get
    done = set(skip) if skip else set()
    for row in table:
        if row.method in done:
            continue
        holds = row.when.evaluate(value) if row.when.props else True
        if holds is False or (holds is None and not optimistic):
            continue
        done.add(row.method)
        if cannot_start(row.spec, c, value) is not None:  # type: ignore[arg-type]
            continue
        if row.spec is not None and row.spec.auto_max_n is not None and \
                c.report.n > row.spec.auto_max_n:  # a size auto leaves to the user
            continue
        if row.tier == 2:
            yield Step(row.method, row.reason, False)
        elif holds:
            yield Step(row.method, row.reason, True)
        else:
            yield Step(row.method, row.assumed_reason, None)


def applicability(problem: Any, c: Classifier,
                  registry: Mapping[str, Method] | None = None) -> list[dict[str, Any]]:
    """For each registered method: does it apply to ``problem``, and why (every test run).

    ``applies`` is ``"yes"`` (a guarantee's condition holds), ``"maybe"`` (it may work, without
    a guarantee) or ``"no"`` (wrong problem kind, too large, or it cannot start, e.g. PGS with a
    zero diagonal entry).  ``auto_rank`` is the 1-based position in auto's plan (or None).
    """
    reg = methods() if registry is None else registry
    kind = problem.kind
    rank = {s.method: i + 1 for i, s in enumerate(plan(problem, c, reg))}
    out = []
    for name, m in reg.items():
        if kind not in m.kinds:
            applies, why = "no", (f"handles {'/'.join(k.upper() for k in m.kinds)} problems, "
                                  f"not {kind.upper()}")
        elif m.planner:
            applies, why = "yes", "picks a method from the classification (its plan below)"
        elif (why_not := cannot_start(m, c, c.get)) is not None:
            applies, why = "no", why_not
        else:
            applies, why = _guarantee_or_not(m, kind, c)
        out.append({"method": name, "applies": applies, "why": why,
                    "auto_rank": rank.get(name)})
    return out


def _guarantee_or_not(m: Method, kind: str, c: Classifier) -> tuple[str, str]:
    undecided = []
    for g in m.guarantees:
        if not g.applies_to(kind):
            continue
        holds = g.when.evaluate(c.get)
        if holds:
            return "yes", (f"{g.when}: {g.claim}" if g.when.props else g.claim)
        if holds is None:
            undecided.append(str(g.when))
    if undecided:
        return "maybe", f"{' / '.join(undecided)} undecided: no guarantee known"
    extra = f"; {m.fallback}" if m.fallback else ""
    if m.guarantees:
        classes = "; ".join(str(g.when) for g in m.guarantees if g.applies_to(kind))
        return "maybe", f"outside its classes ({classes or 'none for this kind'}){extra}"
    return "maybe", (m.fallback or m.notes or "no guarantee")


def info_report(problem: Any, file: str | None = None,
                registry: Mapping[str, Method] | None = None) -> dict[str, Any]:
    """The ``lcpcli info`` report (JSON-safe): the complete class report, each method's
    applicability and auto's plan.

    Schema: ``{"file", "problem", "summary", "regime", "classification": {...}, "methods":
    [{"method", "applies", "why", "auto_rank"}], "auto_first": [method, reason] or null,
    "auto_plan": [[method, reason], ...], "seconds"}``: ``auto_first`` is auto's optimistic
    first attempt (cheap tests only), ``auto_plan`` its order with every test run (what it
    tries after a failed first attempt); ``seconds`` is the classification time.
    """
    reg = methods() if registry is None else registry
    t0 = time.perf_counter()
    c = Classifier(problem)
    regime = regime_of(c)
    first = plan(problem, c, reg, optimistic=regime.optimistic, first=True, regime=regime)
    report: ClassReport = c.complete()
    secs = time.perf_counter() - t0
    return {"file": file, "problem": problem.name, "summary": problem.summary(),
            "regime": regime_of(c).name, "classification": report.as_dict(),
            "methods": applicability(problem, c, reg),
            "auto_first": [first[0].method, first[0].reason] if first else None,
            "auto_plan": [[s.method, s.reason] for s in plan(problem, c, reg)],
            "seconds": secs}


# ---------------------------------------------------------------------------- docs tables
BEGIN = "<!-- policy tables: generated by `python -m lcpcli.solvers.policy docs/methods.md` -->"
END = "<!-- end of policy tables -->"


def markdown(registry: Mapping[str, Method] | None = None) -> str:
    """The method and policy tables of docs/methods.md (between :data:`BEGIN` and
    :data:`END`), generated from the registry and :data:`REGIMES`."""
    reg = methods() if registry is None else registry
    lines = [BEGIN, "", "| method | problems | guarantees (condition: claim) | cannot start | "
             "cost | auto | options |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for name, m in reg.items():
        label = f"`{name}`" + (f" ({', '.join(f'`{a}`' for a in m.aliases)})"
                               if m.aliases else "")
        kinds = ", ".join(k.upper() if k != "box" else "box" for k in m.kinds)
        if m.planner:
            guar, cost, auto = "the guarantees of the method it picks", "-", "(default)"
        else:
            guar = "; ".join(f"{g.when}: {g.claim}"
                             + (f" ({'/'.join(k.upper() for k in g.kinds)} only)"
                                if g.kinds else "") for g in m.guarantees) or "none"
            cost = m.cost.value
            auto = ("never" if not plannable(m) else
                    f"fallback: {m.fallback}" if m.fallback else "only where guaranteed")
        cannot = "; ".join([f"not {r.when} ({r.why})" for r in m.needs]
                           + ([f"n > {m.max_n}"] if m.max_n is not None else [])
                           + ([f"auto: n > {m.auto_max_n}"] if m.auto_max_n is not None
                              else [])) or "-"
        opts = ", ".join(f"`{o}`" for o in m.options) or "-"
        lines.append(f"| {label} | {kinds} | {guar} | {cannot} | {cost} | {auto} | {opts} |")
    lines += ["", "Regimes (first match wins), the order in which `auto` tries cost "
              "classes there, and whether its first attempt is optimistic (planned on the "
              "O(n) and O(n^2) tests only):", "",
              "| regime | problems | cost classes, in order | first attempt |",
              "| --- | --- | --- | --- |"]
    for r in REGIMES:
        first = "optimistic" if r.optimistic else "after the tests its rows need"
        lines.append(f"| {r.name} | {r.text} | {', '.join(c.value for c in r.order)} | "
                     f"{first} |")
    lines += ["", "The resulting order for an LCP whose classes are all established "
              "(within a regime, a method is tried at its first row whose condition holds):", ""]
    for r in REGIMES:
        table = ordered(rows("lcp", reg), r)
        parts = [f"`{row.method}` ({row.when})" if row.tier < 2 else f"`{row.method}`"
                 for row in table]
        lines.append(f"- **{r.name}**: " + ", ".join(parts) + ".")
    lines += ["", END]
    return "\n".join(lines)


def write_docs(path: str | Path) -> bool:
    """Replace the generated block of ``path`` by :func:`markdown`; True if it changed."""
    p = Path(path)
    text = p.read_text()
    start, stop = text.index(BEGIN), text.index(END) + len(END)
    new = text[:start] + markdown() + text[stop:]
    if new != text:
        p.write_text(new)
    return new != text


if __name__ == "__main__":  # python -m lcpcli.solvers.policy docs/methods.md
    for arg in sys.argv[1:] or ["docs/methods.md"]:
        print(f"{arg}: {'updated' if write_docs(arg) else 'up to date'}")
