"""Per-file batches through worker processes (issue 25 item 4): rows sent in groups and the
``input_hash`` hashed by the worker from the bytes it parsed give the same result file as one
process solving row by row and the client hashing each file itself."""

from __future__ import annotations

import json

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.batch.output import content_fingerprint, input_fingerprint, read_rows
from lcpcli.batch.records import SolveOptions
from lcpcli.batch.run import run_batch

#: Row fields that are timings, not results.
TIMED = ("seconds",)


def _files(tmp_path, count: int, n: int = 5) -> list[str]:
    rng = np.random.default_rng(count)
    paths = []
    for k in range(count):
        A = rng.standard_normal((n, n))
        doc = {"M": (A @ A.T / n + np.eye(n)).tolist(), "q": rng.standard_normal(n).tolist()}
        if k % 7 == 3:  # some bad inputs among them: error rows in the same groups
            doc = {"M": doc["M"], "q": doc["q"][:-1]}
        if k % 11 == 5:
            doc = {"M": doc["M"], "q": doc["q"], "q ": 1}
        p = tmp_path / f"p{k:03d}.json"
        p.write_text(json.dumps(doc))
        paths.append(str(p))
    return paths


def _untimed(rows: list[dict]) -> dict[tuple[str, str], dict]:
    return {(r["source"], r["problem"]): {k: v for k, v in r.items() if k not in TIMED}
            for r in rows}


def test_grouped_worker_rows_equal_one_process_rows(tmp_path):
    """200 files (chunks of many rows per message with two workers) against one job: the
    same rows apart from timings, each input_hash the client's fingerprint of its file."""
    files = _files(tmp_path, 200)
    one, two = tmp_path / "one.jsonl", tmp_path / "two.jsonl"
    r1 = run_batch(files, SolveOptions("lemke"), jobs=1, output=one)
    r2 = run_batch(files, SolveOptions("lemke"), jobs=2, output=two)
    assert r1.tally.counts == r2.tally.counts and r2.new == 200
    assert r1.tally.counts.get("error", 0) > 0 and r1.tally.counts.get("solved", 0) > 0
    rows1, rows2 = read_rows(one), read_rows(two)
    assert len(rows2) == len(rows1) == 200
    assert _untimed(rows1) == _untimed(rows2)
    for row in rows2:
        assert row["input_hash"] == input_fingerprint(row["source"])


@settings(max_examples=30, deadline=None)
@given(data=st.binary(max_size=3 << 20))
def test_content_fingerprint_is_the_file_fingerprint(tmp_path_factory, data):
    """The worker's hash of the bytes it read equals the client's hash of the file (read in
    1 MiB blocks)."""
    path = tmp_path_factory.mktemp("fp") / "x.json"
    path.write_bytes(data)
    assert content_fingerprint(data) == input_fingerprint(path)


def test_folder_listing_matches_pathlib(tmp_path):
    """The one-scandir folder listing finds what ``Path.glob``/``rglob`` found: problem files by
    extension (any case, hidden ones too), links to files followed, links to folders not
    descended into, a broken link skipped; the sub-folder hint as before."""
    from pathlib import Path

    from lcpcli.batch.inputs import _folder_files
    from lcpcli.io import PROBLEM_EXTENSIONS

    root = tmp_path / "tree"
    (root / "sub" / "deep").mkdir(parents=True)
    (root / "other").mkdir()
    for name in ("a.json", "B.JSON", ".hidden.json", "c.txt", "sub/d.npz", "sub/deep/e.h5",
                 "other/f.dat", "sub/g.json5"):
        (root / name).write_text("{}")
    (root / "link.json").symlink_to(root / "a.json")
    (root / "broken.json").symlink_to(root / "missing.json")
    (root / "sub" / "up").symlink_to(root / "other", target_is_directory=True)
    for recursive in (False, True):
        walker = root.rglob("*") if recursive else root.glob("*")
        want = sorted(str(f) for f in walker
                      if f.is_file() and f.suffix.lower() in PROBLEM_EXTENSIONS)
        found, subfolders = _folder_files(str(root), recursive)
        assert found == want and subfolders == any(c.is_dir() for c in Path(root).iterdir())
        assert len(found) == (4 if not recursive else 7)


def test_workers_started_early_are_stopped_when_the_batch_is_refused(tmp_path):
    """Workers start before the inputs are listed; a batch refused after that (its output is a
    hard link to one of the files found in its folder), or with fewer chunks than workers,
    leaves no worker process behind."""
    import multiprocessing as mp
    import os

    import pytest

    from lcpcli.core.errors import ProblemError

    folder = tmp_path / "in"
    folder.mkdir()
    files = _files(folder, 3)
    out = tmp_path / "same.jsonl"
    os.link(files[0], out)
    with pytest.raises(ProblemError, match="holds problems of this batch"):
        run_batch([str(folder)], SolveOptions("lemke"), jobs=2, output=out)
    assert not mp.active_children()
    report = run_batch(files[:1], SolveOptions("lemke"), jobs=2, output=tmp_path / "one.jsonl")
    assert report.new == 1 and not mp.active_children()
