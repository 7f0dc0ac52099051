"""Start-up discipline: what a one-liner imports (the module budget), never how long it takes.

Timings are in benchmarks/bench_startup.py; here we check the *cause* of slow start-ups: heavy
modules imported by commands that do not need them.
"""

from __future__ import annotations

import json

import pytest

#: Never imported by a one-problem solve of a small dense JSON problem.
HEAVY = ("scipy", "h5py", "matplotlib", "dask", "pydantic", "pydantic_core", "numba")
#: The module count of ``lcpcli solve samples/seed004.json`` (table output) was 350 when this
#: budget was set (469 before issue 13, about 890 with numba); the budget leaves some room.
MODULE_BUDGET = 420


def imported(stderr: str) -> set[str]:
    """Top-level package names from ``-X importtime`` output (PYTHONPROFILEIMPORTTIME)."""
    names = set()
    for line in stderr.splitlines():
        if line.startswith("import time:") and "|" in line:
            name = line.rsplit("|", 1)[-1].strip()
            if name and name != "imported package":
                names.add(name)
    return names


def heavy_in(names: set[str]) -> set[str]:
    return {n for n in names if n.split(".")[0] in HEAVY}


@pytest.mark.parametrize("args", [
    ("solve", "samples/seed004.json"),
    ("solve", "samples/seed004.json", "--json"),
    ("solve", "samples/seed004.json", "-m", "lemke-tableau", "--json"),
    ("solve", "samples/seed004.json", "-m", "enum", "--json"),
])
def test_small_solve_imports_nothing_heavy(cli, args):
    r = cli(*args, env={"PYTHONPROFILEIMPORTTIME": "1"})
    assert r.returncode == 0, r.stderr[-2000:]
    names = imported(r.stderr)
    assert "numpy" in names and "lcpcli.solvers.kernels.lemke" in names  # the check sees them
    assert not heavy_in(names), sorted(heavy_in(names))
    assert len(names) <= MODULE_BUDGET, len(names)


def test_stdin_one_liner_imports_nothing_heavy(cli):
    r = cli("solve", "-", "--json", stdin='{"M": [[2,1],[1,2]], "q": [-5,-6]}',
            env={"PYTHONPROFILEIMPORTTIME": "1"})
    assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads(r.stdout.strip())["status"] == "solved"
    assert not heavy_in(imported(r.stderr))


def test_help_imports_no_numpy(cli):
    r = cli("--help", env={"PYTHONPROFILEIMPORTTIME": "1"})
    assert r.returncode == 0
    names = imported(r.stderr)
    assert "typer" in names
    assert not heavy_in(names) and "numpy" not in names


def numpy_blas_files() -> list:
    from lcpcli.solvers.kernels.dense import _numpy_blas_files

    return _numpy_blas_files()


def test_large_factorisation_uses_lapack_without_scipy(cli, tmp_path):
    """Above the LAPACK crossover the dense Lemke path calls the LAPACK of numpy's OpenBLAS:
    scipy.linalg is never imported (its 0.3 s once counted in the reported seconds)."""
    import numpy as np

    n = 120
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    f = tmp_path / "big.json"
    f.write_text(json.dumps({"M": (A @ A.T + n * np.eye(n)).tolist(),
                             "q": (-np.abs(rng.standard_normal(n)) - 1).tolist()}))
    for method in ("lemke", "auto"):
        r = cli("solve", str(f), "-m", method, "--json", env={"PYTHONPROFILEIMPORTTIME": "1"})
        assert r.returncode == 0, r.stderr[-2000:]
        assert json.loads(r.stdout.strip().splitlines()[-1])["status"] == "solved"
        assert "scipy.linalg" not in imported(r.stderr) or not numpy_blas_files()


def test_plain_coercion_keeps_typers_errors(cli):
    """Values the plain coercion does not take go through typer's own checks and messages."""
    for args in (("--max-iter", "abc"), ("--tol", "x1"), ("--jobs", "0")):
        r = cli("solve", "samples/seed004.json", *args)
        assert r.returncode == 2, (args, r.stderr)
        assert r.stderr.startswith("lcpcli: error: ") and "Traceback" not in r.stderr
        assert args[0] in r.stderr
    r = cli("solve", "samples/seed004.json", "--tol", "1e-9", "--max-iter", "+50", "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["status"] == "solved"


def test_plain_coercion_converts_like_typer():
    """The plain conversion agrees with typer's for the values it accepts."""
    from pathlib import Path

    from lcpcli.cli.plain_params import _plain

    class Info:
        min = None
        max = None
        exists = False
        resolve_path = False
        file_okay = True
        dir_okay = True
        allow_dash = False
        writable = False
        readable = True

    info = Info()
    assert _plain(int, info, "42") == (True, 42)
    assert _plain(int, info, "4.2") == (False, None)
    assert _plain(float, info, "1e-8") == (True, 1e-8)
    assert _plain(float, info, ".5") == (True, 0.5)
    assert _plain(float, info, "nan")[0] is False  # left to typer
    assert _plain(str, info, "lemke") == (True, "lemke")
    assert _plain(bool, info, True) == (True, True)
    assert _plain(list[str], info, ("a", "b")) == (True, ["a", "b"])
    assert _plain(Path, info, "x.json") == (True, Path("x.json"))
    info.min = 1
    assert _plain(int, info, "0") == (False, None)
