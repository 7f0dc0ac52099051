"""lcpcli.solve_many: batched kernels, the same verdict rules as lcpcli.solve, backends."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import lcpcli
from lcpcli.api import plan_stack, solve_many
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.result import STATUS_CODES, Status
from lcpcli.solvers import batched
from tests.references import componentwise_error

SOLVED = STATUS_CODES[Status.SOLVED]


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """K random positive definite (non-symmetric) problems: one solution each."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    B = rng.standard_normal((K, n, n)) * 0.3
    M = A @ A.transpose(0, 2, 1) / n + np.eye(n) + (B - B.transpose(0, 2, 1))
    return M, rng.standard_normal((K, n))


def assert_honest(M, q, res, lower=None, upper=None):
    """Every 'solved' answer passes the independent reference check at the result's tol."""
    for k in np.flatnonzero(res.solved):
        lo = None if lower is None else np.broadcast_to(lower, q.shape)[k]
        up = None if upper is None else np.broadcast_to(upper, q.shape)[k]
        err = componentwise_error(M[k], q[k], res.z[k], lo, up)
        assert err <= res.tol * (1 + 1e-6), (k, err)
        scale = np.abs(M[k]) @ np.abs(res.z[k]) + np.abs(q[k])  # w row by row, to rounding
        assert np.all(np.abs(res.w[k] - (M[k] @ res.z[k] + q[k])) <= 1e-12 * scale), k


@pytest.mark.parametrize("method", ["lemke", "lemke-tableau", "pgs", "psor", "auto"])
def test_batched_answers_match_one_problem_solves(method):
    M, q = pd_stack(60, 7, seed=1)
    if method in ("pgs", "psor"):  # their class: symmetric positive definite
        M = (M + M.transpose(0, 2, 1)) / 2
    res = solve_many(M, q, method=method)
    assert res.batched
    assert res.solved.all()
    assert_honest(M, q, res)
    for k in range(0, 60, 7):
        one = lcpcli.solve(M[k], q[k], method=method)
        assert one.solved
        np.testing.assert_allclose(res.z[k], one.z, rtol=1e-6, atol=1e-8)


def test_threads_do_not_change_results():
    M, q = pd_stack(500, 9, seed=2)
    one = solve_many(M, q, method="lemke", threads=1)
    two = solve_many(M, q, method="lemke", threads=2)
    np.testing.assert_array_equal(one.z, two.z)
    np.testing.assert_array_equal(one.status, two.status)
    np.testing.assert_array_equal(one.iterations, two.iterations)


def test_verdicts_follow_solve_rules_on_a_mixed_stack():
    """Solvable, infeasible (M = 0, q < 0: Farkas), badly scaled rows and q >= 0 in one stack."""
    n = 2
    M = np.zeros((5, n, n))
    q = np.zeros((5, n))
    M[0], q[0] = [[2.0, 1.0], [1.0, 2.0]], [-1.0, -1.0]
    M[1], q[1] = 0.0, [-1.0, 2.0]  # no z >= 0 has w = q >= 0
    M[2], q[2] = np.diag([1e8, 1e-8]), [-1e8, -1e-8]  # solution (1, 1)
    M[3], q[3] = [[2.0, 1.0], [1.0, 2.0]], [1.0, 0.0]  # z = 0
    M[4], q[4] = np.array([[2.0, 1.0], [1.0, 2.0]]) * 1e-300, [-1e-300, -1e-300]
    res = solve_many(M, q, method="lemke")
    statuses = res.statuses()
    assert statuses == [Status.SOLVED, Status.NO_SOLUTION, Status.SOLVED, Status.SOLVED,
                        Status.SOLVED]
    np.testing.assert_allclose(res.z[2], [1.0, 1.0], rtol=1e-12)
    np.testing.assert_allclose(res.z[4], [1 / 3, 1 / 3], rtol=1e-12)
    assert "Farkas" in res.message(1)
    assert res.retried[1] and not res.retried[0]
    assert_honest(M, q, res)
    # the same verdicts one by one
    for k in range(5):
        assert lcpcli.solve(M[k], q[k], method="lemke").status == statuses[k]


