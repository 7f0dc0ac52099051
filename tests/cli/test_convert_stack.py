"""``lcpcli convert`` with stacked files: folder <-> stack <-> multi-group HDF5 <-> folder."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from lcpcli.core.problem import Problem
from lcpcli.io import load, save
from lcpcli.io.stack import iter_problems, stack_info, write_stack


def folder_of_problems(path, n=3, count=5):
    path.mkdir()
    rng = np.random.default_rng(3)
    problems = {}
    for k in range(count):
        p = Problem.create(2 * np.eye(n) + 0.1 * rng.random((n, n)), rng.normal(size=n),
                           name=f"p{k}")
        save(p, path / f"p{k}.{['json', 'npz', 'h5'][k % 3]}")
        problems[f"p{k}"] = p
    return problems


def one_line_error(r, text):
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and text in lines[0], r.stderr


@pytest.mark.parametrize("ext", ["h5", "npz"])
def test_folder_stack_folder_round_trip(cli, tmp_path, ext):
    problems = folder_of_problems(tmp_path / "in")
    stack = tmp_path / f"s.{ext}"
    r = cli("convert", str(tmp_path / "in"), str(stack), "--stack")
    assert r.returncode == 0, r.stderr
    info = stack_info(stack)
    assert (info.K, info.n, info.has_names) == (5, 3, True)
    assert [p.name for p in iter_problems(stack)] == sorted(problems)
    r = cli("convert", str(stack), str(tmp_path / "out"), "--format", "json")
    assert r.returncode == 0, r.stderr
    back = sorted(f.name for f in (tmp_path / "out").iterdir())
    assert back == [f"{name}.json" for name in sorted(problems)]
    for name, p in problems.items():
        q = load(tmp_path / "out" / f"{name}.json")
        np.testing.assert_array_equal(q.M, p.M)
        np.testing.assert_array_equal(q.q, p.q)
        assert q.name == name
    # existing files are not overwritten without --force
    r = cli("convert", str(stack), str(tmp_path / "out"), "--format", "json")
    one_line_error(r, "exists already (use --force to overwrite)")
    assert cli("convert", str(stack), str(tmp_path / "out"), "--format", "json",
               "--force").returncode == 0


def test_multi_group_stack_multi_group(cli, tmp_path):
    problems = folder_of_problems(tmp_path / "in", n=2, count=4)
    groups = tmp_path / "groups.h5"
    from lcpcli.io.hdf5_format import write_many

    write_many(list(problems.values()), groups)
    assert cli("convert", str(groups), str(tmp_path / "s.h5"), "--stack").returncode == 0
    assert [p.name for p in iter_problems(tmp_path / "s.h5")] == sorted(problems)
    # a stack to a stack: copied (re-chunked, other format)
    assert cli("convert", str(tmp_path / "s.h5"), str(tmp_path / "s.npz"),
               "--stack").returncode == 0
    r = cli("convert", str(tmp_path / "s.npz"), str(tmp_path / "back.h5"))
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "back.h5") as f:
        assert sorted(f) == sorted(problems)
    for name, p in problems.items():
        got = load(tmp_path / "back.h5", name)
        np.testing.assert_array_equal(got.M, p.M)
        np.testing.assert_array_equal(got.q, p.q)


def test_mismatched_n_refused(cli, tmp_path):
    folder_of_problems(tmp_path / "in", n=3, count=3)
    save(Problem.create(np.eye(4), np.ones(4)), tmp_path / "in" / "p1b.json")
    out = tmp_path / "s.h5"
    r = cli("convert", str(tmp_path / "in"), str(out), "--stack")
    one_line_error(r, "p1b.json: n = 4, but")
    assert "has n = 3" in r.stderr
    assert not out.exists() and not list(tmp_path.glob(".s.h5*"))


def test_refused_outputs_and_usage(cli, tmp_path):
    folder_of_problems(tmp_path / "in", count=2)
    one_line_error(cli("convert", str(tmp_path / "in"), str(tmp_path / "in" / "s.h5"),
                       "--stack"), "is inside the input folder")
    one_line_error(cli("convert", str(tmp_path / "in"), str(tmp_path / "s.json"), "--stack"),
                   "a stacked file is written as .h5/.hdf5/.hdf or .npz")
    one_line_error(cli("convert", str(tmp_path / "in"), str(tmp_path / "s.h5")),
                   "add --stack")
    M = np.tile(np.eye(2), (3, 1, 1))
    write_stack(tmp_path / "s.h5", M, np.ones((3, 2)))
    # OUT is never IN, even with --force
    one_line_error(cli("convert", str(tmp_path / "s.h5"), str(tmp_path / "s.h5"), "--stack",
                       "--force"), "is the same file as the input")
    one_line_error(cli("convert", str(tmp_path / "s.h5"), str(tmp_path / "x.json")),
                   "holds 3 stacked problems")
    (tmp_path / "afile").write_text("x")
    one_line_error(cli("convert", str(tmp_path / "s.h5"), str(tmp_path / "afile"),
                       "--format", "json"), "not a folder")
    (tmp_path / "link").symlink_to(tmp_path / "in")
    one_line_error(cli("convert", str(tmp_path / "s.h5"), str(tmp_path / "link"),
                       "--format", "json"), "not a folder")
    one_line_error(cli("convert", str(tmp_path / "s.h5"), str(tmp_path / "o.h5"),
                       "--stack", "--format", "json"), "give one of them")


def test_dash_with_format_is_stdout_never_a_folder(cli, tmp_path, samples):
    """``convert IN - --format json`` prints JSON on stdout, as without --format; a binary
    --format is refused with one line; no folder named '-' is ever made."""
    import json

    src = samples / "box_small.json"
    plain = cli("convert", str(src), "-")
    res = cli("convert", str(src), "-", "--format", "json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout) == json.loads(plain.stdout)
    for fmt in ("npz", "h5", "dat"):
        res = cli("convert", str(src), "-", "--format", fmt, cwd=tmp_path)
        assert res.returncode == 2, res.stderr
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("lcpcli: error: -: "), res.stderr
        assert res.stdout == ""
    assert not (tmp_path / "-").exists()
