"""Siconos worker for :mod:`lcpcli.bench.peers`: runs under Debian's ``/usr/bin/python3``.

Standalone on purpose (stdlib, numpy and ``siconos.numerics`` only; it never imports lcpcli,
whose dependencies that interpreter may lack).  Usage::

    /usr/bin/python3 siconos_worker.py PROBLEM.npz REQUEST_JSON

``PROBLEM.npz`` holds a dense ``M`` and ``q``; ``REQUEST_JSON`` is
``{"solvers": {"siconos-lemke": "LCP_LEMKE", ...}, "tol": 1e-8, "repeat": 5, "budget": 1.0,
"max_iter": null}``.  For each solver one line ``@@PEER@@{json}`` on stdout with ``name``,
``info`` (Siconos return code, 0 = success), ``iterations``, ``seconds`` (median of the timed
driver calls; one untimed warm-up first), ``repeats``, ``z``.  Siconos' C chatter is sent to
stderr.  A list of the available solvers: ``--probe`` (prints ``@@PEER@@{"version": ...}``).
"""

import json
import math
import os
import statistics
import sys
import time

MARK = "@@PEER@@"


def _emit(fd, obj):
    os.write(fd, (MARK + json.dumps(obj) + "\n").encode())


def main(argv):
    real_stdout = os.dup(1)
    os.dup2(2, 1)  # C printf output -> stderr
    import numpy as np
    import siconos.numerics as sn

    if argv[0] == "--probe":
        import siconos

        _emit(real_stdout, {"version": str(getattr(siconos, "version", "?"))})
        return 0
    with np.load(argv[0], allow_pickle=False) as data:
        M = np.array(data["M"], dtype=float)
        q = np.array(data["q"], dtype=float).ravel()
    req = json.loads(argv[1])
    n = q.size
    for name, key in req["solvers"].items():
        out = {"name": name}
        try:
            sid = getattr(sn, "SICONOS_" + key)
            prob = sn.LCP(M, q)
            z = np.zeros(n)
            w = np.zeros(n)

            def once(sid=sid, prob=prob, z=z, w=w):
                z[:] = 0.0
                w[:] = 0.0
                opts = sn.SolverOptions(sid)
                opts.dparam[sn.SICONOS_DPARAM_TOL] = float(req["tol"])
                if req.get("max_iter"):
                    opts.iparam[sn.SICONOS_IPARAM_MAX_ITER] = int(req["max_iter"])
                t0 = time.perf_counter()
                info = sn.linearComplementarity_driver(prob, z, w, opts)
                dt = time.perf_counter() - t0
                return int(info), dt, int(opts.iparam[sn.SICONOS_IPARAM_ITER_DONE])

            info, first, iters = once()
            times = []
            total = 0.0
            if first <= req["budget"]:
                for _ in range(max(0, int(req["repeat"]))):
                    info, dt, iters = once()
                    times.append(dt)
                    total += dt
                    if total > req["budget"]:
                        break
            out.update(info=info, iterations=iters,
                       seconds=statistics.median(times) if times else first,
                       repeats=len(times),
                       z=[float(x) if math.isfinite(x) else None for x in z])
        except Exception as exc:  # bindings raise RuntimeError for unbuilt solvers
            out.update(info=None, error=f"{type(exc).__name__}: {exc}")
        _emit(real_stdout, out)
    return 0


if __name__ == "__main__":
    code = main(sys.argv[1:])
    sys.stdout.flush()
    os._exit(code)  # skip interpreter teardown (Siconos destructors may abort)
