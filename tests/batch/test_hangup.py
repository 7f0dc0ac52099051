"""SIGHUP (the terminal closed, ``kill -HUP``) stops a batch as SIGTERM does: exit 129, the
output closed cleanly with every finished result (no journal, lock or temporary file left),
and ``--resume`` ends with the content of an uninterrupted run; under ``nohup`` (SIGHUP
ignored) the batch runs on to its end.

Most runs send the signal from inside the process at a fixed point of its work (a patched
function: after its ``AFTER``-th call), so the verdicts do not depend on timing; one sends it
to the whole process group from outside, as a closing terminal does.
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

from lcpcli.batch.output import journal_path, read_rows
from lcpcli.core.problem import Problem
from lcpcli.io import save
from lcpcli.io.stack import write_stack

ROOT = Path(__file__).resolve().parents[2]
SLOW_KEYS = ("seconds", "wall_seconds")

#: ``python -c SELF_SIGNAL SIG MODULE:ATTR AFTER ARGS...``: the CLI with ``MODULE.ATTR`` (a
#: function or method) patched to send ``SIG`` to its own process right after its
#: ``AFTER``-th call returned (0: nothing patched); stacks in chunks of
#: ``LCPCLI_TEST_CHUNK`` problems.
SELF_SIGNAL = """
import importlib, os, signal, sys
from lcpcli.cli import main

SIG, (module, attr), AFTER = getattr(signal, sys.argv[1]), sys.argv[2].split(":"), int(sys.argv[3])
if os.environ.get("LCPCLI_TEST_CHUNK"):
    import lcpcli.io.stack as stack_mod
    stack_mod.chunk_size = lambda n, **kw: int(os.environ["LCPCLI_TEST_CHUNK"])
owner = importlib.import_module(module)
*path, name = attr.split(".")
for part in path:
    owner = getattr(owner, part)
real, calls = getattr(owner, name), [0]


def patched(*args, **kwargs):
    out = real(*args, **kwargs)
    calls[0] += 1
    if calls[0] == AFTER:
        os.kill(os.getpid(), SIG)
    return out


if AFTER:
    setattr(owner, name, patched)
main(sys.argv[4:])
"""


def env() -> dict[str, str]:
    e = {**os.environ, "PYTHONPATH": str(ROOT), "LCPCLI_TEST_CHUNK": "50"}
    e.pop("LCPCLI_DEBUG", None)
    return e


def self_signal(sig: str, target: str, after: int, *args: str, ignore_hup: bool = False,
                ) -> subprocess.CompletedProcess[str]:
    """``lcpcli ARGS`` that sends itself ``sig`` after ``after`` calls of ``target``;
    ``ignore_hup``: started with SIGHUP ignored, as ``nohup`` starts it."""
    preexec = (lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN)) if ignore_hup else None
    return subprocess.run([sys.executable, "-c", SELF_SIGNAL, sig, target, str(after), *args],
                          env=env(), capture_output=True, text=True, timeout=120,
                          preexec_fn=preexec)


def lcpcli(*args: str) -> subprocess.CompletedProcess[str]:
    """``lcpcli ARGS`` as :func:`self_signal` runs it (stacks in the same chunks), no signal."""
    return self_signal("SIGHUP", "lcpcli.cli:main", 0, *args)


def strip(row: dict) -> dict:
    return {k: v for k, v in row.items() if k not in SLOW_KEYS}


def by_key(path: Path) -> dict:
    rows = read_rows(path)
    out = {(r["source"], r["problem"]): strip(r) for r in rows}
    assert len(out) == len(rows), "duplicate rows"
    return out


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 random positive definite LCPs (n = 5), one file each."""
    d = tmp_path_factory.mktemp("hup")
    rng = np.random.default_rng(3)
    for i in range(12):
        A = rng.standard_normal((5, 5))
        save(Problem.create(A @ A.T + 0.5 * np.eye(5), rng.standard_normal(5), name=f"p{i:02d}"),
             d / f"p{i:02d}.json")
    return d


#: The writer whose ``write`` takes each finished row of a per-file batch, by output kind.
ROW_WRITERS = {"jsonl": "lcpcli.batch.output:JsonlWriter.write",
               "h5": "lcpcli.batch.output:Hdf5Writer.write"}


@pytest.mark.parametrize("ext", ["jsonl", "h5"])
def test_sighup_stops_a_batch_cleanly_and_resume_completes_it(folder, tmp_path, ext):
    """``lcpcli solve DIR -o r.jsonl`` hung up after 5 rows: exit 129, one line naming the
    file to resume, only r.jsonl in its folder, 5 whole rows; --resume gives the rows of an
    uninterrupted run (SIGHUP killed the process, exit -1, and left r.jsonl.lock, and for
    HDF5 r.h5.journal, beside the output)."""
    ref, out = tmp_path / "ref" / f"r.{ext}", tmp_path / "out" / f"r.{ext}"
    ref.parent.mkdir(), out.parent.mkdir()
    common = ("solve", str(folder), "-m", "lemke", "-j", "1", "-q")
    assert lcpcli(*common, "-o", str(ref)).returncode == 0
    r = self_signal("SIGHUP", ROW_WRITERS[ext], 5, *common, "-o", str(out))
    assert r.returncode == 129, r.stderr
    assert r.stderr.startswith("lcpcli: hung up after ") and r.stderr.endswith(
        f" of 12; finished results are in {out}: run again with --resume to go on\n"), r.stderr
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]
    first = by_key(out)
    assert len(first) == 5
    before = out.read_bytes()
    r = lcpcli(*common, "-o", str(out), "--resume")
    assert r.returncode == 0, r.stderr
    assert by_key(out) == by_key(ref)
    if ext == "jsonl":
        assert out.read_bytes().startswith(before)  # the finished rows, untouched
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]


