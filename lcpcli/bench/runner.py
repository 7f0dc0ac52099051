"""The benchmark runner behind ``lcpcli bench``: speed against error, with defect detection.

Conventions (all stated once here; ``docs/bench.md`` repeats them for users):

* **Timing.**  Each (problem, method, tol) is solved once untimed (the warm-up; its answer is
  the one certified), then up to ``repeat`` more times, stopping early once the timed runs add up
  to ``budget`` seconds; ``seconds`` is the median of the timed runs, each the method's own time
  from :func:`lcpcli.api.solve`: the dispatcher's run, which includes the certificate of the
  answer (no file loading, no request checks; nothing is compiled at run time).  A peer's time
  is its solver call alone, which certifies nothing.  When the warm-up alone exceeds
  ``budget`` there are no timed runs and its time is used (``repeats = 0``).
* **Success** means the right outcome: ``solved`` on a problem expected ``solvable``,
  ``no_solution`` on one expected ``infeasible``, either on one of unknown outcome.
* **Defect** (must never happen; exit code 1): a method claims ``solved`` but the certificate
  recomputed here from the problem and the returned z fails; or it claims ``no_solution`` on a
  problem known to be solvable, or without a Farkas vector (``info["farkas_y"]``) that passes
  :func:`lcpcli.analysis.proof.check_farkas` re-run here on the problem; or the suite says
  ``infeasible`` but a certified solution came back (then the suite is wrong).  ``unsolved``
  is never a defect: it is an honest failure.
* **Shifted geometric mean** of times: ``exp(mean(log(t + s))) - s`` with shift ``s = 10 ms``
  over the problems a method was run on; a failure counts as :data:`PENALTY` times the slowest
  time any method (peers included) took on that problem, and never less than its own time.
* **Performance profile** (Dolan and More 2002): the methods and peers run on at least one
  problem, over the problems at least one of them was run on,
  ``r[p, s] = t[p, s] / min_s t[p, s]`` with failures infinite (a problem a method was not run
  on, of another kind or above its size limit, is a failure; times floored at the clock's
  resolution :data:`TIME_FLOOR`); ``rho_s(tau) = fraction of problems with r[p, s] <= tau``.
* **Errors** are the certificate's error (:mod:`lcpcli.core.certificate`); ``z_error`` is the
  forward error ``||z - z*||_inf / max(1, ||z*||_inf)`` when the case has a unique known z*.
"""

from __future__ import annotations

import math
import statistics
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from lcpcli.bench.suites import INFEASIBLE, SOLVABLE, Case
from lcpcli.core.certificate import certify, validate_tol
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.limits import CostNote
from lcpcli.core.result import Status
from lcpcli.core.text import one_line_warnings
from lcpcli.solvers.kernels import process_context

#: Shift of the shifted geometric mean, in seconds.
SHIFT = 0.010
#: The clock's resolution: a time below it (0.0) counts as this in ratios of times
#: (performance profile, peer ratios), which need positive times.
TIME_FLOOR = time.get_clock_info("perf_counter").resolution
#: A failure counts as this many times the slowest time on its problem.
PENALTY = 10.0
#: Default tolerances, repeats and time budget per (problem, method, tol).
DEFAULT_TOLS = (1e-8,)
DEFAULT_REPEAT = 5
DEFAULT_BUDGET = 1.0
UNKNOWN = "unknown"
ERROR = Status.ERROR  # status when a method raised instead of returning
TIMEOUT = Status.TIMEOUT  # status when an isolated run was killed
#: Default wall-clock limit of one (problem, method, tol) run, warm-up and repeats included.
DEFAULT_TIMEOUT = 60.0
#: Modules the forkserver of isolated runs imports once (each child starts with them).
PRELOAD = ("lcpcli.api", "lcpcli.bench.runner")


