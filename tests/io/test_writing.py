"""The writing layer (lcpcli.io.writing): disk full, permission errors, links, same-file outputs.

Every write path of the CLI is run against a full disk: a real 2 MiB tmpfs where mounting is
permitted (root), and everywhere a file-size limit (``RLIMIT_FSIZE``: the kernel fails writes
past it with EFBIG) and injected ENOSPC for the Python API.  The invariants: exit code 2,
exactly one ``lcpcli: error: PATH: ...`` line, no traceback, the previous output byte for byte
as it was, and no temporary or partial file left behind (or, for incrementally written
results, a resumable prefix that ``--resume`` completes).
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lcpcli.core.errors import OutputError
from lcpcli.io import writing
from lcpcli.io.stack import write_stack
from tests.conftest import ROOT, SAMPLES, run_cli

PREVIOUS = b"the previous output\n"


def pd_problems(K: int, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((K, n, n))
    return A @ A.transpose(0, 2, 1) / n + np.eye(n), rng.standard_normal((K, n))


def one_line(res: subprocess.CompletedProcess[str], reason: str) -> str:
    """The single stderr line of a refused run (exit 2, no traceback)."""
    assert res.returncode == 2, (res.returncode, res.stderr[-2000:])
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: "), res.stderr[-2000:]
    assert reason in lines[0], lines[0]
    assert "Traceback" not in res.stderr and "internal error" not in res.stderr
    return lines[0]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    """A problem, a folder of 300 problems, a stack of 2,000 and a scene (outside the disk)."""
    base = tmp_path_factory.mktemp("inputs")
    M, q = pd_problems(2000, 8)
    folder = base / "dir"
    folder.mkdir()
    for k in range(300):
        (folder / f"p{k:03d}.json").write_text(json.dumps({"M": M[k].tolist(),
                                                           "q": q[k].tolist()}))
    write_stack(base / "stack.h5", M, q)
    shutil.copy(SAMPLES / "seed004.json", base / "p.json")
    shutil.copy(SAMPLES / "scene_cradle.json", base / "scene.json")
    return {"p": base / "p.json", "dir": folder, "stack": base / "stack.h5",
            "scene": base / "scene.json"}


#: (name, the command with OUT for the output, what OUT is)
WRITE_PATHS = [
    ("solve -o", ["solve", "{p}", "-o", "{out}"], "r.json"),
    ("batch jsonl", ["solve", "{dir}", "-o", "{out}", "-j", "1"], "r.jsonl"),
    ("batch csv", ["solve", "{dir}", "-o", "{out}", "-j", "1"], "r.csv"),
    ("batch h5", ["solve", "{dir}", "-o", "{out}", "-j", "1"], "r.h5"),
    ("stacked h5", ["solve", "{stack}", "-o", "{out}"], "r.h5"),
    ("stacked npz", ["solve", "{stack}", "-o", "{out}"], "r.npz"),
    ("contact -o", ["contact-matrix", "{scene}", "-o", "{out}"], "lcp.json"),
    ("contact --impulses", ["contact-matrix", "{scene}", "--solve", "--impulses", "{out}"],
     "imp.json"),
    ("enumerate -o", ["enumerate", "{p}", "-o", "{out}"], "e.json"),
    ("convert", ["convert", "{p}", "{out}", "--force"], "p.h5"),
    ("convert --stack h5", ["convert", "{dir}", "{out}", "--stack", "--force"], "s.h5"),
    ("convert --stack npz", ["convert", "{dir}", "{out}", "--stack", "--force"], "s.npz"),
    ("unstack", ["convert", "{stack}", "{out}", "--format", "json"], "un"),
]


def _args(template: list[str], inputs: dict[str, Path], out: Path) -> list[str]:
    return [a.format(out=out, **inputs) for a in template]


def _previous(out: Path) -> None:
    """The previous output: a file, or for an unstack folder a file already in it."""
    if out.suffix:
        out.write_bytes(PREVIOUS)
    else:
        out.mkdir()
        (out / "keep.txt").write_bytes(PREVIOUS)


def _assert_previous_intact(out: Path) -> None:
    if out.suffix:
        assert out.read_bytes() == PREVIOUS
        leftovers = sorted(p.name for p in out.parent.iterdir() if p != out)
    else:
        assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]
        assert (out / "keep.txt").read_bytes() == PREVIOUS
        leftovers = sorted(p.name for p in out.parent.iterdir() if p != out)
    assert leftovers in ([], ["filler"]), leftovers  # no temporary, journal or lock file


# ----------------------------------------------------------------------------- a real full disk
@pytest.fixture
def full_disk(tmp_path):
    """A 2 MiB tmpfs (skipped where mounting is not permitted), unmounted afterwards."""
    mnt = tmp_path / "full"
    mnt.mkdir()
    if shutil.which("mount") is None or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)],
                       capture_output=True, check=False)
    if r.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted here ({r.stderr.strip()[:80]!r})")
    yield mnt
    subprocess.run(["umount", "-l", str(mnt)], check=False)


def fill(folder: Path) -> None:
    """Write ``folder/filler`` until the file system is full."""
    with open(folder / "filler", "wb", buffering=0) as fh:
        block = b"\0" * 4096
        try:
            while True:
                fh.write(block)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC


@pytest.mark.parametrize(("name", "template", "target"), WRITE_PATHS,
                         ids=[w[0] for w in WRITE_PATHS])
def test_full_disk_every_write_path(full_disk, inputs, name, template, target):
    """ENOSPC on a real tmpfs: exit 2, one line, previous output intact, nothing partial
    (``convert DIR s.h5 --stack`` segfaulted here, exit 139, before io.writing; a new batch
    replaced its previous result file as it started, before ReplacingWriter).  Without a
    previous file, a batch leaves a resumable prefix that --resume completes."""
    out = full_disk / target
    _previous(out)
    fill(full_disk)
    res = run_cli(*_args(template, inputs, out))
    line = one_line(res, "no space left on device")
    assert str(full_disk) in line
    _assert_previous_intact(out)
    if name.startswith("batch "):
        out.unlink()
        line = one_line(run_cli(*_args(template, inputs, out)), "no space left on device")
        _assert_resumable(out, full_disk, template, inputs)


def _assert_resumable(out: Path, folder: Path, template: list[str], inputs: dict) -> None:
    """A first batch result file is written in place: after a failure it is absent or holds
    complete rows only, and --resume completes it."""
    from lcpcli.batch.output import read_rows

    extra = {p.name for p in folder.iterdir()} - {out.name, "filler", f"{out.name}.journal"}
    assert not extra, extra
    before = read_rows(out)
    assert all(r["status"] == "solved" for r in before)
    os.unlink(folder / "filler")
    res = run_cli(*_args(template, inputs, out), "--resume", "-q")
    assert res.returncode == 0, res.stderr
    assert sorted(r["problem"] for r in read_rows(out)) == [f"p{k:03d}" for k in range(300)]


def test_full_disk_behind_stdout_is_one_line(full_disk, inputs):
    """``solve p.json --json > FULL/x``: the failed write of stdout is one line too."""
    fill(full_disk)
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    with open(full_disk / "x", "w") as stdout:
        res = subprocess.run([sys.executable, "-m", "lcpcli", "solve", str(inputs["p"]),
                              "--json"], stdout=stdout, stderr=subprocess.PIPE, text=True,
                             env=env, cwd=ROOT, timeout=120)
    one_line(res, "standard output: no space left on device")


def test_full_disk_mid_batch_leaves_a_resumable_prefix(full_disk, inputs):
    """A disk that fills in the middle of a JSONL batch: the rows written are complete lines,
    and once there is space again --resume finishes the batch with every problem once."""
    out = full_disk / "r.jsonl"
    st = os.statvfs(full_disk)
    (full_disk / "filler").write_bytes(b"\0" * (st.f_bavail * st.f_frsize - 48 * 1024))
    res = run_cli("solve", str(inputs["dir"]), "-o", str(out), "-j", "1", "-q")
    one_line(res, "no space left on device")
    data = out.read_bytes()
    assert data.endswith(b"\n") and 0 < data.count(b"\n") < 300
    assert all(json.loads(line)["status"] == "solved" for line in data.splitlines())
    os.unlink(full_disk / "filler")
    res = run_cli("solve", str(inputs["dir"]), "-o", str(out), "--resume", "-q")
    assert res.returncode == 0, res.stderr
    rows = [json.loads(line) for line in out.read_bytes().splitlines()]
    assert sorted(r["problem"] for r in rows) == [f"p{k:03d}" for k in range(300)]


def test_read_only_result_file_is_one_line(full_disk, inputs):
    """--resume on a result file that cannot be written (a read-only file system here; a
    read-only file for non-root users): one line, exit 2 (was exit 3 PermissionError)."""
    out = full_disk / "r.h5"
    assert run_cli("solve", str(inputs["stack"]), "-o", str(out)).returncode == 0
    before = out.read_bytes()
    subprocess.run(["mount", "-o", "remount,ro", str(full_disk)], check=True)
    for target in (out, full_disk / "r.npz", full_disk / "r.jsonl"):
        res = run_cli("solve", str(inputs["stack"]), "-o", str(target), "--resume")
        one_line(res, "read-only file system")
    assert out.read_bytes() == before


# ----------------------------------------------------------------------------- a size limit
FSIZE_RUNNER = """
import resource, sys
limit = int(sys.argv[1])  # Python ignores SIGXFSZ: the write fails with EFBIG instead
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
from lcpcli.cli import main
main(sys.argv[2:])
"""


def run_limited(limit: int, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("LCPCLI_DEBUG", None)
    return subprocess.run([sys.executable, "-c", FSIZE_RUNNER, str(limit), *args],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)


@pytest.mark.parametrize(("name", "template", "target"),
                         [w for w in WRITE_PATHS if w[0] in (
                             "batch jsonl", "batch csv", "batch h5", "stacked h5", "stacked npz",
                             "convert --stack h5", "convert --stack npz")],
                         ids=lambda w: w if isinstance(w, str) else None)
def test_file_size_limit_is_one_line(tmp_path, inputs, name, template, target):
    """Writes past RLIMIT_FSIZE fail with EFBIG (no root needed): one line, exit 2, and the
    previous output intact; a first batch (no previous file) leaves a resumable prefix."""
    out = tmp_path / target
    _previous(out)
    res = run_limited(64 * 1024, *_args(template, inputs, out))
    one_line(res, "file too large")
    _assert_previous_intact(out)
    if name.startswith("batch "):
        out.unlink()
        one_line(run_limited(64 * 1024, *_args(template, inputs, out)), "file too large")
        if target.endswith(".h5"):  # the rows are in the journal; --resume rebuilds the file
            assert (tmp_path / "r.h5.journal").exists()
        res = run_cli(*_args(template, inputs, out), "--resume", "-q")
        assert res.returncode == 0, res.stderr
        from lcpcli.batch.output import read_rows

        assert sorted(r["problem"] for r in read_rows(out)) == [f"p{k:03d}" for k in range(300)]


READONLY_RUNNER = """
import errno, os, sys
target = os.path.basename(sys.argv[1])
real_open = os.open

