"""Limits on what a user may ask for, defined once (numpy-free: the CLI checks them at start)."""

from __future__ import annotations

#: The largest iteration or pivot limit accepted (the kernels count in 32-bit signed integers
#: in places; a larger limit means "never stop" anyway).
MAX_ITER = 2**31 - 1
