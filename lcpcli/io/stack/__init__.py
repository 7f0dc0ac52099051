"""Stacked problem files: K problems of one size n in one NPZ or HDF5 file, by job.

* :mod:`~lcpcli.io.stack.layout`: the format (names, shapes, the rules a header must meet),
  :class:`StackInfo`, :class:`StackChunk`, the naming rule and :func:`chunk_size`;
* :mod:`~lcpcli.io.stack.readers`: detection from headers (:func:`is_stack`),
  :class:`StackReader` (chunked reads) and the functions built on it;
* :mod:`~lcpcli.io.stack.writer`: :class:`StackWriter`, :func:`write_stack`;
* :mod:`~lcpcli.io.stack.convert`: folders, lists of problems and multi-group HDF5 files to and
  from stacks (``lcpcli convert``).

The names below are the package's interface; callers import them from ``lcpcli.io.stack``
(and look :func:`chunk_size` up here, at call time, so that a test may replace it).
"""

from __future__ import annotations

from lcpcli.io.stack.convert import (
    check_member_name,
    check_output_folder,
    copy_stack,
    source_names,
    source_problems,
    stack_from_problems,
    write_folder,
    write_groups,
    write_stack_from,
)
from lcpcli.io.stack.layout import (
    H5_CACHE_BYTES,
    H5_CACHE_SLOTS,
    H5_CHUNK_BYTES,
    MAX_NAMES_DECLARED,
    MAX_STACK_PROBLEMS,
    STACK_FORMATS,
    StackChunk,
    StackInfo,
    chunk_size,
    problem_name,
    stacked_message,
)
from lcpcli.io.stack.readers import (
    StackReader,
    is_stack,
    iter_problems,
    list_names,
    open_stack,
    read_single,
    stack_info,
)
from lcpcli.io.stack.writer import StackWriter, write_stack

__all__ = [
    "H5_CACHE_BYTES", "H5_CACHE_SLOTS", "H5_CHUNK_BYTES", "MAX_NAMES_DECLARED",
    "MAX_STACK_PROBLEMS", "STACK_FORMATS", "StackChunk", "StackInfo", "StackReader",
    "StackWriter", "check_member_name", "check_output_folder", "chunk_size", "copy_stack",
    "is_stack", "iter_problems", "list_names", "open_stack", "problem_name", "read_single",
    "source_names", "source_problems", "stack_from_problems", "stack_info", "stacked_message",
    "write_folder", "write_groups", "write_stack", "write_stack_from",
]