def test_diverging_psor_is_not_solved():
    """A non-symmetric PD stack outside PSOR's class: never 'solved' without the certificate."""
    rng = np.random.default_rng(5)
    n = 30
    S = rng.standard_normal((n, n)) * 3
    M = np.stack([np.eye(n) + S - S.T] * 4)
    q = rng.standard_normal((4, n))
    res = solve_many(M, q, method="psor", max_iter=200)
    assert_honest(M, q, res)
    assert not res.solved.all()


def test_nan_problems_are_marked_or_raise():
    M, q = pd_stack(10, 4)
    M[3, 1, 1] = np.nan
    with pytest.raises(ProblemError, match="problem 3"):
        solve_many(M, q)
    res = solve_many(M, q, on_error="mark")
    assert res.statuses()[3] == Status.ERROR
    assert res.counts() == {"solved": 9, "error": 1}
    assert np.isinf(res.error[3])


def test_box_stacks_use_the_sor_kernel_and_match_solve():
    M, q = pd_stack(40, 6, seed=3)
    M = (M + M.transpose(0, 2, 1)) / 2
    lo, up = -np.ones(6), np.ones(6)
    res = solve_many(M, q * 3, method="pgs", lower=lo, upper=up)
    assert res.batched and res.solved.all()
    assert_honest(M, q * 3, res, lo, up)
    for k in (0, 17, 39):
        one = lcpcli.solve(M[k], q[k] * 3, method="pgs", lower=lo, upper=up)
        np.testing.assert_allclose(res.z[k], one.z, atol=1e-6)


def test_options_the_kernel_does_not_take_solve_one_by_one():
    M, q = pd_stack(5, 4)
    res = solve_many(M, q, method="pgs", z0=np.zeros(4))
    assert not res.batched and res.solved.all()
    res = solve_many(M, q, n_eq=1)
    assert not res.batched and res.solved.all()


def test_bad_arguments():
    M, q = pd_stack(3, 4)
    with pytest.raises(ProblemError, match="shape"):
        solve_many(M[0], q)
    with pytest.raises(ProblemError, match="shape"):
        solve_many(M, q[:, :3])
    with pytest.raises(OptionError, match="no option"):
        solve_many(M, q, method="lemke", omega=1.5)
    with pytest.raises(OptionError, match="tol"):
        solve_many(M, q, tol=1.0)
    with pytest.raises(OptionError, match="threads"):
        solve_many(M, q, threads=0)
    with pytest.raises(OptionError, match="backend"):
        solve_many(M, q, backend="no-such")
    with pytest.raises(ProblemError, match="lower > upper"):
        solve_many(M, q, method="pgs", lower=np.ones(4), upper=np.zeros(4))
    with pytest.raises(ProblemError):
        solve_many(M.astype(complex), q)


def test_auto_routes_by_a_sample_and_the_plan_can_be_reused():
    M, q = pd_stack(200, 8, seed=4)
    plan = plan_stack(M, q)
    assert plan.method == "auto" and plan.kernel_method is not None
    res = solve_many(M, q, plan=plan)
    assert res.solved.all() and res.batched
    with pytest.raises(OptionError, match="plan"):
        solve_many(M, q, method="pgs", plan=plan)


