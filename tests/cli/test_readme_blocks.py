"""The README's code blocks run as written (issue 27).

Every ```python block (in order, in one interpreter, as a reader pastes them) and every
```console line (``$ ...``) is run in a temporary folder holding a copy of ``samples/``,
twice (a second run must work too). ``lcpcli`` on a console line means this checkout's CLI:
it is run as ``sys.executable -m lcpcli`` (the ``lcpcli`` executable on PATH may be another
install); an absolute ``/tmp/`` path is moved into the temporary folder.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def blocks(kind: str) -> list[str]:
    """The bodies of the README's fenced blocks of one language."""
    text = README.read_text()
    return re.findall(rf"^```{kind}\n(.*?)^```", text, re.M | re.S)


def console_lines() -> list[str]:
    return [line[2:] for block in blocks("console") for line in block.splitlines()
            if line.startswith("$ ")]


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    shutil.copytree(ROOT / "samples", tmp_path / "samples")
    return tmp_path


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env["NO_COLOR"] = "1"
    env.pop("LCPCLI_DEBUG", None)
    return env


def test_the_readme_has_the_blocks():
    assert len(blocks("python")) >= 2 and len(console_lines()) >= 5


def test_python_blocks_run_as_written(folder):
    code = "\n\n".join(blocks("python"))
    script = folder / "readme_blocks.py"
    script.write_text(code)
    for _ in range(2):
        p = subprocess.run([sys.executable, str(script)], cwd=folder, env=_env(),
                           capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stderr[-3000:]


def _command(line: str, folder: Path) -> str:
    """A console line for bash: this checkout's CLI, /tmp/ moved into ``folder``."""
    python = shlex.quote(sys.executable)
    line = line.replace("/tmp/", f"{folder}/")  # first: the interpreter may live under /tmp
    line = re.sub(r"(^|\|\s*)lcpcli\b", lambda m: f"{m.group(1)}{python} -m lcpcli", line)
    return re.sub(r"(^|\|\s*)python\b", lambda m: f"{m.group(1)}{python}", line)


@pytest.mark.parametrize("line", console_lines())
def test_console_lines_run_as_written(line, folder):
    command = _command(line, folder)
    for attempt in range(2):  # a second run in the same folder works as well
        p = subprocess.run(["bash", "-c", command], cwd=folder, env=_env(),
                           capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, (line, attempt, p.stderr[-2000:])
        assert "Traceback" not in p.stderr


# ------------------------------------------------------------------------ the batch estimate
def _simulate(monkeypatch, capsys, total: int, startup: float, per_problem: float) -> str:
    """Feed ``_maybe_estimate`` a batch on a fake clock: ``startup`` seconds before the first
    result, then one result every ``per_problem`` seconds; return what it printed."""
    from lcpcli.cli import batch_run

    clock = {"t": 0.0}
    monkeypatch.setattr(batch_run.time, "perf_counter", lambda: clock["t"])
    state = {"total": total, "done": 0, "start": 0.0, "estimated": False}
    clock["t"] = startup
    for _ in range(total):
        state["done"] += 1
        batch_run._maybe_estimate(state, quiet=False)
        clock["t"] += per_problem
    return capsys.readouterr().err


def _seconds(text: str) -> float:
    from lcpcli.cli.common import duration

    m = re.search(r"about (.+?) to go", text)
    assert m, text
    for s in range(1, 10**6):  # invert duration(): the first whole second that prints the same
        if duration(float(s)) == m.group(1):
            return float(s)
    raise AssertionError(text)


@pytest.mark.parametrize("startup, per_problem", [(8.0, 0.05), (0.2, 0.05), (30.0, 0.5)])
def test_batch_estimate_is_within_3x_of_the_time_left(monkeypatch, capsys, startup,
                                                      per_problem):
    """A long start-up (worker processes) does not inflate the estimate: it is measured after
    the first result (before: 8 s of start-up and 400 problems at 50 ms said 'about 53 min')."""
    total = 400
    err = _simulate(monkeypatch, capsys, total, startup, per_problem)
    assert err.count("to go") == 1
    from lcpcli.cli.batch_run import ESTIMATE_MIN_PROBLEMS

    actual = (total - 1 - ESTIMATE_MIN_PROBLEMS) * per_problem  # left when it was printed
    assert actual / 3 <= _seconds(err) <= actual * 3


def test_small_or_short_batches_get_no_estimate(monkeypatch, capsys):
    assert _simulate(monkeypatch, capsys, 5, 30.0, 20.0) == ""  # 5 problems: no sample
    assert _simulate(monkeypatch, capsys, 400, 30.0, 0.001) == ""  # done in under 10 s
