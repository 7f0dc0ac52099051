"""Invariants of ``lcpcli solve --trace`` for Lemke's method at the boundary (docs/pivot.md,
"Lemke's method, step by step"): for every valid LCP (small integers, degenerate ties,
``q >= 0``, ``n = 0, 1``, rows and columns scaled by ``2^+-700``, entries at the ends of the
double range) and every covering vector, method spelling and output:

* the exit code is 0 or 1 and agrees with the status; no traceback, no numpy warning;
* ``--json`` is one strict JSON object, the only thing on stdout; the Markdown and LaTeX
  exports are well formed (balanced environments and braces, one cell count per table);
* the trace is a Lemke path: step 0 is the initial tableau (basis ``w1..wn``), every state
  has ``n`` basic and ``n + 1`` nonbasic variables, never ``w_i`` and ``z_i`` both basic,
  ``z0`` basic in every state between its entry and its exit, each pivot's entering variable
  is the one announced by the previous state (the complementary rule) and its leaving one
  was basic in the announced row, the leaving row is one of the rows tied in its ratio test,
  and the number of pivots is the method's (``iterations``), at most the pivot limit;
* the pivots are the compiled kernel's (``lemke_kernel``'s record: the replica claims the
  method's pivots), and on moderate data each state's tableau is the exact pivoted system of
  its basis (:func:`references.principal_pivot_exact`);
* a ``solved`` trace's ``z`` passes the independent check (:func:`references.componentwise_error`),
  and on data the solve leaves unscaled (balanced) the verdict is the one of the same method
  without ``--trace`` (a trace is never equilibrated: on other data, and with ``auto``, which
  tries other methods after Lemke, the verdicts may differ; see docs/pivot.md);

and invalid data or options are one line on stderr, exit 2.  Under ``CI=true`` the examples
are derandomised; ``TRACE_EXAMPLES=2000`` draws more (to hunt).
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from invariants import cli, one_line_error, strict_json
from references import componentwise_error, principal_pivot_exact

from lcpcli.analysis.scaling import is_balanced
from lcpcli.core.problem import Problem
from lcpcli.core.tolerances import PIVOT_TOL, TIE_TOL
from lcpcli.solvers.kernels.lemke import default_max_iter, lemke_kernel

SETTINGS = settings(max_examples=int(os.environ.get("TRACE_EXAMPLES", "60")), deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])
#: Entries at the ends of the double range (as tests/cli/test_invariants_pivot.py).
EXTREMES = (0.0, -0.0, 5e-324, -5e-324, 1e-310, 2.0 ** -1000, 2.0 ** 1000,
            -1.7976931348623157e308, 1.7976931348623157e308, 1.0, -1.0, 3.0)
#: Covering vectors' entries: moderate, and at the ends of the range (extreme data only).
COVER_MODERATE = (1.0, 2.0, 0.5, 3.0)
COVER_EXTREME = (*COVER_MODERATE, 1e-300, 1e300, 5e-324, 1.7976931348623157e308)
#: Data whose tableaux are compared with the exact ones (no entry near the ends of the range).
MODERATE = ("int", "degenerate", "qpos")
LEMKES = ("lemke", "lemke-tableau", "lemke-revised", "auto")
OUTPUTS = ("json", "json-exact", "text", "murty", "markdown", "latex", "pivot1")


@dataclass
class TraceCase:
    """An LCP, a covering vector (None: the default ones), a method and an output."""

    mode: str
    M: np.ndarray
    q: np.ndarray
    covering: np.ndarray | None
    method: str
    output: str

    @property
    def n(self) -> int:
        return int(self.q.shape[0])

    @property
    def d(self) -> np.ndarray:
        return np.ones(self.n) if self.covering is None else self.covering

    def write(self, folder: Path) -> Path:
        path = folder / f"p{np.random.default_rng().integers(1 << 40)}.json"
        path.write_text(json.dumps({"M": self.M.tolist(), "q": self.q.tolist()}))
        return path

    def options(self) -> list[str]:
        out = ["-m", self.method]
        if self.covering is not None:
            out += ["--covering", ",".join(repr(float(x)) for x in self.covering)]
        return out


@st.composite
def trace_cases(draw: st.DrawFn, outputs: tuple[str, ...] = OUTPUTS) -> TraceCase:
    n = draw(st.integers(0, 4))
    mode = draw(st.sampled_from(("int", "degenerate", "qpos", "scaled", "extreme")))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if mode == "extreme":
        M = rng.choice(EXTREMES, (n, n))
        q = rng.choice(EXTREMES, n)
    elif mode == "degenerate":  # entries -1, 0, 1: many ties in the ratio tests
        M = rng.integers(-1, 2, (n, n)).astype(np.float64)
        q = rng.integers(-1, 2, n).astype(np.float64)
    else:
        M = rng.integers(-3, 4, (n, n)).astype(np.float64)
        q = rng.integers(0 if mode == "qpos" else -4, 5, n).astype(np.float64)
    if mode == "scaled":  # rows or columns by 2^+-700 (exact: the entries stay in range)
        r, c = np.zeros(n, dtype=np.int32), np.zeros(n, dtype=np.int32)
        if draw(st.booleans()):
            r = rng.integers(-700, 701, n).astype(np.int32)
        else:
            c = rng.integers(-700, 701, n).astype(np.int32)
        M = np.ldexp(M, r[:, None] + c[None, :]) if n else M
        q = np.ldexp(q, r)
    covering = None
    if n and draw(st.booleans()):
        covering = rng.choice(COVER_EXTREME if mode == "extreme" else COVER_MODERATE, n)
    method = draw(st.sampled_from(LEMKES if covering is None else LEMKES[:3]))
    return TraceCase(mode, M, q, covering, method, draw(st.sampled_from(outputs)))


# ---------------------------------------------------------------------------- checks
def check_exports(text: str, fmt: str) -> None:
    """A Markdown export: every table keeps one cell count; LaTeX: environments and braces
    balanced (unescaped), no 'nan' or 'inf' printed as a number."""
    assert text.strip(), "empty export"
    if fmt == "markdown":
        table: list[int] = []
        for line in [*text.splitlines(), ""]:
            if line.startswith("|"):
                table.append(len(re.findall(r"(?<!\\)\|", line)))
            elif table:
                assert len(set(table)) == 1, table
                table = []
        return
    body = re.sub(r"\\[{}]", "", text)
    assert body.count("{") == body.count("}"), "unbalanced braces"
    begins = re.findall(r"\\begin\{(\w+\*?)\}", text)
    ends = re.findall(r"\\end\{(\w+\*?)\}", text)
    assert sorted(begins) == sorted(ends), (begins, ends)


def code_of(name: str, n: int) -> int:
    """The kernel's variable code of a 1-based name (``w``: 0..n-1, ``z``: n..2n-1, z0 2n)."""
    if name == "z0":
        return 2 * n
    return int(name[1:]) - 1 + (n if name[0] == "z" else 0)


