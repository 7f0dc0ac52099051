"""Invariants of ``lcpcli pivot`` and :func:`lcpcli.analysis.pivoting.principal_pivot` at the
boundary (docs/pivot.md): for every problem and every basis, the principal pivoting transform
of Dai & Drumwright that the CLI prints (``--json --full``) equals an independent exact one
(:func:`references.principal_pivot_exact`: Gauss-Jordan on ``[I, -Maug] x = q`` in rationals),
the library gives the same numbers, and a basis that is exactly singular is refused with one
line and exit 2.  Data scaled by powers of two per row and column (to ``2^+-1000`` and
subnormals: Cottle-Pang-Stone 2.3, principal pivoting does not depend on units) give the
transform scaled the same way, or ``beyond double precision`` (exit 2) only where an entry of
it leaves the double range.  Bad tuples (out of range, 0-based names, duplicates, wrong counts,
a driving variable that is dependent) are one line, exit 2; nothing exits 3.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from invariants import cli, one_line_error, strict_json
from references import pivot_variable, principal_pivot_exact

from lcpcli.analysis.pivoting import parse_tuple, parse_var, principal_pivot
from lcpcli.core.errors import ProblemError

SETTINGS = settings(max_examples=100, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])
#: Relative accuracy asked of the transform on small integer data (n <= 5, entries <= 5:
#: condition numbers stay far below 1e6).
RTOL = 1e-9
TINY = 2.0 ** -1070


@dataclass
class PivotCase:
    """Small integer data, a basis (canonical names) and how it is spelled on the command
    line."""

    M: np.ndarray            # n x n
    q: np.ndarray
    d: np.ndarray            # the artificial column
    where: str               # "default" (ones), "covering" (--covering), "file" (n + 1 columns)
    dependent: list[str]
    independent: list[str]   # the completed tuple (in the order the CLI must use)
    give_independent: bool
    driving: str | None
    any_basis: bool
    spell: dict[str, str]    # canonical name -> spelling on the command line

    @property
    def n(self) -> int:
        return int(self.q.shape[0])

    @property
    def Maug(self) -> np.ndarray:
        return np.column_stack([self.M, self.d]) if self.n else np.zeros((0, 1))

    def args(self, path: Path) -> list[str]:
        out = ["pivot", str(path), "-d", ",".join(self.spell[v] for v in self.dependent),
               "--full", "--json"]
        if self.give_independent:
            out += ["-i", ",".join(self.spell[v] for v in self.independent)]
        if self.driving is not None:
            out += ["--driving", self.spell[self.driving]]
        if self.where == "covering":
            out += ["--covering", ",".join(str(int(x)) for x in self.d)]
        if self.any_basis:
            out.append("--any-basis")
        return out


def names(n: int) -> list[str]:
    """``w1..wn, z1..zn, z0``: Dai & Drumwright's order of the variables."""
    return [f"w{i}" for i in range(1, n + 1)] + [f"z{j}" for j in range(1, n + 1)] + ["z0"]


def spelling(name: str, n: int, rng: np.random.Generator) -> str:
    """Another accepted spelling of ``name`` (docs/pivot.md: ``z{n+1}`` for ``z0``; the parser
    also takes upper case, ``_`` and leading zeros)."""
    if name == "z0" and rng.random() < 0.4:
        name = f"z{n + 1}"
    kind, idx = name[0], name[1:]
    if rng.random() < 0.2:
        kind = kind.upper()
    if rng.random() < 0.2:
        idx = "0" + idx if idx != "0" else idx
    return kind + ("_" if rng.random() < 0.2 else "") + idx