def read_only(path, flags, *args, **kwargs):  # the result file is read-only (mode 0444)
    if os.path.basename(os.fsdecode(path)) == target and flags & (os.O_WRONLY | os.O_RDWR):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), path)
    return real_open(path, flags, *args, **kwargs)

os.open = read_only
from lcpcli.cli import main
main(sys.argv[2:])
"""


@pytest.mark.parametrize("ext", ["h5", "jsonl", "csv"])
def test_resume_of_a_read_only_result_is_one_line(tmp_path, inputs, ext):
    """--resume on a result file that cannot be opened for writing (EACCES, as for a
    read-only file of a non-root user; was exit 3 PermissionError): one line, exit 2, the
    file unchanged."""
    out = tmp_path / f"r.{ext}"
    args = ["solve", str(inputs["stack"]), "-o", str(out)]
    assert run_cli(*args).returncode == 0
    if ext == "h5":  # as if interrupted: the second half is still to do
        import h5py

        with h5py.File(out, "a") as f:
            f["stack"]["status"][1000:] = -1
    else:
        lines = out.read_bytes().splitlines(keepends=True)
        out.write_bytes(b"".join(lines[:1000]))
    before = out.read_bytes()
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    res = subprocess.run([sys.executable, "-c", READONLY_RUNNER, out.name, *args, "--resume"],
                         capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    one_line(res, "permission denied")
    assert out.read_bytes() == before


# ----------------------------------------------------------------------------- injected ENOSPC
def _fail_after(monkeypatch, calls: int) -> None:
    """Make os.write / os.pwrite fail with ENOSPC after ``calls`` successful calls."""
    state = {"left": calls}
    real_write, real_pwrite = os.write, os.pwrite

    def gate() -> None:
        if state["left"] <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        state["left"] -= 1

    def write(fd, data):
        gate()
        return real_write(fd, data)

    def pwrite(fd, data, offset):
        gate()
        return real_pwrite(fd, data, offset)

    monkeypatch.setattr(os, "write", write)
    monkeypatch.setattr(os, "pwrite", pwrite)


def test_injected_enospc_atomic_text_keeps_previous(tmp_path, monkeypatch):
    out = tmp_path / "r.json"
    out.write_bytes(PREVIOUS)
    _fail_after(monkeypatch, 0)
    with pytest.raises(OutputError) as exc:
        writing.write_atomic_text(out, "new content")
    monkeypatch.undo()
    assert str(exc.value) == f"{out}: no space left on device"
    assert out.read_bytes() == PREVIOUS and os.listdir(tmp_path) == ["r.json"]


def test_injected_enospc_append_is_cut_back(tmp_path, monkeypatch):
    path = tmp_path / "rows.jsonl"
    f = writing.AppendFile(path)
    f.write('{"a": 1}\n')
    real_write = os.write

    def torn(fd, data):  # half the row lands, then the disk is full
        if len(data) > 4:
            return real_write(fd, bytes(data[:4]))
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "write", torn)
    with pytest.raises(OutputError, match="no space left on device"):
        f.write('{"b": 2}\n')
    monkeypatch.undo()
    f.close()
    assert path.read_bytes() == b'{"a": 1}\n'


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.text(min_size=1, max_size=40).map(lambda t: t.replace("\n", " ") + "\n"),
                     min_size=1, max_size=12),
       fail_at=st.integers(0, 15), landed=st.integers(0, 30))
def test_appended_rows_are_always_a_prefix(tmp_path_factory, rows, fail_at, landed):
    """Whatever row fails and however many of its bytes land first, the file holds exactly
    the rows written before it (a resumable prefix)."""
    path = tmp_path_factory.mktemp("append") / "rows.jsonl"
    f = writing.AppendFile(path)
    real_write = os.write
    calls = {"n": 0}

    def flaky(fd, data):
        calls["n"] += 1
        if calls["n"] - 1 == fail_at:
            if landed and landed < len(data):
                real_write(fd, bytes(data[:landed]))
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)

    written = []
    os.write = flaky
    try:
        for row in rows:
            try:
                f.write(row)
            except OutputError:
                break
            written.append(row)
    finally:
        os.write = real_write
        f.close()
    assert path.read_bytes() == "".join(written).encode("utf-8", "surrogateescape")


def test_injected_enospc_write_stack_hdf5(tmp_path, monkeypatch):
    M, q = pd_problems(500, 6)
    out = tmp_path / "s.h5"
    out.write_bytes(PREVIOUS)
    _fail_after(monkeypatch, 3)
    with pytest.raises(OutputError, match="no space left on device"):
        write_stack(out, M, q)
    monkeypatch.undo()
    assert out.read_bytes() == PREVIOUS and os.listdir(tmp_path) == ["s.h5"]


@pytest.mark.parametrize("ext", ["h5", "npz", "jsonl"])
def test_injected_enospc_stacked_batch_resumes(tmp_path, monkeypatch, ext):
    """ENOSPC in the middle of a stacked batch (Python API; chunks of 500, the disk full from
    the third chunk on, or at the end for NPZ): an OutputError, no temporary or lock file, and a
    file that --resume completes with every answer the one of a fresh run."""
    from lcpcli.api import solve_many
    from lcpcli.batch import stack_output
    from lcpcli.batch.output import read_rows
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch
    from lcpcli.io import stack as stack_mod

    M, q = pd_problems(3000, 6, seed=3)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / f"r.{ext}"
    monkeypatch.setattr(stack_mod, "chunk_size", lambda n, **kw: 500)
    cls = {"h5": stack_output.Hdf5StackWriter, "npz": stack_output.NpzStackWriter,
           "jsonl": stack_output.RowStackWriter}[ext]
    method = "close" if ext == "npz" else "write"
    real_method = getattr(cls, method)
    real_write, real_pwrite = os.write, os.pwrite
    state = {"calls": 0, "full": False}

    def full(fn):
        def wrapped(*args):
            if state["full"]:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return fn(*args)
        return wrapped

    def step(self, *args):
        state["calls"] += 1
        if state["calls"] == 3 or method == "close":
            state["full"] = True
        return real_method(self, *args)

    monkeypatch.setattr(cls, method, step)
    monkeypatch.setattr(os, "write", full(real_write))
    monkeypatch.setattr(os, "pwrite", full(real_pwrite))
    with pytest.raises(OutputError, match="no space left on device"):
        run_batch([str(stack)], SolveOptions(), output=out)
    monkeypatch.setattr(os, "write", real_write)
    monkeypatch.setattr(os, "pwrite", real_pwrite)
    monkeypatch.setattr(cls, method, real_method)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith((".tmp", ".lock"))]
    if ext != "npz":
        assert len(read_rows(out)) == 1000 if ext == "jsonl" else out.exists()
    report = run_batch([str(stack)], SolveOptions(), output=out, resume=True)
    assert report.exit_code == 0 and report.skipped == (0 if ext == "npz" else 1000)
    ref = solve_many(M, q)
    if ext == "jsonl":
        rows = sorted(read_rows(out), key=lambda r: r["index"])
        assert [r["index"] for r in rows] == list(range(3000))
        np.testing.assert_allclose([r["z"] for r in rows], ref.z, atol=1e-12)
    elif ext == "npz":
        with np.load(out) as d:
            np.testing.assert_allclose(d["z"], ref.z, atol=1e-12)
    else:
        import h5py

        with h5py.File(out) as f:
            np.testing.assert_allclose(f["s"]["z"][...], ref.z, atol=1e-12)


# ----------------------------------------------------------------------------- links
def test_symlinked_journal_is_refused_and_victim_untouched(cli, tmp_path):
    """``ln -s victim.txt r.h5.journal`` before --resume: refused with one line; victim.txt
    (no final newline: it used to be truncated, then appended to) is not changed."""
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    shutil.copy(SAMPLES / "seed004.json", a)
    shutil.copy(SAMPLES / "seed000.json", b)
    out = tmp_path / "r.h5"
    assert cli("solve", str(a), "-o", str(out)).returncode == 0
    victim = tmp_path / "victim.txt"
    victim.write_bytes(b"precious, without a final newline")
    (tmp_path / "r.h5.journal").symlink_to(victim)
    res = cli("solve", str(a), str(b), "-o", str(out), "--resume")
    one_line(res, "is a symbolic link")
    assert victim.read_bytes() == b"precious, without a final newline"
    assert (tmp_path / "r.h5.journal").is_symlink()
    for ext in ("jsonl", "csv"):  # a linked row file is refused the same way
        link = tmp_path / f"l.{ext}"
        link.symlink_to(victim)
        one_line(cli("solve", str(a), "-o", str(link), "--resume"), "symbolic link")
    assert victim.read_bytes() == b"precious, without a final newline"


def test_links_beside_a_new_batch_output(cli, tmp_path):
    """Without --resume a linked stale journal is removed (the link, never its target); a
    linked lock file is refused; the target is untouched either way."""
    a = tmp_path / "a.json"
    shutil.copy(SAMPLES / "seed004.json", a)
    victim = tmp_path / "victim.txt"
    victim.write_bytes(b"precious")
    journal = tmp_path / "r.h5.journal"
    journal.symlink_to(victim)
    assert cli("solve", str(a), "-o", str(tmp_path / "r.h5")).returncode == 0
    assert not os.path.lexists(journal) and victim.read_bytes() == b"precious"
    (tmp_path / "s.jsonl.lock").symlink_to(victim)
    one_line(cli("solve", str(a), "-o", str(tmp_path / "s.jsonl")), "symbolic link")
    assert victim.read_bytes() == b"precious" and not (tmp_path / "s.jsonl").exists()


def _foreign(kind: str, path: Path, victim: Path) -> None:
    """Put into the HDF5 result ``path`` an object reaching outside it."""
    import h5py

    with h5py.File(path, "a") as f:
        if kind == "external link":
            del f["s"]
            f["s"] = h5py.ExternalLink(str(victim), "/")
        elif kind == "soft link":
            f["other"] = h5py.SoftLink("/s")
        elif kind == "virtual dataset":
            layout = h5py.VirtualLayout(shape=(4,), dtype="f8")
            layout[:] = h5py.VirtualSource(str(victim), "data", shape=(4,))
            f["s"].create_virtual_dataset("v", layout)
        else:  # external storage
            f["s"].create_dataset("x", shape=(4,), dtype="f8", external=[(str(victim), 0, 32)])


@pytest.mark.parametrize("kind", ["external link", "soft link", "virtual dataset",
                                  "external storage"])
def test_resumed_stacked_result_never_reaches_outside(cli, tmp_path, kind):
    """A results.h5 whose group is an ExternalLink to victim.h5 (or holds a soft link, a
    virtual dataset, external storage): --resume refuses it; victim.h5 is not rewritten."""
    import h5py

    M, q = pd_problems(50, 4)
    stack = tmp_path / "s.h5"
    write_stack(stack, M, q)
    out = tmp_path / "r.h5"
    assert cli("solve", str(stack), "-o", str(out)).returncode == 0
    victim = tmp_path / "victim.h5"
    with h5py.File(victim, "w") as f:
        f["data"] = np.arange(4.0)
        f.attrs["mine"] = "yes"
    before = victim.read_bytes()
    _foreign(kind, out, victim)
    res = cli("solve", str(stack), "-o", str(out), "--resume")
    one_line(res, "lcpcli never writes")
    assert victim.read_bytes() == before


def test_resumed_batch_h5_with_external_link_is_refused(cli, tmp_path):
    import h5py

    a = tmp_path / "a.json"
    shutil.copy(SAMPLES / "seed004.json", a)
    out = tmp_path / "r.h5"
    assert cli("solve", str(a), "-o", str(out)).returncode == 0
    victim = tmp_path / "victim.h5"
    with h5py.File(victim, "w") as f:
        f.create_group("g")
    before = victim.read_bytes()
    with h5py.File(out, "a") as f:
        f["link"] = h5py.ExternalLink(str(victim), "/g")
    one_line(cli("solve", str(a), "-o", str(out), "--resume"), "external link")
    assert victim.read_bytes() == before


# ----------------------------------------------------------------------------- same file
def test_an_output_is_never_an_input_nor_the_other_output(cli, tmp_path):
    scene = tmp_path / "scene.json"
    shutil.copy(SAMPLES / "scene_cradle.json", scene)
    original = scene.read_bytes()
    z0 = tmp_path / "z0.json"
    z0.write_text("[0.0, 0.0]")
    x = tmp_path / "x.json"
    cases = [
        (["contact-matrix", str(scene), "--solve", "--impulses", str(scene)], "same file"),
        (["contact-matrix", str(scene), "--solve", "-o", str(x), "--impulses", str(x)],
         "same file as --output"),
        (["contact-matrix", str(scene), "--solve", "-o", str(x), "--impulses",
          str(tmp_path / "." / "x.json")], "same file as --output"),
        (["contact-matrix", str(scene), "--solve", "--z0", str(z0), "--impulses", str(z0)],
         "same file"),
        (["enumerate", str(SAMPLES / "seed004.json"), "-o", str(x), "--plot", str(x)],
         "same file as --output"),
    ]
    for args, reason in cases:
        one_line(cli(*args), reason)
    assert scene.read_bytes() == original and z0.read_text() == "[0.0, 0.0]"
    assert not x.exists()


def test_a_name_ending_in_a_slash_is_refused_by_every_writer(cli, tmp_path):
    """``-o x.json/`` names a folder: it wrote a regular file x.json (pathlib drops the slash)
    and replaced an existing one.  check_output refuses it (one line, exit 2) for every
    writer; ``-o -`` and plain names are unaffected."""
    p = tmp_path / "p.json"
    shutil.copy(SAMPLES / "degenerate.json", p)
    scene = tmp_path / "scene.json"
    shutil.copy(SAMPLES / "scene_cradle.json", scene)
    kept = tmp_path / "kept.json"
    kept.write_text('{"keep": true}\n')
    reason = "not a directory"
    cases = [
        (["solve", str(p), "-o", f"{tmp_path}/x.json/"], "x.json"),
        (["solve", str(p), "-o", f"{kept}/"], None),
        (["solve", str(p), "-o", f"{tmp_path}/x.json/."], "x.json"),
        (["solve", str(p), str(p), "-o", f"{tmp_path}/r.jsonl/"], "r.jsonl"),
        (["enumerate", str(p), "-o", f"{tmp_path}/e.json/"], "e.json"),
        (["convert", str(p), f"{tmp_path}/c.json/"], "c.json"),
        (["bench", str(p), "-m", "lemke", "-r", "1", "--no-peers", "--timeout", "0",
          "--markdown", f"{tmp_path}/m.md/"], "m.md"),
        (["contact-matrix", str(scene), "--solve", "--impulses", f"{tmp_path}/i.json/"],
         "i.json"),
    ]
    for args, absent in cases:
        line = one_line(cli(*args), reason)
        assert args[-1] in line
        if absent is not None:
            assert not (tmp_path / absent).exists(), args
    assert kept.read_text() == '{"keep": true}\n'
    with pytest.raises(writing.ProblemError, match="not a directory"):
        writing.check_output(f"{tmp_path}/y.json/")
    writing.check_output("-")
    writing.check_output(tmp_path / "y.json")
    writing.check_output(str(kept))
    assert writing.names_folder("a/") and writing.names_folder("a/.")
    assert not writing.names_folder("a.json") and not writing.names_folder("./a.json")
    res = cli("convert", str(p), "-")
    assert res.returncode == 0 and json.loads(res.stdout)
    res = cli("solve", str(p), "-o", str(tmp_path / "ok.json"))
    assert res.returncode == 0 and json.loads((tmp_path / "ok.json").read_text())


# ----------------------------------------------------------------------------- unstack
def test_unstack_is_all_or_nothing(cli, tmp_path):
    """NaN in problem 3 of 5: exit 2 and no a.json, b.json, c.json left (nor the folder)."""
    M, q = pd_problems(5, 3)
    M[3, 0, 0] = np.nan
    stack = tmp_path / "nan.h5"
    write_stack(stack, M, q, names=list("abcde"))
    for folder, existed in ((tmp_path / "new", False), (tmp_path / "old", True)):
        if existed:
            folder.mkdir()
        one_line(cli("convert", str(stack), str(folder), "--format", "json"), "NaN")
        assert folder.exists() == existed
        if existed:
            assert list(folder.iterdir()) == []


# ----------------------------------------------------------------------------- a new batch
def _fail_tmp_writes_after(monkeypatch, calls: int) -> None:
    """ENOSPC for writes to a temporary file ``.NAME.XXXXXXXX.tmp`` after ``calls`` of them
    (other descriptors, such as the worker pipes, are left alone)."""
    state = {"left": calls}
    real_write, real_pwrite = os.write, os.pwrite

    def gated(fd: int) -> None:
        try:
            name = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            return
        if name.endswith(".tmp"):
            if state["left"] <= 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            state["left"] -= 1

    def write(fd, data):
        gated(fd)
        return real_write(fd, data)

    def pwrite(fd, data, offset):
        gated(fd)
        return real_pwrite(fd, data, offset)

    monkeypatch.setattr(os, "write", write)
    monkeypatch.setattr(os, "pwrite", pwrite)


@pytest.mark.parametrize("ext", ["jsonl", "csv", "h5"])
@pytest.mark.parametrize("end", ["full disk", "interrupted", "complete"])
def test_new_batch_replaces_the_previous_result_only_when_complete(tmp_path, monkeypatch,
                                                                  inputs, ext, end):
    """A new batch (no --resume) over an existing result file writes beside it: a full disk
    in the middle or an interruption leaves the previous file -- and an HDF5 file's journal --
    byte for byte as they were, with no temporary file; a complete batch replaces both (was:
    the previous file was replaced as the batch started, so a full disk lost it)."""
    from lcpcli.batch.output import journal_path, read_rows
    from lcpcli.batch.records import SolveOptions
    from lcpcli.batch.run import run_batch

    out = tmp_path / f"r.{ext}"
    out.write_bytes(PREVIOUS)
    journal = journal_path(out)
    if ext == "h5":
        journal.write_bytes(PREVIOUS)
    files = sorted(inputs["dir"].iterdir())[:40]
    if end == "full disk":
        _fail_tmp_writes_after(monkeypatch, 20)
        with pytest.raises(OutputError) as exc:
            run_batch(files, SolveOptions(), output=out, jobs=1)
        monkeypatch.undo()
        assert str(exc.value) == f"{out}: no space left on device (the previous file is kept " \
                                 f"as it was: free space, then run again)"
    elif end == "interrupted":
        def stop(row):
            if row["problem"] == "p010":
                raise KeyboardInterrupt

        with pytest.raises(KeyboardInterrupt):
            run_batch(files, SolveOptions(), output=out, jobs=1, on_row=stop)
    else:
        report = run_batch(files, SolveOptions(), output=out, jobs=1)
        assert report.exit_code == 0
        assert sorted(r["problem"] for r in read_rows(out)) == [p.stem for p in files]
        assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]
        assert out.stat().st_mode & 0o777 == 0o644 & ~_umask()
        return
    assert out.read_bytes() == PREVIOUS
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [out.name] + ([journal.name] if ext == "h5" else []))
    if ext == "h5":
        assert journal.read_bytes() == PREVIOUS


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_start_writeback_changes_no_byte_and_never_fails(tmp_path, monkeypatch):
    """``start_writeback`` (Linux ``sync_file_range``, nothing elsewhere) only starts the
    writing of a file's dirty pages: the bytes read back are those written, before and after
    more writes; a descriptor that is no file, or a C library without the call, is no error;
    a handle opened read-only never asks."""
    path = tmp_path / "f.bin"
    data = os.urandom(3 << 20)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        os.write(fd, data)
        writing.start_writeback(fd)
        os.pwrite(fd, b"x" * 100, 1000)
        writing.start_writeback(fd)
    finally:
        os.close(fd)
    assert path.read_bytes() == data[:1000] + b"x" * 100 + data[1100:]
    writing.start_writeback(fd)  # closed now: the call fails, silently
    monkeypatch.setattr(writing, "_SYNC_FILE_RANGE", False)
    writing.start_writeback(0)
    called = []
    monkeypatch.setattr(writing, "start_writeback", called.append)
    import h5py

    with h5py.File(tmp_path / "r.h5", "w") as f:
        f["x"] = np.arange(3)
    handle = writing.Hdf5Handle(tmp_path / "r.h5", "r")
    handle.start_writeback()
    handle.close()
    assert called == []
