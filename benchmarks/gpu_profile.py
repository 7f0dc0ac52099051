"""One launch of the warp kernel per size, for Nsight Compute on a CUDA device.

    ncu --clock-control none --kernel-name lcp_lemke_warp_stack --section WarpStateStats ... \
        python benchmarks/gpu_profile.py --cubins DIR [--sizes 12:200000,50:20000]

For random positive definite stacks (benchmarks/bench_stack.py's ``make_stack``), Lemke with
the certificate through ``backends/cuda.py``'s ``run_lemke`` as shipped (WARP_TABLE), one
launch per size.  ``--cubins DIR``: the warp kernel built ahead with nvcc (``mb1.cubin`` ...
``mb4.cubin``, ``-DLCP_WARP_MIN_BLOCKS=k``; add ``-lineinfo`` for ncu's source view) in place
of the package's NVRTC build.  Prints each size's certified count, so a profile of a kernel
that failed is not mistaken for one that ran.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _gpu import use_cubins  # noqa: E402
from bench_stack import make_stack  # noqa: E402

from lcpcli.solvers.backends import cuda  # noqa: E402
from lcpcli.solvers.batched import KERNEL_SOLVED  # noqa: E402
from lcpcli.solvers.registry import get_method  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cubins", type=Path, default=None)
    ap.add_argument("--sizes", default="12:200000,50:20000", help="n:K pairs, comma-separated")
    args = ap.parse_args()
    import cupy as cp

    if args.cubins is not None:
        use_cubins(args.cubins)
    spec = get_method("lemke")
    for pair in args.sizes.split(","):
        n, K = (int(x) for x in pair.split(":"))
        M, q = make_stack(K, n, seed=2026)
        Md, qd = cp.asarray(M), cp.asarray(q)
        o = cuda.run_lemke(Md, qd, tol=spec.default_tol, options={}, scaling=spec.scaling,
                           variant="warp")
        cp.cuda.Device().synchronize()
        print(f"n={n} K={K} row={cuda.warp_row(n)} certified="
              f"{int((o['code'] == KERNEL_SOLVED).sum())}", flush=True)


if __name__ == "__main__":
    main()