@st.composite
def pivot_cases(draw: st.DrawFn, max_n: int = 5) -> PivotCase:
    n = draw(st.integers(0, max_n))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    M = rng.integers(-4, 5, (n, n)).astype(np.float64)
    q = rng.integers(-5, 6, n).astype(np.float64)
    where = draw(st.sampled_from(["default", "covering", "file"]))
    if where == "covering" and n == 0:  # --covering takes one number at least
        where = "default"
    d = np.ones(n) if where == "default" else rng.integers(-2, 4, n).astype(np.float64)
    basis = draw(st.sampled_from(["complementary", "almost", "any"]))
    if basis == "any":
        dependent = [str(v) for v in rng.permutation(names(n))[:n]]
    else:
        dependent = [("z" if rng.random() < 0.5 else "w") + str(i) for i in range(1, n + 1)]
        if basis == "almost" and n:
            dependent[int(rng.integers(0, n))] = "z0"
        dependent = [dependent[k] for k in rng.permutation(n)]
    rest = [v for v in names(n) if v not in dependent]
    give = draw(st.booleans())
    independent = [rest[k] for k in rng.permutation(len(rest))] if give else rest
    driving = str(rng.choice(independent)) if draw(st.booleans()) else None
    spell = {v: spelling(v, n, rng) for v in names(n)}
    pairs = any(f"w{i}" in dependent and f"z{i}" in dependent for i in range(1, n + 1))
    return PivotCase(M, q, d, where, dependent, independent, give, driving, pairs, spell)


def write(case: PivotCase, folder: Path, M: np.ndarray | None = None,
          q: np.ndarray | None = None) -> Path:
    """The problem file (an ``n + 1``-column M when the artificial column is in the file)."""
    path = folder / f"p{np.random.default_rng().integers(1 << 40)}.json"
    if M is None:
        M = case.Maug if case.where == "file" else case.M
    path.write_text(json.dumps({"M": M.tolist(), "q": (case.q if q is None else q).tolist()}))
    return path


def near(got: list, exact: list[Fraction], scale: float, what: str) -> None:
    for k, (g, e) in enumerate(zip(got, exact, strict=True)):
        assert g is not None and abs(Fraction(g) - e) <= Fraction(RTOL) * Fraction(scale), \
            (what, k, g, float(e))


def check_transform(doc: dict, case: PivotCase, ref: tuple) -> None:
    """The JSON of one basis against the exact transform (each column of ``M'`` to ``RTOL``
    of its largest entry)."""
    qp, Mp = ref
    n = case.n
    assert doc["dependent"] == case.dependent and doc["independent"] == case.independent
    near(doc["q_prime"], qp, max([1.0] + [abs(float(x)) for x in qp]), "q'")
    assert len(doc["M_prime"]) == n
    for c in range(n + 1):
        col = [Mp[r][c] for r in range(n)]
        near([doc["M_prime"][r][c] for r in range(n)], col,
             max([1.0] + [abs(float(x)) for x in col]), f"M' column {case.independent[c]}")
    if case.driving is None:
        assert doc["driving_column"] is None
    else:
        c = case.independent.index(case.driving)
        assert doc["driving_column"] == [doc["M_prime"][r][c] for r in range(n)]
        assert doc["driving_case"] == case.driving[0]
    # Dai & Drumwright's index sets (1-based), from their definitions
    ind, dep = case.independent, case.dependent
    w_ind = [i for i in range(1, n + 1) if f"w{i}" in ind]
    z_dep = [j for j in range(1, n + 2) if (f"z{j}" if j <= n else "z0") in dep]
    assert doc["alpha"] == w_ind and doc["beta"] == z_dep
    assert doc["alpha_prime"] == [ind.index(f"w{i}") + 1 for i in w_ind]
    assert doc["m"] == len(w_ind) == len(z_dep)


@SETTINGS
@example(case=PivotCase(np.array([[2.0]]), np.array([-1.0]), np.ones(1), "default", ["z1"],
                        ["w1", "z0"], False, "w1", False,
                        {v: v for v in names(1)}))