def check_path(case: TraceCase, doc: dict) -> None:
    """The trace is a Lemke path (see the module docstring)."""
    n, trace = case.n, doc["trace"]
    names = [f"w{i}" for i in range(1, n + 1)] + [f"z{i}" for i in range(1, n + 1)] + ["z0"]
    assert trace and all(s["kind"] == "lemke" for s in trace), [s["kind"] for s in trace]
    assert trace[0]["pivot"] == 0 and trace[0]["basis"] == names[:n]
    pivots = 0
    for k, st_ in enumerate(trace):
        basis, nonbasic = st_["basis"], st_["nonbasic"]
        assert len(basis) == n and len(nonbasic) == n + 1, (k, basis, nonbasic)
        assert sorted(basis + nonbasic) == sorted(names), (k, basis, nonbasic)
        pairs = [i for i in range(1, n + 1) if f"w{i}" in basis and f"z{i}" in basis]
        assert not pairs, f"step {k}: w_i and z_i both basic for i in {pairs}: {basis}"
        if k == 0:
            continue
        prev = trace[k - 1]
        assert st_["entering"] == prev["next_entering"], (k, st_["entering"], prev)
        if st_["rule"] == "ray":  # no pivot made: the last entry, the state unchanged
            assert k == len(trace) - 1 and st_["leaving"] is None
            assert basis == prev["basis"] and not st_["ratio_test"]["tied_rows"]
            continue
        pivots += 1
        assert st_["pivot"] == pivots
        r = st_["row"] - 1
        assert st_["leaving"] == prev["basis"][r], (k, st_["leaving"], prev["basis"])
        assert basis == [*prev["basis"][:r], st_["entering"], *prev["basis"][r + 1:]]
        if k > 1:  # the first pivot's test is the initial rule (its own tie rows)
            assert r in st_["ratio_test"]["tied_rows"], (k, r, st_["ratio_test"])
        last = k == len(trace) - 1
        if not last:  # z0 stays basic between its entry and its exit
            assert "z0" in basis, (k, basis)
        elif st_["leaving"] == "z0":
            assert st_["next_entering"] is None
    assert doc["iterations"] == pivots, (doc["iterations"], pivots)
    assert pivots <= default_max_iter(n)


