"""The command line as users run it: output schema, exit codes, bad input, stdin."""

from __future__ import annotations

import json

import numpy as np
import pytest

SCHEMA = {"file", "status", "method", "n", "z", "w", "iterations", "seconds", "residual",
          "error", "message"}


def test_solve_sample_prints_table(cli):
    r = cli("solve", "samples/seed004.json", "--method", "lemke", env={"NO_COLOR": "1"})
    assert r.returncode == 0, r.stderr
    for text in ("solved", "lemke", "residual", "error", "1.33333", "2.33333"):
        assert text in r.stdout
    assert "\x1b[" not in r.stdout  # no colour codes off a TTY
    assert r.stderr == ""


def test_solve_json_is_one_object_on_stdout(cli):
    r = cli("solve", "samples/seed004.json", "--json")
    assert r.returncode == 0
    lines = r.stdout.strip().splitlines()
    assert len(lines) == 1
    out = json.loads(lines[0])
    assert set(out) >= SCHEMA
    assert out["status"] == "solved" and out["n"] == 2
    np.testing.assert_allclose(out["z"], [4 / 3, 7 / 3])
    assert out["seconds"] > 0 and out["error"] < 1e-12


def test_stdin_dash(cli):
    r = cli("solve", "-", "--json", stdin='{"M": [[2, 1], [1, 2]], "q": [-5, -6]}')
    assert r.returncode == 0 and json.loads(r.stdout)["status"] == "solved"


def test_exit_code_1_when_not_solved(cli, siconos):
    r = cli("solve", str(siconos / "lcp" / "lcp_Pang_isolated_sol_perturbed.dat"), "--json")
    assert r.returncode == 1
    out = json.loads(r.stdout)
    assert out["status"] == "no_solution" and "Farkas" in out["message"]
    r = cli("solve", str(siconos / "lcp" / "lcp_CPS_3.dat"), "--method", "lemke", "--json")
    assert r.returncode == 1 and json.loads(r.stdout)["status"] == "unsolved"


def test_hdf5_problem_option(cli):
    r = cli("solve", "samples/collection.h5", "--problem", "seed000", "--json")
    assert r.returncode == 0
    np.testing.assert_allclose(json.loads(r.stdout)["z"], [0, 1, 3], atol=1e-12)
    # without --problem, a file of several problems is solved as a batch, one line each
    r = cli("solve", "samples/collection.h5", env={"COLUMNS": "120"})
    assert r.returncode == 0 and r.stderr == ""
    for name in ("seed000", "seed004", "trivial", "degenerate", "sparse_chain"):
        assert f"collection.h5 : {name}" in r.stdout
    r = cli("solve", "samples/collection.h5", "--json")
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(rows) == 5 and {row["status"] for row in rows} == {"solved"}


@pytest.mark.parametrize("args,stdin,text", [
    (["solve", "nope.json"], None, "no such file"),
    (["solve", "samples/make_samples.py"], None, "unknown file type"),
    (["solve", "-"], "{not json", "invalid JSON"),
    (["solve", "-"], '{"M": [[1, NaN]], "q": [1]}', "square"),
    (["solve", "-"], '{"M": [[NaN]], "q": [1]}', "NaN"),
    (["solve", "samples/seed004.json", "--bogus"], None, "No such option"),
    (["solve", "samples/seed004.json", "--method", "nope"], None, "unknown method"),
    (["solve", "samples/seed004.json", "-O", "omega=2"], None, "no option"),
    (["solve", "samples/seed004.json", "--tol", "-1"], None, "tolerance"),
    (["solve", "samples/seed004.json", "--covering", "1,x"], None, "covering"),
    (["solve", "samples/seed004.json", "--max-iter", "0"], None, "max_iter"),
    (["solve"], None, "Missing argument"),
    (["frobnicate"], None, "No such command"),
])
def test_bad_usage_and_input_exit_2_with_one_line(cli, args, stdin, text):
    r = cli(*args, stdin=stdin)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr + r.stdout
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and text in lines[0], r.stderr


def test_convert_round_trip_and_no_overwrite(cli, tmp_path):
    out = tmp_path / "p.npz"
    assert cli("convert", "samples/seed004.json", str(out)).returncode == 0
    assert cli("convert", str(out), str(tmp_path / "p.h5")).returncode == 0
    assert cli("convert", str(tmp_path / "p.h5"), str(tmp_path / "p.json")).returncode == 0
    back = json.loads((tmp_path / "p.json").read_text())
    assert back["M"] == [[2, 1], [1, 2]] and back["q"] == [-5, -6]
    r = cli("convert", "samples/seed004.json", str(out))
    assert r.returncode == 2 and "exists" in r.stderr
    # a bad input never touches an existing output
    before = out.read_bytes()
    r = cli("convert", "-", str(out), "--force", stdin="{broken")
    assert r.returncode == 2 and out.read_bytes() == before
    r = cli("convert", "samples/seed004.json", "-")
    assert json.loads(r.stdout)["q"] == [-5, -6]


def test_convert_multi_problem_hdf5(cli, tmp_path):
    r = cli("convert", "samples/collection.h5", str(tmp_path / "x.json"))
    assert r.returncode == 2 and "--problem" in r.stderr
    assert cli("convert", "samples/collection.h5", str(tmp_path / "copy.h5")).returncode == 0
    r = cli("solve", str(tmp_path / "copy.h5"), "-p", "trivial", "--json")
    np.testing.assert_allclose(json.loads(r.stdout)["z"], 1 / np.arange(1, 10))


def test_output_file_and_version_and_module(cli, tmp_path):
    out = tmp_path / "r.json"
    r = cli("solve", "samples/seed000.json", "-o", str(out))
    assert r.returncode == 0 and json.loads(out.read_text())["status"] == "solved"
    r = cli("--version")
    assert r.returncode == 0 and r.stdout.startswith("lcpcli ")


def test_help_lists_exit_codes_and_methods(cli):
    r = cli("--help")
    assert r.returncode == 0 and "Exit codes" in r.stdout
    r = cli("solve", "--help")
    assert "lemke" in r.stdout and "Exit codes" in r.stdout


def test_help_does_not_import_numpy(cli):
    r = cli("--help", env={"PYTHONPROFILEIMPORTTIME": "1"})
    assert r.returncode == 0
    imported = {line.split("|")[-1].strip() for line in r.stderr.splitlines() if "|" in line}
    assert "numpy" not in imported and "h5py" not in imported and "numba" not in imported


def test_methods_command(cli):
    r = cli("methods", "--json")
    names = {m["name"] for m in json.loads(r.stdout)}
    assert "lemke-tableau" in names
