"""Shared fixtures: paths, the Siconos data folder, and a CLI runner.

The CLI is run as ``python -m lcpcli`` with this checkout on PYTHONPATH, so the tests exercise
this tree whatever is installed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

from lcpcli.bench.suites import siconos_root  # noqa: E402  (one definition of where the data is)

#: CI (``CI=true``, as ``.ci/run`` is run) draws the same examples on every run, so a
#: submission lands or fails on its own code; a developer's run draws new ones each time and
#: keeps exploring (a failure found there is added as an explicit example or a regression test).
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
    settings.load_profile("ci")

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
_found = siconos_root()
SICONOS = _found if _found is not None else ROOT.parent / "shared" / "data" / "siconos"
SHARED = SICONOS.parent.parent


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def samples() -> Path:
    return SAMPLES


@pytest.fixture(scope="session")
def siconos() -> Path:
    if not SICONOS.is_dir():
        pytest.skip("../shared/data/siconos is not beside this checkout "
                    "(or set LCPCLI_SICONOS_DATA)")
    return SICONOS


def run_cli(*args: str, stdin: str | None = None, env: dict[str, str] | None = None,
            cwd: Path | None = None, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """Run ``python -m lcpcli ARGS``; returns the completed process (text mode)."""
    full_env = dict(os.environ)
    full_env["PYTHONPATH"] = str(ROOT) + os.pathsep + full_env.get("PYTHONPATH", "")
    full_env.pop("LCPCLI_DEBUG", None)
    if env:
        full_env.update(env)
    return subprocess.run([sys.executable, "-m", "lcpcli", *args], input=stdin,
                          capture_output=True, text=True, env=full_env, cwd=cwd or ROOT,
                          timeout=timeout)


@pytest.fixture(scope="session")
def cli():
    return run_cli