def check_tableaux(case: TraceCase, doc: dict) -> None:
    """Each state's ``q'`` and ``M'`` are the exact pivoted system of its basis, to rounding
    (moderate data: the tableau's entries stay far from the ends of the range)."""
    Maug = np.column_stack([case.M, case.d]) if case.n else np.zeros((0, 1))
    for k, st_ in enumerate(doc["trace"]):
        if st_["tableau"] is None:
            continue
        ref = principal_pivot_exact(Maug, case.q, st_["basis"], st_["nonbasic"])
        assert ref is not None, f"step {k}: the basis {st_['basis']} is singular"
        qp, Mp = ref
        top = max([1.0] + [abs(float(x)) for x in qp])
        for i in range(case.n):
            assert abs(st_["q_prime"][i] - float(qp[i])) <= 1e-9 * top, (k, i, st_["q_prime"])
        for j in range(case.n + 1):
            col = max([1.0] + [abs(float(Mp[i][j])) for i in range(case.n)])
            for i in range(case.n):
                assert abs(st_["tableau"][i][j] - float(Mp[i][j])) <= 1e-9 * col, (k, i, j)


def check_kernel_pivots(case: TraceCase, doc: dict) -> None:
    """The trace's pivots (entering, leaving, row) are the compiled kernel's on the same
    data, with the same status (the replica's claim, docs/pivot.md "The replicas")."""
    n = case.n
    made = [(code_of(s["entering"], n), code_of(s["leaving"], n), s["row"] - 1)
            for s in doc["trace"][1:] if s["rule"] != "ray"]
    record = np.full((len(made) + 2, 3), -1, dtype=np.int64)
    status, _, pivots, *_ = lemke_kernel(case.M, case.q, case.d, default_max_iter(n),
                                         PIVOT_TOL, TIE_TOL, record)
    assert [tuple(x) for x in record[:pivots].tolist()] == made, (record[:pivots], made)
    ray = doc["trace"][-1]["rule"] == "ray"
    assert (status == 1) == ray, (status, doc["trace"][-1]["rule"])


def check_solved(case: TraceCase, doc: dict) -> None:
    z = np.array([np.nan if x is None else x for x in doc["z"]], dtype=np.float64)
    assert np.all(np.isfinite(z))
    err = componentwise_error(case.M, case.q, z)
    tol = doc["certificate"]["tol"]
    assert err <= tol * (1 + 1e-6), f"'solved' but the independent check gives {err:.3g}"


# ---------------------------------------------------------------------------- properties
@SETTINGS
# z0's first ratio q_i / d_i past the double range (-1 / 5e-324): the tie bound
# best + tie_tol |best| was NaN, no row tied (IndexError, exit 3)
@example(case=TraceCase("extreme", np.array([[1.0, 0.0, 1.0], [-1.0, -1.0, 1.0], [0.0, 0.0, 1.0]]),
                        np.array([-1.0, 0.0, 1.0]), np.array([5e-324, 1e300, 1e-300]),
                        "lemke", "json"))
@example(case=TraceCase("extreme", np.array([[-1.7976931348623157e308] * 2, [-1.0, 0.0]]),
                        np.array([1.0, -1.0]), np.array([5e-324, 5e-324]), "lemke-tableau",
                        "latex"))
# every ratio of a falling row past the double range (1.8e308 / 2): the kernel called it a
# ray (tmin = inf), the replica pivoted (those rows tie)
@example(case=TraceCase("extreme", np.array([[1.0, 5e-324, 1e-310], [-0.0, 1.0715086071862673e301,
                                                                     0.0], [0.0, -2.0, 1e-310]]),
                        np.array([1e-310, -1.0, -1.7976931348623157e308]), None, "lemke",
                        "json"))
