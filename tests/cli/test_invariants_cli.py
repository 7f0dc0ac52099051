"""Invariants at the boundary, through the command line (issue 22, What to build 7).

The CLI runs in this process (``lcpcli.cli.main`` with an argv, stdout/stderr captured; the
subprocess tests of tests/cli/test_cli.py cover the process itself).  For valid problems of
every kind, class and scale (tests/invariants.py), read from JSON files, stdin, sparse JSON,
NPZ, HDF5 and stacked files: the exit code is 0 or 1 and agrees with the verdict, the output
is strict JSON (no NaN/Infinity tokens) in every format ``-o`` writes, every ``solved`` passes
the independent componentwise check and every ``no_solution`` is true.  Invalid data exits 2
with one line on stderr.
"""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from invariants import (
    Case,
    cases,
    check_solved,
    check_verdict,
    cli,
    one_line_error,
    strict_json,
)

import lcpcli

METHODS = {kind: [name for name, m in lcpcli.methods().items() if kind in m.kinds]
           for kind in ("lcp", "box", "mlcp")}
#: "inf" or "nan" as a number in a table (not the "_inf" of a norm's name).
NON_FINITE = re.compile(r"(?<![\w])-?(inf|nan)(?![\w])", re.IGNORECASE)
SETTINGS = settings(max_examples=30, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])


def write_problem(case: Case, folder: Path, fmt: str) -> tuple[str, str | None]:
    """The problem as a file of format ``fmt`` (or stdin): (FILE argument, stdin text)."""
    if fmt == "stdin":
        return "-", case.to_json()
    path = folder / f"p.{'json' if fmt.startswith('json') else fmt}"
    if fmt in ("json", "json-sparse"):
        path.write_text(case.to_json(sparse=fmt == "json-sparse"))
    else:
        lcpcli.save(lcpcli.Problem.create(case.M, case.q, **case.kwargs()), path)
    return str(path), None


def assert_verdict(case: Case, code: int, row: dict, method: str) -> None:
    """Exit code and status agree; the status is true (see tests/invariants.py)."""
    status = row["status"]
    assert code == (0 if status == "solved" else 1), (code, status)
    if status == "solved":
        check_solved(case, row["z"], row["certificate"]["tol"])
    check_verdict(case, status, row["message"], method, row.get("info"))


# ---------------------------------------------------------------------------- solve
@SETTINGS
@given(case=cases(max_n=8), data=st.data(),
       fmt=st.sampled_from(["json", "stdin", "json-sparse", "npz", "h5"]))
def test_solve_json_every_input_format(tmp_path: Path, case: Case, data: st.DataObject,
                                       fmt: str) -> None:
    method = data.draw(st.sampled_from(METHODS[case.kind]))
    folder = tmp_path / f"{fmt}-{method}-{np.random.default_rng().integers(1 << 40)}"
    folder.mkdir()
    file, stdin = write_problem(case, folder, fmt)
    code, out, err = cli("solve", file, "-m", method, "--json", stdin=stdin)
    assert code in (0, 1), err
    assert "lcpcli: warning" not in err, err  # no numpy warning escapes on valid data
    lines = out.splitlines()
    assert len(lines) == 1, out
    row = strict_json(lines[0])
    assert_verdict(case, code, row, method)