# Lemke's first pivot from a basis with q' < 0 and z0 driving: a row with q'_i = c_i = 0 made
# a ratio 0/0 = NaN, so no row tied (IndexError, exit 3)
@example(case=PivotCase(np.array([[-1.0, -2, -3, -3], [1, 0, 3, -3], [2, 1, 2, 2], [4, 0, 1, -4]]),
                        np.array([0.0, 0, -2, 0]), np.ones(4), "default", ["z1", "w4", "z4", "w3"],
                        ["z0", "w2", "w1", "z2", "z3"], True, "z0", True,
                        {v: v for v in names(4)}))
@given(case=pivot_cases())
def test_pivot_equals_exact_transform(tmp_path: Path, case: PivotCase) -> None:
    """Exit 0 and the exact transform on every basis, exit 2 (one line, 'singular') exactly
    on the tuples whose block is singular; the library call gives the same numbers."""
    path = write(case, tmp_path)
    code, out, err = cli(*case.args(path))
    ref = principal_pivot_exact(case.Maug, case.q, case.dependent, case.independent)
    if ref is None:
        one_line_error(code, err)
        assert "singular" in err and out == "", err
        return
    assert code == 0, err
    doc = strict_json(out)
    check_transform(doc, case, ref)
    if case.driving is not None:
        test = doc["ratio_test"]
        assert test is not None and test["driving"] == case.driving
        if test["blocking"] is not None:  # a dependent variable leaves, at its row of w'
            assert test["blocking"] == case.dependent[test["row"] - 1], test
    n = case.n
    t = principal_pivot(case.Maug, case.q, parse_tuple(case.dependent, n),
                        parse_tuple(case.independent, n) if case.give_independent else None,
                        driving=None if case.driving is None else parse_var(case.driving, n),
                        full=True, any_basis=case.any_basis)
    assert t.q_prime.tolist() == doc["q_prime"] and t.full.tolist() == doc["M_prime"]