# q' = inf after the first pivot: ztol = 1e-13 max q' = inf, and the replica's zero of the
# data's type, 0 * q', was NaN: no row tied, a ray where the kernel pivots three times
@example(case=TraceCase(
    "extreme", np.array([[1.0715086071862673e301, -1.7976931348623157e308, 1e-310, 0.0],
                         [1.0715086071862673e301, 0.0, -5e-324, -1.0],
                         [9.332636185032189e-302, -1.7976931348623157e308, 3.0, 5e-324],
                         [-1.0, 1.0, 1e-310, -5e-324]]),
    np.array([-5e-324, 9.332636185032189e-302, -1.7976931348623157e308, 9.332636185032189e-302]),
    np.array([2.0, 1.7976931348623157e308, 3.0, 1.7976931348623157e308]), "lemke-tableau", "json"))
@given(case=trace_cases())
def test_trace_is_a_lemke_path(tmp_path: Path, case: TraceCase) -> None:
    """Exit 0 or 1 with the status's code, parseable output of every format, a Lemke path
    with the kernel's pivots, exact tableaux on moderate data, an independently checked
    ``solved``."""
    path = case.write(tmp_path)
    out_args = {"json": ["--json"], "json-exact": ["--json", "--exact"], "text": [],
                "murty": ["--layout", "murty"], "markdown": ["--format", "markdown"],
                "latex": ["--format", "latex", "--layout", "murty"],
                "pivot1": ["--pivot", "1"]}[case.output]
    code, out, err = cli("solve", path, *case.options(), "--trace", *out_args)
    assert "Traceback" not in err and "warning" not in err, err
    if case.output == "pivot1" and code == 2:  # no pivot 1 (q >= 0): the valid steps named
        one_line_error(code, err)
        assert "--pivot" in err, err
        return
    assert code in (0, 1), (code, err)
    if case.output in ("markdown", "latex"):
        check_exports(out, case.output)
        return
    if not case.output.startswith("json"):
        assert out.strip()
        return
    assert len(out.splitlines()) == 1, "--json prints one line"
    doc = strict_json(out)
    assert code == (0 if doc["status"] == "solved" else 1), (code, doc["status"])
    if doc["status"] == "solved":
        check_solved(case, doc)
    check_path(case, doc)
    check_kernel_pivots(case, doc)
    if case.mode in MODERATE:
        check_tableaux(case, doc)


@SETTINGS
@given(case=trace_cases(outputs=("json",)))
def test_trace_verdict_is_the_methods(tmp_path: Path, case: TraceCase) -> None:
    """On data that the solve leaves unscaled (balanced: the trace's replica and the method
    run on the same numbers), ``--trace`` changes neither the status nor the exit code of
    ``lemke``, ``lemke-tableau`` and ``lemke-revised`` (``auto`` may try other methods after
    Lemke, which its trace does not show)."""
    if case.method == "auto" or not is_balanced(Problem.create(case.M, case.q)):
        case.method = "lemke-tableau" if case.method == "auto" else case.method
        if not is_balanced(Problem.create(case.M, case.q)):
            return
    path = case.write(tmp_path)
    code, out, err = cli("solve", path, *case.options(), "--trace", "--json")
    code2, out2, err2 = cli("solve", path, *case.options(), "--json")
    assert code in (0, 1) and code2 in (0, 1), (err, err2)
    doc, plain = strict_json(out), strict_json(out2)
    assert (code, doc["status"]) == (code2, plain["status"]), (doc["message"], plain["message"])


# ---------------------------------------------------------------------------- invalid input
@SETTINGS
@given(case=trace_cases(outputs=("json",)), how=st.sampled_from(
    ["nan_M", "inf_q", "shape", "covering_length", "covering_zero", "covering_negative",
     "covering_nan", "pivot_range", "method_without_replica", "step_with_format",
     "bad_layout", "mlcp"]))