@dataclass
class Record:
    """One benchmark row: a method (or peer) on a problem at a tolerance."""

    problem: str
    n: int
    method: str
    status: str
    seconds: float | None
    iterations: int | None
    error: float | None
    expected: str
    defect: bool
    tol: float
    kind: str = "lcp"
    success: bool = False
    defect_reason: str = ""
    residual: float | None = None
    z_error: float | None = None
    repeats: int = 0
    peer: str | None = None
    claimed: bool | None = None
    message: str = ""
    #: Wall seconds after which the run was killed (status ``timeout``), else None: its own
    #: time is at least this, which the failure penalty of :func:`charged_time` respects.
    killed_after: float | None = None

    def to_json(self) -> dict[str, Any]:
        """The ``--json`` line (non-finite numbers become null)."""
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, float) and not math.isfinite(v):
                d[k] = None
        return d


@dataclass
class BenchReport:
    """All records of a run plus what was (not) run."""

    records: list[Record]
    methods: list[str]
    tols: list[float]
    problems: list[tuple[str, int, str, str]]  # (name, n, kind, expected)
    peers: dict[str, str] = field(default_factory=dict)  # family -> version
    missing_peers: dict[str, str] = field(default_factory=dict)  # family -> why
    skipped: list[tuple[str, str, str]] = field(default_factory=list)  # (problem, method, why)

    @property
    def defects(self) -> list[Record]:
        return [r for r in self.records if r.defect]

    @property
    def errors(self) -> list[Record]:
        """Rows of our own methods that raised or whose child process died (status
        ``error``; a timeout is not one, nor a peer's failure): an internal error."""
        return [r for r in self.records if r.status == ERROR and not r.peer]

    def all_methods(self) -> list[str]:
        """Own methods first, then the peer solvers that produced records."""
        peers = []
        for r in self.records:
            if r.peer and r.method not in peers:
                peers.append(r.method)
        return list(self.methods) + peers


# ---------------------------------------------------------------------- problems
def cases_from_paths(paths: Iterable[str]) -> list[Case]:
    """Load files, folders (recursively, known extensions) and every problem of HDF5 files.

    Problems are named after their file (``stem``, or ``stem/group`` inside a multi-problem
    HDF5 file).  The expected outcome of a file is ``unknown`` unless the problem's ``meta`` has
    ``expected`` (``solvable``/``infeasible``).  Loading happens here, outside any timing.
    """
    from lcpcli.io import FORMATS, list_problems, load

    cases: list[Case] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            files = sorted(f for f in p.rglob("*") if f.suffix.lower() in FORMATS and f.is_file())
            if not files:
                raise ProblemError("folder holds no problem files", str(p))
        elif p.exists():
            files = [p]
        else:
            raise ProblemError("no such file", str(p))
        for f in files:
            names = list_problems(f)
            many = len(names) > 1
            for name in names:
                prob = load(f, name if many else None)
                prob.name = f"{f.stem}/{name}" if many else f.stem
                exp = str(prob.meta.get("expected", UNKNOWN))
                cases.append(Case(problem=prob, expected=exp if exp in (SOLVABLE, INFEASIBLE)
                                  else UNKNOWN, note=str(f), source=str(f)))
    return cases