def test_warm_rows_and_solve_each_arguments_are_checked():
    """A stack's warm rows hold real numbers or booleans (text raised numpy's UFuncTypeError,
    complex rows were taken); solve_each checks warms= against the problems (a short list
    raised IndexError) and takes every warm form solve takes (a Result, letters: refused with
    a shape error) and Problems only (a tuple: AttributeError)."""
    M, q = pd_stack(9, 4, seed=5)
    for rows in (np.full((9, 4), "1"), np.ones((9, 4), complex)):
        with pytest.raises(OptionError, match="warm start of a stack holds"):
            solve_many(M, q, "lemke", warm=rows)
    problems = [lcpcli.Problem.create(M[k], q[k]) for k in range(9)]
    prev = [lcpcli.solve(p, "lemke") for p in problems]
    with pytest.raises(OptionError, match="one warm start"):
        lcpcli.solve_each(problems, "lemke", warms=prev[:3])
    with pytest.raises(TypeError, match="item 0 is a tuple"):
        lcpcli.solve_each([(M[k], q[k]) for k in range(9)], "lemke")
    with pytest.raises(OptionError, match="one letter per pair"):
        lcpcli.solve_each(problems, "lemke", warms=["FXLL"] * 9)
    letters = ["".join("LUF"[c] for c in r.basis) for r in prev]
    for warms in (prev, letters, [r.z_basic for r in prev]):
        out = lcpcli.solve_each(problems, "lemke", warms=warms)
        assert all(r.solved and r.info["warm"] for r in out)
        assert all(np.array_equal(r.z_basic, p.z_basic) for r, p in zip(out, prev, strict=True))


@pytest.mark.parametrize("method", ["pgs", "auto", "newton"])
def test_a_problem_with_bad_bounds_is_refused_on_its_own(method):
    """Per-problem bounds are problem data: on_error="mark" marks the problem whose bounds
    break the rules (NaN, lower > upper) and solves the others; "raise" names it.  Shared
    bounds are the whole stack's and raise as before."""
    M, q = np.tile(np.eye(3) * 2, (6, 1, 1)), -np.ones((6, 3))
    lower, upper = np.zeros((6, 3)), np.ones((6, 3))
    upper[2, 0] = np.nan
    lower[4, 1] = 5.0
    res = solve_many(M, q, method, lower=lower, upper=upper, on_error="mark",
                     record_basis=True, certificates=True)
    assert res.statuses()[2] == "error" and res.message(2) == "upper contains NaN"
    assert res.statuses()[4] == "error" and "lower > upper" in res.message(4)
    assert res.counts() == {"solved": 4, "error": 2}
    assert np.isnan(res.z[[2, 4]]).all() and (res.basis[[2, 4]] == -1).all()
    if res.certificates is not None:
        assert np.isnan(res.certificates[[2, 4]]).all()
    assert_honest(M, q, res, lower, upper)
    with pytest.raises(ProblemError, match="problem 2 of the stack: upper contains NaN"):
        solve_many(M, q, method, lower=lower, upper=upper)
    with pytest.raises(ProblemError, match="upper contains NaN"):
        solve_many(M, q, method, upper=upper[2], on_error="mark")


@pytest.mark.parametrize("kind", [{"upper": np.full(3, 0.1)}, {"n_eq": 1}])
def test_a_plan_of_an_lcp_stack_never_certifies_a_box_or_mlcp_stack(kind):
    """auto's plan of an LCP stack runs Lemke's LCP kernel, which knows no bounds and no
    equations: given with a box or MLCP stack it is refused, never used (it answered the
    LCP's z = (0, 1/2, 1/2) as 'solved', above the upper bound 0.1 / with w_0 = 1 on an
    equation row)."""
    M, q = np.tile(np.eye(3) * 2, (9, 1, 1)), np.tile([1.0, -1.0, -1.0], (9, 1))
    plan = plan_stack(M, -np.ones((9, 3)))
    assert plan.kernel_method == "lemke-revised"
    with pytest.raises(OptionError, match="plan"):
        solve_many(M, q, plan=plan, **kind)
    res = solve_many(M, q, plan=plan_stack(M, q, **kind), **kind)  # its own plan: solved
    assert res.solved.all()
    lo = np.zeros(3) if "upper" in kind else np.array([-np.inf, 0.0, 0.0])
    up = kind.get("upper", np.full(3, np.inf))
    for k in range(9):
        assert componentwise_error(M[k], q[k], res.z[k], lo, up) <= res.tol


