"""The device benchmarks' one way to run the warp kernel from modules built ahead with nvcc."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def use_cubins(folder: Path) -> dict[tuple[str, ...], Any]:
    """Make ``backends/cuda.py``'s module lookup return the modules in ``folder``
    (``mb1.cubin`` ... ``mb4.cubin``: ``lcp_stack.h`` built with ``-DLCP_WARP_MIN_BLOCKS=k``)
    instead of NVRTC builds, for the NVRTC options of that budget (``mb1`` also for no
    option: budget 1 is the default); other options still go to NVRTC.  The modules by
    options."""
    import cupy as cp

    from lcpcli.solvers.backends import cuda

    modules: dict[tuple[str, ...], Any] = {}
    for mb in (1, 2, 3, 4):
        path = folder / f"mb{mb}.cubin"
        if path.exists():
            modules[(f"-DLCP_WARP_MIN_BLOCKS={mb}",)] = cp.RawModule(path=str(path))
            if mb == 1:
                modules[()] = modules[(f"-DLCP_WARP_MIN_BLOCKS={mb}",)]
    nvrtc = cuda._module

    def lookup(device: int, extra: tuple[str, ...] = ()) -> Any:
        return modules[extra] if extra in modules else nvrtc(device, extra)
    cuda._module = lookup
    return modules