def test_trace_bad_input_one_line(tmp_path: Path, case: TraceCase, how: str) -> None:
    """Invalid data or options with ``--trace``: one line on stderr, exit 2, nothing on
    stdout."""
    n = max(case.n, 1)
    M = case.M if case.n else np.ones((1, 1))
    q = case.q if case.n else -np.ones(1)
    data: dict = {"M": M.tolist(), "q": q.tolist()}
    args = ["-m", case.method if case.method != "auto" else "lemke"]
    if how == "nan_M":
        data["M"][0][0] = "NaN"
    elif how == "inf_q":
        data["q"][-1] = "-Infinity"
    elif how == "shape":
        data["q"] = data["q"] + [1.0]
    elif how == "covering_length":
        args += ["--covering", ",".join(["1"] * (n + 1))]
    elif how == "covering_zero":
        args += ["--covering", ",".join(["1"] * (n - 1) + ["0"])]
    elif how == "covering_negative":
        args += ["--covering", ",".join(["-1"] * n)]
    elif how == "covering_nan":
        args += ["--covering", ",".join(["nan"] * n)]
    elif how == "pivot_range":
        args += ["--pivot", str(default_max_iter(n) + 5)]
    elif how == "method_without_replica":
        args = ["-m", "newton"]
    elif how == "step_with_format":
        args += ["--step", "--format", "latex"]
    elif how == "bad_layout":
        args += ["--layout", "tableau"]
    else:  # no replica handles an MLCP
        data["n_eq"] = n
        args = ["-m", "auto"]
    path = tmp_path / f"bad{np.random.default_rng().integers(1 << 40)}.json"
    path.write_text(json.dumps(data).replace('"NaN"', "NaN").replace('"-Infinity"', "-Infinity"))
    if how != "pivot_range":  # (--pivot picks a page of the text or export, not of --json)
        args.append("--json")
    code, out, err = cli("solve", path, "--trace", *args)
    one_line_error(code, err)
    assert out == "", out


# ---------------------------------------------------------------------------- pivot --follow
def on_lemke_path(dependent: list[str], driving: str) -> bool:
    """Whether ``driving`` entering from ``dependent`` is a step of Lemke's path: ``z0`` from
    a complementary basis (Lemke's first pivot), else, from a basis holding ``z0``, one of the
    pair with neither variable dependent."""
    if "z0" not in dependent:
        return driving == "z0"
    pair = ("w" if driving[0] == "z" else "z") + driving[1:]
    return driving != "z0" and pair not in dependent


@st.composite
def follow_starts(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, list[str], str, bool]:
    """``(M, q, dependent, driving, any_basis)``: small integers, a complementary or almost
    complementary basis (or, with ``any_basis``, one holding a pair) and an independent
    driving variable."""
    n = draw(st.integers(1, 3))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    M = rng.integers(-3, 4, (n, n)).astype(np.float64)
    q = rng.integers(-3, 4, n).astype(np.float64)
    dep = [("z" if rng.random() < 0.5 else "w") + str(i) for i in range(1, n + 1)]
    kind = draw(st.sampled_from(["start", "complementary", "almost", "pair"]))
    if kind == "start":
        dep = [f"w{i}" for i in range(1, n + 1)]
    elif kind == "almost":
        dep[int(rng.integers(0, n))] = "z0"
    elif kind == "pair" and n >= 2:
        i = int(rng.integers(1, n + 1))
        dep = [f"w{i}", f"z{i}", *[v for v in dep if v[1:] != str(i)]][:n]
    names = [f"w{i}" for i in range(1, n + 1)] + [f"z{i}" for i in range(1, n + 1)] + ["z0"]
    rest = [v for v in names if v not in dep]
    driving = "z0" if kind == "start" and draw(st.booleans()) else draw(st.sampled_from(rest))
    pair = any(f"w{i}" in dep and f"z{i}" in dep for i in range(1, n + 1))
    return M, q, dep, driving, pair


