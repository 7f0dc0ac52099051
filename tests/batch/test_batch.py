"""Batch solving: many files, bad inputs, resume after interruption, outputs, jobs, timeout, Dask.

Solutions are checked by substitution (w = M z + q recomputed from the original data), the
three output formats against each other, and parallel runs against serial ones.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from lcpcli.batch.output import journal_path, read_rows
from lcpcli.core.problem import Problem
from lcpcli.io import save
from lcpcli.io.hdf5_format import write_many

ROOT = Path(__file__).resolve().parents[2]
SLOW_KEYS = ("seconds", "wall_seconds")


def spd_problem(rng: np.random.Generator, n: int, name: str) -> Problem:
    """A random positive definite LCP: it has exactly one solution, Lemke finds it."""
    A = rng.standard_normal((n, n))
    return Problem.create(A @ A.T + 0.5 * np.eye(n), rng.standard_normal(n), name=name)


def murty(n: int) -> Problem:
    """Murty's P-matrix family: Lemke needs 2^n pivots (a slow problem on demand)."""
    M = np.tril(2.0 * np.ones((n, n)), -1) + np.eye(n)
    return Problem.create(M, -np.ones(n), name=f"murty{n}")


def check_by_substitution(row: dict, problem: Problem) -> None:
    z = np.array(row["z"], dtype=float)
    w = problem.M @ z + problem.q
    assert np.allclose(w, row["w"], atol=1e-9)
    assert np.max(np.abs(np.minimum(z, w))) < 1e-8
    assert row["n"] == problem.n


def lib(inputs: list, **kw):
    """The library entry point, in this process (faster than the CLI for most checks)."""
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch

    opts = SolveOptions(method=kw.pop("method", "auto"),
                        options={"max_iter": kw.pop("max_iter")} if "max_iter" in kw else {})
    return run_batch([str(i) for i in inputs], opts, **kw)


def strip(row: dict) -> dict:
    return {k: v for k, v in row.items() if k not in SLOW_KEYS}


def by_key(rows: list[dict]) -> dict[tuple[str, str], dict]:
    out = {(r["source"], r["problem"]): r for r in rows}
    assert len(out) == len(rows), f"duplicate rows: {sorted(k for k in out)} vs {len(rows)}"
    return out


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Problem]]:
    """12 JSON problems in a folder tree, two bad ones in the middle."""
    base = tmp_path_factory.mktemp("batch")
    d = base / "probs"
    (d / "sub").mkdir(parents=True)
    rng = np.random.default_rng(7)
    problems = {}
    for i in range(12):
        where = d / "sub" if i >= 9 else d
        path = where / f"p{i:02d}.json"
        if i == 5:
            path.write_text('{"M": [[1, 2], [3, 4]], "q": [1, 2')  # torn JSON
            continue
        if i == 6:
            path.write_text(json.dumps({"M": [[1, 0], [0, 1]], "q": [1, 2, 3]}))  # wrong shape
            continue
        p = spd_problem(rng, 3 + i % 5, path.stem)
        save(p, path)
        problems[str(path.relative_to(base))] = p
    return base, problems


def test_bad_files_recorded_rest_solved(cli, folder):
    base, problems = folder
    r = cli("solve", "probs", "--recursive", "-j", "2", "-o", "r.jsonl", "-q", cwd=base)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert "batch summary" in r.stdout
    rows = by_key(read_rows(base / "r.jsonl"))
    assert len(rows) == 12
    bad = {k: v for k, v in rows.items() if v["status"] == "error"}
    assert {Path(k[0]).name for k in bad} == {"p05.json", "p06.json"}
    for (src, _), row in bad.items():
        assert row["message"].startswith(src) and "\n" not in row["message"]
    assert "invalid JSON" in rows[("probs/p05.json", "p05")]["message"]
    assert "q has length 3" in rows[("probs/p06.json", "p06")]["message"]
    for src, p in problems.items():
        row = rows[(src, Path(src).stem)]
        assert row["status"] == "solved" and row["file"] == src
        check_by_substitution(row, p)
    # without --recursive the sub-folder is not searched
    report = lib([base / "probs"], jobs=1, output=base / "top.jsonl")
    assert report.total == 9 and len(read_rows(base / "top.jsonl")) == 9