@st.composite
def scalings(draw: st.DrawFn, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Exponents of the rows (n) and of the columns (n + 1, the artificial one included) that
    keep the integer data exact (entries below 2^3, so ``r_i + c_j`` in ``[-1071, 1020]``)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    mode = draw(st.sampled_from(["global", "rows_cols", "rows", "cols"]))
    r = np.zeros(n, dtype=np.int64)
    c = np.zeros(n + 1, dtype=np.int64)
    if mode == "global":
        r[:] = int(rng.integers(-1071, 1021))
    elif mode == "rows":
        r = rng.integers(-1000, 1001, n)
    elif mode == "cols":
        c = rng.integers(-1000, 1001, n + 1)
    else:
        r, c = rng.integers(-500, 501, n), rng.integers(-500, 501, n + 1)
    return r, c


@SETTINGS
@given(case=pivot_cases(max_n=4), data=st.data())
def test_pivot_scaled_data(tmp_path: Path, case: PivotCase, data: st.DataObject) -> None:
    """``w~ = D1 w``, ``z~ = D2^-1 z``: the transform of ``D1 Maug D2, D1 q`` is the exact
    one scaled by the same powers of two (variable ``w_i`` by ``2^r_i``, ``z_j`` by
    ``2^-c_j``); exit 2 ('beyond double precision') only where an entry of it, or the
    rounding error of its column in its units, leaves the range; never 'singular' on a basis
    of the unscaled data, never exit 3."""
    check_scaled(tmp_path, case, *data.draw(scalings(case.n)))


def _basis_case(M: list, d: list, q: list, dependent: str) -> PivotCase:
    n = len(q)
    dep = dependent.split(",")
    return PivotCase(np.array(M, dtype=float), np.array(q, dtype=float), np.array(d, dtype=float),
                     "file", dep, [v for v in names(n) if v not in dep], False, None, False,
                     {v: v for v in names(n)})


@pytest.mark.parametrize("case,r,c", [
    # the row-then-column equilibration of M^{alpha beta} lost an entry below 2^-1074: q' was
    # (.., -9, ..) for (.., -7, ..)
    (_basis_case([[0, 4, 0], [-4, 1, 2], [-4, 0, -1]], [1, 1, 1], [2, 2, -5], "z0,w3,z1"),
     [0, 0, 0], [702, 274, 22, -461]),
    # D_r b underflowed for a column in units far from the rows' (the z0 column of M' was 0)
    (_basis_case([[-4, 2, -3], [-2, 4, -3], [1, -2, -1]], [1, 1, 1], [5, -3, 3], "z3,z2,z1"),
     [0, 0, 0], [702, 274, 22, -461]),
    # entries of 1e-205 beside 0.75 after the quick equilibration: a basis called singular
    (_basis_case([[3, -4, -3], [-2, -3, 3], [3, 1, -4]], [1, 0, -1], [-4, -2, -1], "z3,z0,z2"),
     [-27, 12, 255], [451, -466, -356, 323]),
])
def test_pivot_scaled_regressions(tmp_path: Path, case: PivotCase, r: list, c: list) -> None:
    check_scaled(tmp_path, case, np.array(r), np.array(c))


def check_scaled(tmp_path: Path, case: PivotCase, r: np.ndarray, c: np.ndarray) -> None:
    """The property of :func:`test_pivot_scaled_data` for row exponents ``r`` and column
    exponents ``c`` (the artificial column's last)."""
    n = case.n
    Ms = np.ldexp(case.Maug, (r[:, None] + c[None, :]).astype(np.int32)) if n else case.Maug
    qs = np.ldexp(case.q, r.astype(np.int32))
    case.where = "file"
    path = write(case, tmp_path, Ms, qs)
    code, out, err = cli(*case.args(path))
    assert code in (0, 2), err
    ref = principal_pivot_exact(case.Maug, case.q, case.dependent, case.independent)
    if ref is None:
        one_line_error(code, err)
        return

    def exp(v: str) -> int:  # the variable's scale: w_i by 2^r_i, z_j by 2^-c_j
        kind, j = pivot_variable(v, n)
        return int(r[j]) if kind == "w" else -int(c[j])

    qp, Mp = ref
    qs_ex = [x * Fraction(2) ** exp(v) for x, v in zip(qp, case.dependent, strict=True)]
    Ms_ex = [[Mp[k][m] * Fraction(2) ** (exp(case.dependent[k]) - exp(case.independent[m]))
              for m in range(n + 1)] for k in range(n)]
    top = max([abs(x) for x in qs_ex] + [abs(x) for row in Ms_ex for x in row], default=0)
    # the size of each entry's column in the entry's units (an exact 0 is computed as a
    # rounding error of that size): what floating point has to represent
    q_top = max([Fraction(1)] + [abs(x) for x in qp])
    col_top = [max([Fraction(1)] + [abs(Mp[i][m]) for i in range(n)]) for m in range(n + 1)]
    sizes = [Fraction(2) ** exp(case.dependent[k]) * max(
        [q_top] + [col_top[m] / Fraction(2) ** exp(case.independent[m]) for m in range(n + 1)])
        for k in range(n)]
    if code == 2:
        one_line_error(code, err)
        assert "beyond double precision" in err, err
        assert max(sizes, default=0) >= Fraction(2) ** 990, \
            f"refused, but the largest entry is {float(top):g}"
        return
    assert top < Fraction(2) ** 1024, "an entry beyond the double range was printed"
    doc = strict_json(out)
    rowsum = np.sum(np.abs(Ms), axis=1) if n else np.zeros(0)

    def slack(k: int) -> Fraction:  # absolute error from underflow (subnormal intermediates)
        kind, j = pivot_variable(case.dependent[k], n)
        return Fraction(TINY) * (1 + (Fraction(float(rowsum[j])) if kind == "w" else 16))

    for k in range(n):
        unit = Fraction(2) ** exp(case.dependent[k])
        bound = Fraction(RTOL) * unit * q_top + slack(k)
        assert abs(Fraction(doc["q_prime"][k]) - qs_ex[k]) <= bound, \
            ("q'", k, doc["q_prime"][k], float(qs_ex[k]))
        for m in range(n + 1):
            unit_m = unit / Fraction(2) ** exp(case.independent[m])
            bound = Fraction(RTOL) * unit_m * col_top[m] + slack(k)
            assert abs(Fraction(doc["M_prime"][k][m]) - Ms_ex[k][m]) <= bound, \
                ("M'", k, m, doc["M_prime"][k][m], float(Ms_ex[k][m]))


# ---------------------------------------------------------------------------- invalid tuples
@SETTINGS
@given(case=pivot_cases(max_n=4), how=st.sampled_from(
    ["out_of_range_w", "out_of_range_z", "zero_based_w", "duplicate", "short", "long",
     "both_tuples", "pair_without_any_basis", "driving_dependent", "unknown_name",
     "independent_short", "zero_based_shift"]))
def test_pivot_bad_tuples_one_line(tmp_path: Path, case: PivotCase, how: str) -> None:
    """Names are 1-based (docs/pivot.md): ``w0``, ``w{n+1}``, ``z{n+2}`` are out of range and a
    tuple written 0-based (``w0..w{n-1}``) is refused; a name twice, a tuple of the wrong
    length, a name in both tuples, ``w_i`` and ``z_i`` both dependent without
    ``--any-basis``, a dependent driving variable: one line, exit 2, nothing on stdout."""
    n = case.n
    dep = list(case.dependent)
    args = ["--full", "--json"]
    if how == "out_of_range_w":
        dep = dep[:-1] + [f"w{n + 1}"] if n else [f"w{n + 1}"]
    elif how == "out_of_range_z":
        dep = dep[:-1] + [f"z{n + 2}"] if n else [f"z{n + 2}"]
    elif how == "zero_based_w":
        dep = dep[:-1] + ["w0"] if n else ["w0"]
    elif how == "zero_based_shift":  # w0..w{n-1}: the 0-based spelling of w1..wn
        dep = [f"w{i}" for i in range(n)] if n else ["w0"]
    elif how == "duplicate":
        dep = dep[:-1] + dep[:1] if n >= 2 else ["w1", "w1"] if n else ["z0", "z0"]
    elif how == "short":
        dep = dep[:-1] if n else ["z0"]
    elif how == "long":
        dep = dep + [next(v for v in names(n) if v not in dep)]
    elif how == "both_tuples":
        ind = case.independent[:-1] + [dep[0]] if n else ["z0", "z0"]
        args += ["-i", ",".join(ind)]
    elif how == "pair_without_any_basis":
        dep = ["w1", "z1"] + [f"w{i}" for i in range(3, n + 1)] if n >= 2 else ["w1", "z1"]
    elif how == "driving_dependent":
        args += ["--driving", dep[0] if n else "w1"]
    elif how == "unknown_name":
        dep = dep[:-1] + ["x1"] if n else ["x1"]
    else:  # independent_short
        args += ["-i", ",".join(case.independent[:-1]) or "w1,w1"]
    path = write(case, tmp_path)
    extra = ["--covering", ",".join(str(int(x)) for x in case.d)] \
        if case.where == "covering" and n else []
    code, out, err = cli("pivot", path, "-d", ",".join(dep), *args, *extra)
    one_line_error(code, err)
    assert out == ""


def test_pivot_library_refuses_singular_block_as_problem_error() -> None:
    """The library's refusal is a ProblemError (what the CLI turns into exit 2)."""
    Maug = np.array([[1.0, 2.0, 1.0], [2.0, 4.0, 1.0]])
    try:
        principal_pivot(Maug, np.array([-1.0, -1.0]), parse_tuple("z1,z2", 2))
    except ProblemError as exc:
        assert "singular" in str(exc)
    else:
        raise AssertionError("a singular M^{alpha beta} was accepted")
    assert math.isfinite(float(principal_pivot(Maug, np.array([-1.0, -1.0]),
                                               parse_tuple("z1,w2", 2)).q_prime[0]))


#: Entries at the ends of the double range (subnormal, 2^+-1000, the largest double, -0.0).
EXTREMES = (0.0, -0.0, 5e-324, -5e-324, 1e-310, 2.0 ** -1000, 2.0 ** 1000,
            -1.7976931348623157e308, 1.7976931348623157e308, 1.0, -1.0, 3.0)


@st.composite
def extreme_pivots(draw: st.DrawFn) -> tuple[list, list, list[str], str]:
    """``(M, q, dependent, driving)``: entries from :data:`EXTREMES`, a complementary basis
    and a driving variable among the others."""
    n = draw(st.integers(1, 4))
    entries = st.sampled_from(EXTREMES)
    M = draw(st.lists(st.lists(entries, min_size=n, max_size=n), min_size=n, max_size=n))
    q = draw(st.lists(entries, min_size=n, max_size=n))
    dependent = [f"{draw(st.sampled_from(['w', 'z']))}{i}" for i in range(1, n + 1)]
    return M, q, dependent, draw(st.sampled_from([v for v in names(n) if v not in dependent]))


@SETTINGS
@example(data=([[-1.0]], [1.7976931348623157e308], ["w1"], "z1"),
         extra=["--json", "--full"])  # the ratio q'/c overflowed: a numpy warning on stderr
@example(data=([[1e-310]], [-1.0], ["w1"], "z0"), extra=["--follow", "--json"])
@example(data=([[1e-310, 0.0, 1.0, -1.0],
                [9.332636185032189e-302, -5e-324, 1.0715086071862673e301, 1.0],
                [-0.0, 1.7976931348623157e308, -0.0, 3.0],
                [-5e-324, -1.0, 5e-324, 1.0715086071862673e301]],
               [-5e-324, -1.7976931348623157e308, -0.0, 1.7976931348623157e308],
               ["w1", "z2", "z3", "z4"], "w3"),
         extra=["--json", "--full"])  # the block's own units overflowed in ldexp (a warning)
@example(data=([[-5e-324, 0.0], [-5e-324, 0.0]], [0.0, 0.0], ["w1", "w2"], "z1"),
         extra=["--full"])  # lexicographic keys B^-1 / 5e-324 overflowed (a warning)
@example(data=([[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0715086071862673e301, 0.0],
                [0.0, 0.0, -1.0, 0.0], [0.0, 0.0, 1.7976931348623157e308, 0.0]],
               [0.0, 0.0, 0.0, 0.0], ["w1", "w2", "z3", "w4"], "w3"),
         extra=["--json", "--full"])  # NaN keys (B^-1 overflowed): no row kept, exit 3
@example(data=([[9.332636185032189e-302, 0.0, 0.0, 0.0],
                [1.0715086071862673e301, -1.7976931348623157e308, 0.0, 0.0],
                [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]],
               [0.0, 0.0, 0.0, 0.0], ["z1", "z2", "w3", "w4"], "z0"),
         extra=["--json", "--full"])  # np.linalg.inv called this basis singular: exit 3
@given(data=extreme_pivots(),
       extra=st.sampled_from([["--json", "--full"], ["--follow", "--json"], ["--full"],
                              ["--format", "latex"]]))
def test_pivot_extreme_data_never_exit_3(tmp_path: Path, data: tuple, extra: list[str]) -> None:
    """Data at the ends of the double range, every basis and driving variable, every output:
    exit 0 (strict JSON) or one line and exit 2 ('singular', 'beyond double precision'),
    never exit 3 and never a numpy warning on stderr."""
    M, q, dependent, driving = data
    n = len(M)
    path = tmp_path / f"p{np.random.default_rng().integers(1 << 40)}.json"
    path.write_text(json.dumps({"M": M, "q": q}))
    if "--follow" in extra:
        dependent, driving = [f"w{i}" for i in range(1, n + 1)], "z0"
    code, out, err = cli("pivot", path, "-d", ",".join(dependent), "--driving", driving, *extra)
    assert "warning" not in err, err
    if code == 2:
        one_line_error(code, err)
        return
    assert code == 0, err
    if "--json" in extra:
        strict_json(out)