def test_a_backend_that_certifies_nothing_still_gives_honest_results():
    """The backend interface: a kernel handing everything back costs speed, not verdicts."""

    def lazy(M, q, lower, upper, *, tol, options, out, threads, scaling):
        out.code[:] = batched.KERNEL_RETRY

    batched.register_backend("lazy-test", lambda: batched.Backend("lazy-test",
                                                                   {"lemke": lazy}))
    M, q = pd_stack(20, 5)
    res = solve_many(M, q, method="lemke", backend="lazy-test")
    assert res.solved.all() and res.retried.all()
    ref = solve_many(M, q, method="lemke")
    np.testing.assert_allclose(res.z, ref.z, atol=1e-9)
    with pytest.raises(OptionError, match="no 'sor' kernel"):
        solve_many(M, q, method="pgs", backend="lazy-test")


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 6), st.integers(1, 5), st.integers(0, 2**31 - 1),
       st.sampled_from(["lemke", "pgs", "auto"]), st.floats(-200, 200))
def test_no_false_solved_on_random_stacks(n, K, seed, method, log_scale):
    """Any matrices (not only P), rows scaled by 2^k: every 'solved' passes the reference."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((K, n, n))
    q = rng.standard_normal((K, n))
    rows = 2.0 ** np.round(rng.uniform(-abs(log_scale), abs(log_scale), (K, n)))
    M *= rows[:, :, None]
    q *= rows
    res = solve_many(M, q, method=method)
    assert_honest(M, q, res)
    for k in range(K):
        assert res.statuses()[k] == lcpcli.solve(M[k], q[k], method=method).status


def test_solve_each_matches_solve_one_by_one():
    """Equal-size dense LCPs are stacked (>= STACK_MIN), the rest solved alone; same verdicts."""
    from lcpcli.api import STACK_MIN, solve_each
    from lcpcli.core.problem import Problem

    M, q = pd_stack(STACK_MIN + 2, 5, seed=8)
    problems = [Problem.create(M[k], q[k], name=f"p{k}") for k in range(len(q))]
    problems.append(Problem.create(np.zeros((2, 2)), [-1.0, 1.0], name="infeasible"))
    problems += [Problem.create(np.zeros((5, 5)), -np.ones(5), name="stacked-infeasible")]
    M3, q3 = pd_stack(3, 3, seed=9)
    problems += [Problem.create(M3[k], q3[k]) for k in range(3)]  # too few of size 3
    results = solve_each(problems, "lemke")
    for p, r in zip(problems, results, strict=True):
        one = lcpcli.solve(p, "lemke")
        assert r.status == one.status, p.name
        assert r.problem_name == p.name
        if one.solved:
            np.testing.assert_allclose(r.z, one.z, atol=1e-9)
            assert r.certificate.passed and r.error <= 1e-8
    assert results[0].info.get("batched") and not results[-1].info.get("batched")
    assert "Farkas" in results[STACK_MIN + 3].message


def test_stack_api_has_one_home_and_the_old_names_still_work() -> None:
    """The stack API lives in lcpcli.stacks; lcpcli.solve_many and lcpcli.api.solve_many are
    that very function (the move kept the public names)."""
    import lcpcli
    import lcpcli.api
    import lcpcli.stacks

    for name in ("solve_many", "solve_each", "plan_stack", "StackPlan", "STACK_MIN"):
        assert getattr(lcpcli.api, name) is getattr(lcpcli.stacks, name)
    assert lcpcli.solve_many is lcpcli.stacks.solve_many
    assert lcpcli.solve_each is lcpcli.stacks.solve_each
    with pytest.raises(AttributeError):
        lcpcli.api.no_such_name  # noqa: B018


def test_batched_kernels_take_their_parameters_from_the_method_records() -> None:
    """Policy as data: a method's BatchSpec names its kernel and its parameter defaults; every
    record declaring one kernel gives the same ``params``, and the backend modules import no
    method module."""
    import ast
    from pathlib import Path

    from lcpcli.solvers import registry
    from lcpcli.solvers.methods.lemke import default_max_iter
    from lcpcli.solvers.methods.pgs import DEFAULT_MAX_ITER

    by_kernel: dict[str, set] = {}
    for m in registry.methods().values():
        if m.batch is not None:
            by_kernel.setdefault(m.batch.kernel, set()).add(m.batch.params)
    assert set(by_kernel) == {"lemke", "sor"}
    assert all(len(p) == 1 and None not in p for p in by_kernel.values()), by_kernel
    assert batched.kernel_params("lemke", 7, {}) == {"covering": None,
                                                     "max_iter": default_max_iter(7)}
    p = batched.kernel_params("lemke", 3, {"covering": 2.0, "max_iter": 5})
    assert p["max_iter"] == 5 and p["covering"].tolist() == [2.0, 2.0, 2.0]
    assert batched.kernel_params("lemke", 3, p)["covering"].tolist() == [2.0, 2.0, 2.0]
    assert batched.kernel_params("sor", 4, {}) == {"omega": 1.0, "max_iter": DEFAULT_MAX_ITER}
    root = Path(batched.__file__).parent
    for path in [root / "batched.py", *sorted((root / "backends").glob("*.py"))]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                assert not (node.module or "").startswith("lcpcli.solvers.methods"), path


def _fresh(M, q, z, tol, lower=None, upper=None):
    """The certificate, w and pair states of ``z`` computed afresh (lcpcli.core.certificate)."""
    from lcpcli.core.certificate import check
    from lcpcli.core.problem import Problem

    p = Problem.create(M, q, lower=lower, upper=upper)
    states = np.empty(len(q), np.int8)
    cert, w = check(p, z, tol, state=states)
    return cert, w, states


@pytest.mark.parametrize("case", ["lemke", "lemke-warm", "pgs", "psor-box"])
def test_kernel_certificate_rows_equal_the_certificate_computed_afresh(case) -> None:
    """solve_many(certificates=True): each kernel-certified answer's row is the certificate
    check() gives for that z (every field, bit for bit); NaN rows exactly where the kernel
    handed the problem back (those come with their own Result)."""
    from lcpcli.core.certificate import from_row

    M, q = pd_stack(40, 6, seed=21)
    q[3] = 0.0  # z = 0 is the answer
    lower = upper = None
    method, warm = case.split("-")[0], None
    if case == "lemke-warm":
        warm = solve_many(M, q * 1.01, "lemke")
    if case == "psor-box":
        lower, upper = -np.ones(6), np.full(6, 0.5)
    res = solve_many(M, q, method, certificates=True, warm=warm, lower=lower, upper=upper)
    assert res.certificates is not None and res.certificates.shape == (40, 9)
    kernel_rows = ~np.isnan(res.certificates[:, 0])
    assert kernel_rows.sum() >= 20 and not kernel_rows[sorted(res.results)].any()
    for k in np.flatnonzero(kernel_rows):
        cert, w, states = _fresh(M[k], q[k], res.z[k], res.tol, lower, upper)
        assert from_row(res.certificates[k], res.tol) == cert, k
        assert np.array_equal(res.w[k], w), k
        if res.basis is not None:
            assert np.array_equal(res.basis[k], states), k
    assert solve_many(M, q, method, lower=lower, upper=upper).certificates is None


@pytest.mark.parametrize("warm", [False, True])
def test_solve_each_takes_the_kernel_certificate_and_it_equals_a_fresh_one(warm,
                                                                           monkeypatch) -> None:
    """solve_each's stacked Results carry the kernel's certificate, w and basis (no second
    certificate pass); each equals what check() computes for that z."""
    import lcpcli.stacks as stacks
    from lcpcli.api import solve_each
    from lcpcli.core.problem import Problem

    M, q = pd_stack(30, 7, seed=22)
    problems = [Problem.create(M[k], q[k]) for k in range(len(q))]
    warms = None
    if warm:
        warms = [r.z_basic for r in solve_each(problems, "lemke")]
        problems = [Problem.create(M[k], q[k] * 1.01) for k in range(len(q))]
    calls = []
    original = stacks.check

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(stacks, "check", counted)
    results = solve_each(problems, "lemke", warms=warms)
    monkeypatch.undo()
    assert all(r.info.get("batched") for r in results)
    assert not calls  # every answer came certified from the kernel
    for p, r in zip(problems, results, strict=True):
        cert, w, states = _fresh(p.M, p.q, r.z, r.certificate.tol)
        assert r.certificate == cert and np.array_equal(r.w, w)
        assert np.array_equal(r.basis, states)


def test_default_threads_follow_the_work(monkeypatch) -> None:
    """A default stack gets one thread per MIN_THREAD_SECONDS of estimated work (a small stack
    runs on one: on a busy machine a second thread's join costs a time slice); an explicit
    ``threads`` is taken as given."""
    from lcpcli.solvers.batched import MIN_THREAD_SECONDS, default_threads, useful_threads

    assert useful_threads(8, 20, 72) == 1 and useful_threads(8, 0, 12) == 1
    assert useful_threads(2, 834, 72) == 2 and useful_threads(16, 10**6, 12) == 16
    for K in (1, 10, 100, 10**3, 10**4, 10**5):
        t = [useful_threads(th, K, 30) for th in (1, 2, 4, 64)]
        assert t == sorted(t) and t[0] >= 1
        assert all(a <= b for a, b in zip(t, (1, 2, 4, 64), strict=True))
        assert useful_threads(64, K, 30) <= max(1, K * (2e-7 + 1.5e-10 * 30**3)
                                                 / MIN_THREAD_SECONDS)
    seen = []
    monkeypatch.setattr(batched, "useful_threads",
                        lambda threads, K, n: seen.append((threads, K, n)) or 1)
    M, q = pd_stack(12, 4, seed=3)
    assert solve_many(M, q, "lemke").solved.all()
    assert seen == [(default_threads(), 12, 4)]
    solve_many(M, q, "lemke", threads=2)
    assert len(seen) == 1


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 9), st.integers(0, 2**32 - 1), st.sampled_from(["pd", "psd", "degenerate"]),
       st.booleans())
def test_pivot_basis_is_complementary_to_every_certified_answer(n, seed, family, warm) -> None:
    """A recorded pivoting basis agrees with its answer: z_i != 0 only where z_i is basic, and
    w_i != 0 (beyond rounding of its row) only where w_i is (z_i nonbasic); rows of problems
    the kernel did not certify stay -1."""
    rng = np.random.default_rng(seed)
    K = 12
    A = rng.standard_normal((K, n, max(1, n // 2) if family != "pd" else n))
    M = A @ A.transpose(0, 2, 1) + (np.eye(n) if family == "pd" else 0.0)
    q = rng.standard_normal((K, n))
    if family == "degenerate":
        q[:, : n // 2] = 0.0
    prev = solve_many(M, q, "lemke", pivot_basis=True) if warm else None
    res = solve_many(M, q * 1.01, "lemke", pivot_basis=True, warm=prev)
    assert res.pivot_basis is not None and res.pivot_basis.shape == (K, n)
    for k in range(K):
        row = res.pivot_basis[k]
        if k in res.results or not res.solved[k]:
            assert (row == -1).all()
            continue
        assert set(row.tolist()) <= {0, 1}
        scale = np.abs(M[k]) @ np.abs(res.z[k]) + np.abs(q[k] * 1.01)
        assert np.all((res.z[k] == 0) | (row == 1)), (k, row, res.z[k])
        big_w = np.abs(res.w[k]) > 1e-9 * np.maximum(scale, 1e-300)
        assert np.all(~big_w | (row == 0)), (k, row, res.w[k])