@SETTINGS
@given(case=cases(max_n=8))
def test_solve_output_every_format(tmp_path: Path, case: Case) -> None:
    """``-o`` writes strict JSON (.json), JSON Lines (.jsonl), CSV and HDF5 result files that
    read back with the verdict of ``--json``."""
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    file, _ = write_problem(case, folder, "json")
    code, out, err = cli("solve", file, "--json")
    assert code in (0, 1), err
    row = strict_json(out)
    assert_verdict(case, code, row, "auto")
    code_j, _, err = cli("solve", file, "-o", folder / "r.json")
    assert code_j == code, err
    assert strict_json((folder / "r.json").read_text())["status"] == row["status"]
    from lcpcli.batch.output import read_rows

    for ext in ("jsonl", "csv", "h5"):
        target = folder / f"r.{ext}"
        code_o, _, err = cli("solve", file, "-o", target)
        assert code_o == code, (ext, err)
        if ext == "jsonl":
            rows = [strict_json(line) for line in target.read_text().splitlines()]
        elif ext == "csv":
            rows = list(csv.DictReader(io.StringIO(target.read_text())))
            for r in rows:  # numbers are numbers or empty, never 'inf'/'nan'
                for col in ("seconds", "residual", "error"):
                    assert r[col] == "" or np.isfinite(float(r[col])), (col, r[col])
        else:
            rows = read_rows(target)
        assert [r["status"] for r in rows] == [row["status"]], ext


