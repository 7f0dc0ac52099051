"""Batch backends beside the built-in ``"cpu"`` one (:mod:`lcpcli.solvers.batched`).

Both run the single-source kernels, ``lcpcli/solvers/kernels/src/lcp_stack.h`` (one C text
of batched Lemke with the lexicographic ratio test, projected SOR and the certificate):

* ``"c"`` (:mod:`.c`): that text compiled by the C compiler (:mod:`lcpcli.solvers.kernels.
  stack_c`, OpenMP threads).  The test suite checks it against the ``"cpu"`` backend on every
  run: it is the device's code, run where there is no device.
* ``"cuda"`` (:mod:`.cuda`): the same text compiled by NVRTC through CuPy (the ``gpu``
  extra: ``pip install "lcpcli[gpu]"``), one device thread per problem.

Each kernel hands back (``KERNEL_RETRY``) what it does not certify; the backend runs the
``"cpu"`` kernel on those problems before the caller's full pipeline sees the rest, so the
verdicts are those of the ``"cpu"`` backend.
"""

from __future__ import annotations

#: The name of the source every backend here compiles (in :mod:`lcpcli.solvers.kernels`).
SOURCE = "src/lcp_stack.h"