# ---------------------------------------------------------------------- verdicts
def judge(case: Case, status: str, z: np.ndarray | None, tol: float,
          farkas: Any = None) -> tuple[bool, bool, str, Any]:
    """(success, defect, reason, certificate) for a claimed ``status``, returned ``z`` and, for
    ``no_solution``, the Farkas vector ``farkas`` behind it (``Result.info["farkas_y"]``).

    The certificate and the Farkas check are recomputed here from the problem, trusting nothing
    the method said.
    """
    cert = None
    if z is not None and np.asarray(z).shape == (case.n,):
        cert = certify(case.problem, np.asarray(z, dtype=float), tol)
    passed = bool(cert is not None and cert.passed)
    defect, reason = False, ""
    if status == Status.SOLVED and not passed:
        defect = True
        err = "none" if cert is None else f"{cert.error:.3g}"
        reason = f"claimed solved but the recomputed certificate fails (error {err} > {tol:g})"
    elif status == Status.NO_SOLUTION and case.expected == SOLVABLE:
        defect = True
        reason = "claimed no_solution on a problem known to be solvable"
    elif status == Status.NO_SOLUTION and (why := _farkas_fails(case, farkas)):
        defect = True
        reason = f"claimed no_solution but {why}"
    elif case.expected == INFEASIBLE and passed and status == Status.SOLVED:
        defect = True
        reason = ("claimed solved on a problem proven infeasible: the certified error "
                  f"{cert.error:.2g} passes only because ||z||_inf = "
                  f"{float(np.max(np.abs(z))):.2g} (residual {cert.residual:.2g})")
    if case.expected == INFEASIBLE:
        success = status == Status.NO_SOLUTION and not defect
    elif case.expected == SOLVABLE:
        success = status == Status.SOLVED and passed
    else:  # unknown outcome: a certified solution or a re-checked proof
        success = (status == Status.SOLVED and passed) or (status == Status.NO_SOLUTION
                                                           and not defect)
    return success, defect, reason, cert


def _farkas_fails(case: Case, farkas: Any) -> str:
    """Why ``farkas`` does not prove ``case`` infeasible ("" when it does), by
    :func:`lcpcli.analysis.proof.check_farkas` on the problem as given."""
    from lcpcli.analysis.proof import check_farkas

    if farkas is None:
        return "it gave no Farkas vector"
    lo, up = case.problem.bounds()
    got = check_farkas(case.problem.M, case.problem.q, lo, up,
                       np.asarray(farkas, dtype=np.float64))
    return "" if got.passed else f"its Farkas vector fails the check ({got.reason})"


def _z_error(case: Case, z: np.ndarray | None) -> float | None:
    if z is None or case.solution is None or not case.unique:
        return None
    z = np.asarray(z, dtype=float)
    if z.shape != case.solution.shape or not np.all(np.isfinite(z)):
        return None
    return float(np.max(np.abs(z - case.solution)) / max(1.0, np.max(np.abs(case.solution))))


# ---------------------------------------------------------------------- runner
SolveFn = Callable[..., Any]


def _default_solve() -> SolveFn:
    from lcpcli.api import solve

    return solve


def resolve_methods(names: Iterable[str] | None) -> list[str]:
    """Canonical method names (aliases resolved, duplicates dropped); None = all registered."""
    from lcpcli.solvers.registry import methods
    from lcpcli.solvers.request import method_of

    if names is None:
        return list(methods())
    out: list[str] = []
    for name in names:
        if not name.strip():
            continue
        canon = method_of(name).name
        if canon not in out:
            out.append(canon)
    if not out:
        raise OptionError("no method given")
    return out