@SETTINGS
@given(start=follow_starts())
def test_follow_from_any_start(tmp_path: Path, start: tuple) -> None:
    """``pivot --follow`` from a start on Lemke's path: exit 0 (or one line, exit 2, for a
    singular basis), every basis (almost) complementary, ``z0`` in every one but the last
    after ``z0`` left; from ``w1..wn`` with ``z0`` driving, the bases of ``solve --trace``.
    From any other start: one line, exit 2, that says which ``--driving`` Lemke's path needs,
    never "driving variable ... is not independent" (which the complementary rule gave when
    it named a variable that had just entered)."""
    M, q, dep, driving, pair = start
    n = len(q)
    path = tmp_path / f"f{np.random.default_rng().integers(1 << 40)}.json"
    path.write_text(json.dumps({"M": M.tolist(), "q": q.tolist()}))
    code, out, err = cli("pivot", path, "-d", ",".join(dep), "--driving", driving, "--follow",
                         "--json", *(["--any-basis"] if pair else []))
    assert "is not independent" not in err, err
    if not pair and not on_lemke_path(dep, driving):
        one_line_error(code, err)
        assert "--follow follows Lemke's path" in err and "give --driving" in err, err
        return
    if code == 2:
        one_line_error(code, err)
        assert "singular" in err or "--follow:" in err and pair, err
        return
    assert code == 0, err
    doc = strict_json(out)
    steps = doc.get("steps", [doc])
    for k, s in enumerate(steps):
        d = s["dependent"]
        assert len(d) == n
        if pair:
            continue
        assert not any(f"w{i}" in d and f"z{i}" in d for i in range(1, n + 1)), (k, d)
        if 0 < k < len(steps) - 1:
            assert "z0" in d, (k, d)
    if dep == [f"w{i}" for i in range(1, n + 1)] and driving == "z0":
        code, out, err = cli("solve", path, "-m", "lemke-tableau", "--trace", "--json")
        trace = [s["basis"] for s in strict_json(out)["trace"] if s["rule"] != "ray"]
        assert [s["dependent"] for s in steps] == trace


@pytest.mark.parametrize("M,q,args,before", [
    # w1 blocks z1 at once: the complementary rule named z1 again
    ([[-1, 0], [0, 1]], [1, 1], ["-d", "w1,w2", "--driving", "z1"],
     "driving variable z1 is not independent"),
    # w2 blocks z1: the next basis held w1 and z1
    ([[1, 0], [-1, 1]], [1, 1], ["-d", "w1,w2", "--driving", "z1"],
     "dependent tuple holds both w1 and z1"),
    # z2's complement w2 is dependent beside z0: z0 blocks, the final basis held w2 and z2
    ([[1, 2], [-2, 1]], [-1, 0], ["-d", "z0,w2", "--driving", "z2"],
     "dependent tuple holds both w2 and z2"),
    # ... or w2 blocks and the rule named z2 again
    ([[-2, 0], [2, -2]], [-1, 0], ["-d", "z0,w2", "--driving", "z2"],
     "driving variable z2 is not independent"),
])
def test_follow_off_lemkes_path_says_which_driving(tmp_path: Path, M: list, q: list,
                                                   args: list, before: str) -> None:
    """The start of --follow is judged before any pivot: one line naming the --driving that
    Lemke's path takes (the messages before were about later bases the user never gave)."""
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"M": M, "q": q}))
    code, out, err = cli("pivot", path, *args, "--follow")
    one_line_error(code, err)
    assert before not in err and out == ""
    assert "--follow follows Lemke's path" in err, err
    assert ("give --driving z0" if "z0" not in args[1] else "give --driving w1 or --driving z1") \
        in err, err


def test_follow_any_basis_rule_names_a_dependent_variable(tmp_path: Path) -> None:
    """From a start holding a pair (--any-basis) the complementary rule can name a dependent
    variable: the message says so in Lemke's terms (it was "driving variable w1 is not
    independent")."""
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"M": [[0, 1], [3, 2]], "q": [1, 0]}))
    code, out, err = cli("pivot", path, "-d", "w1,z1", "--any-basis", "--driving", "z0",
                         "--follow")
    one_line_error(code, err)
    assert "is not independent" not in err
    assert "at step 0 z1 left" in err and "w1 would enter next" in err, err


def test_driving_z0_from_a_solution_is_no_ray(tmp_path: Path) -> None:
    """``q' >= 0`` on a complementary basis solves the LCP: with ``z0`` driving, Lemke's method
    makes no pivot (rule ``solution``, as ``solve --trace`` says for ``q >= 0``); it was a
    "secondary ray" when no entry of z0's column was negative."""
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"M": [[2, 1], [1, 2]], "q": [1, 0]}))
    for extra in ([], ["--follow"]):
        code, out, err = cli("pivot", path, "-d", "w1,w2", "--driving", "z0", "--json", *extra)
        assert code == 0, err
        test = strict_json(out)["ratio_test"]
        assert test["rule"] == "solution" and test["blocking"] is None, test
        assert "solves the LCP" in test["reason"] and "ray" not in test["reason"]