def test_outputs_agree_and_jobs(cli, folder):
    """JSONL, CSV and HDF5 hold the same results; --jobs 2 equals --jobs 1."""
    base, _ = folder
    outs = {}
    r = cli("solve", "probs", "-r", "-j", "1", "-o", "a.jsonl", "--json", cwd=base)
    assert r.returncode == 2
    summary = json.loads(r.stdout)  # with --output, --json prints one summary object
    assert summary["summary"]["counts"] == {"error": 2, "solved": 10}
    outs["a.jsonl"] = by_key(read_rows(base / "a.jsonl"))
    cwd = os.getcwd()
    os.chdir(base)
    try:
        for name in ("a.csv", "a.h5", "b.jsonl"):
            report = lib(["probs"], recursive=True, jobs=2, output=name)
            assert report.exit_code == 2 and report.new == 12
            outs[name] = by_key(read_rows(base / name))
    finally:
        os.chdir(cwd)
    assert not journal_path(base / "a.h5").exists()  # removed after a clean finish
    j1, j2, csv_rows, h5 = outs["a.jsonl"], outs["b.jsonl"], outs["a.csv"], outs["a.h5"]
    assert {k: strip(v) for k, v in j1.items()} == {k: strip(v) for k, v in j2.items()}
    assert {k: strip(v) for k, v in j1.items()} == {k: strip(v) for k, v in h5.items()}
    assert set(csv_rows) == set(j1)
    for k, row in csv_rows.items():
        for col in ("status", "method", "n", "iterations", "residual", "error", "message"):
            assert row[col] == j1[k][col], (k, col)
    import h5py

    with h5py.File(base / "a.h5") as f:
        g = f["p00"]
        ref = j1[("probs/p00.json", "p00")]
        assert np.array_equal(g["z"][()], ref["z"]) and g.attrs["status"] == "solved"
        assert g["certificate"].attrs["error"] == ref["certificate"]["error"]


def test_hdf5_many_problems_input(cli, tmp_path):
    rng = np.random.default_rng(3)
    problems = [spd_problem(rng, 4 + i % 6, f"g{i:03d}") for i in range(60)]
    write_many(problems, tmp_path / "many.h5")
    import h5py

    with h5py.File(tmp_path / "many.h5", "a") as f:  # damage one group: q of wrong length
        del f["g030"]["q"]
        f["g030"].create_dataset("q", data=np.ones(2))
    r1 = cli("solve", "many.h5", "-j", "1", "-o", "one.jsonl", "-q", cwd=tmp_path)
    assert r1.returncode == 2
    report = lib([tmp_path / "many.h5"], jobs=2, output=tmp_path / "two.jsonl")
    assert report.exit_code == 2
    for row in read_rows(tmp_path / "two.jsonl"):  # make keys relative like the CLI run's
        row["source"] = row["file"] = "many.h5"
        row["message"] = row["message"].replace(str(tmp_path / "many.h5"), "many.h5")
        with open(tmp_path / "two_rel.jsonl", "a") as f:
            f.write(json.dumps(row) + "\n")
    one = by_key(read_rows(tmp_path / "one.jsonl"))
    two = by_key(read_rows(tmp_path / "two_rel.jsonl"))
    assert {k: strip(v) for k, v in one.items()} == {k: strip(v) for k, v in two.items()}
    assert len(one) == 60
    assert one[("many.h5", "g030")]["status"] == "error"
    for p in problems:
        if p.name != "g030":
            check_by_substitution(one[("many.h5", p.name)], p)


def _wait_lines(path: Path, n: int, proc: subprocess.Popen, limit: float = 40) -> None:
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if path.exists() and path.read_bytes().count(b"\n") >= n:
            return
        if proc.poll() is not None:
            pytest.fail(f"batch ended early: {proc.stderr.read()}")
        time.sleep(0.05)
    pytest.fail("batch produced no output in time")