@pytest.mark.parametrize("ext", ["h5", "jsonl"])
def test_sighup_stops_a_stacked_batch_cleanly_and_resume_completes_it(tmp_path, ext):
    """``lcpcli solve stack.h5 -o res.h5`` hung up after its third chunk was solved: exit
    129, only res.h5 beside the output, its finished chunks marked done; --resume gives
    the arrays of an uninterrupted run."""
    rng = np.random.default_rng(8)
    A = rng.standard_normal((500, 4, 4))
    stack = tmp_path / "s.h5"
    write_stack(stack, A @ A.transpose(0, 2, 1) + 0.5 * np.eye(4), rng.standard_normal((500, 4)))
    ref, out = tmp_path / "ref" / f"r.{ext}", tmp_path / "out" / f"r.{ext}"
    ref.parent.mkdir(), out.parent.mkdir()
    common = ("solve", str(stack), "-m", "lemke", "-j", "2", "-q")
    assert lcpcli(*common, "-o", str(ref)).returncode == 0
    r = self_signal("SIGHUP", "lcpcli.batch.stacked:solve_read", 3, *common, "-o", str(out))
    assert r.returncode == 129, r.stderr
    assert r.stderr.startswith("lcpcli: hung up after ") and "--resume" in r.stderr, r.stderr
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]
    r = lcpcli(*common, "-o", str(out), "--resume", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["skipped"] >= 100  # the finished chunks were kept
    if ext == "h5":
        with h5py.File(out, "r") as f, h5py.File(ref, "r") as g:
            for key in ("z", "status", "chunk_digest", "basis"):
                np.testing.assert_array_equal(f["s"][key][...], g["s"][key][...])
    else:
        def rows(p: Path) -> dict:
            return {r["index"]: (r["z"], r["status"], r["input_hash"]) for r in read_rows(p)}
        assert rows(out) == rows(ref)


def test_nohup_keeps_a_batch_running_after_sighup(folder, tmp_path):
    """Started with SIGHUP ignored (``nohup lcpcli ...``), a batch is not stopped by it: it
    runs to its end (exit 0, every row)."""
    out = tmp_path / "r.jsonl"
    r = self_signal("SIGHUP", ROW_WRITERS["jsonl"], 5, "solve", str(folder), "-m", "lemke",
                    "-j", "1", "-q", "-o", str(out), ignore_hup=True)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert len(by_key(out)) == 12
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def murty(n: int) -> Problem:
    """Murty's P-matrix family: Lemke needs 2^n pivots (a slow problem on demand)."""
    M = np.tril(2.0 * np.ones((n, n)), -1) + np.eye(n)
    return Problem.create(M, -np.ones(n), name=f"murty{n}")


@pytest.mark.parametrize("ext", ["jsonl", "h5"])
def test_a_closing_terminal_stops_a_batch_and_its_workers_cleanly(tmp_path, ext):
    """SIGHUP to the whole process group (what a closing terminal sends: the workers and the
    forkserver get it too) once 6 rows are written, a slow problem holding the 7th: exit
    129, no lock or journal left, no row recorded for a worker that died of it, and
    --resume solves the rest."""
    d = tmp_path / "in"
    d.mkdir()
    rng = np.random.default_rng(4)
    for i in range(12):
        A = rng.standard_normal((5, 5))
        p = murty(23) if i == 6 else Problem.create(A @ A.T + 0.5 * np.eye(5),
                                                    rng.standard_normal(5), name=f"p{i:02d}")
        save(p, d / f"p{i:02d}.json")
    out = tmp_path / "out" / f"r.{ext}"
    out.parent.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "lcpcli", "solve", str(d), "-m", "lemke",
                             "-j", "1", "--timeout", "300", "--max-iter", "1000000000",
                             "-o", str(out), "-q"], env=env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    rows = journal_path(out) if ext == "h5" else out
    end = time.monotonic() + 60
    while not (rows.exists() and rows.read_bytes().count(b"\n") >= 6):
        if proc.poll() is not None or time.monotonic() > end:
            proc.kill()
            pytest.fail(f"the batch ended or wrote nothing in time: {proc.communicate()}")
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGHUP)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 129 and "--resume" in err and "Traceback" not in err, err
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]
    first = read_rows(out)
    assert len(first) >= 6 and all(r["status"] == "solved" for r in first)
    r = lcpcli("solve", str(d), "-m", "lemke", "--timeout", "2", "--max-iter", "1000000000",
               "-j", "1", "-o", str(out),
               "--resume", "-q")
    assert r.returncode == 1, r.stderr  # murty23 within 2 s: unsolved
    assert len(read_rows(out)) == 12