def run_one(case: Case, method: str, tol: float, *, repeat: int = DEFAULT_REPEAT,
            budget: float = DEFAULT_BUDGET, solve_fn: SolveFn | None = None) -> Record:
    """Benchmark ``method`` on ``case`` at ``tol`` (warm-up, timed repeats, verdict).  The
    cost notes of the runs (:class:`lcpcli.core.limits.CostNote`: an enumeration of 2^24
    cones, once per run and repeat) are not shown: the bench announces its own work."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CostNote)
        return _run_one(case, method, tol, repeat=repeat, budget=budget, solve_fn=solve_fn)


def _run_one(case: Case, method: str, tol: float, *, repeat: int, budget: float,
             solve_fn: SolveFn | None) -> Record:
    solve_fn = solve_fn or _default_solve()
    prob = case.problem
    try:
        first = solve_fn(prob, method, tol=tol)
    except OptionError:
        raise
    except Exception as exc:  # noqa: BLE001 - a crashing method is a result, not a bench crash
        success, defect, reason, _ = judge(case, ERROR, None, tol)
        return Record(prob.name, prob.n, method, ERROR, None, None, None, case.expected, defect,
                      tol, prob.kind, success, reason, message=f"{type(exc).__name__}: {exc}")
    times: list[float] = []
    if first.seconds <= budget:
        total = 0.0
        for _ in range(max(0, repeat)):
            t = solve_fn(prob, method, tol=tol).seconds
            times.append(t)
            total += t
            if total > budget:
                break
    seconds = statistics.median(times) if times else float(first.seconds)
    farkas = first.info.get("farkas_y") if first.status == Status.NO_SOLUTION else None
    success, defect, reason, cert = judge(case, first.status, first.z, tol, farkas)
    return Record(
        problem=prob.name, n=prob.n, method=method, status=first.status, seconds=seconds,
        iterations=int(first.iterations), error=None if cert is None else cert.error,
        expected=case.expected, defect=defect, tol=tol, kind=prob.kind, success=success,
        defect_reason=reason, residual=None if cert is None else cert.residual,
        z_error=_z_error(case, first.z), repeats=len(times), message=first.message)


def run_isolated(case: Case, method: str, tol: float, *, timeout: float,
                 repeat: int = DEFAULT_REPEAT, budget: float = DEFAULT_BUDGET,
                 solve_fn: SolveFn | None = None) -> Record:
    """:func:`run_one` in a child process killed after ``timeout`` seconds.

    The child is started by :func:`lcpcli.solvers.kernels.process_context` (``forkserver``,
    else ``spawn``; never a bare ``fork``, which the enumeration kernel's OpenMP threads do
    not survive), so ``case`` and ``solve_fn`` must be picklable (module-level functions).
    A child that times out or dies gives a record with status ``timeout`` or ``error`` (a
    failure, not a defect).  Timing is unchanged: it is measured inside the child by
    :func:`lcpcli.api.solve`.
    """
    ctx = process_context(PRELOAD)
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, case, method, tol, repeat, budget, solve_fn),
                       daemon=True)
    proc.start()
    send.close()
    status = ERROR
    try:
        if recv.poll(timeout):
            return recv.recv()
        status = TIMEOUT
    except EOFError:
        pass
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()
        recv.close()
    message = (f"killed after {timeout:g} s" if status == TIMEOUT
               else f"worker process died (exit code {proc.exitcode})")
    prob = case.problem
    success, defect, reason, _ = judge(case, status, None, tol)
    return Record(prob.name, prob.n, method, status, None, None, None, case.expected, defect, tol,
                  prob.kind, success, reason, message=message,
                  killed_after=timeout if status == TIMEOUT else None)


def _child(conn: Any, case: Case, method: str, tol: float, repeat: int, budget: float,
           solve_fn: SolveFn | None) -> None:
    one_line_warnings()  # a warning of a run: one 'lcpcli: warning:' line, as in the CLI
    try:
        try:
            rec = run_one(case, method, tol, repeat=repeat, budget=budget, solve_fn=solve_fn)
        except Exception as exc:  # noqa: BLE001 - a row saying why, never a child's traceback
            prob = case.problem
            success, defect, reason, _ = judge(case, ERROR, None, tol)
            rec = Record(prob.name, prob.n, method, ERROR, None, None, None, case.expected,
                         defect, tol, prob.kind, success, reason,
                         message=" ".join(f"{type(exc).__name__}: {exc}".split()))
        conn.send(rec)
    finally:
        conn.close()


def run_peer(case: Case, peer: Any, tol: float, *, repeat: int = DEFAULT_REPEAT,
             budget: float = DEFAULT_BUDGET, timeout: float | None = None) -> list[Record]:
    """Run every solver of a peer family on ``case``; certify each z like our own methods."""
    prob = case.problem
    runs = peer.run_many(prob, tol, repeat, budget, timeout=timeout)
    out = []
    for name, run in runs.items():
        status = Status.UNSOLVED
        z = run.z
        if z is not None and z.shape == (prob.n,):
            cert = certify(prob, z, tol)
            status = Status.SOLVED if cert.passed else Status.UNSOLVED
        elif run.killed_after is not None:
            status = TIMEOUT
        elif run.seconds is None:
            status = ERROR
        success, _, reason, cert = judge(case, status, z, tol)
        out.append(Record(
            problem=prob.name, n=prob.n, method=name, status=status, seconds=run.seconds,
            iterations=run.iterations, error=None if cert is None else cert.error,
            expected=case.expected, defect=False, tol=tol, kind=prob.kind, success=success,
            defect_reason=reason,
            residual=None if cert is None else cert.residual, z_error=_z_error(case, z),
            repeats=run.repeats, peer=peer.family, claimed=run.claimed, message=run.message,
            killed_after=run.killed_after))
    return out


def run_bench(cases: list[Case], methods: list[str], tols: Iterable[float] = DEFAULT_TOLS, *,
              repeat: int = DEFAULT_REPEAT, budget: float = DEFAULT_BUDGET,
              peers: list[Any] | None = None, missing_peers: dict[str, str] | None = None,
              solve_fn: SolveFn | None = None, timeout: float | None = None,
              on_record: Callable[[Record], None] | None = None) -> BenchReport:
    """Run every method (and peer) on every case at every tolerance; see the module docstring.

    With ``timeout`` (seconds) each (problem, method, tol) runs in a child process that is
    killed after that long (:func:`run_isolated`); without it, everything runs in this process.

    A method that does not handle a problem's kind (e.g. an LCP-only method on an MLCP) is
    skipped and listed in ``report.skipped``.  ``on_record`` is called as each row completes.
    Problems are told apart by name: a name already taken is renamed (:func:`unique_names`).
    """
    tols = [validate_tol(t) for t in tols]  # the one rule on a tolerance, as for a solve
    if not tols:
        raise OptionError("give at least one tolerance")
    if repeat < 0:
        raise OptionError("--repeat must be >= 0")
    unique_names(cases)
    report = BenchReport(records=[], methods=list(methods), tols=tols,
                         problems=[(c.name, c.n, c.problem.kind, c.expected) for c in cases],
                         peers={p.family: p.version for p in peers or []},
                         missing_peers=dict(missing_peers or {}))
    for case in cases:
        for tol in tols:
            for method in methods:
                why = skip_reason(case, method)
                if why:
                    if tol == tols[0]:
                        report.skipped.append((case.name, method, why))
                    continue
                if timeout:
                    rec = run_isolated(case, method, tol, timeout=timeout, repeat=repeat,
                                       budget=budget, solve_fn=solve_fn)
                else:
                    rec = run_one(case, method, tol, repeat=repeat, budget=budget,
                                  solve_fn=solve_fn)
                report.records.append(rec)
                if on_record:
                    on_record(rec)
            for peer in peers or []:
                if case.problem.kind not in peer.kinds:
                    if tol == tols[0]:
                        report.skipped.append((case.name, peer.family,
                                               f"peer does not handle {case.problem.kind.upper()}"))
                    continue
                for rec in run_peer(case, peer, tol, repeat=repeat, budget=budget,
                                    timeout=timeout):
                    report.records.append(rec)
                    if on_record:
                        on_record(rec)
    return report


def unique_names(cases: list[Case]) -> None:
    """Rename in place every problem whose name an earlier case already has to ``name (k)``
    (k = 2, 3, ...): every per-problem figure (table rows, the failure penalty, the
    performance profile, peer ratios) is keyed by the name, so two problems called ``p`` (two
    files ``a/p.json``, ``b/p.dat``, or a suite case and the same file) must not share one."""
    taken: set[str] = set()
    for case in cases:
        name, k = case.problem.name, 1
        while case.problem.name in taken:
            k += 1
            case.problem.name = f"{name} ({k})"
        taken.add(case.problem.name)


def skip_reason(case: Case, method: str) -> str:
    """Why :func:`run_bench` skips ``method`` on ``case`` ("" when it runs it): a problem kind
    the method does not handle, or a size above its ``max_n`` (a name not in the registry
    handles everything)."""
    from lcpcli.solvers.registry import get_method

    try:
        spec = get_method(method)
    except OptionError:
        return ""
    kind = case.problem.kind
    if kind not in spec.kinds:
        return f"{method} does not handle {kind.upper()}"
    if spec.max_n is not None and case.n > spec.max_n:
        return f"n = {case.n} is above {method}'s limit max_n = {spec.max_n}"
    return ""


# ---------------------------------------------------------------------- statistics
def shifted_geomean(times: Iterable[float], shift: float = SHIFT) -> float:
    """``exp(mean(log(t + shift))) - shift`` (nan for no times)."""
    ts = [float(t) for t in times]
    if not ts:
        return float("nan")
    return float(math.exp(sum(math.log(t + shift) for t in ts) / len(ts)) - shift)


def _slowest(records: list[Record]) -> dict[tuple[str, float], float]:
    worst: dict[tuple[str, float], float] = {}
    for r in records:
        if r.seconds is not None and math.isfinite(r.seconds):
            key = (r.problem, r.tol)
            worst[key] = max(worst.get(key, 0.0), r.seconds)
    return worst


def charged_time(r: Record, slowest: dict[tuple[str, float], float]) -> float:
    """The time a record counts for in the shifted geometric mean (failures penalised).

    A failure counts :data:`PENALTY` times the slowest time on its problem, never less than its
    own time; a run killed by the timeout took at least ``killed_after`` seconds."""
    own = r.seconds if r.seconds is not None and math.isfinite(r.seconds) else 0.0
    if r.killed_after is not None:
        own = max(own, r.killed_after)
    if r.success:
        return own
    return max(own, PENALTY * slowest.get((r.problem, r.tol), own))


@dataclass
class MethodSummary:
    """Per method and tolerance: the figures of the summary table."""

    method: str
    tol: float
    runs: int
    successes: int
    defects: int
    sgm_seconds: float
    median_seconds: float
    median_error: float
    worst_error: float
    peer: str | None = None
    #: Over the successful runs on problems with a unique known z*: the forward error
    #: ``||z - z*||_inf / max(1, ||z*||_inf)`` (median and worst; NaN when there is none).
    median_z_error: float = float("nan")
    worst_z_error: float = float("nan")

    @property
    def success_rate(self) -> float:
        return self.successes / self.runs if self.runs else float("nan")

    def to_json(self) -> dict[str, Any]:
        d = asdict(self)
        d["success_rate"] = self.success_rate
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in d.items()}


def summarize(report: BenchReport) -> list[MethodSummary]:
    """One :class:`MethodSummary` per (method, tol); errors over problems not expected
    infeasible, from runs that returned a z."""
    slowest = _slowest(report.records)
    out = []
    for tol in report.tols:
        for method in report.all_methods():
            rs = [r for r in report.records if r.method == method and r.tol == tol]
            if not rs:
                continue
            errs = [r.error for r in rs if r.error is not None and r.expected != INFEASIBLE
                    and math.isfinite(r.error)]
            ok_times = [r.seconds for r in rs if r.success and r.seconds is not None]
            zerrs = [r.z_error for r in rs if r.success and r.z_error is not None
                     and math.isfinite(r.z_error)]
            out.append(MethodSummary(
                method=method, tol=tol, runs=len(rs), successes=sum(r.success for r in rs),
                defects=sum(r.defect for r in rs),
                sgm_seconds=shifted_geomean(charged_time(r, slowest) for r in rs),
                median_seconds=statistics.median(ok_times) if ok_times else float("nan"),
                median_error=statistics.median(errs) if errs else float("nan"),
                worst_error=max(errs) if errs else float("nan"),
                peer=rs[0].peer,
                median_z_error=statistics.median(zerrs) if zerrs else float("nan"),
                worst_z_error=max(zerrs) if zerrs else float("nan")))
    return out


def performance_profile(report: BenchReport, tol: float | None = None,
                        methods: list[str] | None = None) -> dict[str, Any]:
    """Dolan-More profile data at ``tol`` (default: the first tolerance).

    Returns ``{"tol", "problems": [...], "tau": [...], "rho": {method: [...]},
    "ratios": {method: [...]}}``; ``tau`` holds 1 and every finite ratio that occurs, so the
    profile is exact as a step function.  Methods are those run on at least one problem at
    ``tol`` (a method of another kind than every problem is left out), problems those at least
    one of them was run on; a problem a method was not run on (another kind, above its size
    limit) counts as one it did not solve, as in Dolan and More's profiles.
    """
    tol = report.tols[0] if tol is None else tol
    by: dict[tuple[str, str], Record] = {(r.problem, r.method): r for r in report.records
                                         if r.tol == tol}
    ran = {m for _, m in by}
    methods = [m for m in (methods or report.all_methods()) if m in ran]
    problems = [p for p, *_ in report.problems if any((p, m) in by for m in methods)]
    ratios: dict[str, list[float]] = {m: [] for m in methods}
    for p in problems:
        t = {m: (max(by[p, m].seconds, TIME_FLOOR) if (p, m) in by and by[p, m].success
                 and by[p, m].seconds is not None else math.inf) for m in methods}
        best = min(t.values())
        for m in methods:
            if math.isinf(best) or math.isinf(t[m]):
                ratios[m].append(math.inf)
            else:
                ratios[m].append(t[m] / best)
    taus = sorted({1.0} | {x for rs in ratios.values() for x in rs if math.isfinite(x)})
    rho = {m: [sum(x <= tau for x in ratios[m]) / len(problems) if problems else 0.0
               for tau in taus] for m in methods}
    return {"tol": tol, "problems": problems, "tau": taus, "rho": rho,
            "ratios": {m: [x if math.isfinite(x) else None for x in v]
                       for m, v in ratios.items()}}


def peer_ratios(report: BenchReport, tol: float | None = None) -> list[dict[str, Any]]:
    """For each (own method, peer solver): geometric mean of ``t_own / t_peer`` over the problems
    both solved at ``tol``, with the count; ratio < 1 means ours is faster."""
    tol = report.tols[0] if tol is None else tol
    recs = [r for r in report.records if r.tol == tol and r.success and r.seconds is not None]
    own = {(r.problem, r.method): max(r.seconds, TIME_FLOOR) for r in recs if r.peer is None}
    peer = {(r.problem, r.method): max(r.seconds, TIME_FLOOR) for r in recs
            if r.peer is not None}
    peer_names = sorted({m for _, m in peer})
    out = []
    for m in report.methods:
        for pm in peer_names:
            common = [p for (p, mm) in own if mm == m and (p, pm) in peer]
            if not common:
                continue
            logs = [math.log(own[p, m] / peer[p, pm]) for p in common]
            out.append({"method": m, "peer": pm, "problems": len(common),
                        "geomean_ratio": math.exp(sum(logs) / len(logs)),
                        "min_ratio": math.exp(min(logs)), "max_ratio": math.exp(max(logs))})
    return out


def work_precision(report: BenchReport) -> list[dict[str, Any]]:
    """Points (method, tol, problem, seconds, error, z_error, success) for the work-precision
    scatters (``z_error``: the forward error where the case has a unique known z*, else None)."""
    return [{"method": r.method, "tol": r.tol, "problem": r.problem, "seconds": r.seconds,
             "error": r.error, "z_error": r.z_error, "success": r.success}
            for r in report.records
            if r.seconds is not None and r.error is not None and r.expected != INFEASIBLE]