def _popen(args: list[str], cwd: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-m", "lcpcli", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def slow_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """30 easy problems with a slow one (Murty n = 23, about 8e6 pivots) at position 12."""
    d = tmp_path_factory.mktemp("slow")
    rng = np.random.default_rng(11)
    for i in range(30):
        p = murty(23) if i == 12 else spd_problem(rng, 5, f"e{i:02d}")
        save(p, d / f"e{i:02d}.json")
    return d


def test_resume_after_kill_9(cli, slow_folder, tmp_path):
    out = tmp_path / "r.jsonl"
    proc = _popen(["solve", str(slow_folder), "-m", "lemke", "-j", "1", "--timeout", "300",
                   "--max-iter", "1000000000", "-o", str(out), "-q"], tmp_path)
    _wait_lines(out, 12, proc)
    proc.kill()  # kill -9: no chance to clean up
    proc.wait()
    with open(out, "ab") as f:  # and a torn half line, as if killed inside a write
        f.write(b'{"file": "x", "status": "sol')
    before = out.read_bytes().splitlines()[:-1]
    assert len(read_rows(out)) == len(before) >= 12  # the torn line is ignored
    # the same solve settings (--resume refuses others); murty23 stopped by --timeout
    r = cli("solve", str(slow_folder), "-m", "lemke", "-j", "2", "--max-iter", "1000000000",
            "--timeout", "2", "-o", str(out), "--resume", "--json", cwd=tmp_path)
    assert r.returncode == 1, r.stderr  # murty23 within 2 s: unsolved
    summary = json.loads(r.stdout)
    assert summary["skipped"] == len(before) and summary["new"] == 30 - len(before)
    rows = read_rows(out)
    keys = by_key(rows)  # no duplicates
    assert {k[1] for k in keys} == {f"e{i:02d}" for i in range(30)}  # nothing lost
    assert out.read_bytes().splitlines()[: len(before)] == before  # old rows untouched
    assert keys[(str(slow_folder / "e12.json"), "e12")]["status"] == "unsolved"
    assert sum(r["status"] == "solved" for r in rows) == 29
    # a second resume has nothing left to do
    report = lib([slow_folder], output=out, resume=True, jobs=1, method="lemke",
                 max_iter=1_000_000_000)
    assert report.new == 0 and report.skipped == 30 and len(read_rows(out)) == 30


def test_sigterm_leaves_valid_hdf5_and_resume(cli, slow_folder, tmp_path):
    out = tmp_path / "r.h5"
    proc = _popen(["solve", str(slow_folder), "-m", "lemke", "-j", "1", "--timeout", "300",
                   "--max-iter", "1000000000", "-o", str(out), "-q"], tmp_path)
    _wait_lines(journal_path(out), 12, proc)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143 and "--resume" in err and "Traceback" not in err
    assert not journal_path(out).exists()
    first = by_key(read_rows(out))
    assert len(first) >= 12
    r = cli("solve", str(slow_folder), "-m", "lemke", "--max-iter", "1000000000",
            "--timeout", "2", "-o", str(out), "--resume", "-q",
            cwd=tmp_path)
    assert r.returncode == 1
    rows = by_key(read_rows(out))
    assert len(rows) == 30
    assert all(strip(rows[k]) == strip(v) for k, v in first.items())


@pytest.mark.parametrize("ext", ["jsonl", "h5"])
def test_sigterm_of_a_new_batch_keeps_the_previous_result(slow_folder, tmp_path, ext):
    """SIGTERM of a new batch (no --resume) over an existing result file: exit 143, the
    message says the previous file is kept, and it is byte for byte as it was with no
    temporary file beside it (the batch wrote to one, replaced only when complete)."""
    out = tmp_path / f"r.{ext}"
    out.write_bytes(b"the previous results\n")
    proc = _popen(["solve", str(slow_folder), "-m", "lemke", "-j", "1", "--timeout", "300",
                   "--max-iter", "1000000000", "-o", str(out), "-q"], tmp_path)
    end = time.monotonic() + 40
    while time.monotonic() < end and not any(p.name.endswith(".tmp") and p.stat().st_size > 2048
                                             for p in tmp_path.iterdir()):
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143 and "Traceback" not in err, err
    assert f"{out} is kept as it was (a new batch replaces it only when complete)" in err
    assert out.read_bytes() == b"the previous results\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def test_hdf5_repaired_from_journal(cli, folder, tmp_path):
    """kill -9 in the middle of an HDF5 write: the journal rebuilds the file on --resume."""
    base, _ = folder
    out = tmp_path / "r.h5"
    lib([base / "probs"], recursive=True, jobs=1, output=out)
    full = by_key(read_rows(out))
    jrows = [json.dumps(row) for row in list(full.values())[:7]]
    journal_path(out).write_text("\n".join(jrows) + "\n" + jrows[7 % len(jrows)][:20])
    out.write_bytes(out.read_bytes()[:1000])  # a damaged HDF5 file
    assert len(read_rows(out)) == 7
    report = lib([base / "probs"], recursive=True, jobs=1, output=out, resume=True)
    assert report.exit_code == 2 and report.skipped == 7 and report.new == 5
    again = by_key(read_rows(out))
    assert {k: strip(v) for k, v in again.items()} == {k: strip(v) for k, v in full.items()}


def test_resume_csv_torn_line(cli, folder, tmp_path):
    base, _ = folder
    out = tmp_path / "r.csv"
    lib([base / "probs"], recursive=True, jobs=1, output=out)
    data = out.read_bytes()
    cut = data.index(b"\n", len(data) // 2) + 15
    out.write_bytes(data[:cut])
    n_kept = len(read_rows(out))
    assert 0 < n_kept < 12
    report = lib([base / "probs"], recursive=True, jobs=2, output=out, resume=True)
    assert report.new == 12 - n_kept and report.skipped == n_kept
    rows = read_rows(out)
    assert len(by_key(rows)) == 12
    assert out.read_text().count("source,problem") == 1


def test_timeout_kills_worker(cli, tmp_path):
    rng = np.random.default_rng(5)
    save(spd_problem(rng, 6, "a"), tmp_path / "a.json")
    save(murty(30), tmp_path / "b_slow.json")  # 2^30 pivots: would run for many minutes
    save(spd_problem(rng, 6, "c"), tmp_path / "c.json")
    t0 = time.monotonic()
    r = cli("solve", "a.json", "b_slow.json", "c.json", "--timeout", "1.5", "--max-iter",
            "2000000000", "--json", cwd=tmp_path)
    assert time.monotonic() - t0 < 40
    assert r.returncode == 1, r.stderr
    rows = by_key([json.loads(line) for line in r.stdout.splitlines()])
    slow = rows[("b_slow.json", "b_slow")]
    assert slow["status"] == "unsolved" and slow["message"] == "timeout"
    assert slow["termination"] == "timeout" and slow["seconds"] == 1.5
    assert rows[("a.json", "a")]["status"] == rows[("c.json", "c")]["status"] == "solved"


def test_single_file_mode_unchanged(cli, samples, tmp_path):
    r = cli("solve", str(samples / "seed004.json"), "--json")
    assert r.returncode == 0
    lines = r.stdout.splitlines()
    assert len(lines) == 1
    payload = json.loads(lines[0])
    assert "source" not in payload and payload["status"] == "solved"
    assert np.allclose(payload["z"], [4 / 3, 7 / 3])
    rng = np.random.default_rng(0)
    write_many([spd_problem(rng, 3, "x"), spd_problem(rng, 3, "y")], tmp_path / "two.h5")
    r = cli("solve", str(tmp_path / "two.h5"), "--json")  # several problems: a batch
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert r.returncode == 0 and sorted(row["problem"] for row in rows) == ["x", "y"]
    r = cli("solve", str(tmp_path / "two.h5"), "-p", "y", "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["problem"] == "y"


@pytest.mark.parametrize("args, needle", [
    (["--resume"], "--resume needs --output"),
    (["-o", "r.txt"], "unknown result file type"),
    (["-p", "x"], "--problem"),
    (["--timeout", "0"], "--timeout"),
    (["-m", "nosuchmethod"], "nosuchmethod"),
])
def test_bad_batch_usage(cli, folder, args, needle):
    base, _ = folder
    r = cli("solve", "probs", "nothere_*.json", *args, cwd=base)
    assert r.returncode == 2
    assert needle in r.stderr and "Traceback" not in r.stderr + r.stdout
    assert r.stdout == ""


def test_stream_json_rows_and_globs(cli, folder):
    base, problems = folder
    r = cli("solve", "probs/p0[0-4].json", "probs/nothere_*.json", "--json", cwd=base)
    assert r.returncode == 2  # the pattern that matches nothing is a bad input
    rows = by_key([json.loads(line) for line in r.stdout.splitlines()])
    assert len(rows) == 6
    assert rows[("probs/nothere_*.json", "")]["status"] == "error"
    for i in range(5):
        src = f"probs/p0{i}.json"
        check_by_substitution(rows[(src, f"p0{i}")], problems[src])


def test_dask_local_cluster(cli, folder, tmp_path):
    distributed = pytest.importorskip("distributed")
    base, problems = folder
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster:
        r = cli("solve", "probs", "-r", "--scheduler", cluster.scheduler_address,
                "-o", str(tmp_path / "d.jsonl"), "-q", cwd=base)
    assert r.returncode == 2, r.stderr
    rows = by_key(read_rows(tmp_path / "d.jsonl"))
    local = by_key(read_rows(base / "a.jsonl")) if (base / "a.jsonl").exists() else None
    assert len(rows) == 12
    assert sum(v["status"] == "error" for v in rows.values()) == 2
    for src, p in problems.items():
        check_by_substitution(rows[(src, Path(src).stem)], p)
    if local is not None:
        assert {k: strip(v) for k, v in rows.items()} == {k: strip(v) for k, v in local.items()}


def test_worker_crash_costs_one_problem(folder, tmp_path):
    """A worker that dies (segfault, OOM kill) is replaced; only its problem is lost.

    Workers do not fork from this process (forkserver), so nothing here can be patched into
    them: a slow problem keeps one worker busy, and once every other row is in, the test kills
    the workers with SIGKILL, as the kernel's OOM killer would.
    """
    import multiprocessing as mp

    from lcpcli.batch.inputs import expand_inputs
    from lcpcli.batch.pool import iter_local
    from lcpcli.batch.records import SolveOptions

    base, problems = folder
    slow = tmp_path / "slow.json"
    save(murty(23), slow)  # about 8e6 Lemke pivots: seconds
    tasks, bad = expand_inputs([str(base / "probs" / f"p0{i}.json") for i in (0, 1, 2, 3, 4)]
                               + [str(slow)] + [str(base / "probs" / f"p0{i}.json")
                                                for i in (7, 8)])
    assert not bad and len(tasks) == 8
    opts = SolveOptions(method="lemke", options={"max_iter": 10**9})
    rows, killed = [], []
    for row in iter_local(tasks, opts, jobs=2):
        rows.append(row)
        if len(rows) == len(tasks) - 1 and not killed:  # only the slow problem is left
            for proc in mp.active_children():
                os.kill(proc.pid, signal.SIGKILL)
                killed.append(proc.pid)
    assert killed and len(rows) == len(tasks)
    (crashed,) = [r for r in rows if r["source"] == str(slow)]
    rows = by_key(rows)
    assert crashed["status"] == "error" and "worker process died" in crashed["message"]
    assert f"exit code -{int(signal.SIGKILL)}" in crashed["message"]
    for src, p in problems.items():
        if Path(src).stem in {f"p0{i}" for i in (0, 1, 2, 3, 4, 7, 8)}:
            row = rows[(str(base / src), Path(src).stem)]
            check_by_substitution(row, p)


def test_hdf5_groups_read_like_single_loads(tmp_path):
    """The batch's fast HDF5 reader gives the same problems as ``load(path, group)``."""
    from lcpcli.io import load

    rng = np.random.default_rng(9)
    plain = spd_problem(rng, 5, "plain")
    mlcp = Problem.create(plain.M, plain.q, n_eq=2, name="mixed")
    box = Problem.create(plain.M, plain.q, lower=-np.ones(5), upper=np.ones(5), name="box")
    ints = Problem.create(np.eye(3, dtype=int), np.array([-1, 2, -3]), name="ints")
    write_many([plain, mlcp, box, ints], tmp_path / "kinds.h5")
    report = lib([tmp_path / "kinds.h5"], jobs=1, output=tmp_path / "k.jsonl", method="lemke")
    rows = by_key(read_rows(tmp_path / "k.jsonl"))
    src = str(tmp_path / "kinds.h5")
    assert report.total == 4
    for name in ("mixed", "box"):  # lemke handles LCPs only: the kind must survive the read
        assert rows[(src, name)]["status"] == "error"
        assert load(src, name).kind.upper() in rows[(src, name)]["message"]
    for p in (plain, ints):
        check_by_substitution(rows[(src, p.name)], load(src, p.name))
    assert rows[(src, "ints")]["z"] == [1.0, 0.0, 3.0]


def test_output_inside_input_folder_is_not_an_input(tmp_path):
    rng = np.random.default_rng(4)
    for i in range(3):
        save(spd_problem(rng, 4, f"x{i}"), tmp_path / f"x{i}.json")
    out = tmp_path / "results.h5"
    first = lib([tmp_path], jobs=1, output=out)
    again = lib([tmp_path], jobs=1, output=out, resume=True)
    assert first.total == again.total == again.skipped == 3 and again.exit_code == 0


def test_signals_deferred_holds_a_signal_another_thread_receives():
    """A row is written whole even when the kernel hands SIGTERM to another thread (BLAS and
    OpenMP threads exist in every lcpcli process): the handler runs only after the block."""
    import threading

    from lcpcli.batch.run import signals_deferred

    class Stop(Exception):
        pass

    def on_term(signum, frame):
        raise Stop()

    idle = threading.Event()
    helper = threading.Thread(target=idle.wait, daemon=True)  # signals unblocked there
    helper.start()
    old = signal.signal(signal.SIGTERM, on_term)
    steps = []
    try:
        with pytest.raises(Stop), signals_deferred():
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(200):
                time.sleep(0.001)  # the handler would run here if the signal were not held
            steps.append("written")
    finally:
        signal.signal(signal.SIGTERM, old)
        idle.set()
    assert steps == ["written"]
