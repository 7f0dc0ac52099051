"""``--resume`` keeps only results computed from the same data, and fails in one line otherwise.

A stacked result records a digest per chunk of its input and the solve options; a
per-file batch records ``input_hash`` per row.  Resuming against other data (same path, K and n),
other options, a file without fingerprints (an older lcpcli) or a damaged status is refused with
one line and exit code 2; nothing of the result file is changed by the refusal.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from lcpcli.api import solve_many
from lcpcli.batch.output import read_rows
from lcpcli.io.stack import write_stack
from tests.conftest import ROOT


def pd_stack(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


def problem_files(tmp_path, M: np.ndarray, q: np.ndarray) -> list[str]:
    """One JSON problem file per problem of the stack, ``p0.json``, ``p1.json``, ..."""
    files = []
    for k in range(M.shape[0]):
        f = tmp_path / f"p{k}.json"
        f.write_text(json.dumps({"M": M[k].tolist(), "q": q[k].tolist()}))
        files.append(str(f))
    return files


def one_line(res, reason: str) -> None:
    assert res.returncode == 2, (res.returncode, res.stderr[-1500:])
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: "), res.stderr[-1500:]
    assert reason in lines[0], lines[0]
    assert "Traceback" not in res.stderr


@pytest.mark.parametrize("ext", ["h5", "npz", "jsonl", "csv"])
def test_resume_against_another_stack_is_refused(cli, tmp_path, ext):
    """The same path, K and n, other data: refused (5,000 wrong 'solved' answers were kept);
    the same data again: everything skipped, the answers unchanged."""
    M, q = pd_stack(400, 5)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / f"r.{ext}"
    assert cli("solve", str(stack), "-o", str(out), "--json").returncode == 0
    res = cli("solve", str(stack), "-o", str(out), "--resume", "--json")
    assert res.returncode == 0 and json.loads(res.stdout.splitlines()[-1])["skipped"] == 400
    before = out.read_bytes()
    write_stack(stack, M, -q)  # another stack under the same name
    one_line(cli("solve", str(stack), "-o", str(out), "--resume"), "other data")
    assert out.read_bytes() == before


@pytest.mark.parametrize("ext", ["h5", "npz", "jsonl", "csv"])
def test_resume_with_other_options_is_refused(cli, tmp_path, ext):
    """A stacked result (file or rows) resumed with another tol or method: one line, the
    file unchanged (row outputs kept results of another method before); the same settings:
    every problem skipped."""
    M, q = pd_stack(50, 4)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / f"r.{ext}"
    assert cli("solve", str(stack), "-o", str(out)).returncode == 0
    before = out.read_bytes()
    one_line(cli("solve", str(stack), "-o", str(out), "--resume", "--tol", "1e-6"),
             "computed with")
    one_line(cli("solve", str(stack), "-o", str(out), "--resume", "-m", "pgs"),
             "computed with")
    assert out.read_bytes() == before
    res = cli("solve", str(stack), "-o", str(out), "--resume", "--json")
    assert res.returncode == 0 and json.loads(res.stdout.splitlines()[-1])["skipped"] == 50


def test_results_without_fingerprint_are_refused(cli, tmp_path):
    """Files of an older lcpcli (no digests, no input_hash, the old CSV header): refused with
    a message saying to run without --resume."""
    M, q = pd_stack(30, 4)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / "r.h5"
    assert cli("solve", str(stack), "-o", str(out)).returncode == 0
    with h5py.File(out, "a") as f:
        del f["s"]["chunk_digest"]
        del f["s"].attrs["solve_options"]
    older = ("without the fingerprints of their input and solve settings (written by an older "
             "lcpcli), so they cannot be checked against them; run again without --resume")
    one_line(cli("solve", str(stack), "-o", str(out), "--resume"),
             f"{out}: holds results of {stack} {older}")
    rows = tmp_path / "r.jsonl"
    assert cli("solve", str(stack), "-o", str(rows)).returncode == 0
    lines = [json.loads(x) for x in rows.read_text().splitlines()]
    rows.write_text("".join(json.dumps({k: v for k, v in r.items() if k != "input_hash"}) + "\n"
                            for r in lines))
    one_line(cli("solve", str(stack), "-o", str(rows), "--resume"),
             f"{rows}: holds results of {stack} {older}")
    p = tmp_path / "p.json"
    p.write_text(json.dumps({"M": M[0].tolist(), "q": q[0].tolist()}))
    old_csv = tmp_path / "old.csv"
    old_csv.write_text("source,problem,status,method,n,iterations,seconds,residual,error,"
                       "message,index\n" f"{p},p,solved,auto,4,3,0.1,0.0,0.0,ok,\n")
    one_line(cli("solve", str(p), "-o", str(old_csv), "--resume"), "without --resume")


def test_per_file_batch_resume_checks_each_input(cli, tmp_path):
    """A problem file changed since its row was written: refused; unchanged: skipped."""
    M, q = pd_stack(3, 4)
    files = problem_files(tmp_path, M, q)
    for ext in ("jsonl", "csv", "h5"):
        out = tmp_path / f"r.{ext}"
        assert cli("solve", *files[:2], "-o", str(out)).returncode == 0
        res = cli("solve", *files, "-o", str(out), "--resume", "--json")
        assert res.returncode == 0, res.stderr
        assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 2
        rows = read_rows(out)
        assert all(len(r["input_hash"]) == 32 for r in rows) and len(rows) == 3
    (tmp_path / "p1.json").write_text(json.dumps({"M": M[1].tolist(), "q": (-q[1]).tolist()}))
    for ext in ("jsonl", "csv", "h5"):
        one_line(cli("solve", *files, "-o", str(tmp_path / f"r.{ext}"), "--resume"),
                 f"holds results of {files[1]} computed from other data: {files[1]} has "
                 f"changed since; run again without --resume, or give another --output")


@pytest.mark.parametrize("ext", ["jsonl", "csv", "h5"])
def test_per_file_batch_resume_checks_the_settings(cli, tmp_path, ext):
    """Per-file --resume with another method, tol or option: refused with one line naming the
    setting, the result file unchanged (the settings were not recorded: results of another
    method were kept); the same settings: the finished rows are skipped."""
    M, q = pd_stack(3, 4)
    files = problem_files(tmp_path, M, q)
    out = tmp_path / f"r.{ext}"
    # one job: rows in file order, so the refusal names p0 (two workers finish in any order)
    assert cli("solve", *files[:2], "-o", str(out), "-m", "lemke", "--max-iter", "50",
               "-j", "1").returncode == 0
    before = out.read_bytes()
    for args, words in (
            (["-m", "pgs", "--max-iter", "50"], "method was 'lemke-revised', now 'pgs'"),
            (["-m", "lemke", "--max-iter", "50", "--tol", "1e-6"],
             "tol was the default, now 1e-06"),
            (["-m", "lemke", "--max-iter", "60"], "option max_iter was 50, now 60"),
            (["-m", "lemke"], "option max_iter was 50, now the default")):
        one_line(cli("solve", *files, "-o", str(out), "--resume", *args),
                 f"holds results of {files[0]} computed with other settings: {words}; give "
                 f"the same settings, or run again without --resume")
        assert out.read_bytes() == before
    res = cli("solve", *files, "-o", str(out), "--resume", "-m", "lemke", "--max-iter", "50",
              "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 2
    assert {r["solve_options"] for r in read_rows(out)} == {
        '{"method": "lemke-revised", "options": {"max_iter": 50}, "tol": null}'}


@pytest.mark.parametrize(("kind", "ext"), [("stack", "h5"), ("stack", "npz"), ("stack", "jsonl"),
                                         ("stack", "csv"), ("files", "jsonl"), ("files", "csv"),
                                         ("files", "h5")])
def test_a_refused_resume_reads_the_same_for_stacks_and_problem_files(cli, tmp_path, kind,
                                                                       ext):
    """Other settings and other data are refused in one wording, the result file first, for
    a stacked and a per-file batch alike (a stacked .h5/.npz said "computed with {raw JSON},
    not {raw JSON}: give the same options", a stack's other data "holds results computed from
    other data than s.h5 has now", a problem file's "of p0.json computed from other content
    than the file has now")."""
    M, q = pd_stack(3, 4)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    inputs = [str(stack)] if kind == "stack" else problem_files(tmp_path, M, q)
    source = inputs[0]
    out = tmp_path / f"r.{ext}"
    assert cli("solve", *inputs, "-o", str(out), "-j", "1").returncode == 0
    one_line(cli("solve", *inputs, "-o", str(out), "--resume", "-m", "pgs"),
             f"lcpcli: error: {out}: holds results of {source} computed with other settings: "
             f"method was 'auto', now 'pgs'; give the same settings, or run again without "
             f"--resume")
    if kind == "stack":
        write_stack(stack, M, -q)
        which = " (problems 0 to 2 differ)"
    else:
        Path(source).write_text(json.dumps({"M": M[0].tolist(), "q": (-q[0]).tolist()}))
        which = ""
    one_line(cli("solve", *inputs, "-o", str(out), "--resume"),
             f"lcpcli: error: {out}: holds results of {source} computed from other data: "
             f"{source} has changed since{which}; run again without --resume, or give another "
             f"--output")


def test_per_file_rows_without_solve_options_are_refused(cli, tmp_path):
    """Rows of an older lcpcli (input_hash but no solve_options): refused, run without --resume."""
    p = tmp_path / "p.json"
    M, q = pd_stack(1, 3)
    p.write_text(json.dumps({"M": M[0].tolist(), "q": q[0].tolist()}))
    out = tmp_path / "r.jsonl"
    assert cli("solve", str(p), "-o", str(out)).returncode == 0
    rows = [json.loads(x) for x in out.read_text().splitlines()]
    out.write_text("".join(json.dumps({k: v for k, v in r.items() if k != "solve_options"})
                           + "\n" for r in rows))
    one_line(cli("solve", str(p), "-o", str(out), "--resume"),
             f"lcpcli: error: {out}: holds results of {p} without the fingerprints of their "
             f"input and solve settings (written by an older lcpcli)")


def test_status_77_is_one_line(cli, tmp_path):
    """A stacked result whose status holds 77 (was exit 3 KeyError)."""
    M, q = pd_stack(20, 3)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / "r.h5"
    assert cli("solve", str(stack), "-o", str(out)).returncode == 0
    with h5py.File(out, "a") as f:
        f["s"]["status"][4] = 77
    one_line(cli("solve", str(stack), "-o", str(out), "--resume"), "holds 77")
    npz = tmp_path / "r.npz"
    assert cli("solve", str(stack), "-o", str(npz)).returncode == 0
    with np.load(npz) as d:
        arrays = {k: d[k] for k in d.files}
    arrays["status"][4] = 77
    np.savez(npz, **arrays)
    one_line(cli("solve", str(stack), "-o", str(npz), "--resume"), "holds 77")


@pytest.mark.parametrize("ext", ["csv", "h5", "jsonl"])
def test_file_names_that_are_not_utf8(tmp_path, ext):
    """A problem file named with the byte 0xff (was exit 3 UnicodeEncodeError for .csv and
    .h5): solved, written, and found again by --resume."""
    M, q = pd_stack(2, 3)
    folder = tmp_path / "in"
    folder.mkdir()
    for k, name in enumerate((b"caf\xe9.json", b"plain.json")):
        path = os.path.join(os.fsencode(folder), name)
        with open(path, "w") as fh:
            json.dump({"M": M[k].tolist(), "q": q[k].tolist()}, fh)
    out = tmp_path / f"r.{ext}"
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    for extra in ([], ["--resume"]):
        res = subprocess.run([sys.executable, "-m", "lcpcli", "solve", str(folder), "-o",
                              str(out), "--json", *extra], capture_output=True, env=env,
                             cwd=ROOT, timeout=120)
        assert res.returncode == 0 and b"Traceback" not in res.stderr, res.stderr
    assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 2
    assert len(read_rows(out)) == 2
    if ext == "csv":  # the name's own bytes, as the file system holds them
        assert b"caf\xe9.json" in out.read_bytes()


def test_stacked_result_row_matches_fresh_solve_after_resume(cli, tmp_path):
    """Resuming an interrupted stacked .h5 (statuses of the second half reset) gives the
    answers of a fresh solve: the fingerprint check does not disturb a legitimate resume."""
    M, q = pd_stack(300, 6)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / "r.h5"
    assert cli("solve", str(stack), "-o", str(out)).returncode == 0
    with h5py.File(out, "a") as f:
        f["s"]["status"][150:] = -1
        f["s"]["z"][150:] = np.nan
    res = cli("solve", str(stack), "-o", str(out), "--resume", "--json")
    assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 150
    with h5py.File(out) as f:
        np.testing.assert_allclose(f["s"]["z"][...], solve_many(M, q).z, atol=1e-12)


def test_kill_9_of_a_jobs_2_batch_leaves_no_worker_traceback(tmp_path):
    """kill -9 of the parent of a --jobs 2 batch: the workers exit quietly (each printed a
    BrokenPipeError traceback before)."""
    M, q = pd_stack(600, 4)
    folder = tmp_path / "in"
    folder.mkdir()
    for k in range(600):
        (folder / f"p{k:03d}.json").write_text(json.dumps({"M": M[k].tolist(),
                                                           "q": q[k].tolist()}))
    out = tmp_path / "r.jsonl"
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.Popen([sys.executable, "-m", "lcpcli", "solve", str(folder), "-o",
                             str(out), "-j", "2", "-q", "-m", "pgs", "-O", "max_iter=20000"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, env=env,
                            cwd=ROOT)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and (not out.exists() or out.stat().st_size < 2000):
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    _, err = proc.communicate(timeout=60)  # the pipe closes when the workers have exited too
    assert b"Traceback" not in err and b"BrokenPipeError" not in err, err.decode()[-2000:]


def test_solve_a_directory_named_like_a_problem_is_one_line(cli, tmp_path):
    (tmp_path / "adir.json").mkdir()
    res = cli("solve", str(tmp_path / "adir.json"))
    one_line(res, "is a directory")
    assert res.stdout == ""


def test_resume_with_a_new_stack_adds_its_group_by_copy(tmp_path, monkeypatch):
    """A resumed stacked .h5 given one more input stack: its group is added in a copy renamed
    over the file, so a full disk then leaves the file byte for byte as it was; with space,
    the first stack is skipped and the second solved."""
    import errno

    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.core.errors import OutputError

    M, q = pd_stack(200, 4, seed=1)
    write_stack(tmp_path / "a.h5", M, q)
    write_stack(tmp_path / "b.h5", M, -q)
    out = tmp_path / "r.h5"
    run_batch([str(tmp_path / "a.h5")], SolveOptions(), output=out)
    before = out.read_bytes()
    real = os.pwrite

    def full(fd, data, offset):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "pwrite", full)
    with pytest.raises(OutputError, match="no space left on device"):
        run_batch([str(tmp_path / "a.h5"), str(tmp_path / "b.h5")], SolveOptions(),
                  output=out, resume=True)
    monkeypatch.setattr(os, "pwrite", real)
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "b.h5", "r.h5"]
    report = run_batch([str(tmp_path / "a.h5"), str(tmp_path / "b.h5")], SolveOptions(),
                       output=out, resume=True)
    assert (report.skipped, report.new) == (200, 200)
    with h5py.File(out) as f:
        np.testing.assert_allclose(f["a"]["z"][...], solve_many(M, q).z, atol=1e-12)
        np.testing.assert_allclose(f["b"]["z"][...], solve_many(M, -q).z, atol=1e-12)


