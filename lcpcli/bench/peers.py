"""Peer solvers for ``lcpcli bench``: other LCP codes run side by side in the same benchmark.

* **Siconos** numerics (Debian ``python3-siconos``, for ``/usr/bin/python3``): run in a child
  process (``lcpcli/bench/siconos_worker.py``), one per problem, so that a solver that aborts cannot
  kill the benchmark.  Solvers: Lemke, Newton-FB (line search) and PGS.  LCP only.
* **lemkelcp** (``pip install lemkelcp``, pure Python/numpy Lemke tableau): run in process.

A peer returns a vector ``z``; the benchmark certifies it with
:func:`lcpcli.core.certificate.certify` exactly like the project's own methods (a peer's own
success flag is kept as ``claimed``). Peers never prove infeasibility here: a peer's verdict is
``solved`` or ``unsolved``.
Timing: one untimed warm-up, then up to ``repeat`` timed calls (stopping once their total
exceeds ``budget`` seconds), median; the time covers the solver call only.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: Debian's interpreter that has ``python3-siconos`` (override: ``$LCPCLI_SICONOS_PYTHON``).
SICONOS_PYTHON = "/usr/bin/python3"
#: Peer method name -> Siconos solver id suffix (``SICONOS_<key>``).
SICONOS_SOLVERS = {
    "siconos-lemke": "LCP_LEMKE",
    "siconos-newton-fb": "LCP_NEWTON_FB_FBLSA",
    "siconos-pgs": "LCP_PGS",
}
#: Seconds before a Siconos worker is killed, per solver (default when no timeout is given).
SICONOS_TIMEOUT = 300.0
WORKER = Path(__file__).with_name("siconos_worker.py")
MARK = "@@PEER@@"


@dataclass
class PeerRun:
    """What a peer returned: ``z`` (None if it gave none), its own success flag, the timing."""

    z: np.ndarray | None
    claimed: bool
    seconds: float | None
    iterations: int | None
    repeats: int
    message: str = ""
    #: Wall seconds after which the worker was killed (a timeout), else None.
    killed_after: float | None = None


@dataclass
class Peer:
    """One peer solver: a name (``siconos-lemke``), its family and a batch runner.

    ``run_many(problem, tol, repeat, budget, timeout=None)`` returns ``{peer name: PeerRun}``
    for every solver of the family in one go (one child process for Siconos).
    """

    family: str
    names: list[str]
    run_many: Callable[..., dict[str, PeerRun]]
    version: str = ""
    kinds: tuple[str, ...] = ("lcp",)
    info: dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------- discovery
def discover(wanted: list[str] | None = None) -> tuple[list[Peer], dict[str, str]]:
    """The peers available on this machine and, for the others, why not.

    ``wanted`` limits the families tried (``siconos``, ``lemkelcp``); None tries all.
    """
    found: list[Peer] = []
    missing: dict[str, str] = {}
    for family, probe in (("siconos", _siconos_peer), ("lemkelcp", _lemkelcp_peer)):
        if wanted is not None and family not in wanted:
            continue
        peer, why = probe()
        if peer is None:
            missing[family] = why
        else:
            found.append(peer)
    return found, missing


def _siconos_python() -> str:
    return os.environ.get("LCPCLI_SICONOS_PYTHON", SICONOS_PYTHON)


def _siconos_peer() -> tuple[Peer | None, str]:
    py = _siconos_python()
    if not (Path(py).exists() or shutil.which(py)):
        return None, f"{py} not found"
    try:
        proc = subprocess.run([py, str(WORKER), "--probe"], capture_output=True, text=True,
                              timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"{py} could not run ({type(exc).__name__})"
    lines = [x for x in proc.stdout.splitlines() if x.startswith(MARK)]
    if not lines:
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        return None, f"python3-siconos not importable by {py}: {tail[:160]}"
    version = str(json.loads(lines[-1][len(MARK):]).get("version", "?"))
    try:  # the Debian package version is the more telling one
        deb = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", "python3-siconos"],
                             capture_output=True, text=True, timeout=10).stdout.strip()
        if deb:
            version = f"{version} (Debian python3-siconos {deb})"
    except (OSError, subprocess.TimeoutExpired):
        pass
    return Peer("siconos", list(SICONOS_SOLVERS), run_siconos, version=version), ""


def _lemkelcp_peer() -> tuple[Peer | None, str]:
    try:
        import lemkelcp  # noqa: F401
    except ImportError:
        return None, "Python package 'lemkelcp' not installed (pip install lemkelcp)"
    from importlib.metadata import PackageNotFoundError, version

    try:
        ver = version("lemkelcp")
    except PackageNotFoundError:
        ver = "?"
    try:  # a smoke test: lemkelcp 0.1 assigns into a range() and fails under Python 3
        from lemkelcp.lemkelcp import lemkelcp as lemke_fn

        lemke_fn(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]), 10)
    except Exception as exc:  # noqa: BLE001
        return None, f"lemkelcp {ver} installed but unusable: {type(exc).__name__}: {exc}"
    return Peer("lemkelcp", ["lemkelcp"], run_lemkelcp, version=ver), ""


# ---------------------------------------------------------------------- runners
def run_siconos(problem: Any, tol: float, repeat: int, budget: float,
                names: list[str] | None = None, timeout: float | None = None) -> dict[str, PeerRun]:
    """Run the Siconos solvers on ``problem`` (dense copy) in one child process.

    If the child dies (a solver that aborts), each solver is retried alone so one crash costs
    only its own result.
    """
    names = list(SICONOS_SOLVERS) if names is None else names
    limit = timeout or SICONOS_TIMEOUT
    out = _siconos_batch(problem, tol, repeat, budget, names, limit * len(names))
    if len(names) > 1 and any(out[n].message.startswith("worker") for n in names):
        for name in names:
            if out[name].message.startswith("worker"):
                out.update(_siconos_batch(problem, tol, repeat, budget, [name], limit))
    return out


def _siconos_batch(problem: Any, tol: float, repeat: int, budget: float,
                   names: list[str], limit: float) -> dict[str, PeerRun]:
    req = {"solvers": {n: SICONOS_SOLVERS[n] for n in names}, "tol": tol, "repeat": repeat,
           "budget": budget, "max_iter": None}
    with tempfile.TemporaryDirectory(prefix="lcpcli_peer_") as tmp:
        path = Path(tmp) / "p.npz"
        np.savez(path, M=np.asarray(problem.dense_M(), dtype=float), q=problem.q)
        killed: float | None = None
        try:
            proc = subprocess.run([_siconos_python(), str(WORKER), str(path), json.dumps(req)],
                                  capture_output=True, text=True, timeout=limit)
            stdout, why = proc.stdout, f"exit code {proc.returncode}"
        except subprocess.TimeoutExpired as exc:
            stdout = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
            why, killed = f"timeout after {limit:g} s", limit
    got: dict[str, PeerRun] = {}
    for line in stdout.splitlines():
        if not line.startswith(MARK):
            continue
        d = json.loads(line[len(MARK):])
        if d.get("info") is None:
            got[d["name"]] = PeerRun(None, False, None, None, 0, d.get("error", "failed"))
            continue
        z = np.array([np.nan if v is None else v for v in d["z"]], dtype=float)
        got[d["name"]] = PeerRun(z, d["info"] == 0, float(d["seconds"]), d.get("iterations"),
                                 int(d["repeats"]), f"Siconos info = {d['info']}")
    for name in names:
        got.setdefault(name, PeerRun(None, False, None, None, 0, f"worker died ({why})",
                                     killed_after=killed))
    return got


def run_lemkelcp(problem: Any, tol: float, repeat: int, budget: float,
                 names: list[str] | None = None, timeout: float | None = None
                 ) -> dict[str, PeerRun]:
    """``lemkelcp.lemkelcp(M, q, maxIter)`` in process (pivot limit max(1000, 100 n)).

    ``timeout`` is not enforced (in process); the pivot limit bounds the work.
    """
    from lemkelcp.lemkelcp import lemkelcp as lemke_fn

    M = np.asarray(problem.dense_M(), dtype=float)
    q = np.asarray(problem.q, dtype=float)
    limit = max(1000, 100 * problem.n)

    def once() -> tuple[Any, float]:
        t0 = time.perf_counter()
        res = lemke_fn(M, q, limit)
        return res, time.perf_counter() - t0

    try:
        (z, code, text), first = once()
        times: list[float] = []
        if first <= budget:
            total = 0.0
            for _ in range(max(0, repeat)):
                (z, code, text), dt = once()
                times.append(dt)
                total += dt
                if total > budget:
                    break
    except Exception as exc:  # noqa: BLE001 - a peer's crash is a result, not our failure
        return {"lemkelcp": PeerRun(None, False, None, None, 0,
                                    f"{type(exc).__name__}: {exc}")}
    zz = None if z is None else np.asarray(z, dtype=float).ravel()
    return {"lemkelcp": PeerRun(zz, code == 0, statistics.median(times) if times else first,
                                None, len(times), str(text))}