@settings(max_examples=15, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(case=cases(min_n=1, max_n=6, kinds=("lcp", "box")), copies=st.integers(1, 3),
       ext=st.sampled_from(["h5", "npz"]), out_ext=st.sampled_from(["h5", "npz", "jsonl",
                                                                     "csv"]))
def test_stacked_files(tmp_path: Path, case: Case, copies: int, ext: str, out_ext: str) -> None:
    """A stacked file (copies of one problem and one with q replaced by |q|; stacks hold
    n >= 1): the batch exits 0 or 1, every result format holds every problem, ``--problem k
    --json`` is strict JSON; for an LCP the |q| problem is solved (z = 0)."""
    from lcpcli.io.stack import write_stack

    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    K = copies + 1
    M = np.broadcast_to(case.M, (K, case.n, case.n)).copy()
    q = np.broadcast_to(case.q, (K, case.n)).copy()
    q[-1] = np.abs(q[-1])
    stack = folder / f"s.{ext}"
    write_stack(stack, M, q, lower=case.lower, upper=case.upper)
    code, out, err = cli("solve", stack, "-o", folder / f"r.{out_ext}", "--json")
    assert code in (0, 1), err
    summary = strict_json(out)
    assert summary["exit_code"] == code
    code, out, err = cli("solve", stack, "--json")
    assert code in (0, 1), err
    rows = [strict_json(line) for line in out.splitlines()]
    assert len(rows) == K
    if case.kind == "lcp":  # q >= 0: z = 0 (not for a box: z_i = 0 between bounds needs w_i = 0)
        assert rows[-1]["status"] == "solved", rows[-1]["message"]
    assert code == (0 if all(r["status"] == "solved" for r in rows) else 1)
    for k in (0, K - 1):
        code_k, out_k, err = cli("solve", stack, "--problem", str(k), "--json")
        assert code_k in (0, 1), err
        assert strict_json(out_k)["status"] in ("solved", "no_solution", "unsolved")


# ---------------------------------------------------------------------------- enumerate, info
@SETTINGS
@given(case=cases(max_n=7, kinds=("lcp",)))
def test_enumerate_and_info_json(tmp_path: Path, case: Case) -> None:
    folder = tmp_path / str(np.random.default_rng().integers(1 << 40))
    folder.mkdir()
    file, _ = write_problem(case, folder, "json")
    code, out, err = cli("info", file, "--json")
    assert code == 0, err
    assert "lcpcli: warning" not in err, err
    strict_json(out)
    code, out, err = cli("enumerate", file, "--json")
    assert code in (0, 1), err
    assert "lcpcli: warning" not in err, err
    res = strict_json(out)
    assert code == (0 if res["solutions"] else 1)
    for sol in res["solutions"]:  # listed solutions are certified ones
        assert sol["error"] is not None and sol["error"] <= 1e-8, sol
        check_solved(case, sol["z"], 1e-8)
    assert not (case.solvable and res["status"] == "no_solution"), \
        f"enumerate finds no solution of a solvable {case.cls} problem"


# ---------------------------------------------------------------------------- invalid data
@SETTINGS
@given(case=cases(max_n=5, kinds=("lcp",)), data=st.data())
def test_invalid_data_is_one_line_exit_2(tmp_path: Path, case: Case, data: st.DataObject) -> None:
    """NaN or Inf anywhere, a wrong shape, text or booleans in the data, n_eq out of range,
    lower > upper: exit 2, one line on stderr, nothing on stdout."""
    doc = json.loads(case.to_json())
    n = case.n
    choices = ["q_short", "bool", "text", "n_eq", "neq_neg"]
    if n:
        choices += ["nan_M", "inf_q", "box"]
    how = data.draw(st.sampled_from(choices))
    if how == "nan_M":
        doc["M"][0][0] = float("nan")
    elif how == "inf_q":
        doc["q"][-1] = float("-inf")
    elif how == "q_short":
        doc["q"] = doc["q"][:-1] if n else [1.0]
    elif how == "bool":
        doc["q"] = [True] * n if n else [True]
    elif how == "text":
        doc["M"] = "1 2 3"
    elif how == "n_eq":
        doc["n_eq"] = n + 1
    elif how == "neq_neg":
        doc["n_eq"] = -1
    else:
        doc["lower"], doc["upper"] = [1.0] * n, [0.0] * n
    text = json.dumps(doc)  # NaN and Infinity tokens: what a careless writer produces
    code, out, err = cli("solve", "-", "--json", stdin=text)
    one_line_error(code, err)
    assert out == ""


# ---------------------------------------------------------------------------- the examples
@pytest.mark.parametrize("method", METHODS["lcp"])
def test_zero_solution_json_every_method_and_source(tmp_path: Path, method: str) -> None:
    """``echo '{"M":[[1]],"q":[1]}' | lcpcli solve - --json`` exited 3 ("Out of range float
    values are not JSON compliant": the relative forward bound is bound / ||z|| = inf)."""
    text = '{"M": [[1]], "q": [1]}'
    (tmp_path / "p.json").write_text(text)
    lcpcli.save(lcpcli.load(tmp_path / "p.json"), tmp_path / "p.h5")
    from lcpcli.io.stack import write_stack

    write_stack(tmp_path / "s.h5", np.ones((2, 1, 1)), np.ones((2, 1)))
    runs = [("-",), (tmp_path / "p.json",), (tmp_path / "p.h5",),
            (tmp_path / "s.h5", "--problem", "1")]
    for args in runs:
        code, out, err = cli("solve", *args, "-m", method, "--json", stdin=text)
        assert code == 0, (args, err)
        row = strict_json(out)
        assert row["z"] == [0.0] and row["status"] == "solved"
        if row["forward_error_bound"] is not None:
            assert row["forward_error_bound"]["relative"] is None  # 0/0: no meaning
    code, out, err = cli("solve", tmp_path / "p.json", "-m", method)
    assert code == 0 and not NON_FINITE.search(out), out


def test_table_says_relative_bound_undefined(tmp_path: Path) -> None:
    (tmp_path / "p.json").write_text('{"M": [[1]], "q": [1]}')
    code, out, _ = cli("solve", tmp_path / "p.json")
    assert code == 0 and "relative: n/a (z = 0)" in out and not NON_FINITE.search(out), out


@pytest.mark.parametrize("method", ["pgs", "psor", "auto"])
def test_diag_1e308(tmp_path: Path, method: str) -> None:
    (tmp_path / "p.json").write_text('{"M": [[1e308, 0], [0, 1]], "q": [-1e308, -1]}')
    code, out, err = cli("solve", tmp_path / "p.json", "-m", method, "--json")
    assert code == 0, err
    np.testing.assert_allclose(strict_json(out)["z"], [1.0, 1.0], rtol=1e-6)


def test_pivot_index_of_5000_digits(samples: Path) -> None:
    name = "z" + "9" * 5000
    for args in (("-d", f"{name},w2,w3"), ("--driving", name, "-d", "w1,w2,w3")):
        code, out, err = cli("pivot", samples / "seed000.json", *args)
        one_line_error(code, err)
        assert "out of range" in err and len(err) < 300


def _scene(samples: Path, tmp_path: Path, edit: dict) -> Path:
    scene = json.loads((samples / "scene_two_balls.json").read_text())
    for (where, k, key), value in edit.items():
        scene[where][k][key] = value
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    return path


@pytest.mark.parametrize("edit,ok", [
    ({("bodies", 1, "mass"): 1e308}, True),
    ({("bodies", 1, "inertia"): [1e308, 1e308, 1e308]}, True),
    ({("bodies", 1, "velocity"): [0, 0, -1e308]}, True),
    ({("contacts", 1, "normal"): [1e308, 1e308, 0]}, True),
    ({("contacts", 1, "normal"): [0, 0, 1e300]}, True),
    ({("contacts", 1, "normal"): [0, 0, 0]}, False),
    ({("contacts", 1, "normal"): [5e-324, 0, 5e-324]}, False),
    ({("bodies", 1, "mass"): 5e-324}, False),
    ({("bodies", 1, "inertia"): [5e-324, 5e-324, 5e-324]}, False),
    ({("bodies", 1, "position"): [1e308, 0, 1e308]}, False),
])
@pytest.mark.parametrize("friction", ["0", "4"])
def test_contact_scenes_at_the_ends_of_the_range(samples: Path, tmp_path: Path, edit: dict,
                                                 ok: bool, friction: str) -> None:
    """Valid extreme scenes are solved (normals normalised by their largest component first:
    (1e308, 1e308, 0) became a zero normal and was solved); a zero normal or one below 1e-12,
    a mass or inertia whose inverse overflows, an LCP that overflows: one line, exit 2."""
    path = _scene(samples, tmp_path, edit)
    code, out, err = cli("contact-matrix", path, "--solve", "--friction", friction, "--json")
    if not ok:
        one_line_error(code, err)
        return
    assert code in (0, 1), err
    doc = strict_json(out)
    normal = next(c["normal"] for c in doc["contacts"] if c["name"] == "floor")
    assert abs(np.linalg.norm(normal) - 1.0) < 1e-12, normal
    assert doc["status"] == "solved", doc["message"]


@pytest.mark.parametrize("M,q,dependent,code", [
    # principal pivoting does not depend on units: these blocks are bases (were "singular")
    ([[5e-324, 0], [0, 1]], [-5e-324, -1], "z1,z2", 0),
    ([[1e300, 1], [1e-300, 1e-300]], [-1, -1], "z1,z2", 0),
    ([[1e300, 1e-300], [1e-300, 1e300]], [-1e300, -1e-300], "z1,z2", 0),
    # q' = 1 / 5e-324 is not a double: one line, exit 2
    ([[5e-324, 0], [0, 1]], [-1, -1], "z1,w2", 2),
])
def test_pivot_on_extreme_data(tmp_path: Path, M: list, q: list, dependent: str,
                               code: int) -> None:
    path = tmp_path / "p.json"
    path.write_text(json.dumps({"M": M, "q": q}))
    got, out, err = cli("pivot", path, "-d", dependent, "--json")
    if code == 2:
        one_line_error(got, err)
        assert "beyond double precision" in err
        return
    assert got == 0, err
    doc = strict_json(out)
    assert all(v is not None for v in doc["q_prime"]), doc["q_prime"]


def test_post_impact_velocity_past_the_range_is_null_without_a_warning(samples: Path,
                                                                        tmp_path: Path) -> None:
    """A 2-D contact 1e308 away along its normal (no lever arm: the LCP is finite) whose body
    spins after the impact: that point's velocity overflows.  It is null in JSON (as an energy
    past the range is), with no numpy warning on stderr (one was printed before)."""
    scene = json.loads((samples / "scene_2d_boxes.json").read_text())
    scene["contacts"][0]["point"][1] = -1e308
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    code, out, err = cli("contact-matrix", path, "--solve", "--json")
    assert code == 0 and err == "", err
    doc = strict_json(out)
    assert doc["status"] == "solved" and doc["normal_velocities"][0] is None