@pytest.mark.parametrize("text", ['hello\n{"a":1}\nworld', '{"a": 1}\n', "[1, 2]\nworld",
                                  "hello"])
def test_jsonl_resume_refuses_a_file_that_is_not_a_result_file(cli, tmp_path, text):
    """A JSON Lines output that is not lcpcli's (a line that is not a row, or a last line
    that cannot start one): --resume refuses it in one line and leaves it as it was (its
    last line was cut off, and rows appended to it, exit 0)."""
    M, q = pd_stack(1, 3)
    p = tmp_path / "p.json"
    p.write_text(json.dumps({"M": M[0].tolist(), "q": q[0].tolist()}))
    out = tmp_path / "notres.jsonl"
    out.write_text(text)
    one_line(cli("solve", str(p), "-o", str(out), "--resume"), "cannot be resumed")
    assert out.read_text() == text
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    one_line(cli("solve", str(stack), "-o", str(out), "--resume"), "cannot be resumed")
    assert out.read_text() == text


def test_jsonl_resume_keeps_cutting_a_torn_row(cli, tmp_path):
    """An interrupted run's torn last row is still cut off and the batch resumed."""
    M, q = pd_stack(2, 3)
    files = problem_files(tmp_path, M, q)
    out = tmp_path / "r.jsonl"
    assert cli("solve", files[0], "-o", str(out)).returncode == 0
    with open(out, "a") as fh:
        fh.write('{"file": "p1.js')
    res = cli("solve", *files, "-o", str(out), "--resume", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 1
    assert len(read_rows(out)) == 2 and out.read_text().endswith("\n")


def test_hdf5_rows_resume_refuses_damaged_or_foreign_files(cli, tmp_path):
    """Per-file HDF5 results with a row that is not one (``json`` of '[' * 5000: read as no
    rows, everything solved again into groups ``p0~2``), a row without source and problem,
    z of another length, a problem file (M and q at the root, or in a group) or a file that
    is not HDF5 (replaced by an empty result file): --resume refuses them in one line and
    never writes into them.  A group whose write was interrupted (no ``json`` yet: the
    journal has its row) is still skipped."""
    M, q = pd_stack(2, 3)
    files = problem_files(tmp_path, M, q)
    good = tmp_path / "good.h5"
    assert cli("solve", *files, "-o", str(good)).returncode == 0

    def damaged(name: str, change) -> Path:
        out = tmp_path / f"{name}.h5"
        out.write_bytes(good.read_bytes())
        with h5py.File(out, "r+") as f:
            change(f)
        return out

    def set_json(text: str):
        return lambda f: f["p0"].attrs.__setitem__("json", text)

    def resize_z(f):
        del f["p0"]["z"]
        f["p0"]["z"] = np.zeros(5)

    def problem(f):
        for name in list(f):
            del f[name]
        f["M"], f["q"] = M[0], q[0]

    def problem_group(f):
        for name in list(f):
            del f[name]
        g = f.create_group("p0")
        g["M"], g["q"] = M[0], q[0]

    outs = [damaged("deep", set_json("[" * 5000)), damaged("anon", set_json('{"a": 1}')),
            damaged("zlen", resize_z), damaged("problem", problem),
            damaged("problem_group", problem_group)]
    text = tmp_path / "text.h5"
    text.write_text("not HDF5\n")
    for out in [*outs, text]:
        before = out.read_bytes()
        one_line(cli("solve", *files, "-o", str(out), "--resume"), "cannot be resumed")
        assert out.read_bytes() == before, out
    interrupted = damaged("interrupted", lambda f: f["p1"].attrs.__delitem__("json"))
    res = cli("solve", *files, "-o", str(interrupted), "--resume", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout.splitlines()[-1])["skipped"] == 1


def test_stacked_h5_resume_checks_every_dataset(cli, tmp_path):
    """A stacked HDF5 result whose datasets were replaced (z of another shape or of strings,
    iterations of 5 entries, basis of floats, a group for error, names of numbers) or whose
    attributes are of another type: --resume refuses it in one line (was exit 3: TypeError
    "Can't broadcast", OSError, ValueError) and leaves it unchanged."""
    M, q = pd_stack(40, 3)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q, names=[f"p{k}" for k in range(40)])
    good = tmp_path / "good.h5"
    assert cli("solve", str(stack), "-o", str(good)).returncode == 0

    def replaced(key: str, value) -> object:
        def change(g) -> None:
            del g[key]
            if value is None:
                g.create_group(key)
            else:
                g[key] = value
        return change

    changes = {
        "z_shape": replaced("z", np.zeros((40, 4))),
        "z_text": replaced("z", np.zeros((40, 3), "S3")),
        "iterations": replaced("iterations", np.zeros(5, np.int64)),
        "basis": replaced("basis", np.zeros((40, 3))), "error": replaced("error", None),
        "residual": replaced("residual", np.zeros(40, "S1")),
        "names": replaced("names", np.zeros(40)),
        "chunk_attr": lambda g: g.attrs.__setitem__("chunk", "abc"),
        "K_attr": lambda g: g.attrs.__setitem__("K", np.zeros(3)),
    }
    for name, change in changes.items():
        out = tmp_path / f"{name}.h5"
        out.write_bytes(good.read_bytes())
        with h5py.File(out, "r+") as f:
            change(f["s"])
        before = out.read_bytes()
        one_line(cli("solve", str(stack), "-o", str(out), "--resume"), "cannot be resumed")
        assert out.read_bytes() == before, name
    res = cli("solve", str(stack), "-o", str(good), "--resume", "--json")
    assert res.returncode == 0 and json.loads(res.stdout.splitlines()[-1])["skipped"] == 40
